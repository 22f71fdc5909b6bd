"""What a system page and a queue page read, at the demo's size and at many systems: each statement the request
sends (SQLAlchemy's ``before_cursor_execute``), its plan (SQLite's ``EXPLAIN QUERY PLAN``, PostgreSQL's ``EXPLAIN``),
the growing tables it scans, and the work it does (SQLite: virtual machine instructions; PostgreSQL: rows its plan
nodes return, ``EXPLAIN ANALYZE``). ``tests/api/test_page_statements.py`` fails when a statement scans a growing table
or when the number of statements differs from the demo's.

The database of many systems is built in seconds: the demo's rows copied ``copies`` times over in SQL
(:func:`multiply`), the ids moved past each table's own (every copy a game of its own, with the demo's frames,
labels, calibrations, triangulations, doubts, player boxes, audit entries and review decisions), then the planner's
statistics refreshed as an import leaves them. Nothing is computed again: the demo's import is the only one. Usage::

    .venv/bin/python benchmarks/page_statements.py [--copies 1421] [--database-url postgresql+psycopg://...]
"""
from __future__ import annotations

import argparse
import re
import sys
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import sqlalchemy as sa
from sqlalchemy import event

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from app.db.models import Base  # noqa: E402  # after the checkout is on the path
from app.db.session import make_session_factory, refresh_statistics  # noqa: E402  # after the checkout is on the path

#: The tables that grow with the dataset: one row or more per game, system or frame. What a request for one system
#: or one page of the queue must never scan. Ordered so that a table comes after those its keys refer to.
GROWING = ("games", "systems", "frames", "ball_labels", "field_lines", "player_boxes", "calibrations",
           "ball_reprojections", "optimised_boxes", "triangulations", "triangulation_pairs", "trajectory_points",
           "doubts", "review_decisions", "review_handoffs", "review_comments", "audit_entries", "predictions")

#: The growing tables no statement of a page may read whole: all but the games', one row per 32 systems in a
#: SoccerNet-v3 set, which PostgreSQL rightly reads whole to hash-join a page's systems to their few hundred games.
NEVER_SCANNED = tuple(t for t in GROWING if t != "games")

#: Columns that hold a key of a growing table without a foreign key (the audit keeps its entries of deleted rows).
_LOOSE_KEYS = {"game_id": "games", "system_id": "systems", "frame_id": "frames"}


def _target(column: sa.Column) -> str | None:
    """The growing table whose ids ``column`` holds, if any."""
    for fk in column.foreign_keys:
        table = fk.column.table.name
        # A triangulation's key is its system's id.
        return "systems" if table == "triangulations" else table if table in GROWING else None
    if column.primary_key and column.table.name in GROWING and column.name == "id":
        return column.table.name
    return _LOOSE_KEYS.get(column.name) if column.table.name in GROWING else None


def copy_rows(source: sa.Connection, target: sa.Connection) -> None:
    """Copy every row of the growing tables of ``source`` into the same (empty, migrated) tables of ``target``,
    e.g. the demo from a SQLite file into a PostgreSQL database; sequences moved past the copied ids."""
    for name in GROWING:
        table = Base.metadata.tables[name]
        rows = [dict(r._mapping) for r in source.execute(sa.select(table))]
        if rows:
            target.execute(sa.insert(table), rows)
    _advance_sequences(target)


def multiply(conn: sa.Connection, copies: int) -> None:
    """Add ``copies`` copies of every row of the growing tables (one statement per table), each copy's ids moved
    past the previous ones' by the table's largest id, its game's name suffixed with the copy's number."""
    strides = {}
    for name in GROWING:
        table = Base.metadata.tables[name]
        if "id" in table.c:
            strides[name] = int(conn.scalar(sa.select(sa.func.max(table.c.id))) or 0)
    n = sa.select(sa.literal(1).label("n")).cte("copies", recursive=True)
    n = n.union_all(sa.select(n.c.n + 1).where(n.c.n < copies))
    for name in GROWING:
        table = Base.metadata.tables[name]
        if not conn.scalar(sa.select(sa.func.count()).select_from(table)):
            continue
        values = []
        for column in table.c:
            target = _target(column)
            if target is not None and target in strides:
                values.append(column + n.c.n * strides[target])
            elif name == "games" and column.name == "match":
                values.append(column + sa.literal(" #") + sa.cast(n.c.n, sa.String))
            else:
                values.append(column)
        conn.execute(sa.insert(table).from_select(list(table.c), sa.select(*values).select_from(table).join(
            n, sa.true())))
        if conn.dialect.name == "postgresql":
            # Each row inserted next checks its foreign keys with a plan made from the statistics: without them,
            # PostgreSQL reads a table it thinks empty whole for each of the next table's rows (the player boxes'
            # copy took a minute instead of a second).
            conn.exec_driver_sql(f"ANALYZE {name}")
    _advance_sequences(conn)


def analyse(engine: sa.Engine) -> None:
    """The planner's statistics of the multiplied database, as an import leaves them
    (``app.db.session.refresh_statistics``)."""
    with make_session_factory(engine)() as session:
        refresh_statistics(session)


def _advance_sequences(conn: sa.Connection) -> None:
    """PostgreSQL: each growing table's id sequence past its largest id (rows were inserted with their ids)."""
    if conn.dialect.name != "postgresql":
        return
    for name in GROWING:
        if "id" in Base.metadata.tables[name].c:
            conn.exec_driver_sql(f"SELECT setval(pg_get_serial_sequence('{name}', 'id'), "
                                 f"coalesce((SELECT max(id) FROM {name}), 0) + 1, false)")


# ----- the statements of a request and their plans ---------------------------------------------------------------

#: The requests whose statements must read in proportion to what they answer: a system page and a queue page, as the
#: review UI asks for them (the default queue and the pending one; a page after a cursor; the order by name, whose
#: first keys are the game's, and a page of it by offset). ``{id}``: the system shown.
REQUESTS = ("/api/systems/{id}", "/api/systems/{id}?status=pending", "/api/systems?limit=5",
            "/api/systems?status=pending&limit=5", "/api/systems?limit=2&after={cursor}",
            "/api/systems/{id}?sort=name", "/api/systems?sort=name&limit=5",
            "/api/systems?sort=-name&limit=2&offset=5")

#: Statements that plan nothing (transaction control).
_CONTROL = ("BEGIN", "COMMIT", "ROLLBACK", "SAVEPOINT", "RELEASE")


@dataclass
class Statement:
    """One statement a request sent: its SQL and parameters as the driver got them, and its plan's lines."""

    sql: str
    params: Any
    plan: list[str] = field(default_factory=list)
    #: What running it took: SQLite's VM instructions or PostgreSQL's rows its plan nodes return (:func:`sqlite_steps`,
    #: :func:`postgresql_rows`); None until measured.
    work: int | None = None

    @property
    def short(self) -> str:
        """The SQL on one line, cut to 160 characters."""
        return " ".join(self.sql.split())[:160]


@contextmanager
def recording() -> Iterator[list[Statement]]:
    """Every statement any engine of the process sends while inside (SQLAlchemy's ``before_cursor_execute``)."""
    statements: list[Statement] = []

    def before(conn: Any, cursor: Any, sql: str, params: Any, context: Any, executemany: bool) -> None:
        if not sql.lstrip().upper().startswith(_CONTROL):
            statements.append(Statement(sql, params))

    event.listen(sa.Engine, "before_cursor_execute", before)
    try:
        yield statements
    finally:
        event.remove(sa.Engine, "before_cursor_execute", before)


def explain(engine: sa.Engine, statements: list[Statement]) -> None:
    """Fill each statement's plan: SQLite's ``EXPLAIN QUERY PLAN`` details, PostgreSQL's ``EXPLAIN`` lines."""
    with engine.connect() as conn:
        raw = conn.connection.driver_connection
        for s in statements:
            cursor = raw.cursor()
            prefix = "EXPLAIN QUERY PLAN " if engine.dialect.name == "sqlite" else "EXPLAIN "
            cursor.execute(prefix + s.sql, s.params)
            s.plan = [row[3] if engine.dialect.name == "sqlite" else row[0] for row in cursor.fetchall()]
            cursor.close()


_SQLITE_SCAN = re.compile(r"^SCAN (\w+)")
_PG_SEQ_SCAN = re.compile(r"Seq Scan on (\w+)")


#: The statements allowed to read a growing table whole: the count of every system (the unfiltered queue's pending
#: ones are that count less the reviewed ones, ``queue._status_counts``), which SQLite answers from its b-tree's pages
#: without visiting a row (about 5 microseconds at 3,000 systems; counting in the status index instead took 800),
#: and PostgreSQL by a scan: what is left for a count kept up to date (``benchmarks/SCALE.md``).
WHOLE_COUNTS = ("SELECT count(*) AS count_1 FROM systems",)


def scanned(statement: Statement) -> list[str]:
    """The growing tables (:data:`NEVER_SCANNED`) the statement's plan reads whole: SQLite's ``SCAN t`` (with or
    without an index: all of it either way), PostgreSQL's ``Seq Scan on t``; an alias (``triangulations_1``) counts
    as its table. None for a statement of :data:`WHOLE_COUNTS`."""
    if " ".join(statement.sql.split()) in WHOLE_COUNTS:
        return []
    out = []
    for line in statement.plan:
        match = _SQLITE_SCAN.match(line.strip()) or _PG_SEQ_SCAN.search(line)
        if match:
            table = re.sub(r"_\d+$", "", match.group(1))
            if table in NEVER_SCANNED:
                out.append(table)
    return out


def sqlite_steps(url: str, statements: list[Statement]) -> list[int]:
    """SQLite: the virtual machine instructions each statement takes to run (read to its end), a count of the
    work done that no other load on the machine changes: what grows with the rows a statement reads."""
    import sqlite3

    connection = sqlite3.connect(sa.make_url(url).database)
    steps = [0]

    def count() -> int:
        steps[0] += 1
        return 0

    connection.set_progress_handler(count, 1)
    out = []
    try:
        for s in statements:
            steps[0] = 0
            connection.execute(s.sql, s.params).fetchall()
            out.append(steps[0])
    finally:
        connection.close()
    return out


def postgresql_rows(engine: sa.Engine, statements: list[Statement]) -> list[int]:
    """PostgreSQL: the rows each statement's plan nodes return, summed (``EXPLAIN (ANALYZE, FORMAT JSON)``'s actual
    rows times loops of every node), in a transaction rolled back."""
    def rows(node: dict[str, Any]) -> int:
        own = int(node.get("Actual Rows", 0) * node.get("Actual Loops", 1))
        return own + sum(rows(child) for child in node.get("Plans", ()))

    out = []
    with engine.connect() as conn:
        raw = conn.connection.driver_connection
        for s in statements:
            cursor = raw.cursor()
            cursor.execute("EXPLAIN (ANALYZE, FORMAT JSON) " + s.sql, s.params)
            out.append(rows(cursor.fetchone()[0][0]["Plan"]))
            cursor.close()
        raw.rollback()
    return out


def request_statements(client: Any, system_id: int, requests: tuple[str, ...] = REQUESTS
                       ) -> dict[str, list[Statement]]:
    """The statements of each request of ``requests`` (``{id}``: ``system_id``; ``{cursor}``: the default queue's
    first page's ``next_cursor``) sent by ``client`` (a logged-in ``TestClient`` of the app), each request sent once
    before it is recorded (what a first request alone loads is not the page's cost)."""
    first = client.get("/api/systems", params={"limit": 2})
    first.raise_for_status()
    out = {}
    for template in requests:
        path = template.format(id=system_id, cursor=first.json()["next_cursor"])
        client.get(path).raise_for_status()
        with recording() as statements:
            answer = client.get(path)
        answer.raise_for_status()
        out[template] = statements
    return out


def _demo(folder: Path) -> str:
    """A SQLite database of the demo as ``v3d serve --demo`` imports it, in ``folder``; its URL."""
    from app.cli.serve import load_demo_if_empty
    from app.core.config import Settings
    from app.db.session import upgrade_database

    url = f"sqlite:///{folder / 'demo.sqlite3'}"
    upgrade_database(url)
    load_demo_if_empty(Settings(_env_file=None, database_url=url, calibration_workers=1))
    return url


def _copy(demo_url: str, url: str, copies: int) -> None:
    """``url`` (a new database, migrated here) filled with the demo's rows and ``copies`` copies of them."""
    from app.db.session import make_engine, upgrade_database

    upgrade_database(url)
    source, target = make_engine(demo_url), make_engine(url)
    try:
        with source.connect() as s, target.begin() as t:
            copy_rows(s, t)
            if copies:
                multiply(t, copies)
        analyse(target)
    finally:
        source.dispose()
        target.dispose()


def _measure(url: str, system_id: int, folder: Path) -> dict[str, list[Statement]]:
    """Log a new admin in on ``url`` and record the requests; their plans and work filled in."""
    from fastapi.testclient import TestClient

    from app.core.config import Settings
    from app.db.session import make_engine
    from app.main import create_app
    from app.services.accounts.users import create_user

    engine = make_engine(url)
    try:
        with make_session_factory(engine)() as session:
            create_user(session, "page-statements", "admin", "page-statements-password")
        settings = Settings(_env_file=None, database_url=url, job_runner=False, allowed_hosts=["testserver"],
                            jobs_dir=folder / "jobs")
        with TestClient(create_app(settings)) as client:
            login = client.post("/api/auth/login", json={"name": "page-statements",
                                                          "password": "page-statements-password"})
            login.raise_for_status()
            client.headers["X-CSRF-Token"] = login.json()["csrf_token"]
            recorded = request_statements(client, system_id)
        for statements in recorded.values():
            explain(engine, statements)
            work = sqlite_steps(url, statements) if engine.dialect.name == "sqlite" \
                else postgresql_rows(engine, statements)
            for s, w in zip(statements, work, strict=True):
                s.work = w
    finally:
        engine.dispose()
    return recorded


def main(argv: list[str] | None = None) -> int:
    """Print, per request and statement, the work at the demo's size and at ``--copies`` more copies of it."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--copies", type=int, default=1421, help="copies of the demo's 9 systems (1421: 12,798)")
    parser.add_argument("--database-url", help="a PostgreSQL server (any database of it): measure there")
    args = parser.parse_args(argv)
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        demo = _demo(folder)
        urls = {}
        for name, copies in (("demo", 0), ("many", args.copies)):
            if args.database_url:
                urls[name] = _postgresql_database(args.database_url, f"v3d_page_statements_{name}")
            else:
                urls[name] = f"sqlite:///{folder / (name + '-copy.sqlite3')}"
            _copy(demo, urls[name], copies)
        system = 5  # a system of the demo; its last copy in the database of many
        figures = {name: _measure(url, system if name == "demo" else system + 9 * args.copies, folder)
                   for name, url in urls.items()}
    unit = "VM steps" if not args.database_url else "rows returned by plan nodes"
    for request in REQUESTS:
        demo_s, many_s = figures["demo"][request], figures["many"][request]
        print(f"\n{request}: {len(demo_s)} statements at 9 systems, {len(many_s)} at {9 * (args.copies + 1)}")
        for d, m in zip(demo_s, many_s, strict=False):
            flag = " SCANS " + ",".join(scanned(m)) if scanned(m) else ""
            print(f"  {d.work:>8} -> {m.work:>8} {unit}{flag}  {m.short}")
    return 0


def _postgresql_database(server: str, name: str) -> str:
    """A new database ``name`` on the PostgreSQL server of ``server`` (dropped first if it exists); its URL."""
    url = sa.make_url(server)
    admin = sa.create_engine(url, isolation_level="AUTOCOMMIT")
    with admin.connect() as conn:
        conn.exec_driver_sql(f'DROP DATABASE IF EXISTS "{name}" WITH (FORCE)')
        conn.exec_driver_sql(f'CREATE DATABASE "{name}"')
    admin.dispose()
    return url.set(database=name).render_as_string(hide_password=False)


if __name__ == "__main__":
    sys.exit(main())
