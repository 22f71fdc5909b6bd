"""``POST /api/assignments``, ``GET /api/assignees``, ``GET /api/systems?assignee=``, the system view's
``assignment`` / ``open_by`` and ``PUT`` / ``DELETE /api/systems/{id}/presence`` (issue 28, item 10), as the
test users of every role (``tests/accounts.py``), on SQLite and PostgreSQL."""
from __future__ import annotations

from collections.abc import Iterator
from datetime import timedelta

import pytest
import sqlalchemy as sa
from fastapi import FastAPI
from fastapi.testclient import TestClient
from sqlalchemy.orm import Session

from app.core.config import Settings
from app.db.models import AuditEntry, Game, ReviewStatus, System, SystemKind, User
from app.db.types import utcnow
from app.services.curation import presence
from tests.accounts import Account, as_session, as_token

from ..factories import Scene, make_game, make_system

pytestmark = pytest.mark.engine


@pytest.fixture
def clients(app: FastAPI, accounts: dict[str, Account]) -> Iterator[dict[str, TestClient]]:
    """A logged-in browser session per role (``annotator``, ``reviewer``, ``admin``)."""
    opened = {role: TestClient(app) for role in accounts}
    for c in opened.values():
        c.__enter__()
    try:
        yield {role: as_session(c, accounts[role]) for role, c in opened.items()}
    finally:
        for c in opened.values():
            c.__exit__(None, None, None)


@pytest.fixture
def games(db_session: Session, db_settings: Settings) -> dict[str, list[int]]:
    """Game "one" with a real three-view system (1.png) and three bare ones (2-4.png, 3 and 4 accepted),
    game "two" with two bare systems."""
    one = make_game(db_session)
    scene: Scene = make_system(db_session, db_settings, one, "1.png")
    two = Game(league="l", season="s", match="two", source_path="/nowhere")
    db_session.add(two)
    db_session.flush()
    bare = [System(game_id=one.id, name=f"{i}.png", kind=SystemKind.SOCCERNET_V3,
                   review_status=ReviewStatus.ACCEPTED if i >= 3 else ReviewStatus.PENDING) for i in (2, 3, 4)]
    bare += [System(game_id=two.id, name=f"{i}.png", kind=SystemKind.SOCCERNET_V3) for i in (1, 2)]
    db_session.add_all(bare)
    db_session.commit()
    return {"one": [scene.system_id] + [s.id for s in bare[:3]], "two": [s.id for s in bare[3:]],
            "game_ids": [one.id, two.id]}


def _ids(answer) -> list[int]:
    assert answer.status_code == 200, answer.text
    return sorted(item["id"] for item in answer.json()["items"])


def test_a_reviewer_assigns_one_system_a_game_and_a_filter_and_each_is_audited(clients, games, accounts, db_session):
    reviewer, annotator = clients["reviewer"], clients["annotator"]
    name = accounts["annotator"].name
    one = reviewer.post("/api/assignments", json={"assignee": name, "system_ids": [games["one"][0]]})
    assert one.status_code == 200, one.text
    assert one.json() == {"assignee": name, "matched": 1, "changed": 1, "system_ids": [games["one"][0]]}
    game = reviewer.post("/api/assignments", json={"assignee": name, "game_id": games["game_ids"][1]}).json()
    assert (game["matched"], game["changed"]) == (2, 2)
    # a queue filter's result: the pending systems of game one (1.png and 2.png; 1.png is already hers)
    flt = reviewer.post("/api/assignments", json={
        "assignee": name, "filter": {"game_id": games["game_ids"][0], "status": "pending"}}).json()
    assert (flt["matched"], flt["changed"], flt["system_ids"]) == (2, 1, [games["one"][1]])
    mine = sorted([games["one"][0], games["one"][1], *games["two"]])
    assert _ids(annotator.get("/api/systems", params={"assignee": "me", "limit": 500})) == mine
    assert _ids(reviewer.get("/api/systems", params={"assignee": name, "limit": 500})) == mine
    assert _ids(reviewer.get("/api/systems", params={"assignee": "none"})) == sorted(games["one"][2:])
    assert _ids(reviewer.get("/api/systems", params={"assignee": "me"})) == []
    row = next(r for r in annotator.get("/api/systems").json()["items"] if r["id"] == games["one"][0])
    assert row["assignment"]["assignee"] == name and row["assignment"]["assigned_by"] == accounts["reviewer"].name
    entries = db_session.scalars(sa.select(AuditEntry).where(AuditEntry.action == "system.assign")
                                 .order_by(AuditEntry.id)).all()
    assert sorted(e.system_id for e in entries) == mine
    assert {(e.actor, e.before["assignee"], e.after["assignee"]) for e in entries} == {
        (accounts["reviewer"].name, None, name)}
    history = annotator.get("/api/audit", params={"system_id": games["one"][0]}).json()["items"]
    assert [(h["action"], h["after"]) for h in history] == [("system.assign", {"assignee": name})]


def test_the_system_view_shows_the_assignee_and_follows_my_systems(clients, games, accounts):
    name = accounts["annotator"].name
    clients["admin"].post("/api/assignments", json={"assignee": name, "system_ids": [games["one"][0], games["two"][1]]})
    view = clients["annotator"].get(f"/api/systems/{games['one'][0]}", params={"assignee": "me", "sort": "name"}).json()
    assert view["assignment"]["assignee"] == name and view["assignment"]["assigned_by"] == accounts["admin"].name
    assert view["next_id"] == games["two"][1] and view["prev_id"] is None  # the neighbours of "my systems"
    other = clients["annotator"].get(f"/api/systems/{games['one'][2]}").json()
    assert other["assignment"] == {"assignee": None, "assigned_at": None, "assigned_by": None}
    cleared = clients["reviewer"].post("/api/assignments", json={"assignee": None, "system_ids": [games["one"][0]]})
    assert cleared.json()["changed"] == 1
    assert clients["annotator"].get(f"/api/systems/{games['one'][0]}").json()["assignment"]["assignee"] is None


def test_annotators_may_not_assign_and_bad_input_names_its_field(clients, games, accounts, app):
    body = {"assignee": accounts["annotator"].name, "system_ids": [games["one"][0]]}
    refused = clients["annotator"].post("/api/assignments", json=body)
    assert refused.status_code == 403 and "reviewer" in refused.json()["detail"]
    assert clients["annotator"].get("/api/assignees").status_code == 403
    with TestClient(app) as c:  # an annotator's API token is refused the same way
        assert as_token(c, accounts["annotator"]).post("/api/assignments", json=body).status_code == 403
    names = [u["name"] for u in clients["reviewer"].get("/api/assignees").json()]
    assert {a.name for a in accounts.values()} <= set(names)
    cases = [
        ({"assignee": "nobody-by-this-name", "system_ids": [games["one"][0]]}, 422, "assignee"),
        ({"assignee": None, "system_ids": [games["one"][0]], "game_id": games["game_ids"][0]}, 422, None),
        ({"assignee": None}, 422, None),
        ({"assignee": None, "filter": {"stauts": "pending"}}, 422, None),  # a misspelt filter widens nothing
        ({"assignee": None, "system_ids": [10**9]}, 404, None),
        ({"assignee": None, "game_id": 10**9}, 404, None),
    ]
    for body, status, field in cases:
        answer = clients["reviewer"].post("/api/assignments", json=body)
        assert answer.status_code == status, (body, answer.text)
        if field:
            assert answer.json()["field"] == field
    unknown = clients["annotator"].get("/api/systems", params={"assignee": "nobody-by-this-name"})
    assert unknown.status_code == 200 and unknown.json()["items"] == []  # as a user with no system: no account named
    assert _ids(clients["reviewer"].get("/api/systems", params={"assignee": "none", "limit": 500})) == sorted(
        games["one"] + games["two"])  # nothing was assigned


def test_presence_is_claimed_by_the_heartbeat_and_seen_by_the_others(clients, games, accounts, db_session):
    sid = games["one"][0]
    a, b = clients["annotator"], clients["reviewer"]
    first = a.put(f"/api/systems/{sid}/presence")
    assert first.status_code == 200, first.text
    body = first.json()
    assert body["wrote"] is True and body["others"] == [] and body["mine"]["name"] == accounts["annotator"].name
    assert (body["heartbeat_seconds"], body["ttl_seconds"]) == (10, 50)
    assert a.put(f"/api/systems/{sid}/presence").json()["wrote"] is False  # a heartbeat within 30 s: read only
    seen = b.put(f"/api/systems/{sid}/presence").json()
    assert [p["name"] for p in seen["others"]] == [accounts["annotator"].name]
    view = b.get(f"/api/systems/{sid}").json()
    assert {p["name"] for p in view["open_by"]} == {accounts["annotator"].name, accounts["reviewer"].name}
    row = next(r for r in b.get("/api/systems").json()["items"] if r["id"] == sid)
    assert [p["name"] for p in row["open_by"]] == [accounts["annotator"].name, accounts["reviewer"].name]
    assert row["open_by"][0]["seconds_open"] >= 0
    assert a.delete(f"/api/systems/{sid}/presence").status_code == 204
    assert [p["name"] for p in b.get(f"/api/systems/{sid}").json()["open_by"]] == [accounts["reviewer"].name]
    assert a.put("/api/systems/999999999/presence").status_code == 404


def test_a_lapsed_claim_is_no_longer_shown(clients, games, accounts, db_session):
    """A page that went away without a word (no DELETE): its claim, written TTL ago, is shown to nobody."""
    sid = games["one"][0]
    user_id = db_session.scalar(sa.select(User.id).where(User.name == accounts["annotator"].name))
    presence.claim(db_session, sid, user_id, utcnow() - presence.TTL - timedelta(seconds=1))
    assert clients["reviewer"].get(f"/api/systems/{sid}").json()["open_by"] == []
    admin_id = db_session.scalar(sa.select(User.id).where(User.name == accounts["admin"].name))
    presence.claim(db_session, sid, admin_id, utcnow() - presence.TTL + timedelta(seconds=30))  # 20 s ago: live
    shown = clients["reviewer"].get(f"/api/systems/{sid}").json()["open_by"]
    assert [p["name"] for p in shown] == [accounts["admin"].name] and shown[0]["seconds_open"] >= 19
