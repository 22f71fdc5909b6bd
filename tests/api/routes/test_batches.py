"""``/api/batches``: a reviewer makes a batch of the queue's pending vouched systems with a random sample of the plan's
size, reviews the sample through the ordinary review and accepts the rest (each audited with the batch's id), or is
refused naming the system that stops it; annotators are refused; an undo puts them back to pending."""
from __future__ import annotations

from typing import Any

import pytest
from fastapi.testclient import TestClient
from sqlalchemy.orm import Session

from app.core.config import Settings
from app.db.models import System
from app.db.models.enums import BallEvidence

from ..factories import Scene, make_game, make_system

#: Decisions run on a real engine, as served (tests/api/conftest.py).
pytestmark = [pytest.mark.served, pytest.mark.engine]


@pytest.fixture
def six(db_session: Session, db_settings: Settings) -> list[Scene]:
    """Six systems of one game: five vouched for, one unconfirmed."""
    game = make_game(db_session)
    scenes = [make_system(db_session, db_settings, game, f"{i + 1}.png") for i in range(6)]
    for i, scene in enumerate(scenes):
        system = db_session.get(System, scene.system_id)
        assert system is not None
        system.ball_evidence = BallEvidence.VOUCHED if i < 5 else BallEvidence.UNCONFIRMED
    db_session.commit()
    return scenes


def _decide(client: TestClient, system_id: int, status: str) -> None:
    etag = client.get(f"/api/systems/{system_id}").headers["ETag"]
    answer = client.post(f"/api/systems/{system_id}/review", json={"status": status}, headers={"If-Match": etag})
    assert answer.status_code == 200, answer.text


def _make(client: TestClient, **body: Any) -> dict[str, Any]:
    made = client.post("/api/batches", json={"filter": {}, "confidence": 0.75, "max_wrong_share": 0.5, **body})
    assert made.status_code == 201, made.text
    return made.json()


def test_a_batch_samples_at_random_and_accepts_the_rest_once_a_person_accepted_the_sample(
        client: TestClient, six: list[Scene]) -> None:
    vouched = [s.system_id for s in six[:5]]
    batch = _make(client)
    assert batch["systems"] == vouched and batch["state"] == "open"
    assert len(batch["sample"]) == 2 and set(batch["sample"]) <= set(vouched)
    assert batch["plan"] == "if none of these 2 is wrong, you can be 75 % sure that at most 50 % of the 5 are"
    assert {s["system_id"] for s in batch["stops"]} == set(batch["sample"])
    assert not any(s["final"] for s in batch["stops"])
    default = _make(client, confidence=0.95, max_wrong_share=0.05)
    assert sorted(default["sample"]) == vouched  # 59 asked, 5 there: all of them
    assert default["plan"] == "all 5 are in the sample: if none of them is wrong, none of the 5 is"
    samples = {tuple(_make(client)["sample"]) for _ in range(12)}
    assert len(samples) > 1  # drawn by the server, not the same every time (10 pairs: 12 equal draws ~ 1e-11)

    waiting = client.post(f"/api/batches/{batch['id']}/accept")
    assert waiting.status_code == 409 and "not decided yet" in waiting.json()["detail"]
    for sid in batch["sample"]:
        _decide(client, sid, "accepted")
    assert client.get(f"/api/batches/{batch['id']}").json()["stops"] == []
    accepted = client.post(f"/api/batches/{batch['id']}/accept")
    assert accepted.status_code == 200 and accepted.json() == {"accepted": 3}
    others = [i for i in vouched if i not in batch["sample"]]
    for sid in others:
        assert client.get(f"/api/systems/{sid}").json()["review"]["status"] == "accepted"
        entry = client.get("/api/audit", params={"system_id": sid, "limit": 1}).json()["items"][0]
        assert entry["action"] == "system.review" and entry["after"]["review"]["batch_id"] == batch["id"]
    read = client.get(f"/api/batches/{batch['id']}").json()
    assert read["state"] == "accepted" and read["accepted"] == 3 and read["decided_by"] == "test-admin"

    undone = client.post(f"/api/batches/{batch['id']}/undo")
    assert undone.status_code == 200 and undone.json() == {"undone": 3, "kept": []}
    assert all(client.get(f"/api/systems/{sid}").json()["review"]["status"] == "pending" for sid in others)
    assert client.post(f"/api/batches/{batch['id']}/undo").status_code == 409


def test_a_rejected_sample_stops_the_batch_for_good_naming_the_system(client: TestClient, six: list[Scene]) -> None:
    batch = _make(client)
    rejected, accepted = batch["sample"]
    _decide(client, rejected, "rejected")
    _decide(client, accepted, "accepted")
    stops = client.get(f"/api/batches/{batch['id']}").json()["stops"]
    assert stops == [{"system_id": rejected, "words": f"system {rejected} was rejected", "final": True}]
    refused = client.post(f"/api/batches/{batch['id']}/accept")
    assert refused.status_code == 409
    assert refused.json()["detail"] == f"batch {batch['id']} is refused: system {rejected} was rejected"
    _decide(client, rejected, "accepted")
    assert client.post(f"/api/batches/{batch['id']}/accept").json()["detail"] == refused.json()["detail"]
    read = client.get(f"/api/batches/{batch['id']}").json()
    assert read["state"] == "refused" and read["refusal"] == refused.json()["detail"]


def test_annotators_are_refused_and_bad_bodies_named(client: TestClient, act_as, six: list[Scene]) -> None:
    batch = _make(client)
    bad = client.post("/api/batches", json={"filter": {}, "confidence": 1.0})
    assert bad.status_code == 422 and "confidence" in bad.text
    assert client.post("/api/batches", json={"filter": {"colour": 1}}).status_code == 422
    status = client.post("/api/batches", json={"filter": {"status": "accepted"}})
    assert status.status_code == 422 and status.json()["field"] == "filter.status"
    tier = client.post("/api/batches", json={"filter": {"ball_evidence": "unconfirmed"}})
    assert tier.status_code == 422 and tier.json()["field"] == "filter.ball_evidence"
    assert client.post("/api/batches", json={"filter": {"ball_evidence": "vouched", "status": "pending"}}).json()[
        "systems"] == batch["systems"]
    assert client.get("/api/batches/999999").status_code == 404
    act_as("ana", "annotator")
    assert client.post("/api/batches", json={"filter": {}}).status_code == 403
    assert client.post(f"/api/batches/{batch['id']}/accept").status_code == 403
    assert client.post(f"/api/batches/{batch['id']}/undo").status_code == 403
    assert client.get(f"/api/batches/{batch['id']}").status_code == 200
    act_as("rev", "reviewer")
    assert client.post("/api/batches", json={"filter": {}}).status_code == 201


def test_the_sample_pass_holds_the_sample_in_its_order(client: TestClient, six: list[Scene]) -> None:
    batch = _make(client)
    made = client.post(f"/api/batches/{batch['id']}/pass")
    assert made.status_code == 201, made.text
    rp = made.json()
    assert rp["systems"] == batch["sample"] and rp["filter"] == {"batch_id": batch["id"]} and rp["sort"] == "sample"
    assert client.post(f"/api/batches/{batch['id']}/pass").json()["id"] == rp["id"]


def test_the_system_view_says_a_batch_accepted_it_after_a_sample_with_the_plan(
        client: TestClient, six: list[Scene]) -> None:
    batch = _make(client)
    for sid in batch["sample"]:
        _decide(client, sid, "accepted")
    assert client.post(f"/api/batches/{batch['id']}/accept").status_code == 200
    other = next(s.system_id for s in six[:5] if s.system_id not in batch["sample"])
    view = client.get(f"/api/systems/{other}").json()
    assert view["review"]["status"] == "accepted" and view["review"]["batch_id"] == batch["id"]
    assert view["accepted_in_batch"] == {
        "batch_id": batch["id"], "created_by": "test-admin", "decided_by": "test-admin",
        "decided_at": view["accepted_in_batch"]["decided_at"], "confidence": 0.75, "max_wrong_share": 0.5,
        "sample": 2, "systems": 5,
        "plan": "if none of these 2 is wrong, you can be 75 % sure that at most 50 % of the 5 are"}
    assert view["accepted_in_batch"]["decided_at"] is not None
    # a sampled system was accepted by a person, and a person's later decision is no batch's
    sampled = client.get(f"/api/systems/{batch['sample'][0]}").json()
    assert sampled["review"]["batch_id"] is None and sampled["accepted_in_batch"] is None
    _decide(client, other, "accepted")
    again = client.get(f"/api/systems/{other}").json()
    assert again["review"]["batch_id"] is None and again["accepted_in_batch"] is None
