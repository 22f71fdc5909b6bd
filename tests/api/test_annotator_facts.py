"""No facts to annotators they do not need: the process running a job (host name and process id) and the OS account
behind work run on the machine (``cli:<os user>`` in the audit) are shown to admins only; the queue's assignee
filter answers an unknown name as it answers a known one with nothing assigned (before, 422 "no user is called
'zzz'" let anyone logged in list the accounts); the assignee filter's words (``me``, ``none``) and names that differ
from another only by case or trailing dots are no user's name, through the API and the CLI alike."""
from __future__ import annotations

import getpass
import socket

import pytest
from fastapi import FastAPI
from fastapi.testclient import TestClient
from sqlalchemy.orm import Session

from app.core.config import Settings
from tests.accounts import Account, as_token

from .conftest import run_queued
from .factories import Scene, make_game, make_system

pytestmark = pytest.mark.engine


@pytest.fixture
def annotator(app: FastAPI, accounts: dict[str, Account]):
    with TestClient(app) as c:
        yield as_token(c, accounts["annotator"])


def _os_account() -> str:
    try:
        return getpass.getuser()
    except (KeyError, OSError):
        return "unknown"


def test_a_jobs_owner_is_shown_to_admins_only(app: FastAPI, client: TestClient, annotator: TestClient,
                                             scene: Scene) -> None:
    """Was: every role read ``owner`` (``host:pid:token``): the server's host name and process ids."""
    job = client.post("/api/recompute").json()
    run_queued(app)
    assert client.get(job["url"]).json()["owner"].startswith(f"{socket.gethostname()}:")
    seen = annotator.get(job["url"]).json()
    assert seen["owner"] is None and seen["state"] == "done"
    assert all(j["owner"] is None for j in annotator.get("/api/jobs").json()["items"])


def test_the_os_account_of_work_run_on_the_machine_is_shown_to_admins_only(
        client: TestClient, annotator: TestClient, db_session: Session, db_settings: Settings, scene: Scene) -> None:
    """Was: the audit showed every role ``cli:root`` (the OS account of the machine's owner), and a decision's
    reset reason and an assignment's ``assigned_by`` wrote it out. Admins still see it in the audit; the other roles
    read ``cli``, and ``user=cli`` lists that work (a ``cli:<name>`` filter matches nothing for them)."""
    from app.services.curation.assignment import assign
    from app.services.curation.decisions import decide_review
    from app.services.curation.editing import update_ball_label

    fid = scene.frame_ids[0]
    decide_review(db_session, system_id=scene.system_id, status="accepted", actor="test-reviewer")
    update_ball_label(db_session, fid, box=[470.0, 260.0, 484.0, 274.0], settings=db_settings)  # on the machine
    assign(db_session, assignee="test-annotator", system_ids=[scene.system_id])
    account = f"cli:{_os_account()}"

    as_admin = client.get("/api/audit", params={"system_id": scene.system_id}).json()["items"]
    assert {e["actor"] for e in as_admin} >= {account}
    seen = annotator.get("/api/audit", params={"system_id": scene.system_id})
    assert account not in seen.text and _os_account() not in {e["actor"] for e in seen.json()["items"]}
    assert {e["actor"] for e in seen.json()["items"]} == {"cli", "test-reviewer"}
    # the edit, the reset it made, the assignment
    assert annotator.get("/api/audit", params={"user": "cli"}).json()["total"] == 3
    assert annotator.get("/api/audit", params={"user": account}).json()["total"] == 0
    system = annotator.get(f"/api/systems/{scene.system_id}")
    assert account not in system.text
    assert system.json()["assignment"]["assigned_by"] == "cli"
    assert system.json()["review"]["reset_reason"].endswith("by cli; decide it again")


def test_an_unknown_assignee_answers_as_a_known_one_with_no_system(annotator: TestClient, scene: Scene) -> None:
    """Was: ``?assignee=zzz`` answered 422 "no user is called 'zzz'" and a real name 200: anyone logged in could
    list the accounts by trying names."""
    unknown = annotator.get("/api/systems", params={"assignee": "zzz"})
    known = annotator.get("/api/systems", params={"assignee": "test-reviewer"})
    assert unknown.status_code == known.status_code == 200, unknown.text
    assert unknown.json()["items"] == known.json()["items"] == [] and unknown.json()["total"] == 0
    assert annotator.get("/api/systems", params={"assignee": "none"}).json()["total"] == 1


@pytest.mark.parametrize("name", ["none", "me", "None", "ME", "none.", "me..", "Test-Annotator", "test-annotator."])
def test_reserved_names_and_near_duplicates_are_refused_for_a_new_user(client: TestClient, name: str) -> None:
    """Was: admins could create users called ``none`` or ``me`` (and ``Ana`` beside ``ana``): systems assigned to
    ``none`` never appeared under ``assignee=none``. Refused naming the field; nothing stored."""
    answer = client.post("/api/users", json={"name": name, "role": "annotator", "password": "pw"})
    assert answer.status_code == 422, answer.text
    assert answer.json()["field"] == "name"
    assert name not in [u["name"] for u in client.get("/api/users").json()]


def test_no_system_can_be_assigned_to_a_reserved_name(client: TestClient, db_session: Session,
                                                      db_settings: Settings) -> None:
    """A user called ``none`` made before such names were refused is given no system: ``assignee=none`` keeps
    meaning the unassigned ones."""
    from app.db.models import User, UserRole

    db_session.add(User(name="none", role=UserRole.ANNOTATOR, password_hash="x"))
    db_session.commit()
    scene = make_system(db_session, db_settings, make_game(db_session, "reserved"), "1.png")
    answer = client.post("/api/assignments", json={"assignee": "none", "system_ids": [scene.system_id]})
    assert answer.status_code == 422 and answer.json()["field"] == "assignee", answer.text
    assert client.get("/api/systems", params={"assignee": "none"}).json()["total"] == 1
