"""Numbers checked at every door (issue 7, item 6): the gaps a review of the write schemas found.
Each bad request answers 4xx naming the field and stores nothing."""
from __future__ import annotations

import pytest
from fastapi.testclient import TestClient

from ..factories import Scene

#: The edit routes run on a real engine, as served (tests/api/conftest.py).
# Served: refused before anything is written: the same on either engine, so not an ``engine`` module.
pytestmark = pytest.mark.served


def _view(client: TestClient, scene: Scene) -> dict:
    return client.get(f"/api/systems/{scene.system_id}").json()


@pytest.mark.parametrize(("box", "at"), [([True, 10, 40, 50], 0), ([10, "10", 40, 50], 1), ([10, 10, 40, None], 3)])
def test_a_box_of_booleans_or_strings_is_not_read_as_numbers(client: TestClient, scene: Scene, box: list,
                                                             at: int) -> None:
    """``true`` was stored as x1 = 1.0 and ``"10"`` as 10.0: a coordinate must be a JSON number."""
    before = _view(client, scene)
    answer = client.patch(f"/api/frames/{scene.frame_ids[0]}/ball", json={"box": box})
    assert answer.status_code == 422, answer.text
    assert answer.json()["detail"][0]["loc"] == ["body", "box", at]
    assert _view(client, scene) == before


def test_field_line_points_far_outside_the_image_are_refused(client: TestClient, scene: Scene) -> None:
    """A point 5000 px left of a 960x540 image was stored and calibrated; up to 5 % of the image's size
    outside it is kept (annotations lie slightly outside), beyond that 422 naming class, polyline, point."""
    before = _view(client, scene)
    far = {"lines": {"Middle line": [[[480, 0], [480, 540]]], "Side line top": [[[0, 10], [-5000, 12]]]}}
    answer = client.put(f"/api/frames/{scene.frame_ids[0]}/field-lines", json=far)
    assert answer.status_code == 422 and answer.json()["field"] == "lines"
    assert "class 'Side line top', polyline 0, point 1: [-5000.0, 12.0]" in answer.json()["detail"]
    assert _view(client, scene) == before
    near = {"lines": {"Middle line": [[[480, -20], [480, 560]]]}}  # 20 px outside a 540-px-high image: kept
    assert client.put(f"/api/frames/{scene.frame_ids[0]}/field-lines", json=near).status_code == 200


def test_line_sets_are_bounded(client: TestClient, scene: Scene) -> None:
    before = _view(client, scene)
    long = {"lines": {"Middle line": [[[480, y / 10] for y in range(1001)]]}}
    answer = client.put(f"/api/frames/{scene.frame_ids[0]}/field-lines", json=long)
    assert answer.status_code == 422 and answer.json()["detail"][0]["loc"][:3] == ["body", "lines", "Middle line"]
    many = {"lines": {"Middle line": [[[480, 10], [480, 20]]] * 101}}
    answer = client.put(f"/api/frames/{scene.frame_ids[0]}/field-lines", json=many)
    assert answer.status_code == 422 and "lines['Middle line']: more than 100 polylines" in answer.text
    coords = {"lines": {"Middle line": [[[480, "10"], [480, 20]]]}}
    answer = client.put(f"/api/frames/{scene.frame_ids[0]}/field-lines", json=coords)
    assert answer.status_code == 422 and answer.json()["detail"][0]["loc"] == ["body", "lines", "Middle line", 0, 0, 1]
    assert _view(client, scene) == before


@pytest.mark.parametrize("query", ["error_min=inf", "error_max=1e999", "jac_min=nan"])
def test_queue_filters_must_be_finite(client: TestClient, scene: Scene, query: str) -> None:
    answer = client.get(f"/api/systems?{query}")
    assert answer.status_code == 422 and answer.json()["detail"][0]["loc"] == ["query", query.split("=")[0]]
    assert client.get(f"/api/frames?{query}").status_code == 422


@pytest.mark.parametrize(("body", "field"), [
    ({"kind": "sn-calibration", "path": "x", "width": 10**9, "height": 540}, "width"),
    ({"kind": "sn-calibration", "path": "x", "width": 960, "height": 1}, "height"),
    ({"kind": "sn-calibration", "path": "x", "width": 960.5, "height": 540}, "width"),
    ({"kind": "soccernet-v3", "path": ""}, "path"),
    ({"kind": "soccernet-v3", "path": "x", "extra": 1}, "extra"),
])
def test_import_fields_are_checked(client: TestClient, body: dict, field: str) -> None:
    answer = client.post("/api/imports", json=body)
    assert answer.status_code == 422 and answer.json()["detail"][0]["loc"] == ["body", field], answer.text
    assert client.get("/api/jobs").json()["total"] == 0


@pytest.mark.parametrize("query", ["user=%00ana", "offset=9223372036854775808"])
def test_list_filters_refuse_nul_characters_and_ids_beyond_the_columns(client: TestClient, query: str) -> None:
    """A NUL in the audit log's ``user`` filter was a 500 on PostgreSQL (its text cannot hold one; found by
    the fuzz test in CI); an offset beyond 64 bits overflowed SQLite's driver. Both are 422 naming the field."""
    for path in ("/api/audit", "/api/jobs") if query.startswith("offset") else ("/api/audit",):
        answer = client.get(f"{path}?{query}")
        assert answer.status_code == 422, (path, answer.text)
        assert answer.json()["detail"][0]["loc"][-1] == query.split("=")[0]


def test_a_boolean_in_a_comments_point_is_refused_naming_it(client: TestClient, scene: Scene) -> None:
    """Was: ``point: [true, 1]`` stored as ``[1.0, 1.0]`` (the body's float read ``true`` as 1 before the service's
    check for booleans)."""
    answer = client.post(f"/api/systems/{scene.system_id}/comments",
                         json={"frame_id": scene.frame_ids[0], "point": [True, 1], "text": "here"})
    assert answer.status_code == 422, answer.text
    assert answer.json()["detail"][0]["loc"] == ["body", "point", 0]
    assert answer.json()["detail"][0]["msg"] == "a number is expected, not a boolean"
    assert client.get(f"/api/systems/{scene.system_id}/comments").json()["items"] == []


def _bodies() -> list[type]:
    from app.api import main  # noqa: F401  (every router, and so every body model, is imported)
    from app.api.schemas import _In

    out, todo = [], [_In]
    while todo:
        for sub in todo.pop().__subclasses__():
            out.append(sub)
            todo.append(sub)
    return out


def _numeric_leaves(schema: dict, defs: dict, at: tuple = ()) -> list[tuple[tuple, object]]:
    """(location, a value putting a boolean there) of each number a body schema holds at its top or in a list."""
    ref = schema.get("$ref")
    if ref:
        schema = defs[ref.rsplit("/", 1)[-1]]
    out = []
    for option in schema.get("anyOf") or [schema]:
        kind = option.get("type")
        if kind in ("number", "integer"):
            out.append((at, True))
        elif kind == "array":
            first = (option.get("prefixItems") or [option.get("items") or {}])[0]
            n = max(option.get("minItems", 1), 1)
            for loc, value in _numeric_leaves(first, defs):
                out.append(((*at, 0, *loc), [value] + [1] * (n - 1)))
    return out


def test_every_number_of_every_request_body_refuses_a_boolean_before_coercion() -> None:
    """One rule for every body (``app.api.schemas.refuse_booleans_for_numbers``): each number field of each request
    body model, given ``true``, answers an error located at it, never 1."""
    from pydantic import ValidationError

    checked = []
    for model in _bodies():
        schema = model.model_json_schema()
        for name, prop in schema.get("properties", {}).items():
            for loc, value in _numeric_leaves(prop, schema.get("$defs", {}), (name,)):
                with pytest.raises(ValidationError) as refused:
                    model.model_validate({name: value})
                errors = [e for e in refused.value.errors() if e["type"] == "bool_for_number"]
                assert errors and errors[0]["loc"] == loc, (model.__name__, name, refused.value.errors())
                checked.append(f"{model.__name__}.{name}")
    from app.api.pass_schemas import PassIn

    with pytest.raises(ValidationError) as nested:  # the queue's filters inside a body
        PassIn.model_validate({"filter": {"game_id": True}})
    assert nested.value.errors()[0]["loc"] == ("filter", "game_id")
    assert {"CommentIn.point", "CommentIn.frame_id", "BallEdit.box", "TokenIn.expires_days", "AssignIn.system_ids",
            "PassIn.system_id"} <= set(checked), checked
