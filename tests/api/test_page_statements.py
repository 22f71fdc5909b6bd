"""A system page and a queue page read in proportion to what they answer, not to the database: on a database of a few
thousand systems (the demo copied over, ``benchmarks/page_statements.py``) no statement of theirs scans a table that
grows with the dataset (SQLite's ``EXPLAIN QUERY PLAN`` ``SCAN``, PostgreSQL's ``Seq Scan`` after the statistics an
import leaves; the one count of every system excepted by name, ``page_statements.WHOLE_COUNTS``), and each request
sends as many statements as on the demo. SQLite always; PostgreSQL in its pass."""
from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import pytest
import sqlalchemy as sa
from fastapi.testclient import TestClient

from app.core.config import Settings
from app.db.session import make_engine
from app.main import create_app
from benchmarks import page_statements as ps
from tests.accounts import as_session, make_accounts
from tests.conftest import PG_ADMIN_URL, TEST_CLIENT_HOST, copy_sqlite, fresh_postgresql_database

#: Copies of the demo's 9 systems added: 2,709 systems, 9,030 frames, about 83,000 player boxes; built in a few
#: seconds of SQL (no import), enough for both planners to prefer an index wherever one answers.
COPIES = 300
#: The demo system shown (its copy in the last game of the large database): one with doubts and pairs.
SYSTEM = 5
#: Requests whose statements depend on where the queue's rows fall, not on the database's size: a page after a
#: cursor walks as many slices of the order as it takes to fill it, more of them in the demo's small queue.
DATA_SHAPED = ("/api/systems?limit=2&after={cursor}",)

BACKENDS = ["sqlite", pytest.param("postgresql", marks=pytest.mark.postgres)]


def _fill(demo: str, url: str, copies: int) -> None:
    engine, source = make_engine(url), make_engine(demo)
    try:
        if engine.dialect.name != "sqlite":  # a SQLite target is a copy of the demo already
            with source.connect() as s, engine.begin() as t:
                ps.copy_rows(s, t)
        if copies:
            with engine.begin() as t:
                ps.multiply(t, copies)
        ps.analyse(engine)
    finally:
        engine.dispose()
        source.dispose()


@pytest.fixture(params=BACKENDS)
def databases(request: pytest.FixtureRequest, demo_template: Path, tmp_path: Path) -> Iterator[dict[str, str]]:
    """``{"demo": url, "many": url}``: the demo, and the demo with :data:`COPIES` copies, on the parameter's engine."""
    if request.param == "sqlite":
        urls = {name: copy_sqlite(demo_template, tmp_path / f"{name}.sqlite3") for name in ("demo", "many")}
        for name, url in urls.items():
            _fill(url, url, COPIES if name == "many" else 0)
        yield urls
        return
    with fresh_postgresql_database(PG_ADMIN_URL, migrated=True) as demo, \
            fresh_postgresql_database(PG_ADMIN_URL, migrated=True) as many:
        urls = {"demo": demo, "many": many}
        for name, url in urls.items():
            _fill(f"sqlite:///{demo_template}", url, COPIES if name == "many" else 0)
        yield urls


def _statements(url: str, system_id: int, tmp_path: Path) -> dict[str, list[ps.Statement]]:
    """Each request's statements on ``url`` as an admin's browser sends it, their plans filled in."""
    account = make_accounts(url, roles=("admin",))["admin"]
    settings = Settings(_env_file=None, database_url=url, job_runner=False, allowed_hosts=[TEST_CLIENT_HOST],
                        jobs_dir=tmp_path / "jobs")
    with TestClient(create_app(settings)) as client:
        recorded = ps.request_statements(as_session(client, account), system_id)
    engine = make_engine(url)
    try:
        for statements in recorded.values():
            ps.explain(engine, statements)
    finally:
        engine.dispose()
    return recorded


def test_pages_read_no_growing_table_whole_and_send_the_demos_statements(databases: dict[str, str],
                                                                          tmp_path: Path) -> None:
    demo = _statements(databases["demo"], SYSTEM, tmp_path)
    many = _statements(databases["many"], SYSTEM + 9 * COPIES, tmp_path)
    engine = make_engine(databases["many"])
    try:
        with engine.connect() as conn:
            assert conn.scalar(sa.text("SELECT count(*) FROM systems")) == 9 * (COPIES + 1)
    finally:
        engine.dispose()

    scans = {f"{request}: {s.short}": (tables, s.plan) for request, statements in many.items()
             for s in statements if (tables := ps.scanned(s))}
    assert not scans, scans
    counts = {request: (len(demo[request]), len(many[request])) for request in ps.REQUESTS
              if request not in DATA_SHAPED}
    assert all(d == m for d, m in counts.values()), counts
    # the detector sees a scan where there is one: a statement the planner can answer only by reading the table
    probe = ps.Statement("SELECT count(*) FROM systems WHERE views_total > 0", {})
    engine = make_engine(databases["many"])
    try:
        ps.explain(engine, [probe])
    finally:
        engine.dispose()
    assert ps.scanned(probe) == ["systems"], probe.plan
