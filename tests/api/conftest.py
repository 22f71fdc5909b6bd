"""API test fixtures: ``create_app`` on the migrated test database, every request's session joined to
the per-test transaction (``db_connection`` of ``tests/conftest.py``) so nothing outlives a test.
``client`` is an admin's logged-in browser session (cookie and CSRF header); ``anonymous`` has neither;
``accounts`` are the test users of every role (``tests/accounts.py``)."""
from __future__ import annotations

from collections.abc import Iterator

import pytest
import sqlalchemy as sa
from fastapi import FastAPI
from fastapi.testclient import TestClient
from sqlalchemy.orm import Session, sessionmaker

from app.api.auth import Principal, current_principal
from app.core.config import Settings
from app.main import create_app

from tests.accounts import Account, as_session, make_accounts

from .factories import Scene, make_game, make_system


@pytest.fixture(scope="session")
def accounts(db_url: str) -> dict[str, Account]:
    """One user per role in the session's test database, each logged in once through the login route."""
    return make_accounts(db_url)


@pytest.fixture
def app(db_settings: Settings, db_connection: sa.Connection) -> FastAPI:
    """The real application; its sessions commit into savepoints of the test's transaction. Queued jobs
    are run by the test (:func:`run_queued`) on those sessions, in its thread (heartbeats only at the
    start and end of a job)."""
    application = create_app(db_settings.model_copy(update={"job_heartbeat_seconds": 3600.0}))
    application.state.session_factory = sessionmaker(
        bind=db_connection, join_transaction_mode="create_savepoint", expire_on_commit=False
    )
    return application


@pytest.fixture
def act_as(app: FastAPI):
    """``act_as(name, role="annotator", via="session")``: every later request of the test comes from
    that principal (``app.dependency_overrides`` of ``current_principal``, past the authentication layer,
    which ``tests/api/test_auth.py`` tests with real sessions and tokens); returns it."""

    def choose(name: str, role: str = "annotator", via: str = "session") -> Principal:
        principal = Principal(abs(hash(name)) % 10_000, name, role, via)  # type: ignore[arg-type]
        app.dependency_overrides[current_principal] = lambda: principal
        return principal

    return choose


@pytest.fixture
def client(app: FastAPI, accounts: dict[str, Account]) -> Iterator[TestClient]:
    """HTTP client of :func:`app` as the admin's logged-in browser session (its cookie, and its CSRF
    token on every request); server errors raise in the test."""
    with TestClient(app) as c:
        yield as_session(c, accounts["admin"])


@pytest.fixture
def anonymous(app: FastAPI) -> Iterator[TestClient]:
    """HTTP client of :func:`app` with neither session nor token."""
    with TestClient(app) as c:
        yield c


@pytest.fixture
def scene(db_session: Session, db_settings: Settings, tmp_path) -> Scene:
    """One game with one three-view system (exact cameras, ball boxes, images for two views)."""
    game = make_game(db_session)
    return make_system(db_session, db_settings, game, "1.png", image_dir=tmp_path)


def run_queued(app: FastAPI) -> list[int]:
    """Run the app's queued jobs to their end, in this thread, as a server's runner would (the real
    ``app.services.jobs.runner`` claim and run); returns their ids."""
    from app.services.jobs import runner as jobs

    owner = jobs.owner_name()
    ran = []
    while (job_id := jobs.claim_next(app.state.session_factory, owner, app.state.settings)) is not None:
        jobs.run_job(app.state.session_factory, job_id, app.state.settings, owner)
        ran.append(job_id)
    return ran
