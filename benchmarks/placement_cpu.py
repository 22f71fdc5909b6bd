"""CPU of the players' placement (``app.services.calibration.players.place_in_game``) on every game of an imported
database, in this process, with the code of a checkout given by ``--code``, so that two checkouts can be compared
in separate processes run one after the other (interleaved: ``A B B A``) on the same inputs.

Each game's views are read as the stored-frames path reads them (``view_of_frame`` with every frame's player
boxes); the views the players placed at the import are weak again (placed anew), as when an import changes a game.
The CPU time (``time.process_time``) of the placement alone is summed over the games (reading the database is not
counted); a digest of the answers (the cameras accepted, their focal lengths summed, the refusals by code) is
printed so that two checkouts can be seen to give the same.

Usage::

    nice -n 10 .venv/bin/python benchmarks/placement_cpu.py --db IMPORTED.sqlite3 [--code CHECKOUT] [--games N]
"""
from __future__ import annotations

import argparse
import sys
import time
from collections import Counter
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--db", type=Path, required=True, help="An imported database (read only).")
    p.add_argument("--code", type=Path, default=ROOT, help="The checkout whose code runs (default: this one).")
    p.add_argument("--games", type=int, help="Only the first N games.")
    args = p.parse_args(argv)
    sys.path.insert(0, str(args.code.resolve()))

    import sqlalchemy as sa
    from sqlalchemy.orm import Session, selectinload

    from app.core.config import Settings
    from app.datasets.records import CalibrationFields
    from app.db.models import Frame, Game, System
    from app.services.calibration.players import place_in_game, view_of_frame
    from app.services.calibration.rigs import uses_rig

    settings = Settings(database_url=f"sqlite:///file:{args.db}?mode=ro&uri=true")
    engine = sa.create_engine(settings.database_url)
    cpu, placed, focal, refused, weak_games = 0.0, 0, 0.0, Counter(), 0
    warm = False
    with Session(engine) as session:
        ids = session.scalars(sa.select(Game.id).order_by(Game.id)).all()[:args.games]
        for gid in ids:
            game = session.scalars(sa.select(Game).where(Game.id == gid).options(
                selectinload(Game.systems).selectinload(System.frames).options(
                    selectinload(Frame.calibration), selectinload(Frame.field_lines),
                    selectinload(Frame.players)))).one()
            systems = [s for s in game.systems if uses_rig(s)]
            views = [[view_of_frame(f, settings) for f in s.frames] for s in systems]
            if not warm:  # numba's cached kernels and first imports: paid once per process, not per game
                place_in_game(views)
                warm = True
            t0 = time.process_time()
            got = place_in_game(views)
            cpu += time.process_time() - t0
            weak_games += any(bool(g) for g in got)
            for fits in got:
                for v in fits.values():
                    if isinstance(v, CalibrationFields):
                        placed += 1
                        focal += float((v.camera or {}).get("x_focal_length", 0.0))
                    else:
                        refused[v.code] += 1
    print(f"code {args.code}: {len(ids)} games ({weak_games} with weak views), placement CPU {cpu:.2f} s; "
          f"placed {placed} (focal lengths summed {focal:.6f} px), refused {dict(sorted(refused.items()))}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
