"""Profile one queue request, one system page and one ball edit on a (scale) database, in process.

Companion of ``benchmarks/scale.py``: where that one times the real server over loopback, this one
runs the same three requests' service calls and response models in process (no server, no
network, one thread) under cProfile and counts the SQL statements each one sends, with their time, so that the cost can
be put on file:function names. Each request is made once to warm up, then ``--repeat`` times profiled. The ball
edit moves an existing box by one pixel and back (the second PATCH is not profiled).

Usage::

    .venv/bin/python benchmarks/scale_profile.py --db /work/scale-runs/full/v3d-scale.sqlite3 [--top 18]

Prints per request: wall ms, SQL statement count and total SQL ms, the slowest statements (their
first characters), and the functions of ``app/`` (and the overall top ``tottime``) by cumulative time.
"""
from __future__ import annotations

import argparse
import cProfile
import io
import pstats
import sys
import time
from pathlib import Path
from typing import Any, Callable

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))


class SqlCounter:
    """Counts and times the SQL statements of every engine (SQLAlchemy cursor events)."""

    def __init__(self) -> None:
        import sqlalchemy as sa
        from sqlalchemy import event

        self.statements: list[tuple[float, str]] = []
        self._t0: list[float] = []
        event.listen(sa.Engine, "before_cursor_execute", self._before)
        event.listen(sa.Engine, "after_cursor_execute", self._after)

    def _before(self, conn: Any, cursor: Any, statement: str, *args: Any) -> None:
        self._t0.append(time.perf_counter())

    def _after(self, conn: Any, cursor: Any, statement: str, *args: Any) -> None:
        self.statements.append(((time.perf_counter() - self._t0.pop()) * 1000.0, " ".join(statement.split())))

    def reset(self) -> None:
        self.statements = []


def profile_call(name: str, call: Callable[[], Any], sql: SqlCounter, top: int, repeat: int = 5) -> str:
    """Warm ``call`` up once, then run it ``repeat`` times under cProfile (the figures printed are
    totals over the repeats; the header gives per-call means); the account as text."""
    call()
    sql.reset()
    prof = cProfile.Profile()
    t0 = time.perf_counter()
    prof.enable()
    for _ in range(repeat):
        call()
    prof.disable()
    wall = (time.perf_counter() - t0) * 1000.0 / repeat
    out = io.StringIO()
    sql_ms = sum(ms for ms, _ in sql.statements) / repeat
    out.write(f"\n=== {name}: {wall:.1f} ms wall per call (under cProfile, mean of {repeat}), "
              f"{len(sql.statements) / repeat:.0f} SQL statements, {sql_ms:.1f} ms in SQL per call ===\n")
    for ms, text in sorted(sql.statements, reverse=True)[:4 * repeat:repeat]:
        out.write(f"  {ms:8.1f} ms  {text[:160]}\n")
    stats = pstats.Stats(prof, stream=out)
    stats.sort_stats("cumulative").print_stats(r"/app/", top)
    stats.sort_stats("tottime").print_stats(10)
    return out.getvalue()


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--db", type=Path, required=True, help="SQLite database (e.g. the one scale.py --db kept).")
    p.add_argument("--top", type=int, default=18, help="Functions listed per request.")
    p.add_argument("--repeat", type=int, default=5, help="Profiled calls per request (default 5).")
    args = p.parse_args(argv)
    if not args.db.is_file():
        print(f"error: --db {args.db}: no such file", file=sys.stderr)
        return 2
    from app.api.view_schemas import SystemPageOut, SystemSummaryOut, SystemView
    from app.core.config import Settings
    from app.db.session import make_engine, make_session_factory
    from app.services.curation import editing
    from app.services.curation import queue as queues
    from app.services.curation.system_page import system_page

    sql = SqlCounter()
    settings = Settings(database_url=f"sqlite:///{args.db.resolve()}")
    engine = make_engine(settings.database_url)
    sessions = make_session_factory(engine)
    filters = queues.SystemFilters()

    def queue() -> str:  # as the route GET /api/systems does, response model included
        with sessions() as s:
            page = queues.list_systems(s, filters, queues.DEFAULT_SORT, 50, 0)
            return SystemPageOut(items=[SystemSummaryOut.of(x) for x in page.items], total=page.total, limit=50,
                                 offset=0, counts=page.counts).model_dump_json()

    def system(sid: int) -> str:  # GET /api/systems/{id}
        with sessions() as s:
            return SystemView.of(system_page(s, sid, filters, queues.DEFAULT_SORT)).model_dump_json()

    def edit(fid: int, sid: int, box: list[float]) -> str:  # PATCH /api/frames/{id}/ball
        with sessions() as s:
            editing.update_ball_label(s, fid, box=box, settings=settings)
            return SystemView.of(system_page(s, sid, filters, queues.DEFAULT_SORT)).model_dump_json()

    with sessions() as s:
        page = queues.list_systems(s, filters, queues.DEFAULT_SORT, 50, 0)
        sid = page.items[len(page.items) // 2].id
        view = SystemView.of(system_page(s, sid, filters, queues.DEFAULT_SORT))
    boxed = [v for v in view.views if v.ball.kind is not None and v.ball.kind.value == "box" and v.ball.box]
    if not boxed:
        print(f"error: system {sid} has no boxed ball to nudge", file=sys.stderr)
        return 2
    fid, box = boxed[0].frame_id, list(boxed[0].ball.box)
    nudged = [box[0] + 1.0, box[1], box[2] + 1.0, box[3]]
    print(f"{args.db}: {page.total} systems; system {sid}, frame {fid}")
    print(profile_call("GET /api/systems (default sort)", queue, sql, args.top, args.repeat))
    print(profile_call(f"GET /api/systems/{sid}", lambda: system(sid), sql, args.top, args.repeat))
    edit(fid, sid, box)
    print(profile_call(f"PATCH /api/frames/{fid}/ball (+1 px, then back)",
                       lambda: (edit(fid, sid, nudged), edit(fid, sid, box)), sql, args.top, args.repeat))
    engine.dispose()
    return 0


if __name__ == "__main__":
    sys.exit(main())
