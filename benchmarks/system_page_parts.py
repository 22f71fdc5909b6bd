"""The system page (``GET /api/systems/{id}``) split into its parts, demo against scale, in one process.

Companion of ``benchmarks/scale.py`` (which times the real server over loopback, wall clock) and
``benchmarks/scale_profile.py`` (cProfile of one system): this one runs what the route runs, part by
part, on random systems of each database in turn, and reports the **CPU time** (``time.process_time``,
robust to other load on the machine) and the wall time of each part, p50 and p95 over the requests,
with the number of SQL statements and what the pages hold (views, doubts, pairs, pitch-line addresses), so that a
part that grows with the database can be told from one that grows with the data of its systems.

Parts, as the route calls them: ``lookup`` (the ``SystemDep`` 404 check), ``load``
(``system_page.load_system``), ``neighbours`` (``queue.queue_neighbours``, the default queue),
``shape`` (``SystemView.of``) and ``dump`` (the JSON of the answer, as FastAPI serialises it).
Systems are drawn as ``scale.py`` draws them: uniformly at random, with repeats (so the 9 demo systems
come back while a scale system is almost always new); ``--rounds`` alternates the databases.

Usage::

    .venv/bin/python benchmarks/system_page_parts.py --db demo.sqlite3 --db scale.sqlite3 [--requests 200]
"""
from __future__ import annotations

import argparse
import random
import sys
import time
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

PARTS = ("lookup", "load", "neighbours", "shape", "dump")


def percentile(values: list[float], q: float) -> float:
    """The ``q``-th percentile (0-100, linear interpolation) of ``values``.

    >>> percentile([1.0, 2.0, 3.0, 4.0, 5.0], 95)
    4.8
    """
    xs = sorted(values)
    k = (len(xs) - 1) * q / 100.0
    lo = int(k)
    hi = min(lo + 1, len(xs) - 1)
    return xs[lo] + (xs[hi] - xs[lo]) * (k - lo)


class Database:
    """One database and the ids of its systems; :meth:`request` runs the route's parts on one system."""

    def __init__(self, path: Path) -> None:
        import sqlalchemy as sa
        from sqlalchemy import event

        from app.db.models import System
        from app.db.session import make_engine, make_session_factory

        self.path = path
        self.engine = make_engine(f"sqlite:///{path.resolve()}")
        self.sessions = make_session_factory(self.engine)
        self.statements = 0
        event.listen(self.engine, "before_cursor_execute", self._count)
        with self.sessions() as s:
            self.ids = list(s.scalars(sa.select(System.id)))
        self.times: dict[str, list[tuple[float, float]]] = {p: [] for p in PARTS}
        self.sizes: list[tuple[int, int, int, int, int]] = []

    def _count(self, *_: Any) -> None:
        self.statements += 1

    def request(self, system_id: int) -> None:
        """Run the parts of ``GET /api/systems/{system_id}`` once, recording (CPU ms, wall ms) of each and
        the page's size (SQL statements, views, doubts, pairs, pitch-line addresses)."""
        from app.api.deps import system_by_id
        from app.api.view_schemas import SystemView
        from app.services.curation.queue import DEFAULT_SORT, SystemFilters, queue_neighbours
        from app.services.curation.system_page import SystemPageData, load_system

        filters = SystemFilters()
        n0 = self.statements
        with self.sessions() as session:
            marks = [(time.process_time(), time.perf_counter())]

            def mark() -> None:
                marks.append((time.process_time(), time.perf_counter()))

            system_by_id(session, system_id)
            mark()
            system = load_system(session, system_id)
            mark()
            prev_id, next_id = queue_neighbours(session, system_id, filters, DEFAULT_SORT)
            mark()
            view = SystemView.of(SystemPageData(system, prev_id, next_id))
            mark()
            view.__pydantic_serializer__.to_json(view, by_alias=True)
            mark()
        for part, (a, b) in zip(PARTS, zip(marks, marks[1:], strict=False), strict=False):
            self.times[part].append(((b[0] - a[0]) * 1000.0, (b[1] - a[1]) * 1000.0))
        tri = system.triangulation
        self.sizes.append((self.statements - n0, len(view.views), len(view.doubts),
                           len(tri.pairs) if tri is not None else 0,
                           sum(v.pitch_lines_url is not None for v in view.views)))

    def report(self) -> str:
        """The table of parts: CPU and wall p50 / p95 in ms, and the mean page size."""
        n = len(self.sizes)
        lines = [f"{self.path} ({len(self.ids)} systems, {n} requests)",
                 f"  {'part':<11} {'cpu p50':>8} {'cpu p95':>8} {'wall p50':>9} {'wall p95':>9}"]
        totals = [tuple(sum(x) for x in zip(*(self.times[p][i] for p in PARTS), strict=False)) for i in range(n)]
        for part, xs in [*self.times.items(), ("total", totals)]:
            cpu, wall = [x[0] for x in xs], [x[1] for x in xs]
            lines.append(f"  {part:<11} {percentile(cpu, 50):8.2f} {percentile(cpu, 95):8.2f} "
                         f"{percentile(wall, 50):9.2f} {percentile(wall, 95):9.2f}")
        means = [sum(col) / n for col in zip(*self.sizes, strict=False)]
        lines.append("  per page: {:.1f} SQL statements, {:.2f} views, {:.2f} doubts, {:.2f} pairs, "
                     "{:.1f} pitch-line addresses (the lines are fetched once per camera)".format(*means))
        return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--db", type=Path, action="append", required=True, help="SQLite database (repeatable).")
    p.add_argument("--requests", type=int, default=200, help="Requests per database (default 200).")
    p.add_argument("--rounds", type=int, default=4, help="Alternations between the databases (default 4).")
    p.add_argument("--seed", type=int, default=0)
    args = p.parse_args(argv)
    for db in args.db:
        if not db.is_file():
            print(f"error: --db {db}: no such file", file=sys.stderr)
            return 2
    rng = random.Random(args.seed)
    dbs = [Database(db) for db in args.db]
    for db in dbs:  # warm-up: imports, the first connection, the page cache
        for sid in db.ids[:3]:
            db.request(sid)
        for part in PARTS:
            db.times[part].clear()
        db.sizes.clear()
    per_round = max(1, args.requests // args.rounds)
    for _ in range(args.rounds):
        for db in dbs:
            for _ in range(per_round):
                db.request(rng.choice(db.ids))
    for db in dbs:
        print(db.report())
        db.engine.dispose()
    return 0


if __name__ == "__main__":
    sys.exit(main())
