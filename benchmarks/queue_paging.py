"""Queue paging at depth (issue 16 item 6): the first page against the last, by ``offset`` and by cursor,
under every sort, in process (``app.services.curation.queue.list_systems``, the SQL and the ORM rows of
a page; the HTTP layer adds the same per row at any depth).

The database is either a scale database made by ``benchmarks/scale.py --import-only --db PATH`` (the
SoccerNet-v3-size set, 12,800 systems: pass ``--db PATH``), or, without one, a database migrated to head
and filled with ``--systems`` bare systems in games of 32 (random figures with ties and NULLs, seed
``--seed``, no frames: the queue reads only the stored per-system figures, so its SQL is the same). A
demo database (9 systems, ``scale.build_demo_db``) is measured the same way for the ratio.

Per sort: ``first`` (offset 0), ``last`` (the offset of the last page), ``random`` (offsets at random
depths), ``cursor`` (``after=`` a random page's ``next_cursor``), ``back`` (``before=`` one), each
``--repeat`` times; p50 / p95 ms, and the most SQLite VM instructions a page took (counted with
``sqlite3``'s progress handler: the work done, whatever else the machine runs). Usage::

    .venv/bin/python benchmarks/queue_paging.py [--db var/scale.sqlite3] [--systems 12800] [--repeat 40]
"""
from __future__ import annotations

import argparse
import random
import sys
import tempfile
import time
from pathlib import Path
from typing import Any, Optional

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

SORTS = ("-severity", "severity", "-doubts", "doubts", "-worst_error", "worst_error", "lowest_jac", "-lowest_jac",
         "name", "-name")
LIMIT = 50


def build_bare_db(path: Path, systems: int, seed: int) -> None:
    """A database at head with ``systems`` systems in games of 32, figures drawn with seed ``seed``."""
    import sqlalchemy as sa

    from app.db.models import Game, ReviewStatus, System, SystemKind
    from app.db.session import make_engine, make_session_factory, upgrade_database

    url = f"sqlite:///{path}"
    upgrade_database(url)
    rng = random.Random(seed)
    engine = make_engine(url)
    with make_session_factory(engine)() as session:
        for g in range((systems + 31) // 32):
            game = Game(league="england_epl", season="2014-2015", match=f"game {g:04d}", source_path="/nowhere")
            session.add(game)
            session.flush()
            session.execute(sa.insert(System), [dict(
                game_id=game.id, name=f"{i + 1}.png", kind=SystemKind.SOCCERNET_V3, doubt_counts={},
                label_doubts=rng.choice([0] * 6 + [1, 2]),
                worst_error_px=None if rng.random() < 0.1 else round(rng.lognormvariate(0.5, 1.0), 3),
                lowest_jac=None if rng.random() < 0.05 else round(rng.uniform(0.5, 1.0), 4),
                review_status=rng.choice([ReviewStatus.PENDING] * 9 + [ReviewStatus.ACCEPTED]),
            ) for i in range(min(32, systems - 32 * g))])
        session.commit()
    engine.dispose()


def percentile(values: list[float], q: float) -> float:
    """The ``q``-th percentile (linear interpolation), as numpy computes it."""
    import numpy as np

    return float(np.percentile(values, q))


def measure(url: str, repeat: int, seed: int) -> dict[str, dict[str, dict[str, float]]]:
    """Per sort and kind of page, p50 / p95 ms of ``list_systems`` (module docstring)."""
    from app.db.session import make_engine, make_session_factory
    from app.services.curation import queue

    rng = random.Random(seed)
    engine = make_engine(url)
    out: dict[str, dict[str, dict[str, float]]] = {}
    with make_session_factory(engine)() as session:
        total = queue.list_systems(session, limit=1).total
        last = max(0, (total - 1) // LIMIT * LIMIT)

        raw = session.connection().connection.driver_connection
        steps = [0]

        def count(_n: list[int] = steps) -> int:
            _n[0] += 1
            return 0

        raw.set_progress_handler(count, 100)  # SQLite VM instructions / 100: the work, whatever the load
        work: dict[str, dict[str, list[float]]] = {}

        def timed(sort: str, kind: str = "", **page: Any) -> float:
            session.expunge_all()
            steps[0] = 0
            t0 = time.perf_counter()
            queue.list_systems(session, sort=sort, limit=LIMIT, **page)  # type: ignore[arg-type]  # page holds list_systems' keywords
            ms = (time.perf_counter() - t0) * 1e3
            if kind:
                work.setdefault(sort, {}).setdefault(kind, []).append(steps[0] / 10.0)
            return ms

        for sort in SORTS:
            timed(sort)  # warm-up
            cursors = []
            for _ in range(8):
                page = queue.list_systems(session, sort=sort, limit=LIMIT, offset=rng.randrange(total))  # type: ignore[arg-type]  # total is a count here
                if page.next_cursor and page.prev_cursor:
                    cursors.append((page.next_cursor, page.prev_cursor))
            kinds: dict[str, list[float]] = {"first": [], "last": [], "random": [], "cursor": [], "back": []}
            for i in range(repeat):
                kinds["first"].append(timed(sort, "first"))
                kinds["last"].append(timed(sort, "last", offset=last))
                kinds["random"].append(timed(sort, "random", offset=rng.randrange(total)))
                if cursors:
                    nxt, prev = cursors[i % len(cursors)]
                    kinds["cursor"].append(timed(sort, "cursor", after=nxt))
                    kinds["back"].append(timed(sort, "back", before=prev))
            out[sort] = {k: {"p50": percentile(v, 50), "p95": percentile(v, 95),
                             "kvm": max(work[sort][k])} for k, v in kinds.items() if v}
        out["_"] = {"systems": {"p50": float(total), "p95": float(total)}}
    engine.dispose()
    return out


def report(name: str, figures: dict[str, dict[str, dict[str, float]]]) -> str:
    """A markdown table of p50 / p95 ms per sort and kind of page."""
    kinds = ("first", "last", "random", "cursor", "back")
    lines = [f"{name}: {int(figures['_']['systems']['p50'])} systems, p50 / p95 ms (the most SQLite VM instructions"
             " of a page, thousands: the work, independent of the machine's load)", "",
             "| sort | " + " | ".join(kinds) + " |", "| --- |" + " --- |" * len(kinds)]
    every95 = []
    for sort, by_kind in figures.items():
        if sort == "_":
            continue
        cells = []
        for k in kinds:
            f = by_kind.get(k)
            cells.append(f"{f['p50']:.1f} / {f['p95']:.1f} ({f['kvm']:.0f}k)" if f else "—")
            if f:
                every95.append(f["p95"])
        lines.append(f"| {sort} | " + " | ".join(cells) + " |")
    lines.append(f"\nworst p95: {max(every95):.1f} ms")
    return "\n".join(lines)


def main(argv: Optional[list[str]] = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--db", type=Path, help="a scale database (scale.py --import-only --db PATH)")
    parser.add_argument("--systems", type=int, default=12_800, help="bare systems when no --db (default 12,800)")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--repeat", type=int, default=40)
    parser.add_argument("--no-demo", action="store_true", help="skip the demo database")
    args = parser.parse_args(argv)
    with tempfile.TemporaryDirectory() as tmp:
        if args.db is not None:
            if not args.db.exists():
                print(f"--db {args.db}: no such file", file=sys.stderr)
                return 2
            url, name = f"sqlite:///{args.db.resolve()}", f"scale ({args.db})"
        else:
            path = Path(tmp) / "bare.sqlite3"
            build_bare_db(path, args.systems, args.seed)
            url, name = f"sqlite:///{path}", f"bare systems (seed {args.seed})"
        print(report(name, measure(url, args.repeat, args.seed)))
        if not args.no_demo:
            from benchmarks.scale import build_demo_db

            demo = build_demo_db(Path(tmp))
            print()
            print(report("demo", measure(f"sqlite:///{demo}", args.repeat, args.seed)))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
