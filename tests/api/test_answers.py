"""The hot routes' answers serialised in their worker thread (``app.api.answers``) are the bytes FastAPI's
``response_model`` would have sent, with the headers and status the route set."""
from __future__ import annotations

from typing import Optional

from fastapi import Response
from pydantic import BaseModel, ConfigDict, Field, TypeAdapter

from app.api.answers import json_answer
from app.api.queue_schemas import SystemPageOut
from app.api.view_schemas import SystemView


class _Inner(BaseModel):
    model_config = ConfigDict(populate_by_name=True, serialize_by_alias=True)
    class_: str = Field(alias="class")
    points: list[list[float]]


class _Answer(BaseModel):
    id: int
    ratio: float
    note: Optional[str]
    inner: list[_Inner]


def test_json_answer_is_the_response_models_bytes_with_the_routes_headers() -> None:
    model = _Answer(id=3, ratio=1e-5, note=None, inner=[_Inner(class_="Side line left", points=[[1.25, 2.0]])])
    sub = Response()
    del sub.headers["content-length"]  # as FastAPI makes a route's Response parameter
    sub.headers["ETag"] = '"frame-3-7"'
    sub.headers["X-V3D-Audit-Entry"] = "12"
    out = json_answer(model, sub)
    assert out.body == TypeAdapter(_Answer).dump_json(model, by_alias=True)  # what serialize_response sends
    assert b'"class":"Side line left"' in out.body and b'"note":null' in out.body
    assert out.headers["content-type"] == "application/json"
    assert out.headers["etag"] == '"frame-3-7"' and out.headers["x-v3d-audit-entry"] == "12"
    assert int(out.headers["content-length"]) == len(out.body)
    assert out.status_code == 200
    sub.status_code = 201
    assert json_answer(model, sub).status_code == 201


def test_the_system_view_answers_as_its_response_model(client, scene) -> None:
    """The page's answer parses as the SystemView it declares, and says so in its OpenAPI schema."""
    r = client.get(f"/api/systems/{scene.system_id}")
    assert r.status_code == 200 and r.headers["content-type"] == "application/json"
    view = SystemView.model_validate_json(r.content)
    assert r.content == TypeAdapter(SystemView).dump_json(view, by_alias=True)
    assert r.headers["etag"] == view.etag
    schema = client.get("/openapi.json").json()["paths"]["/api/systems/{system_id}"]["get"]
    assert schema["responses"]["200"]["content"]["application/json"]["schema"]["$ref"].endswith("/SystemView")


def test_the_queue_answers_as_its_response_model(client, scene) -> None:
    """The queue's page (serialised in its worker thread) parses as the SystemPageOut it declares, its bytes are that
    model's, and its OpenAPI schema still names it."""
    r = client.get("/api/systems", params={"limit": 2})
    assert r.status_code == 200 and r.headers["content-type"] == "application/json"
    page = SystemPageOut.model_validate_json(r.content)
    assert page.items and page.total >= len(page.items)
    assert r.content == TypeAdapter(SystemPageOut).dump_json(page, by_alias=True)
    schema = client.get("/openapi.json").json()["paths"]["/api/systems"]["get"]
    assert schema["responses"]["200"]["content"]["application/json"]["schema"]["$ref"].endswith("/SystemPageOut")
