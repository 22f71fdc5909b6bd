"""No drift between the server and its Python client (``clients/python``): every route of the server's OpenAPI
document is one the client speaks to (``v3d_client.ROUTES``) or one it leaves out saying why
(``v3d_client.LEFT_OUT``), and every field of every answer the client reads has its counterpart in the client's model
of it (and the other way round), through every nested object. A new route or a new answer field fails here until the
client (or its left-out list) follows."""
from __future__ import annotations

import types
import typing
from pathlib import Path
from typing import Any

import pytest
from fastapi import APIRouter
from pydantic import BaseModel

from app.api.schemas import HealthOut
from app.core.config import Settings
from app.main import create_app
from v3d_client import LEFT_OUT, ROUTES
from v3d_client.models import Model


def _spec(tmp_path: Path, extra: APIRouter | None = None) -> dict[str, Any]:
    app = create_app(Settings(_env_file=None, database_url=f"sqlite:///{tmp_path / 'openapi.sqlite3'}"))
    if extra is not None:
        app.include_router(extra, prefix="/api")
    return app.openapi()


def _resolve(spec: dict[str, Any], schema: dict[str, Any]) -> dict[str, Any]:
    while "$ref" in schema:
        schema = spec["components"]["schemas"][schema["$ref"].rsplit("/", 1)[1]]
    return schema


def _objects(spec: dict[str, Any], schema: dict[str, Any]) -> list[dict[str, Any]]:
    """The object schemas (with named properties) that ``schema`` may be or hold as items or values."""
    schema = _resolve(spec, schema)
    found: list[dict[str, Any]] = []
    for option in schema.get("anyOf", []) + schema.get("oneOf", []):
        found += _objects(spec, option)
    if schema.get("properties"):
        found.append(schema)
    for key in ("items", "additionalProperties"):
        if isinstance(schema.get(key), dict):
            found += _objects(spec, schema[key])
    for item in schema.get("prefixItems", []):
        found += _objects(spec, item)
    return found


def _models(annotation: Any) -> list[type[BaseModel]]:
    """The pydantic models ``annotation`` may be or hold (through Optional, unions, lists, dicts, tuples)."""
    if isinstance(annotation, type) and issubclass(annotation, BaseModel):
        return [annotation]
    origin = typing.get_origin(annotation)
    if origin is None and not isinstance(annotation, types.UnionType):
        return []
    return [m for arg in typing.get_args(annotation) for m in _models(arg)]


def _fields(model: type[BaseModel]) -> dict[str, Any]:
    return {(f.alias or name): f.annotation for name, f in model.model_fields.items()}


def _compare(spec: dict[str, Any], schema: dict[str, Any], model: type[BaseModel], where: str) -> list[str]:
    props = schema["properties"]
    fields = _fields(model)
    problems = [f"{where}.{p}: the server answers it, {model.__name__} has no field for it"
                for p in props if p not in fields]
    problems += [f"{where}.{f}: {model.__name__} has it, the server no longer answers it"
                 for f in fields if f not in props]
    for name in props.keys() & fields.keys():
        objects, models = _objects(spec, props[name]), _models(fields[name])
        for obj in objects:
            if not models:
                problems.append(f"{where}.{name}: the server answers an object with fields, {model.__name__} "
                                "types it without a model")
                continue
            best = max(models, key=lambda m: len(set(_fields(m)) & set(obj["properties"])))
            problems += _compare(spec, obj, best, f"{where}.{name}")
    return problems


def drift(spec: dict[str, Any]) -> list[str]:
    """Every difference between the server's OpenAPI ``spec`` and the client, in words (none: no drift)."""
    served = {f"{method.upper()} {path}": op for path, ops in spec["paths"].items() for method, op in ops.items()}
    problems = [f"{r}: the server has this route; the client neither speaks to it (v3d_client.ROUTES) nor leaves it "
                "out saying why (v3d_client.LEFT_OUT)" for r in served if r not in ROUTES and r not in LEFT_OUT]
    problems += [f"{r}: the client names a route the server does not have" for r in {**ROUTES, **LEFT_OUT}
                 if r not in served]
    problems += [f"{r}: both spoken to and left out" for r in ROUTES.keys() & LEFT_OUT.keys()]
    for route, model in ROUTES.items():
        if model is None or route not in served:
            continue
        answers = {code: a for code, a in served[route]["responses"].items() if code.startswith("2")}
        for code, answer in answers.items():
            schema = answer.get("content", {}).get("application/json", {}).get("schema")
            if not schema:
                problems.append(f"{route}: answers no JSON ({code}), the client reads it as {model.__name__}")
                continue
            objects = _objects(spec, schema)
            if not objects:
                problems.append(f"{route}: answers no object with fields ({code})")
            for obj in objects:
                problems += _compare(spec, obj, model, f"{route} {code}")
    return problems


def test_every_route_and_answer_field_has_its_counterpart_in_the_client(tmp_path: Path) -> None:
    assert drift(_spec(tmp_path)) == []


def test_every_route_left_out_says_why() -> None:
    for route, why in LEFT_OUT.items():
        assert len(why.split()) >= 5, f"{route}: {why!r} is no reason"


@pytest.mark.parametrize("change", ["route", "field"])
def test_a_route_or_a_field_added_without_the_client_is_drift(tmp_path: Path, change: str,
                                                              monkeypatch: pytest.MonkeyPatch) -> None:
    """The check itself: a new route, or a new field of an answer the client reads, is reported by name."""
    extra = None
    if change == "route":
        extra = APIRouter()

        @extra.get("/widgets", response_model=HealthOut)
        def widgets() -> HealthOut:
            return HealthOut(status="ok", version="0")

        expected = "GET /api/widgets: the server has this route"
    else:
        monkeypatch.setitem(HealthOut.model_fields, "uptime_s", HealthOut.model_fields["status"])
        HealthOut.model_rebuild(force=True)
        expected = "GET /api/health 200.uptime_s: the server answers it, Health has no field for it"
    try:
        problems = drift(_spec(tmp_path, extra))
    finally:
        monkeypatch.undo()
        HealthOut.model_rebuild(force=True)
    assert any(p.startswith(expected) for p in problems), problems
    assert len(problems) == 1, problems


def test_the_client_models_are_the_clients_own() -> None:
    """Each model of the routes is the client's (never one of the server's schemas imported)."""
    assert all(m is None or issubclass(m, Model) for m in ROUTES.values())
