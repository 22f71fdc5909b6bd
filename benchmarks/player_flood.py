"""A flood of player boxes against the import, as a paired ratio: the dev game of ``../shared`` imported as it is
(``plain``) and with ``--boxes`` (120,000) well-formed player boxes appended to one frame (``flood``: the fifth
security review's 2.9 MB zip), each into a fresh migrated SQLite file, ``--rounds`` (3) pairs alternating which goes
first, in this process (``import_soccernet_v3``, one calibration process). An import of one batch stores the records
its validation read, so the flood costs one parse of its labels file, made without garbage collections (the parsed
boxes are dropped before one could traverse them); everything past ``V3D_MAX_PLAYERS_PER_FRAME`` boxes a frame is
counted, neither converted nor kept. Target: the flood's median within 1.5x the plain game's (before the reader
stopped at the cap: 4.0 s against 1.2 s, 3.3x; parsed twice, with collections: 2.7x).

Prints one JSON object: each round's seconds, the medians and their ratio. Run::

    .venv/bin/python benchmarks/player_flood.py [--boxes 120000] [--rounds 3] [--shared ../shared]
"""
from __future__ import annotations

import argparse
import json
import statistics
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))


def flood(boxes: int):
    """An ``edit`` of ``write_v3_game`` appending ``boxes`` well-formed player boxes to the action ``0.png``."""

    def edit(data: dict) -> None:
        data["actions"]["0.png"]["bboxes"] += [
            {"class": "Player team left", "ID": i, "points": {"x1": 10 + i % 900, "y1": 20, "x2": 30 + i % 900,
                                                            "y2": 80}} for i in range(boxes)]

    return edit


def timed_import(tree: Path, folder: Path) -> tuple[float, int]:
    """Seconds of ``import_soccernet_v3`` of ``tree`` into a fresh SQLite file under ``folder``, and the boxes it
    counted beyond the cap."""
    from app.core.config import Settings
    from app.db.session import make_engine, make_session_factory, upgrade_database
    from app.services.transfer.importing import import_soccernet_v3

    url = f"sqlite:///{folder / 'v3d.sqlite3'}"
    upgrade_database(url)
    engine = make_engine(url)
    try:
        with make_session_factory(engine)() as session:
            t0 = time.perf_counter()
            report = import_soccernet_v3(session, tree, Settings(database_url=url, calibration_workers=1))
            return time.perf_counter() - t0, report.players_dropped
    finally:
        engine.dispose()


def main(argv: list[str] | None = None) -> dict:
    """Run the pairs; the figures as printed."""
    from tests.services.datasets import write_v3_game

    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--boxes", type=int, default=120_000)
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--shared", type=Path, default=ROOT.parent / "shared")
    args = parser.parse_args(argv)
    with tempfile.TemporaryDirectory(prefix="v3d-player-flood-") as tmp:
        work = Path(tmp)
        trees = {"plain": work / "plain", "flood": work / "flood"}
        write_v3_game(args.shared, trees["plain"])
        write_v3_game(args.shared, trees["flood"], edit=flood(args.boxes))
        timed_import(trees["plain"], Path(tempfile.mkdtemp(dir=work)))  # warm-up: compiled kernels, imports
        seconds: dict[str, list[float]] = {"plain": [], "flood": []}
        dropped = 0
        for r in range(args.rounds):
            for name in (("plain", "flood") if r % 2 == 0 else ("flood", "plain")):
                took, counted = timed_import(trees[name], Path(tempfile.mkdtemp(dir=work)))
                seconds[name].append(round(took, 3))
                dropped = max(dropped, counted)
    medians = {name: statistics.median(values) for name, values in seconds.items()}
    figures = {"boxes": args.boxes, "players_dropped": dropped, "seconds": seconds, "median_s": medians,
               "ratio": round(medians["flood"] / medians["plain"], 2)}
    print(json.dumps(figures, indent=2))
    return figures


if __name__ == "__main__":
    main()
