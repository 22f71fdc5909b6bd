"""The team's loop through the API: a reviewer's needs fix goes to the annotator who last edited the system's labels,
with a comment pinned on a view; only she may send it back as fixed (the other annotator's ``fixed`` and her
``accepted`` are 403), also after her edits set the decision back to pending; it then waits for the reviewer under
``assignee=me&status=fixed``; every hand-off is an audit entry in words; her figures count it."""
from __future__ import annotations

from typing import Any

import pytest
import sqlalchemy as sa
from fastapi import FastAPI
from fastapi.testclient import TestClient
from sqlalchemy.orm import Session

from app.api.auth import Principal, current_principal
from app.db.models import AuditEntry, User, UserRole

from ..factories import Scene

#: The edit routes run on a real engine, as served (tests/api/conftest.py).
pytestmark = [pytest.mark.served, pytest.mark.engine]


@pytest.fixture
def team(db_session: Session) -> dict[str, User]:
    """A reviewer (rev) and two annotators (ana, bob), real users of the test database."""
    users = {n: User(name=n, role=r, password_hash="not a hash: these users never log in") for n, r in
             (("rev", UserRole.REVIEWER), ("ana", UserRole.ANNOTATOR), ("bob", UserRole.ANNOTATOR))}
    db_session.add_all(users.values())
    db_session.commit()
    return users


@pytest.fixture
def as_user(app: FastAPI, team: dict[str, User]):
    """``as_user(name)``: the later requests come from that user (past the authentication layer, which
    ``tests/api/test_auth.py`` tests)."""

    def choose(name: str) -> None:
        user = team[name]
        principal = Principal(user.id, user.name, user.role.value, "token")
        app.dependency_overrides[current_principal] = lambda: principal

    return choose


def _system(client: TestClient, scene: Scene) -> tuple[dict[str, Any], str]:
    answer = client.get(f"/api/systems/{scene.system_id}")
    assert answer.status_code == 200, answer.text
    return answer.json(), answer.headers["etag"]


def _nudge(client: TestClient, scene: Scene, k: int, dx: float) -> None:
    view = _system(client, scene)[0]["views"][k]
    box = view["ball"]["box"]
    answer = client.patch(f"/api/frames/{scene.frame_ids[k]}/ball", headers={"If-Match": view["etag"]},
                          json={"box": [box[0] + dx, box[1], box[2] + dx, box[3]]})
    assert answer.status_code == 200, answer.text


def _decide(client: TestClient, scene: Scene, status: str, comment: str = "") -> Any:
    return client.post(f"/api/systems/{scene.system_id}/review", json={"status": status, "comment": comment},
                       headers={"If-Match": _system(client, scene)[1]})


def _ids(client: TestClient, **params: str) -> list[int]:
    answer = client.get("/api/systems", params=params)
    assert answer.status_code == 200, answer.text
    return [row["id"] for row in answer.json()["items"]]


def test_needs_fix_goes_to_the_last_editor_and_comes_back_fixed_to_the_reviewer(client: TestClient, scene: Scene,
                                                                               as_user, db_session: Session) -> None:
    as_user("ana")
    _nudge(client, scene, 1, 6.0)  # ana's label edit: she is the one a needs fix goes back to
    as_user("rev")
    pinned = client.post(f"/api/systems/{scene.system_id}/comments",
                         json={"frame_id": scene.frame_ids[1], "point": [330.5, 210.0],
                               "text": "the box sits on the shadow"})
    assert pinned.status_code == 201, pinned.text
    comment = pinned.json()
    assert (comment["system_id"], comment["frame_id"], comment["point"], comment["author"], comment["resolved"]) == (
        scene.system_id, scene.frame_ids[1], [330.5, 210.0], "rev", False)
    returned = _decide(client, scene, "needs_fix", "the box sits on the shadow")
    assert returned.status_code == 200, returned.text
    assert returned.json()["returned_to"] == "ana"
    assert returned.json()["handoff"] == "returned to ana by rev: the box sits on the shadow"

    as_user("ana")
    assert _ids(client, assignee="me", status="needs_fix") == [scene.system_id]
    view, _ = _system(client, scene)
    assert view["assignment"]["assignee"] == "ana"
    listed = client.get(f"/api/systems/{scene.system_id}/comments").json()["items"]
    assert [c["text"] for c in listed] == ["the box sits on the shadow"]
    assert client.get("/api/handoffs/mine").json() == {"to_fix": 1, "to_re_review": 0, "to_fix_ids": [scene.system_id]}
    assert client.get(f"/api/systems/{scene.system_id}/handoff").json()["may_send_fixed"] is True

    as_user("bob")
    assert client.get(f"/api/systems/{scene.system_id}/handoff").json()["may_send_fixed"] is False
    assert client.post(f"/api/comments/{comment['id']}/resolve").status_code == 403
    assert _decide(client, scene, "fixed").status_code == 403  # not returned to him
    as_user("ana")
    assert _decide(client, scene, "accepted").status_code == 403  # an annotator sends only fixed
    _nudge(client, scene, 1, -6.0)  # sets the decision back to pending: the hand-off stays hers
    assert _system(client, scene)[0]["review"]["status"] == "pending"
    assert _ids(client, assignee="me") == [scene.system_id]
    assert client.get("/api/handoffs/mine").json()["to_fix"] == 1  # the record, not the status
    resolved = client.post(f"/api/comments/{comment['id']}/resolve")
    assert resolved.status_code == 200, resolved.text
    assert resolved.json()["resolved"] is True
    fixed = _decide(client, scene, "fixed")
    assert fixed.status_code == 200, fixed.text
    assert (fixed.json()["status"], fixed.json()["returned_to"]) == ("fixed", "rev")
    assert _decide(client, scene, "fixed").status_code == 403  # back with the reviewer: no longer hers

    as_user("rev")
    assert _ids(client, assignee="me", status="fixed") == [scene.system_id]
    assert client.get("/api/handoffs/mine").json() == {"to_fix": 0, "to_re_review": 1, "to_fix_ids": []}
    words = [e.summary for e in db_session.scalars(
        sa.select(AuditEntry).where(AuditEntry.system_id == scene.system_id).order_by(AuditEntry.id))]
    assert "returned to ana by rev: the box sits on the shadow" in words
    assert "fixed by ana, back to rev for re-review" in words
    assert any(w.startswith("comment on V2 at (330, 210): the box sits on the shadow") for w in words)
    assert "comment on V2 resolved: the box sits on the shadow" in words

    figures = client.get("/api/stats/annotators")
    assert figures.status_code == 200, figures.text
    ana = next(f for f in figures.json()["items"] if f["name"] == "ana")
    assert (ana["edits"], ana["systems_touched"], ana["needs_fix_received"]) == (2, 1, 1)
    assert ana["accepted_first_review"] == 0 and ana["systems_decided"] == 0  # fixed waits for the re-review
    assert ana["median_edit_to_review_s"] is not None and ana["median_edit_to_review_s"] >= 0
    # her label is back where the exact cameras put the ball: within a pixel of the other views' ball
    assert ana["median_label_distance_px"] is not None and ana["median_label_distance_px"] < 1.0
    assert ana["accused_share"] == 0.0
    csv = client.get("/api/stats/annotators", params={"format": "csv"})
    assert csv.status_code == 200 and csv.headers["content-type"].startswith("text/csv")
    lines = csv.text.splitlines()
    assert lines[0].split(",") == list(ana)
    assert any(line.startswith("ana,2,1,0,1,0,") for line in lines[1:])
    assert client.get("/api/stats/annotators", params={"since": "2999-01-01T00:00:00Z"}).json() == {"items": []}
    assert client.get("/api/stats/annotators", params={"since": "2026-01-02", "until": "2026-01-01"}
                      ).json()["field"] == "until"
    as_user("bob")
    assert client.get("/api/stats/annotators").status_code == 403  # reviewers and admins


def test_needs_fix_without_an_editor_goes_to_the_assignee_or_to_the_person_chosen_never_to_nobody(
        client: TestClient, scene: Scene, as_user) -> None:
    as_user("rev")
    version = _system(client, scene)[1]
    nobody = _decide(client, scene, "needs_fix", "look again")
    assert nobody.status_code == 422, nobody.text
    assert nobody.json()["field"] == "assignee"
    assert ("nobody edited this system's labels and it has no assignee: choose whom it goes to"
            in nobody.json()["detail"])
    # refused: nothing written, no hand-off, still pending
    assert _system(client, scene)[1] == version
    assert client.get(f"/api/systems/{scene.system_id}/handoff").json() is None

    def decide_to(who: str, status: str = "needs_fix") -> Any:
        return client.post(f"/api/systems/{scene.system_id}/review",
                           json={"status": status, "comment": "look again", "assignee": who},
                           headers={"If-Match": _system(client, scene)[1]})

    for who, status in (("nobody-here", "needs_fix"), ("ana", "accepted")):
        refused = decide_to(who, status)
        assert (refused.status_code, refused.json()["field"]) == (422, "assignee"), refused.text
    chosen = decide_to("ana")
    assert chosen.status_code == 200, chosen.text
    assert chosen.json()["returned_to"] == "ana"
    assert chosen.json()["handoff"] == "returned to ana by rev: look again"
    as_user("ana")
    assert _ids(client, assignee="me", status="needs_fix") == [scene.system_id]
    as_user("rev")
    assert _decide(client, scene, "accepted").status_code == 200
    assert client.post("/api/assignments", json={"assignee": "bob", "system_ids": [scene.system_id]}).status_code == 200
    to_bob = _decide(client, scene, "needs_fix", "look again")
    assert to_bob.json()["returned_to"] == "bob"
    as_user("bob")
    assert _ids(client, assignee="me", status="needs_fix") == [scene.system_id]


def test_a_view_decision_refuses_fixed_naming_the_status(client: TestClient, scene: Scene, as_user) -> None:
    as_user("rev")
    etag = _system(client, scene)[0]["views"][0]["etag"]
    answer = client.post(f"/api/frames/{scene.frame_ids[0]}/review", json={"status": "fixed", "comment": ""},
                         headers={"If-Match": etag})
    assert answer.status_code == 422
    assert answer.json()["field"] == "status"


def test_who_may_comment_and_what_a_comment_may_say(client: TestClient, scene: Scene, as_user) -> None:
    as_user("ana")
    body = {"frame_id": scene.frame_ids[0], "point": [10, 10], "text": "here"}
    assert client.post(f"/api/systems/{scene.system_id}/comments", json=body).status_code == 403  # not returned to her
    as_user("rev")
    outside = client.post(f"/api/systems/{scene.system_id}/comments", json={**body, "point": [5000, 10]})
    assert outside.status_code == 422 and outside.json()["field"] == "point"
    other = client.post(f"/api/systems/{scene.system_id}/comments", json={**body, "frame_id": 999_999})
    assert other.status_code == 422 and other.json()["field"] == "frame_id"
    whole = client.post(f"/api/systems/{scene.system_id}/comments", json={**body, "point": None})
    assert whole.status_code == 201 and whole.json()["point"] is None
    as_user("bob")
    assert client.post(f"/api/comments/{whole.json()['id']}/resolve").status_code == 403
    as_user("rev")
    assert client.post(f"/api/comments/{whole.json()['id']}/resolve").json()["resolved"] is True
    reopened = client.post(f"/api/comments/{whole.json()['id']}/reopen").json()
    assert (reopened["resolved"], reopened["resolved_by"]) == (False, None)
    assert client.post("/api/comments/999999/resolve").status_code == 404


def test_the_import_panel_offers_the_servers_import_formats() -> None:
    """The queue page's Import panel (static/js/team.js) lists exactly the kinds ``POST /api/imports`` takes."""
    import re
    import typing

    from app.api.job_schemas import ImportFormat
    from app.core.paths import PROJECT_ROOT

    script = (PROJECT_ROOT / "static" / "js" / "team.js").read_text()
    listed = re.findall(r'^  \["([a-z0-9-]+)", "', script, flags=re.M)
    assert sorted(listed) == sorted(typing.get_args(ImportFormat))


def test_a_fixed_never_undoes_an_accept_that_landed_after_its_check(app: FastAPI, client: TestClient, scene: Scene,
                                                                    as_user, team: dict[str, User],
                                                                    db_session: Session, monkeypatch) -> None:
    """Was: an annotator's ``fixed`` (a browser session, no ``If-Match``) racing the reviewer's accept overrode it:
    the route checked the hand-off before the write's transaction, the accept committed in between and closed it, the
    ``fixed`` then wrote over the accept (both 200). Here the accept lands exactly there, every time: the ``fixed`` is
    now refused 409 (checked again in the write, under the lock) and the system stays accepted, in nobody's
    To fix."""
    from app.services.curation import decisions
    from app.services.curation import handoff as handoff_service

    as_user("ana")
    _nudge(client, scene, 1, 6.0)
    as_user("rev")
    assert _decide(client, scene, "needs_fix", "the box sits on the shadow").status_code == 200
    checked = handoff_service.check_fixed_allowed

    def check_then_accept(session: Session, system_id: int, **kw: Any) -> None:
        checked(session, system_id, **kw)  # ana's fixed passes its check: the system is returned to her
        with app.state.session_factory() as other:  # the reviewer's accept commits right after it
            decisions.decide_review(other, system_id=system_id, status="accepted", actor="rev")

    monkeypatch.setattr(handoff_service, "check_fixed_allowed", check_then_accept)
    ana = team["ana"]  # her browser's session: no If-Match needed
    app.dependency_overrides[current_principal] = lambda: Principal(ana.id, ana.name, ana.role.value, "session")
    fixed = client.post(f"/api/systems/{scene.system_id}/review", json={"status": "fixed", "comment": ""})
    monkeypatch.setattr(handoff_service, "check_fixed_allowed", checked)
    assert fixed.status_code == 409, fixed.text
    assert "'fixed' was not applied" in fixed.json()["detail"] and "'accepted'" in fixed.json()["detail"]
    view, _ = _system(client, scene)
    assert view["review"]["status"] == "accepted"
    assert client.get("/api/handoffs/mine").json()["to_fix"] == 0
    actions = [e.action for e in db_session.scalars(
        sa.select(AuditEntry).where(AuditEntry.system_id == scene.system_id).order_by(AuditEntry.id))]
    assert actions[-1] == "system.review"  # the accept, nothing after it
