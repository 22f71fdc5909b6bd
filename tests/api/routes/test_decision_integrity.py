"""Decisions conditional on what was seen, over HTTP (the third security review's attacks on decisions).

* A system decision's ``If-Match`` covers the system's labels: an accept sent with the ETag of a page drawn before an
  annotator moved a ball 40 px is refused (412), nothing is decided, and the answer says who changed what since
  that version (``changes_since`` and, in words, ``detail``).
* The undo of an edit that brings the whole system's labels back to those its decisions were made on gives back the
  decisions that edit reset, in the undo's own entry: a ball moved 1 px and moved back leaves the system accepted
  and in the accepted-only export. An undo that leaves another view's later change in place does not.
"""
from __future__ import annotations

import io
import json
import zipfile
from typing import Any

import pytest
from fastapi.testclient import TestClient

from ..factories import Scene

#: The edit routes run on a real engine, as served (tests/api/conftest.py).
pytestmark = [pytest.mark.served, pytest.mark.engine]


def _system(client: TestClient, scene: Scene) -> tuple[dict[str, Any], str]:
    answer = client.get(f"/api/systems/{scene.system_id}")
    assert answer.status_code == 200, answer.text
    return answer.json(), answer.headers["etag"]


def _moved(box: list[float], dx: float, dy: float = 0.0) -> list[float]:
    return [box[0] + dx, box[1] + dy, box[2] + dx, box[3] + dy]


def _nudge(client: TestClient, scene: Scene, k: int, dx: float, dy: float = 0.0) -> int:
    box = _system(client, scene)[0]["views"][k]["ball"]["box"]
    answer = client.patch(f"/api/frames/{scene.frame_ids[k]}/ball", json={"box": _moved(box, dx, dy)})
    assert answer.status_code == 200, answer.text
    return int(answer.headers["x-v3d-audit-entry"])


def _undo(client: TestClient, entry_id: int) -> dict[str, Any]:
    answer = client.post(f"/api/audit/{entry_id}/undo")
    assert answer.status_code == 200, answer.text
    return answer.json() | {"entry": int(answer.headers["x-v3d-audit-entry"])}


def _accept(client: TestClient, scene: Scene, k: int) -> None:
    """A reviewer's accept of the system and of view ``k``'s ball, on the page as drawn now."""
    _, etag = _system(client, scene)
    fid = scene.frame_ids[k]
    assert client.post(f"/api/frames/{fid}/review", json={"status": "accepted", "comment": ""}).status_code == 200
    assert client.post(f"/api/systems/{scene.system_id}/review", json={"status": "accepted", "comment": "ok"},
                       headers={"If-Match": etag}).status_code == 200


def _accepted_then_nudged(client: TestClient, scene: Scene, act_as) -> int:
    """rita accepts the system and its second view's ball, then ana moves that ball 1 px: her entry's id (the
    requests after come from ana)."""
    act_as("rita", "reviewer")
    _accept(client, scene, 1)
    act_as("ana")
    return _nudge(client, scene, 1, 1.0)


def _entry(client: TestClient, entry_id: int) -> dict[str, Any]:
    items = client.get("/api/audit", params={"limit": 500}).json()["items"]
    return next(e for e in items if e["id"] == entry_id)


def _exported_systems(client: TestClient, act_as, then: tuple[str, str]) -> dict[str, str]:
    """System name -> review status in the accepted-only SoccerNet-v3D export (``v3d_reviews``), downloaded by an
    admin; the requests after it come from ``then`` (name, role)."""
    act_as("adam", "admin")
    answer = client.get("/api/exports/soccernet-v3d", params={"images": "false"})
    act_as(*then)
    assert answer.status_code == 200
    with zipfile.ZipFile(io.BytesIO(answer.content)) as zf:
        reviews: dict[str, str] = {}
        for name in zf.namelist():
            if name.endswith("Labels-v3D.json"):
                reviews.update(json.loads(zf.read(name))["GameMetadata"]["v3d_reviews"])
    return reviews


def test_an_accept_with_the_etag_of_a_page_before_a_40_px_move_is_412_saying_what_changed(
        client: TestClient, scene: Scene, act_as) -> None:
    """Attack: the reviewer reads the system (pending), an annotator moves a ball 40 px, the reviewer's accept with
    the ETag it read answered 200 (the ETag covered the decision, not the labels)."""
    act_as("rita", "reviewer")
    page, seen = _system(client, scene)
    assert page["review"]["status"] == "pending"
    act_as("ana")
    moved = _nudge(client, scene, 1, 40.0)
    act_as("rita", "reviewer")
    stale = client.post(f"/api/systems/{scene.system_id}/review", json={"status": "accepted", "comment": ""},
                        headers={"If-Match": seen})
    assert stale.status_code == 412, stale.text
    out = stale.json()
    assert out["etag"] == stale.headers["etag"] == _system(client, scene)[1] != seen
    assert out["current"]["review"]["status"] == "pending"
    # who changed what since the version the page read, as entries and in words
    assert [(c["id"], c["actor"], c["summary"]) for c in out["changes_since"]] == [
        (moved, "ana", "ball of V2 moved 40.0 px")]
    assert out["last_change"]["id"] == moved
    assert "Since your version: ana: ball of V2 moved 40.0 px" in out["detail"]
    assert _system(client, scene)[0]["review"]["status"] == "pending"  # nothing decided
    # the page drawn now decides
    page, now = _system(client, scene)
    done = client.post(f"/api/systems/{scene.system_id}/review", json={"status": "accepted", "comment": ""},
                       headers={"If-Match": now})
    assert done.status_code == 200 and done.json()["status"] == "accepted"


def test_a_412_names_every_change_since_the_version_seen_oldest_first(client: TestClient, scene: Scene,
                                                                      act_as) -> None:
    act_as("rita", "reviewer")
    _, seen = _system(client, scene)
    act_as("ana")
    first = _nudge(client, scene, 0, 3.0)
    excluded = client.post(f"/api/frames/{scene.frame_ids[2]}/exclusion", json={"excluded": True})
    assert excluded.status_code == 200
    act_as("rita", "reviewer")
    out = client.post(f"/api/systems/{scene.system_id}/review", json={"status": "rejected"},
                      headers={"If-Match": seen}).json()
    assert [(c["actor"], c["summary"]) for c in out["changes_since"]] == [
        ("ana", "ball of V1 moved 3.0 px"), ("ana", "V3 excluded from the 3D ball")]
    assert out["changes_since"][0]["id"] == first
    # a malformed or foreign tag names no version: no account, the newest decision as before
    out = client.post(f"/api/systems/{scene.system_id}/review", json={"status": "rejected"},
                      headers={"If-Match": '"frame-1-1"'}).json()
    assert out["changes_since"] == []


def test_the_undo_of_a_1_px_move_gives_the_decisions_back_and_the_export_keeps_the_system(
        client: TestClient, scene: Scene, act_as) -> None:
    """Attack: the reviewer accepts; an annotator moves a ball 1 px and undoes it: the label is back exactly, but the
    system stayed pending and the accepted-only export lost it."""
    act_as("rita", "reviewer")
    _accept(client, scene, 1)
    name = _system(client, scene)[0]["name"]
    assert _exported_systems(client, act_as, ("ana", "annotator")) == {name: "accepted"}
    nudge = _nudge(client, scene, 1, 0.0, 1.0)
    assert _system(client, scene)[0]["review"]["status"] == "pending"
    assert _exported_systems(client, act_as, ("ana", "annotator")) == {}
    undone = _undo(client, nudge)
    assert undone["review"]["status"] == "accepted" and undone["review"]["comment"] == "ok"
    assert undone["review"]["reset_reason"] is None
    assert undone["views"][1]["review"]["status"] == "accepted"
    assert _exported_systems(client, act_as, ("ana", "annotator")) == {name: "accepted"}
    # in the undo's own entry, said in words
    entry = _entry(client, undone["entry"])
    assert entry["summary"] == (f"undo of entry {nudge}: ball of V2 moved 1.0 px; decisions it reset restored: "
                                "ball of V2 accepted, system accepted (ok)")
    assert entry["actor"] == "ana"
    # the redo moves the ball again: the decisions go back to pending by the rule of every edit
    redone = _undo(client, undone["entry"])
    assert redone["review"]["status"] == "pending" and redone["views"][1]["review"]["status"] == "pending"
    again = _undo(client, redone["entry"])
    assert again["review"]["status"] == "accepted" and again["views"][1]["review"]["status"] == "accepted"


def test_two_moves_undone_in_turn_give_the_decisions_back(client: TestClient, scene: Scene, act_as) -> None:
    act_as("rita", "reviewer")
    _accept(client, scene, 1)
    act_as("ana")
    first = _nudge(client, scene, 1, 2.0)
    second = _nudge(client, scene, 1, 0.0, 3.0)
    assert _undo(client, second)["review"]["status"] == "pending"  # the labels are not yet those accepted
    assert _undo(client, first)["review"]["status"] == "accepted"


def test_an_undo_leaving_another_views_later_edit_leaves_the_system_pending(client: TestClient, scene: Scene,
                                                                           act_as) -> None:
    """Restoring the undone view's label is not enough: every view's labels must be those the reviewer saw."""
    nudge = _accepted_then_nudged(client, scene, act_as)
    act_as("bob")
    _nudge(client, scene, 0, 5.0)
    act_as("ana")
    undone = _undo(client, nudge)
    assert undone["review"]["status"] == "pending" and undone["views"][1]["review"]["status"] == "pending"
    assert "restored" not in _entry(client, undone["entry"])["summary"]


def test_an_undo_after_the_reviewer_decided_again_keeps_that_decision(client: TestClient, scene: Scene,
                                                                      act_as) -> None:
    """A decision taken after the edit is the reviewer's latest word: the undo never replaces it by the older one."""
    nudge = _accepted_then_nudged(client, scene, act_as)
    act_as("rita", "reviewer")
    assert client.post(f"/api/frames/{scene.frame_ids[1]}/review",
                       json={"status": "rejected", "comment": ""}).status_code == 200
    undone = _undo(client, nudge)
    assert undone["views"][1]["review"]["status"] == "pending"  # the undo changed the label its rejection was on
    assert undone["review"]["status"] == "accepted"  # the system's decision nobody took since comes back
