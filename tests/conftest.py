"""Fixtures shared by the whole suite."""
from __future__ import annotations

from pathlib import Path

import pytest

from app.core.paths import SHARED_DIR


@pytest.fixture(scope="session")
def shared_dir() -> Path:
    """``../shared`` beside the checkout; tests that need it skip with the reason when it is absent."""
    if not (SHARED_DIR / "data").is_dir():
        pytest.skip(f"../shared not found at {SHARED_DIR}: real and synthetic data unavailable")
    return SHARED_DIR


# ----- database fixtures (app/db): a migrated SQLite database per test session, one rolled-back
# transaction per test (SQLAlchemy's "join a session into an external transaction" recipe) ---------
from collections.abc import Iterator  # noqa: E402

import sqlalchemy as sa  # noqa: E402
from sqlalchemy.orm import Session  # noqa: E402

from app.core.config import Settings  # noqa: E402
from app.db.session import make_engine, upgrade_database  # noqa: E402


@pytest.fixture(scope="session")
def db_url(tmp_path_factory: pytest.TempPathFactory) -> str:
    """URL of a SQLite file database built by the Alembic migrations, once per test session."""
    url = f"sqlite:///{tmp_path_factory.mktemp('db') / 'v3d-test.sqlite3'}"
    upgrade_database(url)
    return url


@pytest.fixture(scope="session")
def db_engine(db_url: str) -> Iterator[sa.Engine]:
    """Engine on :func:`db_url` (foreign keys on, WAL, working savepoints)."""
    engine = make_engine(db_url)
    yield engine
    engine.dispose()


@pytest.fixture
def db_connection(db_engine: sa.Engine) -> Iterator[sa.Connection]:
    """A connection inside a transaction that is rolled back after the test. Bind sessions to it
    with ``join_transaction_mode="create_savepoint"`` (as :func:`db_session` does) so that the code
    under test may commit and roll back freely."""
    with db_engine.connect() as conn:
        outer = conn.begin()
        try:
            yield conn
        finally:
            if outer.is_active:
                outer.rollback()


@pytest.fixture
def db_session(db_connection: sa.Connection) -> Iterator[Session]:
    """A session whose commits are savepoints of the per-test transaction: nothing outlives the test."""
    session = Session(bind=db_connection, join_transaction_mode="create_savepoint", expire_on_commit=False)
    try:
        yield session
    finally:
        session.close()


@pytest.fixture
def db_settings(db_url: str, tmp_path_factory: pytest.TempPathFactory) -> Settings:
    """Settings pointing at the test database; calibration runs in-process (one worker); HTTP imports may
    read the test session's temporary folders (the data root)."""
    return Settings(database_url=db_url, calibration_workers=1, data_root=tmp_path_factory.getbasetemp())


#: The local PostgreSQL server of the ``postgres``-marked tests (trust authentication).
PG_ADMIN_URL = "postgresql+psycopg://postgres@127.0.0.1:5432/test"


@pytest.fixture
def pg_url() -> Iterator[str]:
    """URL of a fresh, empty PostgreSQL database made for this test and dropped after it, so that
    concurrent runs never collide. Skips with the reason when the server is down."""
    import uuid

    admin = sa.create_engine(PG_ADMIN_URL, isolation_level="AUTOCOMMIT")
    name = f"v3d_test_{uuid.uuid4().hex[:12]}"
    try:
        with admin.connect() as conn:
            conn.exec_driver_sql(f'CREATE DATABASE "{name}"')
    except sa.exc.OperationalError as exc:
        admin.dispose()
        pytest.skip(f"PostgreSQL not reachable at {PG_ADMIN_URL}: {exc.orig}")
    try:
        yield f"postgresql+psycopg://postgres@127.0.0.1:5432/{name}"
    finally:
        with admin.connect() as conn:
            conn.exec_driver_sql(f'DROP DATABASE IF EXISTS "{name}" WITH (FORCE)')
        admin.dispose()
