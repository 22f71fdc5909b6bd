"""Issue 28, items 3 and 4 over HTTP.

Item 3: one rule for decisions after edits: every edit that changes a system's labels or 3D result (a ball
moved, drawn, deleted, snapped to a suggestion; an exclusion; a mirror fix; field lines; an undo) sets the
system's decision, and the touched view's ball decision (its calibration decision for a line edit), back to
pending with the reason, in the same write; an edit that changes nothing resets nothing.

Item 4: the undo of any edit (``POST /api/audit/{id}/undo``; its redo is the undo of the undo), audited as the
edit's own action with ``reverts_id``, restoring the stored label, the camera and the 3D ball to the same
numbers; annotators undo their own edits, reviewers any; every entry carries a summary in words.
"""
from __future__ import annotations

from typing import Any, Callable

import pytest
from fastapi.testclient import TestClient

from app.geometry.annotations import lines_from_json_lists, lines_to_json_lists, mirror_lines

from ..factories import Scene

#: The edit routes run on a real engine, as served (tests/api/conftest.py).
pytestmark = [pytest.mark.served, pytest.mark.engine]


def _system(client: TestClient, scene: Scene) -> dict[str, Any]:
    answer = client.get(f"/api/systems/{scene.system_id}")
    assert answer.status_code == 200, answer.text
    return answer.json()


def _audit(client: TestClient, **params) -> list[dict[str, Any]]:
    answer = client.get("/api/audit", params={"limit": 500, **params})
    assert answer.status_code == 200, answer.text
    return answer.json()["items"]


def _moved(box: list[float], dx: float, dy: float = 0.0) -> list[float]:
    return [box[0] + dx, box[1] + dy, box[2] + dx, box[3] + dy]


def _numbers(system: dict[str, Any]) -> dict[str, Any]:
    """What an undo must bring back exactly: each view's stored ball label, exclusion, field lines and camera,
    and the system's 3D ball and triangulation."""
    return {"ball3d": system["ball3d"], "triangulation": system["triangulation"],
            "views": [{"ball": v["ball"], "excluded": (v.get("review") or {}).get("excluded", False),
                       "field_lines": v["field_lines"], "camera": (v.get("calibration") or {}).get("camera"),
                       "jac": (v.get("calibration") or {}).get("jac")} for v in system["views"]]}


def _undo(client: TestClient, entry_id: int):
    return client.post(f"/api/audit/{entry_id}/undo")


def _mirrored_view(client: TestClient, scene: Scene, k: int) -> int:
    """Label view ``k``'s field lines mirrored (the mistake the mirror fix repairs); answers that write's entry."""
    view = _system(client, scene)["views"][k]
    wrong = lines_to_json_lists(mirror_lines(lines_from_json_lists(view["field_lines"])))
    answer = client.put(f"/api/frames/{scene.frame_ids[k]}/field-lines", json={"lines": wrong})
    assert answer.status_code == 200, answer.text
    return int(answer.headers["x-v3d-audit-entry"])


# ----- item 4: undo restores the numbers ------------------------------------------------------------
def test_undo_and_redo_of_a_ball_nudge_restore_label_camera_and_3d_ball(client: TestClient, scene: Scene,
                                                                        act_as) -> None:
    act_as("ana")
    fid = scene.frame_ids[1]
    before = _system(client, scene)
    box = before["views"][1]["ball"]["box"]
    nudged = client.patch(f"/api/frames/{fid}/ball", json={"box": _moved(box, 12.0, 5.0)})
    assert nudged.status_code == 200, nudged.text
    entry = int(nudged.headers["x-v3d-audit-entry"])
    after_nudge = _system(client, scene)
    assert after_nudge["ball3d"] != before["ball3d"]

    undone = _undo(client, entry)
    assert undone.status_code == 200, undone.text
    assert _numbers(undone.json()) == _numbers(before) == _numbers(_system(client, scene))
    assert undone.headers["etag"] == undone.json()["views"][1]["etag"]
    undo_id = int(undone.headers["x-v3d-audit-entry"])
    log = {e["id"]: e for e in _audit(client)}
    assert (log[undo_id]["action"], log[undo_id]["reverts_id"], log[undo_id]["actor"]) == ("ball.edit", entry, "ana")
    assert log[entry]["summary"] == "ball of V2 moved 13.0 px"
    assert log[undo_id]["summary"] == f"undo of entry {entry}: ball of V2 moved 13.0 px"

    redone = _undo(client, undo_id)  # the redo: the undo of the undo
    assert redone.status_code == 200, redone.text
    assert _numbers(redone.json()) == _numbers(after_nudge)
    redo_id = int(redone.headers["x-v3d-audit-entry"])
    again = _undo(client, redo_id)  # and its undo: an undo again
    assert again.status_code == 200 and _numbers(again.json()) == _numbers(before)
    log = {e["id"]: e for e in _audit(client)}
    assert log[redo_id]["summary"] == f"redo of entry {undo_id}: ball of V2 moved 13.0 px"
    summary = log[int(again.headers["x-v3d-audit-entry"])]["summary"]
    assert summary == f"undo of entry {redo_id}: ball of V2 moved 13.0 px"


def test_undo_of_an_exclusion_restores_the_3d_ball(client: TestClient, scene: Scene, act_as) -> None:
    act_as("ana")
    before = _system(client, scene)
    out = client.post(f"/api/frames/{scene.frame_ids[2]}/exclusion", json={"excluded": True})
    assert out.status_code == 200, out.text
    assert out.json()["ball3d"] != before["ball3d"]
    entry = int(out.headers["x-v3d-audit-entry"])
    undone = _undo(client, entry)
    assert undone.status_code == 200, undone.text
    assert _numbers(undone.json()) == _numbers(before)
    summaries = [e["summary"] for e in _audit(client)]
    assert summaries[:2] == [f"undo of entry {entry}: V3 restored to the 3D ball", "V3 excluded from the 3D ball"]


def test_undo_of_a_mirror_fix_restores_the_lines_the_camera_and_the_3d_ball(client: TestClient, scene: Scene) -> None:
    _mirrored_view(client, scene, 0)
    mislabelled = _system(client, scene)
    fixed = client.post(f"/api/frames/{scene.frame_ids[0]}/field-lines/mirror")
    assert fixed.status_code == 200, fixed.text
    assert _numbers(fixed.json())["views"][0]["camera"] != _numbers(mislabelled)["views"][0]["camera"]
    entry = int(fixed.headers["x-v3d-audit-entry"])
    undone = _undo(client, entry)
    assert undone.status_code == 200, undone.text
    assert _numbers(undone.json()) == _numbers(mislabelled)
    log = {e["id"]: e for e in _audit(client)}
    undo_entry = log[int(undone.headers["x-v3d-audit-entry"])]
    assert (undo_entry["action"], undo_entry["reverts_id"]) == ("field_lines.replace", entry)
    assert log[entry]["summary"].startswith("field lines of V1 mirrored: JaC ")
    assert undo_entry["summary"].startswith(f"undo of entry {entry}: field lines mirrored (V1): JaC ")


def test_an_undo_of_a_changed_resource_is_refused_and_changes_nothing(client: TestClient, scene: Scene,
                                                                      act_as) -> None:
    fid = scene.frame_ids[0]
    box = _system(client, scene)["views"][0]["ball"]["box"]
    act_as("ana")
    first = client.patch(f"/api/frames/{fid}/ball", json={"box": _moved(box, 4.0)})
    client.patch(f"/api/frames/{fid}/ball", json={"box": _moved(box, 9.0)})
    count = len(_audit(client))
    refused = _undo(client, int(first.headers["x-v3d-audit-entry"]))
    assert refused.status_code == 409 and "changed since" in refused.json()["detail"]
    assert _system(client, scene)["views"][0]["ball"]["box"] == _moved(box, 9.0) and len(_audit(client)) == count


def test_annotators_undo_their_own_edits_reviewers_any_and_decisions_are_a_reviewers(
        client: TestClient, scene: Scene, act_as) -> None:
    fid, sid = scene.frame_ids[0], scene.system_id
    box = _system(client, scene)["views"][0]["ball"]["box"]
    act_as("bob")
    bobs = int(client.patch(f"/api/frames/{fid}/ball", json={"box": _moved(box, 3.0)}).headers["x-v3d-audit-entry"])
    act_as("ana")
    refused = _undo(client, bobs)
    assert refused.status_code == 403 and "bob" in refused.json()["detail"]
    anas = int(client.patch(f"/api/frames/{fid}/ball", json={"box": _moved(box, 6.0)}).headers["x-v3d-audit-entry"])
    act_as("bob")
    assert _undo(client, bobs).status_code == 403  # ana wrote the view since: not bob's to undo any more
    act_as("rita", "reviewer")
    decision = client.post(f"/api/systems/{sid}/review", json={"status": "accepted", "comment": ""})
    assert decision.status_code == 200, decision.text
    decided = int(decision.headers["x-v3d-audit-entry"])
    act_as("ana")
    assert _undo(client, decided).status_code == 403  # a system decision: a reviewer's
    act_as("rita", "reviewer")
    undone = _undo(client, decided)
    assert undone.status_code == 200, undone.text
    assert undone.json()["review"]["status"] == "pending"
    act_as("ana")
    mine = _undo(client, anas)  # her own newest edit of the view
    assert mine.status_code == 200 and mine.json()["views"][0]["ball"]["box"] == _moved(box, 3.0)
    assert _undo(client, 10 ** 6).status_code == 404


# ----- item 3: one rule for decisions after edits ---------------------------------------------------
def _accept_all(client: TestClient, scene: Scene, k: int) -> None:
    """Accept the system, view ``k``'s ball and its calibration."""
    fid = scene.frame_ids[k]
    assert client.post(f"/api/frames/{fid}/review", json={"status": "accepted", "comment": ""}).status_code == 200
    assert client.post(f"/api/frames/{fid}/calibration-review",
                       json={"status": "accepted", "comment": ""}).status_code == 200
    assert client.post(f"/api/systems/{scene.system_id}/review",
                       json={"status": "accepted", "comment": "ok"}).status_code == 200


def _ball_edit(change: Callable[[list[float]], dict[str, Any]]):
    def edit(client: TestClient, scene: Scene, k: int):
        box = _system(client, scene)["views"][k]["ball"]["box"]
        return client.patch(f"/api/frames/{scene.frame_ids[k]}/ball", json=change(box))
    return edit


def _lines_edit(client: TestClient, scene: Scene, k: int):
    lines = _system(client, scene)["views"][k]["field_lines"]
    cls = next(c for c, polys in lines.items() if polys and len(polys[0]) > 3 and c != "Line unknown")
    lines[cls][0][1] = [lines[cls][0][1][0] + 9.0, lines[cls][0][1][1] - 4.0]
    return client.put(f"/api/frames/{scene.frame_ids[k]}/field-lines", json={"lines": lines})


def _drawn(client: TestClient, scene: Scene, k: int):
    box = _system(client, scene)["views"][k]["ball"]["box"]
    assert client.patch(f"/api/frames/{scene.frame_ids[k]}/ball", json={"box": None}).status_code == 200
    _accept_all(client, scene, k)  # accepted without a ball in the view: drawing one is the edit under test
    return client.patch(f"/api/frames/{scene.frame_ids[k]}/ball", json={"box": box})


def _undo_of_a_nudge(client: TestClient, scene: Scene, k: int):
    box = _system(client, scene)["views"][k]["ball"]["box"]
    nudge = client.patch(f"/api/frames/{scene.frame_ids[k]}/ball", json={"box": _moved(box, 2.0)})
    _accept_all(client, scene, k)  # accepted after the nudge: its undo is the edit under test
    return _undo(client, int(nudge.headers["x-v3d-audit-entry"]))


EDITS = {
    # kind: (edit, the view's decision it resets, words in the reason)
    "moved": (_ball_edit(lambda b: {"box": _moved(b, 7.0)}), "ball", "ball of V2 moved 7.0 px"),
    "nudged": (_ball_edit(lambda b: {"box": _moved(b, 0.0, 1.0)}), "ball", "ball of V2 moved 1.0 px"),
    "deleted": (_ball_edit(lambda b: {"box": None}), "ball", "ball of V2 deleted"),
    "made a point": (_ball_edit(lambda b: {"point": [(b[0] + b[2]) / 2, (b[1] + b[3]) / 2]}), "ball",
                     "ball of V2 resized"),
    "drawn": (_drawn, "ball", "ball of V2 drawn (a box)"),
    "snapped": (_ball_edit(lambda b: {"box": _moved(b, 5.0), "provenance": {"doubt": "ball_off_consensus",
                                                                          "code": None, "from_views": []}}),
                "ball", "ball of V2 snapped to the suggested box"),
    "excluded": (lambda c, s, k: c.post(f"/api/frames/{s.frame_ids[k]}/exclusion", json={"excluded": True}), "ball",
                 "V2 excluded from the 3D ball"),
    "lines": (_lines_edit, "calibration", "field lines replaced by"),
    "undo": (_undo_of_a_nudge, "ball", "ball of V2 moved 2.0 px (undo of audit entry"),
}


@pytest.mark.parametrize("kind", sorted(EDITS))
def test_every_edit_of_an_accepted_system_sets_it_back_to_pending_with_the_reason(
        client: TestClient, scene: Scene, kind: str) -> None:
    edit, decision, words = EDITS[kind]
    k = 1
    if kind not in ("undo", "drawn"):
        _accept_all(client, scene, k)
    answer = edit(client, scene, k)
    assert answer.status_code == 200, answer.text
    system = answer.json()
    review, view_review = system["review"], system["views"][k]["review"]
    assert review["status"] == "pending" and words in review["reset_reason"], review
    assert review["reset_reason"].startswith(f"{system['views'][k]['name']}: ")
    if decision == "ball":
        assert view_review["status"] == "pending" and view_review["reset_reason"] == review["reset_reason"]
        assert view_review["calibration"]["status"] == "accepted"
    else:
        assert view_review["calibration"]["status"] == "pending" and view_review["status"] == "accepted"
    # the resets are entries of the same write, before the edit's own (still the frame's newest)
    log = _audit(client, system_id=scene.system_id)
    assert log[0]["frame_id"] == scene.frame_ids[k] and log[0]["action"] not in ("system.review", "view.review")
    assert {"system.review"} <= {e["action"] for e in log[1:3]}
    assert any(e["summary"] == "system set back to pending (ok)" for e in log[1:3])


def test_the_mirror_fix_of_an_accepted_system_sets_it_back_to_pending(client: TestClient, scene: Scene) -> None:
    _mirrored_view(client, scene, 0)
    _accept_all(client, scene, 0)
    fixed = client.post(f"/api/frames/{scene.frame_ids[0]}/field-lines/mirror")
    assert fixed.status_code == 200, fixed.text
    review = fixed.json()["review"]
    assert review["status"] == "pending" and "field lines mirrored by" in review["reset_reason"]
    assert fixed.json()["views"][0]["review"]["calibration"]["status"] == "pending"


def test_an_edit_that_changes_nothing_resets_nothing(client: TestClient, scene: Scene) -> None:
    k, fid = 1, scene.frame_ids[1]
    _accept_all(client, scene, k)
    count = len(_audit(client))
    view = _system(client, scene)["views"][k]
    same_ball = client.patch(f"/api/frames/{fid}/ball", json={"box": view["ball"]["box"]})
    same_exclusion = client.post(f"/api/frames/{fid}/exclusion", json={"excluded": False})
    same_lines = client.put(f"/api/frames/{fid}/field-lines", json={"lines": view["field_lines"]})
    assert [a.status_code for a in (same_ball, same_exclusion, same_lines)] == [200] * 3
    system = same_lines.json()
    assert system["review"]["status"] == "accepted" and system["review"]["reset_reason"] is None
    assert system["views"][k]["review"]["status"] == "accepted"
    assert system["views"][k]["review"]["calibration"]["status"] == "accepted"
    log = _audit(client)
    assert [e["action"] for e in log[: len(log) - count]] == ["field_lines.replace", "view.exclusion", "ball.edit"]
    assert log[1]["summary"] == "V2 exclusion unchanged (included)" and log[2]["summary"] == "ball of V2 unchanged"


def test_an_entry_recorded_before_summaries_gets_the_same_words_when_read(client: TestClient, scene: Scene,
                                                                          db_session) -> None:
    from app.db.models import AuditEntry

    old = AuditEntry(actor="ana", action="view.exclusion", frame_id=scene.frame_ids[2], system_id=scene.system_id,
                     game_id=scene.game_id, before={"excluded": False}, after={"excluded": True})
    db_session.add(old)
    db_session.commit()
    assert old.summary is None
    (entry,) = [e for e in _audit(client, system_id=scene.system_id) if e["id"] == old.id]
    assert entry["summary"] == "V3 excluded from the 3D ball"
