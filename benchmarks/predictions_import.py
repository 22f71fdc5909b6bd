"""Speed and memory of ``v3d import predictions`` (``benchmarks/DETECTOR.md``): 100,000 predictions on a
dev-large-sized database, and a 100 MB file, each imported in process, timed (wall) with the peak of Python's
allocations (``tracemalloc``) and the process's peak RSS.

The database is a copy of ``benchmarks/detector_fill.py``'s cached import of ``dev-large`` (run that first, or give
``--db``). Rows: boxes of a ball's size at random places of each stored frame, random scores; the 100 MB file adds rows
naming images v3d does not hold until it weighs 100 MB (they are read, checked, counted and named, not stored), so
that it measures the stream, not SQLite's inserts.

Run: ``.venv/bin/python benchmarks/predictions_import.py [--db PATH] [--rows 100000] [--mb 100]``.
"""
from __future__ import annotations

import argparse
import resource
import shutil
import sys
import time
import tracemalloc
from pathlib import Path
from typing import Sequence

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))


def write_csv(path: Path, frames: list[tuple[str, str, str, str, int, int]], rows: int, mb: float,
              rng: np.random.Generator) -> int:
    """``rows`` predictions on ``frames`` then unknown-image rows until ``mb`` MB; returns the rows written."""
    n = 0
    with path.open("w") as f:
        f.write("league,season,match,image,x1,y1,x2,y2,score\n")
        for i in range(rows):
            league, season, match, image, w, h = frames[i % len(frames)]
            d = rng.uniform(8, 24)
            x, y = rng.uniform(0, w - d), rng.uniform(0, h - d)
            f.write(f"{league},{season},{match},{image},{x:.2f},{y:.2f},{x + d:.2f},{y + d:.2f},{rng.uniform():.3f}\n")
            n += 1
        while f.tell() < mb * (1 << 20):
            x, y = rng.uniform(0, 1900), rng.uniform(0, 1060)
            f.write(f"synth_league_x,2031-2032,nowhere {n % 97},{n % 50}.png,{x:.2f},{y:.2f},{x + 12:.2f},"
                    f"{y + 12:.2f},{rng.uniform():.3f}\n")
            n += 1
    return n


def run(db: Path, rows: int, mb: float, tag: str, trace: bool) -> None:
    import sqlalchemy as sa
    from sqlalchemy.orm import Session

    from app.core.config import Settings
    from app.db.models import Frame, Game, System
    from app.services.transfer.predictions import import_predictions

    work = db.with_name(f"{db.stem}.predictions-{tag}.sqlite3")
    shutil.copyfile(db, work)
    url = f"sqlite:///{work}"
    settings = Settings(_env_file=None, database_url=url)
    engine = sa.create_engine(url)
    with Session(engine) as session:
        frames = [(g.league, g.season, g.match, f.name, f.width, f.height) for f, g in session.execute(
            sa.select(Frame, Game).join(System, System.id == Frame.system_id).join(Game, Game.id == System.game_id))]
    path = work.with_suffix(".csv")
    n = write_csv(path, frames, rows, mb, np.random.default_rng(3))
    size = path.stat().st_size / (1 << 20)
    if trace:
        tracemalloc.start()
    t0 = time.perf_counter()
    with Session(engine) as session:
        report = import_predictions(session, path, settings, source="bench")
    seconds = time.perf_counter() - t0
    peak = tracemalloc.get_traced_memory()[1] if trace else 0
    tracemalloc.stop()
    rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    print(f"[{tag}] {size:.1f} MB, {n} rows ({report.stored} stored on {report.frames} frames of {report.systems} "
          f"systems, {report.unknown} naming unknown images): {seconds:.1f} s wall, of which "
          f"{report.store_seconds:.1f} s reading and storing, the rest recomputing the systems touched; Python "
          f"allocations peak {peak / (1 << 20):.1f} MB (traced: {trace}), process peak RSS {rss:.0f} MB", flush=True)
    engine.dispose()


def main(argv: Sequence[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--db", type=Path, default=Path("/tmp/v3d-detector-fill/dev-large.sqlite3"))
    ap.add_argument("--rows", type=int, default=100_000)
    ap.add_argument("--mb", type=float, default=100.0)
    ap.add_argument("--which", choices=["rows", "mb"], default="rows")
    ap.add_argument("--trace", action="store_true", help="trace Python's allocations (slows the import down)")
    args = ap.parse_args(argv)
    if args.which == "rows":
        run(args.db, args.rows, 0.0, "100k", args.trace)
    else:
        run(args.db, args.rows, args.mb, f"{args.mb:g}MB", args.trace)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
