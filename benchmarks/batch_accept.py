"""What a batch's accept and undo cost at the SoccerNet-v3 size (``benchmarks/BATCHES.md``): both hold the write lock
for their whole write (one write unit), so their time is what other writers wait (``V3D_WRITE_LOCK_TIMEOUT_S``).

A fresh SQLite database (``--db``) of ``--systems`` pending systems whose ball is vouched for (bare rows: the accept
reads and writes the systems' versions, decisions and audit entries, never their views), one batch at 95 % / 5 %
(``app.services.curation.batches``), its sample accepted by a person through the ordinary decision; then, timed:
making the batch, reading what stops it, its accept and its undo. ``--repeats`` times; medians printed with the load
average (other work on the machine stretches every figure).

Run: ``.venv/bin/python benchmarks/batch_accept.py [--systems 12800] [--repeats 3] [--db /tmp/batches.sqlite3]``.
"""
from __future__ import annotations

import argparse
import os
import random
import statistics
import time
from pathlib import Path

import sqlalchemy as sa
from sqlalchemy.orm import Session

from app.db.models import BallEvidence, Game, System, SystemKind
from app.db.session import make_engine, upgrade_database
from app.services.curation import batches, decisions
from app.services.curation.queue import SystemFilters


def once(path: Path, systems: int, seed: int) -> dict[str, float]:
    """One run on a new database at ``path``: seconds per step."""
    path.unlink(missing_ok=True)
    url = f"sqlite:///{path}"
    upgrade_database(url)
    engine = make_engine(url)
    try:
        with Session(engine) as session:
            game = Game(league="bench", season="bench", match="bench", source_path="/nowhere")
            session.add(game)
            session.flush()
            session.execute(sa.insert(System), [{"game_id": game.id, "name": f"{i}.png",
                                                 "kind": SystemKind.SOCCERNET_V3, "ball_evidence": BallEvidence.VOUCHED}
                                                for i in range(systems)])
            session.commit()
            t0 = time.perf_counter()
            batch = batches.create_batch(session, "bench", SystemFilters(), 0.95, 0.05, rng=random.Random(seed))
            t1 = time.perf_counter()
            for sid in batch.sample_ids:
                decisions.decide_review(session, system_id=sid, status="accepted", actor="person")
            t2 = time.perf_counter()
            assert batches.stops(session, batch) == []
            t3 = time.perf_counter()
            accepted = batches.accept_batch(session, batch.id, "bench")
            t4 = time.perf_counter()
            undone = batches.undo_batch(session, batch.id, "bench").undone
            t5 = time.perf_counter()
            assert accepted == undone == systems - len(batch.sample_ids)
    finally:
        engine.dispose()
    return {"create": t1 - t0, "stops": t3 - t2, "accept": t4 - t3, "undo": t5 - t4}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--systems", type=int, default=12_800)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--db", type=Path, default=Path("/tmp/v3d-batch-bench.sqlite3"))
    args = parser.parse_args()
    runs = [once(args.db, args.systems, seed) for seed in range(args.repeats)]
    medians = {k: statistics.median(r[k] for r in runs) for k in runs[0]}
    print(f"{args.systems} vouched systems, sample of {batches.sample_size(0.95, 0.05, args.systems)}, "
          f"{args.repeats} runs, load average {os.getloadavg()[0]:.1f}: "
          + ", ".join(f"{k} {v:.2f} s" for k, v in medians.items()))


if __name__ == "__main__":
    main()
