"""``POST /api/frames/{id}/calibration-preview`` (issue 29, item 5): the calibration a field-line edit would store,
computed by the edit's own calibration and stored nowhere; bad lines answer as the edit does; one preview per user
and view at a time."""
from __future__ import annotations

from typing import Any

import pytest
from fastapi import FastAPI
from fastapi.testclient import TestClient

from app.api.routes import frames as frames_route
from tests.accounts import Account, as_session

from ..factories import Scene


def _view(client: TestClient, scene: Scene, index: int = 0) -> dict[str, Any]:
    return client.get(f"/api/systems/{scene.system_id}").json()["views"][index]


def _moved(lines: dict, dx: float) -> dict:
    """The lines with the first point of the first polyline of each class moved by ``dx`` px (a drag)."""
    return {cls: [[[x + dx, y] if (p == 0 and i == 0) else [x, y] for i, (x, y) in enumerate(poly)]
                  for p, poly in enumerate(polys)] for cls, polys in lines.items()}


def _audit_count(client: TestClient) -> int:
    return len(client.get("/api/audit", params={"limit": 500}).json()["items"])


def test_a_preview_is_what_the_edit_stores_and_writes_nothing(client: TestClient, scene: Scene) -> None:
    fid = scene.frame_ids[0]
    lines = _view(client, scene)["field_lines"]
    assert client.put(f"/api/frames/{fid}/field-lines", json={"lines": lines}).status_code == 200  # computed
    system_before = client.get(f"/api/systems/{scene.system_id}")
    view = system_before.json()["views"][0]
    entries = _audit_count(client)
    # the stored lines give the stored calibration back
    same = client.post(f"/api/frames/{fid}/calibration-preview", json={"lines": view["field_lines"]})
    assert same.status_code == 200, same.text
    assert same.headers["cache-control"] == "no-store"
    body = same.json()
    assert body["frame_id"] == fid and body["status"] == "calibrated" and body["admitted"] is True
    assert body["jac"] == pytest.approx(view["calibration"]["jac"])
    assert body["camera"] == view["calibration"]["camera"]  # the same code on the same lines: the same camera
    assert body["retry"] is None and body["differs"] is None and body["elapsed_ms"] > 0
    drawn = client.get(view["pitch_lines_url"]).json()["lines"]
    assert [line["class"] for line in body["pitch_lines"]] == [line["class"] for line in drawn]
    # a dragged point: the preview is the calibration the edit then stores, camera and residuals included
    lines = _moved(view["field_lines"], 25.0)
    preview = client.post(f"/api/frames/{fid}/calibration-preview", json={"lines": lines}).json()
    after = client.get(f"/api/systems/{scene.system_id}")
    assert after.json() == system_before.json() and after.headers["etag"] == system_before.headers["etag"]
    assert _audit_count(client) == entries  # nothing written, nothing audited
    assert preview["camera"] != body["camera"] and preview["residuals_px"] != body["residuals_px"]
    stored = client.put(f"/api/frames/{fid}/field-lines", json={"lines": lines}).json()["views"][0]
    assert _audit_count(client) == entries + 1
    cal = stored["calibration"]
    assert (preview["status"], preview["admitted"], preview["flags"]) == (cal["status"], cal["admitted"], cal["flags"])
    assert preview["jac"] == pytest.approx(cal["jac"])
    assert preview["camera"] == cal["camera"]
    assert preview["residuals_px"] == pytest.approx(cal["residuals_px"])
    assert preview["pitch_lines"] == client.get(stored["pitch_lines_url"]).json()["lines"]


def test_lines_that_cannot_calibrate_preview_a_refusal(client: TestClient, scene: Scene) -> None:
    """Two points of one line leave the camera open: the preview says refused, with no camera and no pitch."""
    fid = scene.frame_ids[1]
    answer = client.post(f"/api/frames/{fid}/calibration-preview",
                         json={"lines": {"Middle line": [[[480.0, 10.0], [481.0, 500.0]]]}})
    assert answer.status_code == 200, answer.text
    body = answer.json()
    assert body["status"] == "refused" and body["camera"] is None and body["pitch_lines"] == []
    assert body["admitted"] is False
    # the refusal in a curator's words: how many lines, how many constraints of how many a camera needs
    assert body["reason"].startswith("too few field lines for a camera: 1 usable line gives "), body["reason"]
    assert body["reason"].endswith(" of the 7 independent constraints a camera needs"), body["reason"]


@pytest.mark.parametrize(("lines", "field_word"), [
    ({"Not a class": [[[1.0, 2.0], [3.0, 4.0]]]}, "Not a class"),
    ({"Middle line": [[[1e6, 2.0], [3.0, 4.0]]]}, "Middle line"),
])
def test_bad_lines_are_422_naming_lines_as_the_edit_answers(client: TestClient, scene: Scene, lines: dict,
                                                           field_word: str) -> None:
    answer = client.post(f"/api/frames/{scene.frame_ids[0]}/calibration-preview", json={"lines": lines})
    assert answer.status_code == 422
    assert "lines" in answer.text and field_word in answer.text
    assert client.post("/api/frames/2147483647/calibration-preview", json={"lines": {}}).status_code == 404
    assert client.post(f"/api/frames/{scene.frame_ids[0]}/calibration-preview",
                       json={"lines": {}, "undo_of": 3}).status_code == 422  # a preview undoes nothing


def test_a_second_preview_of_the_same_view_in_flight_is_429(client: TestClient, scene: Scene,
                                                            accounts: dict[str, Account], app: FastAPI) -> None:
    fid = scene.frame_ids[0]
    lines = _view(client, scene)["field_lines"]
    with frames_route._one_preview(accounts["admin"].name, fid):  # the admin's preview of this view is running
        busy = client.post(f"/api/frames/{fid}/calibration-preview", json={"lines": lines})
        assert busy.status_code == 429 and busy.headers["retry-after"] == "1" and "already" in busy.json()["detail"]
        other_view = scene.frame_ids[1]
        assert client.post(f"/api/frames/{other_view}/calibration-preview",
                           json={"lines": _view(client, scene, 1)["field_lines"]}).status_code == 200
        with as_session(TestClient(app), accounts["annotator"]) as annotator:  # another user, the same view
            assert annotator.post(f"/api/frames/{fid}/calibration-preview", json={"lines": lines}).status_code == 200
    assert client.post(f"/api/frames/{fid}/calibration-preview", json={"lines": lines}).status_code == 200


def test_the_annotator_role_and_the_csrf_token_are_needed_as_for_the_edit(app: FastAPI, scene: Scene,
                                                                          accounts: dict[str, Account]) -> None:
    """The preview needs what the edit needs (the annotator role) and, from a browser, the CSRF token."""
    with TestClient(app) as anonymous:
        assert anonymous.post(f"/api/frames/{scene.frame_ids[0]}/calibration-preview",
                              json={"lines": {}}).status_code == 401
    with as_session(TestClient(app), accounts["annotator"]) as browser:
        browser.headers.pop("x-csrf-token", None)
        for name in list(browser.headers):
            if "csrf" in name.lower():
                browser.headers.pop(name)
        assert browser.post(f"/api/frames/{scene.frame_ids[0]}/calibration-preview",
                            json={"lines": {}}).status_code == 403
