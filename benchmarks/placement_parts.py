"""Whether each shortcut of the players' placement matters: its CPU with and without it, paired in one process.

The placement (``app.services.calibration.players.place_in_game``) runs on every game of an imported database, as
``placement_cpu.py`` runs it (the views the players placed weak again), in this process. For each part named below
the same placement is timed (``time.process_time``) with this checkout's function and with the one of another
checkout (``--off``, e.g. ``git archive`` of main before the shortcut), swapped in place of it and put back, in
alternating order (on, off, off, on, ...: ``--rounds`` pairs); the answers of both are compared (every number of the
cameras and refusals to the bit, ``placement_cpu.answer``: their wall times left out). Prints per part the median
CPU of each and their ratio.

Parts (this checkout's function; the other checkout's is swapped in for "off"):

- ``starts``: ``players._rig_starts`` (the focal hypotheses' rotations in one compiled call);
- ``rewhiten``: ``PlayerProblem.rewhiten`` and ``_head_whitening`` (the grass neighbours and covariances made once);
- ``grass``: ``players_on_grass`` as the placement calls it (a view's players fused at once).

Usage::

    nice -n 10 .venv/bin/python benchmarks/placement_parts.py --db IMPORTED.sqlite3 --off OTHER_CHECKOUT \\
        [--games 10] [--rounds 3] [--parts starts,rewhiten]
"""
from __future__ import annotations

import argparse
import importlib.util
import statistics
import sys
import time
from pathlib import Path
from types import ModuleType
from typing import Any, Callable

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "benchmarks"))

from placement_cpu import answer  # noqa: E402  # benchmarks/ on the path above


def other_module(checkout: Path, dotted: str) -> ModuleType:
    """The module ``dotted`` of another checkout, loaded under its own name (its imports of ``app`` are this
    checkout's)."""
    path = checkout / (dotted.replace(".", "/") + ".py")
    spec = importlib.util.spec_from_file_location(f"_off_{dotted.replace('.', '_')}", path)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module  # dataclasses read their module while the class is made
    spec.loader.exec_module(module)
    return module


def swaps(off: Path) -> dict[str, list[tuple[Any, str, Any]]]:
    """Per part, the (owner, attribute, the other checkout's value) to swap in."""
    from app.geometry.calibration import player_problem, players
    from app.services.calibration import players as placing

    geo = other_module(off, "app.geometry.calibration.players")
    problem = other_module(off, "app.geometry.calibration.player_problem")
    grass = other_module(off, "app.geometry.calibration.grass")
    cls = player_problem.PlayerProblem
    return {
        "starts": [(players, "_rig_starts", geo._rig_starts)],
        "rewhiten": [(cls, "rewhiten", problem.PlayerProblem.rewhiten),
                     (cls, "_head_whitening", problem.PlayerProblem._head_whitening)],
        "grass": [(placing, "players_on_grass", grass.players_on_grass)],
    }


def timed(run: Callable[[], list[Any]]) -> tuple[float, list[Any]]:
    t0 = time.process_time()
    got = run()
    return time.process_time() - t0, got


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--db", type=Path, required=True, help="An imported database (read only).")
    p.add_argument("--off", type=Path, required=True, help="The checkout whose functions are swapped in for 'off'.")
    p.add_argument("--games", type=int, default=10, help="The first N games (default 10).")
    p.add_argument("--rounds", type=int, default=3, help="Pairs of runs per part (default 3).")
    p.add_argument("--parts", default="starts,rewhiten,grass", help="Comma-separated parts.")
    args = p.parse_args(argv)

    import sqlalchemy as sa
    from sqlalchemy.orm import Session, selectinload

    from app.core.config import Settings
    from app.db.models import Frame, Game, System
    from app.services.calibration.players import place_in_game, view_of_frame
    from app.services.calibration.rigs import uses_rig

    settings = Settings(database_url=f"sqlite:///file:{args.db}?mode=ro&uri=true")
    engine = sa.create_engine(settings.database_url)
    games = []
    with Session(engine) as session:
        for gid in session.scalars(sa.select(Game.id).order_by(Game.id)).all()[:args.games]:
            game = session.scalars(sa.select(Game).where(Game.id == gid).options(
                selectinload(Game.systems).selectinload(System.frames).options(
                    selectinload(Frame.calibration), selectinload(Frame.field_lines),
                    selectinload(Frame.players)))).one()
            games.append([[view_of_frame(f, settings) for f in s.frames] for s in game.systems if uses_rig(s)])

    def run() -> list[Any]:
        return [place_in_game(views) for views in games]

    def answers_of(got: list[Any]) -> str:  # every view's answer but its wall time
        return repr([[{i: answer(v) for i, v in fits.items()} for fits in game] for game in got])

    run()  # numba's cached kernels and first imports: paid once, before any timing
    table = swaps(args.off)
    print(f"{len(games)} games; CPU s of the placement, median of {args.rounds} per side")
    print("| part | on (this checkout) | off (the other's) | on / off | same answers |")
    print("|---|---|---|---|---|")
    for part in args.parts.split(","):
        times: dict[str, list[float]] = {"on": [], "off": []}
        answers: dict[str, str] = {}
        for k in range(args.rounds):
            for side in (("on", "off") if k % 2 == 0 else ("off", "on")):
                saved = [(owner, name, getattr(owner, name)) for owner, name, _ in table[part]]
                if side == "off":
                    for owner, name, value in table[part]:
                        setattr(owner, name, value)
                try:
                    cpu, got = timed(run)
                finally:
                    for owner, name, value in saved:
                        setattr(owner, name, value)
                times[side].append(cpu)
                answers[side] = answers_of(got)
        on, off = statistics.median(times["on"]), statistics.median(times["off"])
        same = answers["on"] == answers["off"]
        print(f"| {part} | {on:.2f} | {off:.2f} | {on / off:.2f} | {'yes' if same else 'NO'} |", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
