"""``/api/passes`` (issue 28): begin or continue a pass, read it, where a system stands, the owner's visits;
an accept through the API over open label doubts records them in its audit entry."""
from __future__ import annotations

import pytest
from fastapi.testclient import TestClient
from sqlalchemy.orm import Session

from app.core.config import Settings

from ..factories import Scene, make_game, make_system

pytestmark = pytest.mark.engine


@pytest.fixture
def three(db_session: Session, db_settings: Settings) -> list[Scene]:
    game = make_game(db_session)
    return [make_system(db_session, db_settings, game, "1.png"),
            make_system(db_session, db_settings, game, "2.png", shift_px=(0.0, 60.0, 0.0)),
            make_system(db_session, db_settings, game, "3.png")]


def test_a_pass_freezes_every_page_of_the_queue_and_moves_to_the_next_pending(client: TestClient,
                                                                             three: list[Scene]) -> None:
    listing = [s["id"] for s in client.get("/api/systems", params={"sort": "name", "limit": 2}).json()["items"]]
    cursor = client.get("/api/systems", params={"sort": "name", "limit": 2}).json()["next_cursor"]
    listing += [s["id"] for s in client.get("/api/systems",
                                            params={"sort": "name", "limit": 2, "after": cursor}).json()["items"]]

    made = client.post("/api/passes", json={"filter": {}, "sort": "name", "system_id": listing[0]})
    assert made.status_code == 201, made.text
    rp = made.json()
    assert rp["systems"] == listing and rp["position"] == 0 and rp["filter"] == {} and rp["sort"] == "name"
    assert rp["counts"] == {"accepted": 0, "rejected": 0, "needs_fix": 0, "sent_back": 0, "by_others": 0, "skipped": 3}
    assert client.post("/api/passes",
                       json={"filter": {}, "sort": "name", "system_id": listing[1]}).json()["id"] == rp["id"]

    etag = client.get(f"/api/systems/{listing[1]}").headers["ETag"]
    assert client.post(f"/api/systems/{listing[1]}/review", json={"status": "needs_fix", "assignee": "test-annotator"},
                       headers={"If-Match": etag}).status_code == 200
    place = client.get(f"/api/passes/{rp['id']}/place", params={"system_id": listing[0]}).json()
    assert place["next_pending_id"] == listing[2] and place["next_id"] == listing[1] and place["index"] == 0

    visit = client.post(f"/api/passes/{rp['id']}/visits", json={"system_id": listing[2]})
    assert visit.status_code == 200 and visit.json()["first_pending_id"] == listing[0]
    # nothing pending after the last: back to the first one left pending (the pass wraps round)
    assert not visit.json()["finished"] and visit.json()["next_pending_id"] == listing[0]
    assert visit.json()["next_pending_index"] == 0
    assert client.get(f"/api/passes/{rp['id']}").json()["position"] == 2
    mine = client.get("/api/passes").json()
    assert [p["id"] for p in mine] == [rp["id"]] and mine[0]["systems"] == [] and mine[0]["total"] == 3


def test_bad_pass_requests_are_named(client: TestClient, three: list[Scene]) -> None:
    assert client.get("/api/passes/999999").status_code == 404
    bad = client.post("/api/passes", json={"filter": {}, "sort": "sideways"})
    assert bad.status_code == 422 and "sort" in bad.text
    assert client.post("/api/passes", json={"filter": {}, "colour": 1}).status_code == 422


def test_another_users_pass_is_read_but_not_moved(client: TestClient, act_as, three: list[Scene]) -> None:
    rp = client.post("/api/passes", json={"filter": {"game_id": None}, "sort": "name"}).json()
    act_as("someone-else", "reviewer")
    assert client.get(f"/api/passes/{rp['id']}").status_code == 200
    assert client.post(f"/api/passes/{rp['id']}/visits", json={"system_id": rp["systems"][1]}).status_code == 403
    assert client.get("/api/passes").json() == []
    assert [p["id"] for p in client.get("/api/passes", params={"mine": "false"}).json()] == [rp["id"]]


def test_an_api_accept_of_a_doubtful_system_lists_its_doubts_in_the_audit_entry(client: TestClient,
                                                                                three: list[Scene]) -> None:
    sid = three[1].system_id
    system = client.get(f"/api/systems/{sid}")
    doubts = [d for d in system.json()["doubts"] if d["accuses_label"]]
    assert doubts
    assert client.post(f"/api/systems/{sid}/review", json={"status": "accepted"},
                       headers={"If-Match": system.headers["ETag"]}).status_code == 200
    entry = client.get("/api/audit", params={"system_id": sid, "limit": 1}).json()["items"][0]
    assert entry["action"] == "system.review"
    assert [(d["kind"], d["frame_id"], d["message"]) for d in entry["after"]["overrode_doubts"]] == \
        [(d["kind"], d["frame_id"], d["message"]) for d in doubts]


def test_three_hundred_fresh_passes_of_one_annotator_leave_at_most_fifty_stored(
        app, db_session: Session, three: list[Scene], accounts) -> None:
    """Was: 300 ``POST /api/passes {"fresh": true}`` by one annotator in 2.7 s stored 300 passes, each with every
    system id of its queue (about 77 KB at SoccerNet-v3's size): one annotator grew the database without bound. A
    user keeps at most V3D_MAX_PASSES_PER_USER (50) passes, the least recently visited dropped; another user's passes
    and ``GET /api/passes`` (a JSON list) are as before."""
    import sqlalchemy as sa

    from app.db.models import ReviewPass
    from tests.accounts import as_token

    with TestClient(app) as c:
        annotator = as_token(c, accounts["annotator"])
        reviewer_pass = as_token(TestClient(app), accounts["reviewer"]).post("/api/passes", json={"fresh": True})
        assert reviewer_pass.status_code == 201
        made = [annotator.post("/api/passes", json={"fresh": True}) for _ in range(300)]
        assert {m.status_code for m in made} == {201}
        stored = db_session.scalars(sa.select(ReviewPass.id).where(
            ReviewPass.user_name == accounts["annotator"].name).order_by(ReviewPass.id)).all()
        assert len(stored) == 50
        assert stored == [m.json()["id"] for m in made[-50:]]  # the newest kept, the oldest dropped
        assert db_session.get(ReviewPass, reviewer_pass.json()["id"]) is not None  # another user's: untouched
        listed = annotator.get("/api/passes", params={"limit": 100})
        assert listed.status_code == 200 and isinstance(listed.json(), list) and len(listed.json()) == 50
