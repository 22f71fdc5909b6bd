"""The queue page (``GET /api/systems``, the default sort, the browser's 50 rows) split into its parts, demo against
scale, in one process.

Companion of ``benchmarks/scale.py`` (the real server over loopback, wall clock) and ``benchmarks/system_page_parts.py``
(the system page). This one runs what the route runs, part by part, on each database in turn (``--rounds``
alternations, so that both share the machine's load), and reports the **CPU time** of each part
(``time.thread_time``: what the request's thread did, whatever else the machine runs; the whole request,
``--http``, by the process's CPU time, its app running in the test client's threads), p50 and p95, with the SQL
statements sent and the rows shown, so that a part that grows with the database can be told from one that grows with
the rows of the page (the demo's page holds its 9 systems, a scale page 50). ``--orm`` runs the parts a second
time per round with the rows as ORM objects (``queue._queue_from``, ``SystemSummaryOut.of``), as the route read them
before its plain rows: both ways paired in one process.

Parts, as the route calls them: ``walk`` (the page's ids along the sort's index and the cursors' look-ahead,
``queue._walk``), ``rows`` (the page's systems with their games, decisions and 3D balls), ``counts`` (the status
counts, ``total``), ``assign`` (the rows' assignments), ``presence`` (who has them open), ``shape`` (the response
models) and ``dump`` (the answer's JSON, as FastAPI serialises it). ``--http`` also times the whole request through
the app (``TestClient``: routing, the session's authentication, the answer) on each database.

Usage::

    .venv/bin/python benchmarks/queue_parts.py --db demo.sqlite3 --db scale.sqlite3 [--requests 300] [--http] [--orm]
"""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from benchmarks.system_page_parts import percentile  # noqa: E402  # after the checkout is on the path

PARTS = ("walk", "rows", "counts", "assign", "presence", "shape", "dump")
LIMIT = 50  # the browser's page (static/js/queue.js PAGE_SIZE)


class Database:
    """One database; :meth:`request` runs the queue route's parts once."""

    def __init__(self, path: Path, http: bool, orm: bool = False) -> None:
        from sqlalchemy import event

        from app.db.session import make_engine, make_session_factory

        self.path = path
        self.orm = orm
        self.url = f"sqlite:///{path.resolve()}"
        self.engine = make_engine(self.url)
        self.sessions = make_session_factory(self.engine)
        self.statements = 0
        event.listen(self.engine, "before_cursor_execute", self._count)
        self.times: dict[str, list[float]] = {p: [] for p in (*PARTS, "total")}
        self.http: list[float] = []
        self.shown: list[tuple[int, int]] = []
        self.client: Any = None
        if http:
            self.client = _client(self.url, path.parent)

    def _count(self, *_: Any) -> None:
        self.statements += 1

    def request(self) -> None:
        """The parts of ``GET /api/systems?limit=50`` once: CPU ms of each, statements and rows shown."""
        from app.api.assignment_schemas import AssignmentOut, PresenceOut
        from app.api.view_schemas import SystemPageOut, SystemSummaryOut
        from app.db.types import utcnow
        from app.services.curation import assignment, presence
        from app.services.curation import queue as q

        n0 = self.statements
        filters, sort = q.SystemFilters(), q.DEFAULT_SORT
        with self.sessions() as session:
            conds = q._system_conditions(filters)
            marks = [time.thread_time()]

            def mark() -> None:
                marks.append(time.thread_time())

            rows = q._walk(session, sort, conds, None, "after", LIMIT + 1)
            more_after = len(rows) > LIMIT
            rows = rows[:LIMIT]
            more_before = False  # a page from the queue's start: nothing lies before it (queue._page)
            mark()
            ids = [r[-1] for r in rows]
            if self.orm:
                by_id = {s.id: s for s in session.scalars(q._queue_from().where(q.System.id.in_(ids))).unique()}
            else:
                by_id = {r["id"]: r for r in session.execute(q._summary_statement(), {"ids": ids}).mappings()}
            items = [by_id[i] for i in ids if i in by_id]
            mark()
            counts = q._status_counts(session, q._system_conditions(filters, with_status=False))
            total = sum(counts.values())
            mark()
            assigned, now = assignment.assignments_of(session, ids), utcnow()
            mark()
            present = presence.open_on(session, ids, now)
            mark()
            shape = SystemSummaryOut.of if self.orm else SystemSummaryOut.of_row
            out = SystemPageOut(items=[shape(s, AssignmentOut.of(assigned.get(i)),
                                             [PresenceOut.of(p, now) for p in present.get(i, [])])
                                       for i, s in zip(ids, items, strict=True)],
                                total=total, limit=LIMIT, offset=0, counts=counts,
                                next_cursor=q.encode_cursor(sort, rows[-1]) if more_after else None,
                                prev_cursor=q.encode_cursor(sort, rows[0]) if more_before else None)
            mark()
            out.__pydantic_serializer__.to_json(out, by_alias=True)
            mark()
        for part, a, b in zip(PARTS, marks, marks[1:], strict=False):
            self.times[part].append((b - a) * 1000.0)
        self.times["total"].append((marks[-1] - marks[0]) * 1000.0)
        self.shown.append((self.statements - n0, len(items)))
        if self.client is not None:  # the app runs in the client's other threads: the process's CPU
            t0 = time.process_time()
            self.client.get("/api/systems", params={"limit": LIMIT, "offset": 0}).raise_for_status()
            self.http.append((time.process_time() - t0) * 1000.0)

    def reset(self) -> None:
        for xs in self.times.values():
            xs.clear()
        self.http.clear()
        self.shown.clear()

    def report(self) -> str:
        """CPU p50 / p95 ms per part, the statements and rows of a page."""
        n = len(self.shown)
        kind = " (ORM rows)" if self.orm else ""
        lines = [f"{self.path}{kind} ({n} requests; {sum(s for s, _ in self.shown) / n:.1f} statements, "
                 f"{sum(r for _, r in self.shown) / n:.0f} rows a page)",
                 f"  {'part':<9} {'cpu p50':>8} {'cpu p95':>8}"]
        for part, xs in [*self.times.items(), *([("http", self.http)] if self.http else [])]:
            lines.append(f"  {part:<9} {percentile(xs, 50):8.2f} {percentile(xs, 95):8.2f}")
        return "\n".join(lines)


def _client(url: str, folder: Path) -> Any:
    """A ``TestClient`` of the app on ``url``, logged in as an admin made for it (once per database)."""
    from fastapi.testclient import TestClient

    from app.core.config import Settings
    from app.db.models import User
    from app.db.session import make_engine, make_session_factory
    from app.main import create_app
    from app.services.accounts.users import create_user

    name, password = "queue-parts", "queue-parts-password"
    engine = make_engine(url)
    with make_session_factory(engine)() as session:
        if session.query(User).filter_by(name=name).first() is None:
            create_user(session, name, "admin", password)
    engine.dispose()
    settings = Settings(_env_file=None, database_url=url, job_runner=False, allowed_hosts=["testserver"],
                        jobs_dir=folder / "queue-parts-jobs")
    client = TestClient(create_app(settings))
    client.__enter__()
    login = client.post("/api/auth/login", json={"name": name, "password": password})
    login.raise_for_status()
    client.headers["X-CSRF-Token"] = login.json()["csrf_token"]
    return client


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--db", type=Path, action="append", required=True, help="SQLite database (repeatable).")
    p.add_argument("--requests", type=int, default=300, help="Requests per database (default 300).")
    p.add_argument("--rounds", type=int, default=10, help="Alternations between the databases (default 10).")
    p.add_argument("--http", action="store_true", help="Also time the whole request through the app (logs an "
                                                       "admin made for it in: writes a user to each database).")
    p.add_argument("--orm", action="store_true", help="Also run the parts with the rows loaded as ORM objects and "
                                                      "shaped from them (the queue before its plain rows), "
                                                      "interleaved with the plain rows in the same rounds.")
    args = p.parse_args(argv)
    for db in args.db:
        if not db.is_file():
            print(f"error: --db {db}: no such file", file=sys.stderr)
            return 2
    dbs = [Database(db, args.http) for db in args.db]
    if args.orm:
        dbs = [x for db in args.db for x in (Database(db, False, orm=True), Database(db, args.http))]
    for db in dbs:  # warm-up: imports, the first connection, the page cache
        for _ in range(5):
            db.request()
        db.reset()
    per_round = max(1, args.requests // args.rounds)
    for _ in range(args.rounds):
        for db in dbs:
            for _ in range(per_round):
                db.request()
    for db in dbs:
        print(db.report())
        if db.client is not None:
            db.client.__exit__(None, None, None)
        db.engine.dispose()
    return 0


if __name__ == "__main__":
    sys.exit(main())
