"""Issue 16, items 1 and 2 over HTTP: the pitch model's classes for the line editor (``GET /api/pitch-model``),
the audit entry a field-line write answers (``X-V3D-Audit-Entry``), and the page's undo and redo: a new
field-line write with the earlier lines, audited as ``field_lines.replace`` with ``reverts_id`` naming the
entry it undoes, whose lines, camera and JaC come back exactly as they were (nothing else changed)."""
from __future__ import annotations

import copy
from typing import Any

import pytest
from fastapi.testclient import TestClient

from app.geometry import pitch

from ..factories import Scene

#: The edit routes run on a real engine, as served (tests/api/conftest.py).
pytestmark = [pytest.mark.served, pytest.mark.engine]


def _view(client: TestClient, scene: Scene, k: int) -> tuple[dict[str, Any], str]:
    answer = client.get(f"/api/frames/{scene.frame_ids[k]}")
    assert answer.status_code == 200, answer.text
    return answer.json(), answer.headers["etag"]


def _moved(lines: dict[str, Any], cls: str, dx: float, dy: float) -> dict[str, Any]:
    """``lines`` with the first point of ``cls``'s first polyline moved by (dx, dy) px."""
    out = copy.deepcopy(lines)
    out[cls][0][0] = [out[cls][0][0][0] + dx, out[cls][0][0][1] + dy]
    return out


def _put(client: TestClient, fid: int, etag: str, lines: dict[str, Any], undo_of: int | None = None):
    body: dict[str, Any] = {"lines": lines}
    if undo_of is not None:
        body["undo_of"] = undo_of
    return client.put(f"/api/frames/{fid}/field-lines", json=body, headers={"If-Match": etag})


def _entry(client: TestClient, entry_id: int) -> dict[str, Any]:
    items = client.get("/api/audit", params={"limit": 500}).json()["items"]
    return next(e for e in items if e["id"] == entry_id)


def test_pitch_model_lists_the_geometrys_classes(client: TestClient, anonymous: TestClient) -> None:
    answer = client.get("/api/pitch-model")
    assert answer.status_code == 200, answer.text
    model = answer.json()
    assert [c["name"] for c in model["classes"]] == list(pitch.LINE_CLASSES)
    by_name = {c["name"]: c for c in model["classes"]}
    assert by_name["Goal left post left "]["mirror"] == "Goal right post left"  # trailing space kept
    assert by_name["Big rect. left top"]["mirror"] == "Big rect. right bottom"
    assert [c["name"] for c in model["classes"] if not c["modelled"]] == ["Goal unknown", "Line unknown"]
    assert (model["length_m"], model["width_m"]) == (105.0, 68.0)
    assert anonymous.get("/api/pitch-model").status_code == 401


def test_undo_and_redo_bring_back_the_lines_the_camera_and_the_jac(client: TestClient, scene: Scene) -> None:
    fid = scene.frame_ids[0]
    view, etag = _view(client, scene, 0)
    cls = next(c for c, polys in view["field_lines"].items() if polys and len(polys[0]) > 3 and c != "Line unknown")

    # edit 1 (a recalibration from the lines as they are: the camera becomes a computed one), edit 2 (a point
    # moved 25 px: the camera and JaC change)
    first = _put(client, fid, etag, view["field_lines"])
    assert first.status_code == 200, first.text
    lines_b = first.json()["views"][0]["field_lines"]
    cal_b = first.json()["views"][0]["calibration"]
    lines_c = _moved(lines_b, cls, 25.0, -18.0)
    second = _put(client, fid, first.headers["etag"], lines_c)
    assert second.status_code == 200, second.text
    entry_c = int(second.headers["x-v3d-audit-entry"])
    cal_c = second.json()["views"][0]["calibration"]
    assert cal_c["camera"] != cal_b["camera"] and cal_c["residuals_px"] != cal_b["residuals_px"]
    assert _entry(client, entry_c)["after"] == {"lines": lines_c}

    # undo: the lines before edit 2, marked as its undo; lines, camera and JaC exactly as after edit 1
    undo = _put(client, fid, second.headers["etag"], lines_b, undo_of=entry_c)
    assert undo.status_code == 200, undo.text
    undone = undo.json()["views"][0]
    assert undone["field_lines"] == lines_b
    assert undone["calibration"]["camera"] == cal_b["camera"]
    assert undone["calibration"]["jac"] == cal_b["jac"]
    assert undone["calibration"]["residuals_px"] == cal_b["residuals_px"]
    undo_entry = _entry(client, int(undo.headers["x-v3d-audit-entry"]))
    assert (undo_entry["action"], undo_entry["reverts_id"]) == ("field_lines.replace", entry_c)
    assert undo_entry["before"] == {"lines": lines_c} and undo_entry["after"] == {"lines": lines_b}

    # redo: the undo undone
    redo = _put(client, fid, undo.headers["etag"], lines_c, undo_of=undo_entry["id"])
    assert redo.status_code == 200, redo.text
    redone = redo.json()["views"][0]
    assert redone["field_lines"] == lines_c and redone["calibration"]["camera"] == cal_c["camera"]
    assert redone["calibration"]["jac"] == cal_c["jac"]
    redo_entry = _entry(client, int(redo.headers["x-v3d-audit-entry"]))
    assert (redo_entry["action"], redo_entry["reverts_id"]) == ("field_lines.replace", undo_entry["id"])


def test_an_undo_that_does_not_match_its_entry_is_refused_and_stores_nothing(client: TestClient, scene: Scene) -> None:
    fid, other = scene.frame_ids[0], scene.frame_ids[1]
    view, etag = _view(client, scene, 0)
    cls = next(c for c, polys in view["field_lines"].items() if polys and c != "Line unknown")
    edit = _put(client, fid, etag, _moved(view["field_lines"], cls, 10.0, 0.0))
    assert edit.status_code == 200, edit.text
    entry = int(edit.headers["x-v3d-audit-entry"])
    etag = edit.headers["etag"]
    other_view, other_etag = _view(client, scene, 1)
    total = client.get("/api/audit").json()["total"]
    for fid_, etag_, lines, undo_of, says in (
            (fid, etag, _moved(view["field_lines"], cls, 3.0, 0.0), entry, "not those before"),  # other lines
            (other, other_etag, other_view["field_lines"], entry, "no field-line write of frame"),  # another frame
            (fid, etag, view["field_lines"], 987654, "no audit entry")):
        answer = _put(client, fid_, etag_, lines, undo_of=undo_of)
        assert answer.status_code == 422, answer.text
        assert answer.json()["field"] == "undo_of" and says in answer.json()["detail"]
    assert client.get("/api/audit").json()["total"] == total
    assert _view(client, scene, 0)[1] == etag  # nothing stored
    # a ball edit's entry is not a field-line write either
    ball = client.patch(f"/api/frames/{other}/ball", json={"box": None}, headers={"If-Match": other_etag})
    assert ball.status_code == 200, ball.text
    ball_entry = client.get("/api/audit", params={"frame_id": other}).json()["items"][0]["id"]
    answer = _put(client, other, ball.headers["etag"], other_view["field_lines"], undo_of=ball_entry)
    assert answer.status_code == 422 and answer.json()["field"] == "undo_of"
