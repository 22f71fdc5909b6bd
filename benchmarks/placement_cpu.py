"""CPU of the players' placement (``app.services.calibration.players.place_in_game``) on every game of an imported
database, in this process, with the code of a checkout given by ``--code``, so that two checkouts can be compared
in separate processes run one after the other (interleaved: ``A B B A``) on the same inputs.

Each game's views are read as the stored-frames path reads them (``view_of_frame`` with every frame's player
boxes); the views the players placed at the import are weak again (placed anew), as when an import changes a game.
The CPU time (``time.process_time``) of the placement alone is summed over the games (reading the database is not
counted); a digest of the answers (the cameras accepted, their focal lengths summed, the refusals by code) is
printed so that two checkouts can be seen to give the same. ``--answers FILE`` writes every view's answer (by game,
system and view: the calibration's fields, or the refusal's code and numbers) as JSON; ``--against FILE`` compares
this run's answers with such a file: the same views placed and refused, with the same codes, and the largest relative
difference of the cameras' numbers (and of every other number) is printed.

Usage::

    nice -n 10 .venv/bin/python benchmarks/placement_cpu.py --db IMPORTED.sqlite3 [--code CHECKOUT] [--games N] \\
        [--answers OUT.json] [--against OLD.json]
"""
from __future__ import annotations

import argparse
import dataclasses
import json
import math
import sys
import time
from collections import Counter
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--db", type=Path, required=True, help="An imported database (read only).")
    p.add_argument("--code", type=Path, default=ROOT, help="The checkout whose code runs (default: this one).")
    p.add_argument("--games", type=int, help="Only the first N games.")
    p.add_argument("--answers", type=Path, help="Write every view's answer here (JSON).")
    p.add_argument("--against", type=Path, help="Compare every view's answer with this --answers file.")
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
    cpu, placed, focal, weak_games = 0.0, 0, 0.0, 0
    refused: Counter[str] = Counter()
    warm = False
    answers: dict[str, Any] = {}
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
            for k, fits in enumerate(got):
                for i, v in fits.items():
                    answers[f"{gid}/{k}/{i}"] = answer(v)
                    if isinstance(v, CalibrationFields):
                        placed += 1
                        focal += float((v.camera or {}).get("x_focal_length", 0.0))
                    else:
                        refused[v.code] += 1
    print(f"code {args.code}: {len(ids)} games ({weak_games} with weak views), placement CPU {cpu:.2f} s; "
          f"placed {placed} (focal lengths summed {focal:.6f} px), refused {dict(sorted(refused.items()))}")
    if args.answers:
        args.answers.write_text(json.dumps(answers, indent=0, sort_keys=True))
    if args.against:
        return compare(json.loads(args.against.read_text()), json.loads(json.dumps(answers)))
    return 0


def answer(v: Any) -> dict[str, Any]:
    """A view's answer as plain JSON values: the calibration's fields (its wall time left out), or the refusal."""
    if dataclasses.is_dataclass(v) and not isinstance(v, type) and hasattr(v, "camera"):
        fields = {k: w for k, w in dataclasses.asdict(v).items() if k != "elapsed_ms"}
        return {"placed": json.loads(json.dumps(fields, default=str))}
    return {"refused": v.code, "numbers": {k: float(w) for k, w in v.numbers.items()}}


def _largest_difference(a: Any, b: Any, where: str, out: dict[str, float]) -> bool:
    """Whether ``a`` and ``b`` have the same shape and the same non-numbers; the largest relative difference of their
    numbers per top-level field goes into ``out``: ``|a - b| / |a|`` of a number, ``||a - b|| / ||a||`` of a list of
    numbers (a vector, a matrix)."""
    if isinstance(a, dict) and isinstance(b, dict):
        return a.keys() == b.keys() and all(_largest_difference(a[k], b[k], where or k, out) for k in a)
    if isinstance(a, list) and isinstance(b, list):
        if len(a) != len(b):
            return False
        flat_a, flat_b = _numbers(a), _numbers(b)
        if flat_a is not None and flat_b is not None and len(flat_a) == len(flat_b):
            # A vector or matrix (a rotation, a position) as a whole: its entries near zero are not relative to
            # themselves but to its norm.
            gap = math.sqrt(sum((x - y) ** 2 for x, y in zip(flat_a, flat_b, strict=True)))
            norm = math.sqrt(sum(x * x for x in flat_a))
            out[where] = max(out.get(where, 0.0), 0.0 if gap == 0 else gap / max(norm, 1e-12))
            return True
        return all(_largest_difference(x, y, where, out) for x, y in zip(a, b, strict=True))
    if isinstance(a, (int, float)) and isinstance(b, (int, float)) and not isinstance(a, bool):
        fa, fb = float(a), float(b)
        if fa == fb or (math.isnan(fa) and math.isnan(fb)):
            rel = 0.0
        else:
            rel = abs(fa - fb) / max(abs(fa), 1e-12)
        out[where] = max(out.get(where, 0.0), rel)
        return True
    return bool(a == b)


def _numbers(a: Any) -> list[float] | None:
    """The numbers of a nested list, flattened; None when it holds anything else."""
    if isinstance(a, list):
        out: list[float] = []
        for x in a:
            got = _numbers(x)
            if got is None:
                return None
            out += got
        return out
    return [float(a)] if isinstance(a, (int, float)) and not isinstance(a, bool) else None


def compare(old: dict[str, Any], new: dict[str, Any]) -> int:
    """Print whether ``new`` answers every view as ``old`` does (same views, placed or refused alike, same codes) and
    the largest relative differences of the numbers; 0 when the decisions are the same, 1 otherwise."""
    differ = sorted(k for k in old.keys() | new.keys() if k not in old or k not in new
                    or old[k].keys() != new[k].keys() or old[k].get("refused") != new[k].get("refused"))
    diffs: dict[str, float] = {}
    shaped = [k for k in old.keys() & new.keys() if k not in differ and not (
        _largest_difference(old[k]["placed"], new[k]["placed"], "", diffs) if "placed" in old[k]
        else _largest_difference(old[k]["numbers"], new[k]["numbers"], "refusal numbers", diffs))]
    n_placed = sum("placed" in v for v in new.values())
    print(f"compared {len(old.keys() | new.keys())} views ({n_placed} placed, {len(new) - n_placed} refused): "
          f"{len(differ)} differ in their decision {differ[:10]}, {len(shaped)} in their fields' shape {shaped[:10]}")
    print("largest relative differences: " + ", ".join(f"{k} {v:.2e}" for k, v in sorted(diffs.items())))
    return 1 if differ or shaped else 0


if __name__ == "__main__":
    raise SystemExit(main())
