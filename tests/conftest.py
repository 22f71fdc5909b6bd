"""Fixtures shared by the whole suite."""
from __future__ import annotations

import os
import shutil
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import pytest
import sqlalchemy as sa
from sqlalchemy.orm import Session

from app.core.config import Settings
from app.core.paths import SHARED_DIR
from app.db import unit as write_units
from app.db.session import V3dSession, make_engine, upgrade_database
from tests.recording import RECORDER, RecordedBrowser, Recorder

#: The Host of Starlette's test client (``http://testserver``) is no loopback name: the apps of the tests accept
#: it because the tests' settings name it (``app.api.hosts``; a served v3d refuses it unless V3D_ALLOWED_HOSTS
#: does). ``tests/api/test_hosts.py`` builds apps without it to see the refusal.
TEST_CLIENT_HOST = "testserver"
os.environ["V3D_ALLOWED_HOSTS"] = ",".join(filter(None, [os.environ.get("V3D_ALLOWED_HOSTS"), TEST_CLIENT_HOST]))
#: Every write unit of the suite checks that what it changes of a system bumps the system's version (``app.db.unit``).
write_units.CHECK_VERSIONS = True


@pytest.hookimpl(tryfirst=True)  # before pytest-xdist reads the groups (its worker's hook of the same name)
def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    """The marks the tiers and passes select by that follow from others (docs/testing.md): a test that reads
    ``../shared`` (:func:`shared_dir`) is a ``shared`` one. A test without an ``xdist_group`` of
    its own runs on the worker that runs the rest of its module (``--dist loadgroup``): a module's fixtures (a
    served database, a Chromium page's login) are made once, and the tests of a module that walk one database step
    by step keep their order."""
    for item in items:
        if "shared_dir" in getattr(item, "fixturenames", ()):  # doctests have no fixtures
            item.add_marker(pytest.mark.shared)
        if item.get_closest_marker("xdist_group") is None:
            item.add_marker(pytest.mark.xdist_group(item.nodeid.split("::", 1)[0].removeprefix("tests/")))


def sizes(ci: object, full: object) -> list[object]:
    """The two sizes of a load, concurrency, fault, fuzz or two-node test, as ``pytest.mark.parametrize`` values:
    ``ci``, the smaller run CI's suite keeps, and ``full``, the full-size run marked ``slow`` (``scripts/test.sh
    --slow``; docs/testing.md lists each pair)."""
    return [pytest.param(ci, id="ci"), pytest.param(full, id="full", marks=pytest.mark.slow)]


#: Debian's Chromium, and the flags it runs with here (no sandbox as root; no call to Google's services, which
#: this machine's closed network refuses).
CHROMIUM = Path("/usr/bin/chromium")
CHROMIUM_ARGS = [
    "--no-sandbox",
    "--disable-gpu",
    "--disable-background-networking",
    "--disable-component-update",
    "--no-first-run",
]


@pytest.fixture(scope="session")
def chromium() -> Iterator[object]:
    """Headless Debian Chromium, one for the test session (each test has a context of its own, through
    :func:`browser`); the test skips (with the reason) where it is not installed."""
    if not CHROMIUM.exists() or shutil.which(str(CHROMIUM)) is None:
        pytest.skip(f"{CHROMIUM} not found: install Debian's chromium (apt-get install -y chromium) to run browser "
                    "tests")
    sync_api = pytest.importorskip("playwright.sync_api", reason="playwright (Python) is not installed")
    with sync_api.sync_playwright() as pw:
        b = pw.chromium.launch(executable_path=str(CHROMIUM), args=CHROMIUM_ARGS, headless=True)
        try:
            yield b
        finally:
            b.close()


@pytest.fixture
def browser(chromium, request: pytest.FixtureRequest) -> Iterator[RecordedBrowser]:
    """The session's Chromium for one test: each context it makes records a Playwright trace, kept in
    ``test-artifacts/traces/`` only when the test fails, whose report then also lists the pages' console errors and
    failed requests (``tests/recording.py``)."""
    recorder = request.node.stash.setdefault(RECORDER, Recorder(request.node.nodeid))
    yield RecordedBrowser(chromium, recorder)
    recorder.finish()


@pytest.hookimpl(wrapper=True)
def pytest_runtest_makereport(item: pytest.Item, call: pytest.CallInfo) -> Iterator[None]:
    """A browser test's outcome reaches its :class:`~tests.recording.Recorder` (which keeps its traces only when it
    failed), and a failure's report gets the ``browser`` section: the traces' paths and what the pages said."""
    report = yield
    recorder = item.stash.get(RECORDER, None)
    if recorder is not None:
        if report.when in ("setup", "call"):
            recorder.failed = bool(recorder.failed) or report.failed
        if report.failed:  # a teardown's failure (the page's JavaScript errors) comes after the traces were dropped
            report.sections.append(("browser", recorder.report(traces=report.when != "teardown")))
    return report


@pytest.fixture(scope="session")
def shared_dir() -> Path:
    """``../shared`` beside the checkout; tests that need it skip with the reason when it is absent."""
    if not (SHARED_DIR / "data").is_dir():
        pytest.skip(f"../shared not found at {SHARED_DIR}: real and synthetic data unavailable")
    return SHARED_DIR


# ----- database fixtures (app/db): a migrated SQLite database per test session, one rolled-back
# transaction per test (SQLAlchemy's "join a session into an external transaction" recipe) ---------

#: Environment variable naming a PostgreSQL server (any database of it, to connect): the database
#: fixtures then use a fresh database made on that server for the test session (``.ci/run``).
TEST_DATABASE_ENV = "V3D_TEST_DATABASE_URL"


def create_test_database(conn: sa.Connection, name: str, template: str | None = None) -> None:
    """``CREATE DATABASE name`` (a copy of ``template`` when given) on an autocommit connection of a PostgreSQL
    server, whose commits then return before their write-ahead log reaches the disk (``synchronous_commit``
    off, PostgreSQL's "non-durable settings" for throwaway databases): a test database outlives no server crash,
    and each commit no longer waits a few milliseconds for the disk. Nothing a test checks depends on it (a killed
    v3d process loses nothing the server acknowledged)."""
    conn.exec_driver_sql(f'CREATE DATABASE "{name}"' + (f' TEMPLATE "{template}"' if template else ""))
    conn.exec_driver_sql(f'ALTER DATABASE "{name}" SET synchronous_commit TO off')


@contextmanager
def fresh_postgresql_database(server_url: str, *, migrated: bool = False) -> Iterator[str]:
    """A new database ``v3d_test_<hex>`` on the PostgreSQL server of ``server_url``, dropped (connections closed)
    afterwards; yields its URL, so that concurrent runs never collide. Empty, or, when ``migrated``, at the
    migrations' head: a copy (``CREATE DATABASE ... TEMPLATE``) of a database migrated once per test process and
    server (:func:`_postgresql_template`), its session key drawn anew as for SQLite's copies. Skips with the reason
    when the server cannot be reached."""
    import uuid

    server = sa.make_url(server_url)
    admin = sa.create_engine(server, isolation_level="AUTOCOMMIT")
    name = f"v3d_test_{uuid.uuid4().hex[:12]}"
    try:
        template = _postgresql_template(server) if migrated else None
        with admin.connect() as conn:
            create_test_database(conn, name, template)
    except sa.exc.OperationalError as exc:
        admin.dispose()
        pytest.skip(f"PostgreSQL not reachable at {server.render_as_string()}: {exc.orig}")
    url = server.set(database=name).render_as_string(hide_password=False)
    try:
        if migrated:
            _draw_session_key(url)
        yield url
    finally:
        with admin.connect() as conn:
            conn.exec_driver_sql(f'DROP DATABASE IF EXISTS "{name}" WITH (FORCE)')
        admin.dispose()


#: The migrated PostgreSQL database of each server this test process copies its migrated databases from.
_POSTGRESQL_TEMPLATES: dict[str, str] = {}


def _postgresql_template(server: sa.URL) -> str:
    """The name of a database on ``server`` migrated to head once per test process (replaying the migrations costs
    a few seconds of the server's time per database, and CI's PostgreSQL pass makes dozens), dropped when the process
    ends. Nothing connects to it after its migration, as ``CREATE DATABASE ... TEMPLATE`` requires."""
    import atexit
    import uuid

    key = server.render_as_string(hide_password=False)
    if key not in _POSTGRESQL_TEMPLATES:
        admin = sa.create_engine(server, isolation_level="AUTOCOMMIT")
        name = f"v3d_template_{uuid.uuid4().hex[:12]}"
        try:
            with admin.connect() as conn:
                create_test_database(conn, name)
            upgrade_database(server.set(database=name))
        except BaseException:
            with admin.connect() as conn:
                conn.exec_driver_sql(f'DROP DATABASE IF EXISTS "{name}" WITH (FORCE)')
            raise
        finally:
            admin.dispose()

        def drop() -> None:
            engine = sa.create_engine(server, isolation_level="AUTOCOMMIT")
            try:
                with engine.connect() as conn:
                    conn.exec_driver_sql(f'DROP DATABASE IF EXISTS "{name}" WITH (FORCE)')
            except sa.exc.OperationalError:  # the server went first: nothing is left to drop
                pass
            finally:
                engine.dispose()

        atexit.register(drop)
        _POSTGRESQL_TEMPLATES[key] = name
    return _POSTGRESQL_TEMPLATES[key]


def _draw_session_key(url: str) -> None:
    """A new session key in the copied database ``url``, drawn as the migration that made the key draws one, so that
    no two of the suite's databases share it."""
    import secrets

    engine = sa.create_engine(url)
    try:
        with engine.begin() as conn:
            conn.execute(sa.text("UPDATE server_secrets SET value = :value WHERE name = 'session'"),
                         {"value": secrets.token_urlsafe(48)})
    finally:
        engine.dispose()


#: A SQLite file migrated to head once per test process (:func:`migrate_new_database`), in a folder of its own.
_MIGRATED_SQLITE: list[Path] = []


def migrate_new_database(url: str) -> None:
    """Bring the database ``url`` to the migrations' head, as ``app.db.session.upgrade_database`` does. A SQLite file
    that does not exist yet is made as a copy of one migrated once per test process (replaying the migrations costs
    about 0.6 s of CPU per database, and the suite makes a few hundred), its session key then drawn anew as the
    migration that made it draws one, so that no two databases share it; any other database is migrated."""
    import atexit
    import tempfile

    parsed = sa.make_url(url)
    path = Path(parsed.database or "")
    if parsed.get_backend_name() != "sqlite" or not parsed.database or parsed.database == ":memory:" \
            or path.exists():
        upgrade_database(url)
        return
    if not _MIGRATED_SQLITE:
        folder = Path(tempfile.mkdtemp(prefix="v3d-migrated-"))
        atexit.register(shutil.rmtree, folder, True)
        upgrade_database(f"sqlite:///{folder / 'head.sqlite3'}")
        _MIGRATED_SQLITE.append(folder / "head.sqlite3")
    copy_sqlite(_MIGRATED_SQLITE[0], path)


def copy_sqlite(source: Path, target: Path) -> str:
    """A copy at ``target`` of the SQLite database ``source`` (its write-ahead log included: SQLite's backup API),
    with a session key of its own, drawn as the migration that made the key draws one; answers its URL."""
    import sqlite3

    target.parent.mkdir(parents=True, exist_ok=True)
    original, copy = sqlite3.connect(source), sqlite3.connect(target)
    try:
        original.backup(copy)
    finally:
        original.close()
        copy.close()
    _draw_session_key(f"sqlite:///{target}")
    return f"sqlite:///{target}"


@pytest.fixture(scope="session")
def demo_template(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A migrated SQLite file holding the demo as ``v3d serve --demo`` imports it (no account), made once per test
    process: the tests whose subject is not the demo's import start from a copy of it (:func:`copy_sqlite`; its
    frames name the dataset in the template's folder), not from an import of their own (about 6 s of CPU each)."""
    from app.cli.serve import load_demo_if_empty

    path = tmp_path_factory.mktemp("demo-template") / "v3d.sqlite3"
    migrate_new_database(f"sqlite:///{path}")
    assert load_demo_if_empty(Settings(_env_file=None, database_url=f"sqlite:///{path}",
                                       calibration_workers=1)).startswith("demo: imported")
    return path


@pytest.fixture(scope="session")
def db_url(tmp_path_factory: pytest.TempPathFactory) -> Iterator[str]:
    """URL of a database built by the Alembic migrations, once per test session: a SQLite file, or,
    when ``V3D_TEST_DATABASE_URL`` names a PostgreSQL server, a fresh database on it (dropped at the end)."""
    server = os.environ.get(TEST_DATABASE_ENV)
    if server:
        with fresh_postgresql_database(server, migrated=True) as url:
            yield url
        return
    url = f"sqlite:///{tmp_path_factory.mktemp('db') / 'v3d-test.sqlite3'}"
    upgrade_database(url)
    yield url


@pytest.fixture(scope="session")
def db_backend(db_url: str) -> str:
    """``sqlite`` or ``postgresql``: the backend of :func:`db_url`."""
    return sa.make_url(db_url).get_backend_name()


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


@contextmanager
def joined_session(conn: sa.Connection) -> Iterator[Session]:
    """A session whose commits are savepoints of ``conn``'s transaction (SQLAlchemy's "join a session into an
    external transaction" recipe), closed at the end."""
    session = V3dSession(bind=conn, join_transaction_mode="create_savepoint", expire_on_commit=False)
    try:
        yield session
    finally:
        session.close()


@pytest.fixture
def db_session(db_connection: sa.Connection) -> Iterator[Session]:
    """A session whose commits are savepoints of the per-test transaction: nothing outlives the test."""
    with joined_session(db_connection) as session:
        yield session


@pytest.fixture
def db_settings(db_url: str, tmp_path_factory: pytest.TempPathFactory, tmp_path: Path) -> Settings:
    """Settings pointing at the test database; calibration runs in-process (one worker); HTTP imports may
    read the test session's temporary folders (the data root); no job runner thread (tests run queued
    jobs themselves, on their own session factory; the fault tests start real servers). The jobs' files are the
    test's own: job ids start again in every test's database (a rolled-back transaction, a copied template), and a
    PostgreSQL database would otherwise keep them under the checkout's ``var/``, shared by every worker."""
    return Settings(database_url=db_url, calibration_workers=1, data_root=tmp_path_factory.getbasetemp(),
                    job_runner=False, allowed_hosts=[TEST_CLIENT_HOST], jobs_dir=tmp_path / "jobs")


#: The local PostgreSQL server of the ``postgres``-marked tests (trust authentication).
PG_ADMIN_URL = os.environ.get(TEST_DATABASE_ENV) or "postgresql+psycopg://postgres@127.0.0.1:5432/test"


@pytest.fixture
def pg_url() -> Iterator[str]:
    """URL of a fresh, empty PostgreSQL database made for this test and dropped after it, so that
    concurrent runs never collide. Skips with the reason when the server is down."""
    with fresh_postgresql_database(PG_ADMIN_URL) as url:
        yield url


@pytest.fixture
def pg_migrated_url() -> Iterator[str]:
    """As :func:`pg_url`, the database at the migrations' head (a copy of the test process's migrated template):
    for the tests whose subject is not the migrations."""
    with fresh_postgresql_database(PG_ADMIN_URL, migrated=True) as url:
        yield url
