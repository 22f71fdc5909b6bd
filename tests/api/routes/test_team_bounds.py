"""The team's loop within bounds: a reviewer's comment on a view leaves the annotator's undo of her own edit hers (a
comment writes no label), a system holds at most ``V3D_MAX_COMMENTS_PER_SYSTEM`` comments (resolved ones count: 409
naming the cap when reached) and its comments are listed a page at a time, as the audit log is."""
from __future__ import annotations

from typing import Any

import pytest
from fastapi import FastAPI
from fastapi.testclient import TestClient
from sqlalchemy.orm import Session

from app.api.auth import Principal, current_principal
from app.db.models import User, UserRole

from ..factories import Scene

#: The edit routes run on a real engine, as served (tests/api/conftest.py).
pytestmark = [pytest.mark.served, pytest.mark.engine]


@pytest.fixture
def team(db_session: Session) -> dict[str, User]:
    """A reviewer (rev) and an annotator (ana), real users of the test database."""
    users = {n: User(name=n, role=r, password_hash="not a hash: these users never log in") for n, r in
             (("rev", UserRole.REVIEWER), ("ana", UserRole.ANNOTATOR))}
    db_session.add_all(users.values())
    db_session.commit()
    return users


@pytest.fixture
def as_user(app: FastAPI, team: dict[str, User]):
    """``as_user(name)``: the later requests come from that user."""

    def choose(name: str) -> None:
        user = team[name]
        principal = Principal(user.id, user.name, user.role.value, "token")
        app.dependency_overrides[current_principal] = lambda: principal

    return choose


def _view(client: TestClient, scene: Scene, k: int) -> dict[str, Any]:
    answer = client.get(f"/api/systems/{scene.system_id}")
    assert answer.status_code == 200, answer.text
    return answer.json()["views"][k]


def _move(client: TestClient, scene: Scene, k: int, box: list[float], dx: float):
    return client.patch(f"/api/frames/{scene.frame_ids[k]}/ball", headers={"If-Match": _view(client, scene, k)["etag"]},
                        json={"box": [box[0] + dx, box[1], box[2] + dx, box[3]]})


def _comment(client: TestClient, scene: Scene, text: str, k: int = 0):
    return client.post(f"/api/systems/{scene.system_id}/comments",
                       json={"frame_id": scene.frame_ids[k], "point": None, "text": text})


def test_a_reviewers_comment_on_a_view_leaves_the_annotators_undo_of_her_edit_hers(
        client: TestClient, scene: Scene, as_user) -> None:
    as_user("ana")
    box = _view(client, scene, 1)["ball"]["box"]
    moved = _move(client, scene, 1, box, 7.0)
    assert moved.status_code == 200, moved.text
    entry = int(moved.headers["x-v3d-audit-entry"])
    as_user("rev")
    pinned = _comment(client, scene, "is this the ball or its shadow?", k=1)
    assert pinned.status_code == 201, pinned.text
    assert client.post(f"/api/comments/{pinned.json()['id']}/resolve").status_code == 200  # resolving: no label write
    as_user("ana")
    undone = client.post(f"/api/audit/{entry}/undo")
    assert undone.status_code == 200, undone.text
    assert undone.json()["views"][1]["ball"]["box"] == box
    # a reviewer's write of the view's labels still takes the undo of her next edit away
    again = _move(client, scene, 1, box, 5.0)
    assert again.status_code == 200, again.text
    as_user("rev")
    assert _move(client, scene, 1, box, 2.0).status_code == 200
    as_user("ana")
    refused = client.post(f"/api/audit/{int(again.headers['x-v3d-audit-entry'])}/undo")
    assert refused.status_code == 403 and "rev changed the view since" in refused.json()["detail"]


def _limited(app: FastAPI, **values: Any) -> None:
    app.state.settings = app.state.settings.model_copy(update=values)


def test_a_system_holds_at_most_the_cap_of_comments_resolved_ones_included(
        app: FastAPI, client: TestClient, scene: Scene, as_user) -> None:
    _limited(app, max_comments_per_system=5)
    as_user("rev")
    made = [_comment(client, scene, f"look at this, {i}") for i in range(5)]
    assert [m.status_code for m in made] == [201] * 5
    for m in made[:3]:  # resolved comments still count
        assert client.post(f"/api/comments/{m.json()['id']}/resolve").status_code == 200
    refused = _comment(client, scene, "one more")
    assert refused.status_code == 409, refused.text
    assert "V3D_MAX_COMMENTS_PER_SYSTEM" in refused.json()["detail"] and "holds 5 comments" in refused.json()["detail"]
    listed = client.get(f"/api/systems/{scene.system_id}/comments").json()
    assert listed["total"] == 5 and [c["text"] for c in listed["items"]] == [f"look at this, {i}" for i in range(5)]
    adds = client.get("/api/audit", params={"system_id": scene.system_id, "limit": 500}).json()["items"]
    assert sum(e["action"] == "comment.add" for e in adds) == 5  # the refused one left no entry


def test_the_comments_are_listed_a_page_at_a_time_as_the_audit_log(
        app: FastAPI, client: TestClient, scene: Scene, as_user) -> None:
    as_user("rev")
    for i in range(12):
        assert _comment(client, scene, f"comment {i}", k=i % 3).status_code == 201
    url = f"/api/systems/{scene.system_id}/comments"
    first = client.get(url, params={"limit": 5}).json()
    assert (len(first["items"]), first["total"], first["limit"], first["offset"], first["next_offset"]) == (
        5, 12, 5, 0, 5)
    last = client.get(url, params={"limit": 5, "offset": 10}).json()
    assert [c["text"] for c in last["items"]] == ["comment 10", "comment 11"] and last["next_offset"] is None
    texts, offset = [], 0
    while offset is not None:
        page = client.get(url, params={"limit": 5, "offset": offset}).json()
        texts += [c["text"] for c in page["items"]]
        offset = page["next_offset"]
    assert texts == [f"comment {i}" for i in range(12)]  # oldest first, each once
    assert client.get(url, params={"limit": 0}).status_code == 422
    assert client.get(url, params={"limit": 501}).status_code == 422
    assert client.get(url, params={"offset": -1}).status_code == 422
    # a page stops before V3D_MAX_ANSWER_KB of JSON (one comment at least), next_offset naming the rest
    _limited(app, max_answer_kb=2)
    for i in range(3):
        assert _comment(client, scene, f"{i} " + "long " * 300).status_code == 201
    capped = client.get(url, params={"limit": 500, "offset": 12}).json()
    assert len(capped["items"]) == 1 and capped["next_offset"] == 13 and capped["total"] == 15
