"""Issue 7, items 2 and 3 over HTTP: every write audited (who, what, before, after), the audit list
(filters, paging, newest first), reverts (state and recomputation restored, audited, 409 on a changed
resource), strong ETags (stable when a sibling view's edit recomputes the frame), 412 on a stale
``If-Match`` with nothing changed, and 428 for a token's write without ``If-Match``."""
from __future__ import annotations

from datetime import datetime
from typing import Any

import pytest
from fastapi.testclient import TestClient
from sqlalchemy.orm import Session

from app.api.schemas import InvalidOut
from app.core.config import Settings

from ..factories import Scene, make_system

#: The edit routes run on a real engine, as served (tests/api/conftest.py).
pytestmark = [pytest.mark.served, pytest.mark.engine]


def _frame(client: TestClient, frame_id: int) -> tuple[dict[str, Any], str]:
    answer = client.get(f"/api/frames/{frame_id}")
    assert answer.status_code == 200, answer.text
    return answer.json(), answer.headers["etag"]


def _moved(box: list[float], dx: float) -> list[float]:
    return [box[0] + dx, box[1], box[2] + dx, box[3]]


def _audit(client: TestClient, **params) -> dict[str, Any]:
    answer = client.get("/api/audit", params=params)
    assert answer.status_code == 200, answer.text
    return answer.json()


def _geometry(view: dict[str, Any]) -> dict[str, Any]:
    """What a recomputation derives, per system view: the ball, the pairs, and every view's label,
    reprojection and optimised box (without the versions)."""
    return {"ball3d": view["ball3d"], "triangulation": view["triangulation"], "doubts": view["doubts"],
            "views": [{k: v for k, v in x.items() if k != "etag"} for x in view["views"]]}


# ----- ETags ---------------------------------------------------------------------------------------
def test_get_frame_answers_the_frame_with_its_ball_and_a_strong_etag(client: TestClient, scene: Scene) -> None:
    frame, etag = _frame(client, scene.frame_ids[2])
    system = client.get(f"/api/systems/{scene.system_id}").json()
    # one frame's answer carries its projected pitch; the system view names its address
    pitch = frame.pop("pitch_lines")
    assert pitch == client.get(system["views"][2]["pitch_lines_url"]).json()["lines"]
    assert frame == {**system["views"][2], "system_id": scene.system_id}
    assert etag == frame["etag"] == f'"frame-{scene.frame_ids[2]}-1"' and not etag.startswith("W/")
    assert frame["ball"]["kind"] == "box" and len(frame["ball"]["box"]) == 4
    assert client.get("/api/frames/987654").status_code == 404


def test_an_edit_answers_the_new_etag_and_a_siblings_etag_stays(client: TestClient, scene: Scene) -> None:
    first, first_etag = _frame(client, scene.frame_ids[0])
    third, third_etag = _frame(client, scene.frame_ids[2])
    answer = client.patch(f"/api/frames/{scene.frame_ids[2]}/ball", json={"box": _moved(third["ball"]["box"], 8.0)},
                          headers={"If-Match": third_etag})
    assert answer.status_code == 200, answer.text
    assert answer.headers["etag"] == f'"frame-{scene.frame_ids[2]}-2"' == answer.json()["views"][2]["etag"]
    assert _frame(client, scene.frame_ids[2])[1] == answer.headers["etag"]
    sibling, sibling_etag = _frame(client, scene.frame_ids[0])
    # the sibling was recomputed (its reprojection moved with the 3D ball) but nobody edited it
    assert abs(sibling["reprojection_error_px"] - first["reprojection_error_px"]) > 0.1
    assert sibling_etag == first_etag


def test_a_stale_if_match_gets_412_with_the_current_state_and_changes_nothing(
        client: TestClient, scene: Scene, act_as) -> None:
    fid = scene.frame_ids[1]
    frame, etag = _frame(client, fid)
    act_as("ana")
    ana_box = _moved(frame["ball"]["box"], 5.0)
    assert client.patch(f"/api/frames/{fid}/ball", json={"box": ana_box}, headers={"If-Match": etag}).status_code == 200
    after_ana = client.get(f"/api/systems/{scene.system_id}").json()
    entries = _audit(client)["total"]

    act_as("bob")
    for method, path, body in (("patch", "ball", {"box": _moved(frame["ball"]["box"], -5.0)}),
                               ("post", "exclusion", {"excluded": True}),
                               ("post", "review", {"status": "rejected"}),
                               ("put", "field-lines", {"lines": {}}),
                               ("post", "field-lines/mirror", None)):
        stale = client.request(method.upper(), f"/api/frames/{fid}/{path}", json=body, headers={"If-Match": etag})
        assert stale.status_code == 412, (path, stale.text)
        out = stale.json()
        assert out["etag"] == stale.headers["etag"] == f'"frame-{fid}-2"'
        assert out["current"]["ball"]["box"] == ana_box and out["current"]["etag"] == out["etag"]
        assert out["last_change"]["actor"] == "ana" and out["last_change"]["action"] == "ball.edit"
        assert "was changed since the version you sent" in out["detail"]
    assert client.get(f"/api/systems/{scene.system_id}").json() == after_ana
    assert _audit(client)["total"] == entries
    # weak, foreign and malformed tags never match; * matches any version for a browser session
    for tag in (f'W/"frame-{fid}-2"', f'"frame-{scene.frame_ids[0]}-2"', "garbage"):
        assert client.post(f"/api/frames/{fid}/exclusion", json={"excluded": True},
                           headers={"If-Match": tag}).status_code == 412
    assert client.post(f"/api/frames/{fid}/exclusion", json={"excluded": True},
                       headers={"If-Match": "*"}).status_code == 200


def test_token_writes_need_if_match_and_session_writes_do_not(client: TestClient, scene: Scene, act_as) -> None:
    fid = scene.frame_ids[0]
    frame, etag = _frame(client, fid)
    act_as("script", "annotator", "token")
    refused = client.patch(f"/api/frames/{fid}/ball", json={"box": _moved(frame["ball"]["box"], 3.0)})
    assert refused.status_code == 428 and "If-Match" in refused.json()["detail"]
    for any_version in ("*", " * "):  # '*' does not stand in for an ETag on a token's write (issue 15)
        star = client.patch(f"/api/frames/{fid}/ball", json={"box": _moved(frame["ball"]["box"], 3.0)},
                            headers={"If-Match": any_version})
        assert star.status_code == 428 and "'*' is not one" in star.json()["detail"]
    assert _frame(client, fid)[1] == etag and _audit(client)["total"] == 0
    accepted = client.patch(f"/api/frames/{fid}/ball", json={"box": _moved(frame["ball"]["box"], 3.0)},
                            headers={"If-Match": etag})
    assert accepted.status_code == 200
    act_as("script-reviewer", "reviewer", "token")
    assert client.post(f"/api/systems/{scene.system_id}/review", json={"status": "accepted"}).status_code == 428
    act_as("browser", "annotator", "session")
    assert client.post(f"/api/frames/{fid}/exclusion", json={"excluded": True}).status_code == 200
    assert [e["actor"] for e in _audit(client)["items"]] == ["browser", "script"]


def test_system_review_is_a_conditional_write_of_reviewers(client: TestClient, scene: Scene, act_as) -> None:
    sid = scene.system_id
    view = client.get(f"/api/systems/{sid}")
    etag = view.headers["etag"]
    version = int(etag.strip('"').rsplit("-", 1)[1])
    assert etag == view.json()["etag"] == f'"system-{sid}-{version}"'
    act_as("ann", "annotator")
    assert client.post(f"/api/systems/{sid}/review", json={"status": "accepted"},
                       headers={"If-Match": etag}).status_code == 403
    act_as("rita", "reviewer")
    done = client.post(f"/api/systems/{sid}/review", json={"status": "accepted", "comment": "ok"},
                       headers={"If-Match": etag})
    assert done.status_code == 200 and done.headers["etag"] == f'"system-{sid}-{version + 1}"'
    stale = client.post(f"/api/systems/{sid}/review", json={"status": "rejected"}, headers={"If-Match": etag})
    assert stale.status_code == 412
    assert stale.json()["current"]["review"]["status"] == "accepted" and stale.json()["last_change"]["actor"] == "rita"
    assert client.get(f"/api/systems/{sid}").json()["review"]["status"] == "accepted"
    # a frame's edit of the accepted system sets its decision back to pending: its ETag moves, so a page that drew
    # "accepted" cannot decide over the edit unseen
    frame, fetag = _frame(client, scene.frame_ids[0])
    edit = client.patch(f"/api/frames/{scene.frame_ids[0]}/ball", json={"box": _moved(frame["ball"]["box"], 2.0)},
                        headers={"If-Match": fetag})
    reset = client.get(f"/api/systems/{sid}")
    assert reset.json()["review"]["status"] == "pending" and reset.headers["etag"] not in (etag, done.headers["etag"])
    # the ETag covers the labels its reviewer saw: an accept sent with the ETag of a page drawn before a ball moved
    # 40 px is refused, and nothing is decided
    seen = reset.headers["etag"]
    moved = client.patch(f"/api/frames/{scene.frame_ids[0]}/ball", json={"box": _moved(frame["ball"]["box"], 40.0)},
                         headers={"If-Match": edit.headers["etag"]})
    assert moved.status_code == 200 and client.get(f"/api/systems/{sid}").headers["etag"] != seen
    late = client.post(f"/api/systems/{sid}/review", json={"status": "accepted"}, headers={"If-Match": seen})
    assert late.status_code == 412 and late.json()["current"]["review"]["status"] == "pending"
    assert client.get(f"/api/systems/{sid}").json()["review"]["status"] == "pending"


# ----- the audit log -------------------------------------------------------------------------------
def test_every_write_is_one_entry_with_its_state_before_and_after(client: TestClient, scene: Scene, act_as) -> None:
    fid, sid = scene.frame_ids[2], scene.system_id
    frame, etag = _frame(client, fid)
    lines = frame["field_lines"]
    box = frame["ball"]["box"]
    act_as("ana")
    answers = [
        client.patch(f"/api/frames/{fid}/ball", json={"box": _moved(box, 4.0)}, headers={"If-Match": etag}),
        client.post(f"/api/frames/{fid}/exclusion", json={"excluded": True}),
        client.post(f"/api/frames/{fid}/review", json={"status": "needs_fix", "comment": "lines"}),
        client.put(f"/api/frames/{fid}/field-lines", json={"lines": {k: lines[k] for k in sorted(lines)[:3]}}),
        client.post(f"/api/frames/{fid}/field-lines/mirror"),
    ]
    act_as("rita", "reviewer")
    answers.append(client.post(f"/api/systems/{sid}/review", json={"status": "rejected", "comment": "no"}))
    assert [a.status_code for a in answers] == [200] * 6
    items = _audit(client, system_id=sid)["items"][::-1]  # oldest first
    assert [(e["action"], e["actor"]) for e in items] == [
        ("ball.edit", "ana"), ("view.exclusion", "ana"), ("view.review", "ana"), ("field_lines.replace", "ana"),
        ("field_lines.mirror", "ana"), ("system.review", "rita")]
    assert items[0]["before"] == {"ball": {"box": box, "point": None}}
    assert items[0]["after"] == {"ball": {"box": _moved(box, 4.0), "point": None}}
    assert (items[1]["before"], items[1]["after"]) == ({"excluded": False}, {"excluded": True})
    assert items[2]["before"] == {"review": {"status": "pending", "comment": ""}}
    assert items[2]["after"] == {"review": {"status": "needs_fix", "comment": "lines"}}
    assert items[3]["before"] == {"lines": lines} and set(items[3]["after"]["lines"]) == set(sorted(lines)[:3])
    assert items[4]["before"] == items[3]["after"] and items[4]["after"]["lines"] != items[3]["after"]["lines"]
    assert items[5]["before"]["review"]["status"] == "pending"
    assert items[5]["after"]["review"] == {"status": "rejected", "comment": "no"}
    assert all(e["frame_id"] == fid for e in items[:5]) and items[5]["frame_id"] is None
    assert all(e["system_id"] == sid and e["game_id"] == scene.game_id and e["revertible"] for e in items)
    ats = [e["at"] for e in items]
    assert ats == sorted(ats)
    # a refused write (422) is no entry
    assert client.patch(f"/api/frames/{fid}/ball", json={"box": [1, 1, 0, 0]}).status_code == 422
    assert _audit(client)["total"] == 6


def test_audit_list_filters_by_frame_system_and_user_and_pages_newest_first(
        client: TestClient, scene: Scene, act_as, db_session: Session, db_settings: Settings) -> None:
    from app.db.models import Game

    other = make_system(db_session, db_settings, db_session.get(Game, scene.game_id), "2.png")
    writes = [("ana", scene.frame_ids[0]), ("bob", scene.frame_ids[1]), ("ana", other.frame_ids[0]),
              ("ana", scene.frame_ids[0]), ("bob", other.frame_ids[2])]
    for i, (who, fid) in enumerate(writes):
        act_as(who)
        assert client.post(f"/api/frames/{fid}/exclusion", json={"excluded": i % 2 == 0}).status_code == 200
    everything = _audit(client)
    assert everything["total"] == 5 and (everything["limit"], everything["offset"]) == (50, 0)
    assert [(e["actor"], e["frame_id"]) for e in everything["items"]] == writes[::-1]
    ids = [e["id"] for e in everything["items"]]
    assert ids == sorted(ids, reverse=True)
    assert [e["frame_id"] for e in _audit(client, user="ana")["items"]] == [scene.frame_ids[0], other.frame_ids[0],
                                                                            scene.frame_ids[0]]
    assert _audit(client, frame_id=scene.frame_ids[0])["total"] == 2
    assert {e["frame_id"] for e in _audit(client, system_id=other.system_id)["items"]} == {other.frame_ids[0],
                                                                                           other.frame_ids[2]}
    assert _audit(client, system_id=scene.system_id, user="bob")["total"] == 1
    page = _audit(client, limit=2, offset=2)
    assert page["total"] == 5 and [e["id"] for e in page["items"]] == ids[2:4] and page["next_offset"] == 4
    assert _audit(client, limit=2, offset=4)["next_offset"] is None
    assert _audit(client, user="nobody") == {"items": [], "total": 0, "limit": 50, "offset": 0, "next_offset": None}
    assert client.get("/api/audit", params={"limit": 0}).status_code == 422
    act_as("ann", "annotator", "token")
    assert _audit(client)["total"] == 5  # every role reads it


def test_audit_list_filters_by_when_an_entry_was_written(client: TestClient, db_session: Session) -> None:
    """The audit page's date filter: entries written at or after ``since`` and before ``until`` (UTC unless the time
    names its offset); an empty or reversed span, or a time that is not one, is refused naming its field."""
    from app.db.models import AuditEntry

    # entries are append-only: three recomputes as if run on three days
    days = ["2026-03-01T10:00:00+00:00", "2026-03-02T23:30:00+00:00", "2026-03-03T08:00:00+00:00"]
    entries = [AuditEntry(at=datetime.fromisoformat(day), actor="ana", action="recompute", after={"systems": 1})
               for day in days]
    db_session.add_all(entries)
    db_session.commit()
    ids = [e.id for e in entries]

    def between(**span: str) -> list[int]:
        return [e["id"] for e in _audit(client, **span)["items"]][::-1]

    assert between(since="2026-03-02", until="2026-03-03") == [ids[1]]  # a UTC day
    assert between(since="2026-03-02T00:00:00", until="2026-03-04") == ids[1:]  # no offset: UTC
    assert between(until="2026-03-02T23:30:00Z") == ids[:1]  # until is not included (nothing older than the three)
    assert between(since="2026-03-03T00:00:00+01:00", until="2026-03-03T09:00:00+01:00") == [ids[1]]  # a reader's day
    assert _audit(client, since="2026-03-02", until="2026-03-03")["total"] == 1
    for span, field in (({"since": "2026-03-03", "until": "2026-03-02"}, "until"),
                        ({"since": "2026-03-03", "until": "2026-03-03"}, "until"), ({"since": "yesterday"}, "since"),
                        ({"until": "0001-01-01T00:00:00+05:00"}, "until")):
        refused = client.get("/api/audit", params=span)
        assert refused.status_code == 422 and field in refused.text, refused.text
        InvalidOut.model_validate(refused.json())  # in the form the route declares (schemathesis checks it too)
    declared = client.get("/openapi.json").json()["paths"]["/api/audit"]["get"]["responses"]["422"]
    assert declared["content"]["application/json"]["schema"]["$ref"].endswith("/InvalidOut")


# ----- reverts -------------------------------------------------------------------------------------
def test_revert_restores_the_state_and_the_recomputation_and_is_audited(
        client: TestClient, scene: Scene, act_as) -> None:
    fid = scene.frame_ids[1]
    before = client.get(f"/api/systems/{scene.system_id}").json()
    frame, etag = _frame(client, fid)
    act_as("ana")
    edited = client.patch(f"/api/frames/{fid}/ball", json={"box": _moved(frame["ball"]["box"], 30.0)},
                          headers={"If-Match": etag}).json()
    assert _geometry(edited) != _geometry(before) and edited["ball3d"] != before["ball3d"]
    entry = _audit(client)["items"][0]
    assert client.post(f"/api/audit/{entry['id']}/revert").status_code == 403  # annotators do not revert
    act_as("rita", "reviewer")
    answer = client.post(f"/api/audit/{entry['id']}/revert")
    assert answer.status_code == 200, answer.text
    assert _geometry(answer.json()) == _geometry(before)
    assert answer.headers["etag"] == f'"frame-{fid}-3"' == answer.json()["views"][1]["etag"]
    revert = _audit(client)["items"][0]
    assert (revert["action"], revert["actor"], revert["reverts_id"]) == ("revert", "rita", entry["id"])
    assert (revert["before"], revert["after"]) == (entry["after"], entry["before"])
    # a revert is an entry like any other: reverting it applies the edit again
    again = client.post(f"/api/audit/{revert['id']}/revert")
    assert again.status_code == 200 and _geometry(again.json()) == _geometry(edited)


def test_revert_of_exclusion_and_system_review(client: TestClient, scene: Scene, act_as) -> None:
    act_as("rita", "reviewer")
    sid, fid = scene.system_id, scene.frame_ids[2]
    before = client.get(f"/api/systems/{sid}").json()
    client.post(f"/api/frames/{fid}/exclusion", json={"excluded": True})
    client.post(f"/api/systems/{sid}/review", json={"status": "accepted", "comment": "fine"})
    review_entry, exclusion_entry = _audit(client)["items"]
    out = client.post(f"/api/audit/{review_entry['id']}/revert")
    assert out.status_code == 200 and out.json()["review"]["status"] == "pending"
    assert out.headers["etag"] == client.get(f"/api/systems/{sid}").headers["etag"] != before["etag"]
    out = client.post(f"/api/audit/{exclusion_entry['id']}/revert")
    assert out.json()["views"][2]["review"]["excluded"] is False
    assert _geometry(out.json()) == _geometry(before)


def test_revert_of_a_changed_resource_is_409_unless_forced(client: TestClient, scene: Scene, act_as) -> None:
    fid = scene.frame_ids[0]
    frame, _ = _frame(client, fid)
    box = frame["ball"]["box"]
    act_as("ana")
    client.patch(f"/api/frames/{fid}/ball", json={"box": _moved(box, 4.0)})
    act_as("bob")
    client.patch(f"/api/frames/{fid}/ball", json={"box": _moved(box, 9.0)})
    bob, ana = _audit(client)["items"]
    act_as("rita", "reviewer")
    refused = client.post(f"/api/audit/{ana['id']}/revert")
    assert refused.status_code == 409 and "changed since" in refused.json()["detail"]
    assert refused.json()["current"] == {"ball": {"box": _moved(box, 9.0), "point": None}}
    assert _frame(client, fid)[0]["ball"]["box"] == _moved(box, 9.0) and _audit(client)["total"] == 2
    forced = client.post(f"/api/audit/{ana['id']}/revert", params={"force": True})
    assert forced.status_code == 200 and forced.json()["views"][0]["ball"]["box"] == box
    assert client.post("/api/audit/424242/revert").status_code == 404


@pytest.mark.parametrize("via", ["session", "token"])
def test_revert_needs_no_if_match(client: TestClient, scene: Scene, act_as, via: str) -> None:
    act_as("ana")
    client.post(f"/api/frames/{scene.frame_ids[0]}/exclusion", json={"excluded": True})
    entry = _audit(client)["items"][0]
    act_as("rita", "reviewer", via)
    assert client.post(f"/api/audit/{entry['id']}/revert").status_code == 200


def test_audit_ids_beyond_the_database_integers_are_422(client) -> None:
    """Found by the fuzzer after the merge: a frame id beyond 64 bits was a 500 (OverflowError in SQLite's driver)."""
    answer = client.get("/api/audit", params={"frame_id": 1024009643914140284092416})
    assert answer.status_code == 422 and answer.json()["detail"][0]["loc"] == ["query", "frame_id"]
    assert client.post("/api/audit/99999999999/revert").status_code == 422
