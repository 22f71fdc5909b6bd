"""API test fixtures: ``create_app`` on the migrated test database, every request's session joined to
the per-test transaction (``db_connection`` of ``tests/conftest.py``) so nothing outlives a test.
``client`` is an admin's logged-in browser session (cookie and CSRF header); ``anonymous`` has neither;
``accounts`` are the test users of every role (``tests/accounts.py``).

Modules marked ``served`` (the edit routes') run the production path instead: the app and the test's
``db_session`` on a real engine of a database of the test's own, copied from the session's migrated database with
its accounts (SQLite: a file copy; PostgreSQL: ``CREATE DATABASE ... TEMPLATE``), so that every edit reads, ends its
read transaction, computes and writes under the lock as a served process does."""
from __future__ import annotations

import shutil
import sqlite3
import uuid
from collections.abc import Iterator

import pytest
import sqlalchemy as sa
from fastapi import FastAPI
from fastapi.testclient import TestClient
from sqlalchemy.orm import Session, sessionmaker

from app.api.auth import Principal, current_principal
from app.core.config import Settings
from app.db.session import V3dSession, make_engine
from app.main import create_app
from tests.accounts import Account, as_session, make_accounts
from tests.conftest import create_test_database, joined_session

from .factories import Scene, make_game, make_system

#: The marker of modules whose tests run the app on a real engine (module docstring).
SERVED = "served"


@pytest.fixture(scope="session")
def served_template(db_url: str, db_engine: sa.Engine, accounts: dict[str, Account],
                    tmp_path_factory: pytest.TempPathFactory) -> Iterator[str]:
    """A copy of the session's migrated database with its accounts, never connected to: what each served test's
    database is copied from (PostgreSQL copies only a database nobody is connected to)."""
    url = sa.make_url(db_url)
    if url.get_backend_name() == "sqlite":
        target = tmp_path_factory.mktemp("served") / "template.sqlite3"
        with sqlite3.connect(url.database) as source, sqlite3.connect(target) as copy:
            source.backup(copy)
        yield str(target)
        return
    db_engine.dispose()  # the session's pooled connections: a template must have none
    admin = sa.create_engine(url.set(database="postgres"), isolation_level="AUTOCOMMIT")
    name = f"{url.database}_served"
    with admin.connect() as conn:
        create_test_database(conn, name, template=url.database)
    try:
        yield name
    finally:
        with admin.connect() as conn:
            conn.exec_driver_sql(f'DROP DATABASE IF EXISTS "{name}" WITH (FORCE)')
        admin.dispose()


@pytest.fixture
def served_engine(request: pytest.FixtureRequest, db_url: str, tmp_path) -> Iterator[sa.Engine | None]:
    """For a test of a ``served`` module, an engine on a database of its own (module docstring); else None."""
    if request.node.get_closest_marker(SERVED) is None:
        yield None
        return
    template = request.getfixturevalue("served_template")
    url = sa.make_url(db_url)
    if url.get_backend_name() == "sqlite":
        target = tmp_path / "served.sqlite3"
        shutil.copyfile(template, target)
        engine = make_engine(f"sqlite:///{target}")
        yield engine
        engine.dispose()
        return
    admin = sa.create_engine(url.set(database="postgres"), isolation_level="AUTOCOMMIT")
    name = f"{template}_{uuid.uuid4().hex[:8]}"
    with admin.connect() as conn:
        create_test_database(conn, name, template=template)
    engine = make_engine(url.set(database=name))
    try:
        yield engine
    finally:
        engine.dispose()
        with admin.connect() as conn:
            conn.exec_driver_sql(f'DROP DATABASE IF EXISTS "{name}" WITH (FORCE)')
        admin.dispose()


@pytest.fixture
def db_session(request: pytest.FixtureRequest, served_engine: sa.Engine | None) -> Iterator[Session]:
    """The test's session: on the served engine's database (commits are real) for a ``served`` module, else the
    session of ``tests/conftest.py`` (commits are savepoints of the per-test transaction)."""
    if served_engine is None:
        with joined_session(request.getfixturevalue("db_connection")) as joined:
            yield joined
        return
    session = V3dSession(served_engine, expire_on_commit=False)
    try:
        yield session
    finally:
        session.close()


@pytest.fixture(scope="session")
def accounts(db_url: str) -> dict[str, Account]:
    """One user per role in the session's test database, each logged in once through the login route."""
    return make_accounts(db_url)


@pytest.fixture
def app(request: pytest.FixtureRequest, db_settings: Settings, served_engine: sa.Engine | None) -> FastAPI:
    """The real application; its sessions commit into savepoints of the test's transaction, or, in a ``served``
    module, on its own engine of the test's database as a served process's do. Queued jobs are run by the test
    (:func:`run_queued`) on those sessions, in its thread (heartbeats only at the start and end of a job)."""
    if served_engine is not None:
        url = served_engine.url.render_as_string(hide_password=False)
        return create_app(db_settings.model_copy(update={"job_heartbeat_seconds": 3600.0, "database_url": url}))
    application = create_app(db_settings.model_copy(update={"job_heartbeat_seconds": 3600.0}))
    application.state.session_factory = sessionmaker(
        bind=request.getfixturevalue("db_connection"), class_=V3dSession, join_transaction_mode="create_savepoint",
        expire_on_commit=False)
    return application


@pytest.fixture
def act_as(app: FastAPI):
    """``act_as(name, role="annotator", via="session")``: every later request of the test comes from
    that principal (``app.dependency_overrides`` of ``current_principal``, past the authentication layer,
    which ``tests/api/test_auth.py`` tests with real sessions and tokens); returns it."""

    def choose(name: str, role: str = "annotator", via: str = "session") -> Principal:
        principal = Principal(abs(hash(name)) % 10_000, name, role, via)  # type: ignore[arg-type]  # role and via as plain strings
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

    owner = jobs.owner_name(app.state.settings)
    ran = []
    while (job_id := jobs.claim_next(app.state.session_factory, owner, app.state.settings)) is not None:
        jobs.run_job(app.state.session_factory, job_id, app.state.settings, owner)
        ran.append(job_id)
    return ran
