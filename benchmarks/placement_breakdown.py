"""Where the players' placement spends its CPU, without a profiler's overhead: each step's CPU time, summed.

cProfile charges every numpy call its own overhead, which is most of what the placement does (a few dozen rows per
call): its figures over-weigh the steps made of many small calls (the whitening, the starts) against the compiled fit.
Here the placement (``app.services.calibration.players.place_in_game``) runs on the first ``--games`` games of an
imported database, as ``placement_cpu.py`` runs it (the views the players placed weak again), once to warm numba's
kernels, once timed whole, then once with each step below wrapped in a ``time.process_time`` timer (a microsecond a
call): per step its CPU seconds (inclusive: a step's figure holds the steps it calls), calls and microseconds a call.

Steps: ``fit_camera_to_players`` (a view's whole fit), ``_rig_starts``, ``_best`` (two robust fits per start, each
whitened first), ``PlayerProblem.fit`` (the compiled robust fit), ``PlayerProblem.rewhiten``, ``_judge``,
``_accepted``, ``_free_pose``, ``_lines_retried``; outside the fit ``fields_of_fit`` (the stored fields: JaC,
residuals, words), ``players_on_grass``, ``feet_of``, ``_kept`` and ``rig_of_views``.

Usage::

    nice -n 10 .venv/bin/python benchmarks/placement_breakdown.py --db IMPORTED.sqlite3 [--games 20]
"""
from __future__ import annotations

import argparse
import sys
import time
from collections import Counter, defaultdict
from pathlib import Path
from typing import Any, Callable

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))


def load_games(db: Path, games: int) -> list[Any]:
    """Per game, per system of a kind with a rig, its views as the stored-frames path reads them (``view_of_frame``
    with every frame's player boxes)."""
    import sqlalchemy as sa
    from sqlalchemy.orm import Session, selectinload

    from app.core.config import Settings
    from app.db.models import Frame, Game, System
    from app.services.calibration.players import view_of_frame
    from app.services.calibration.rigs import uses_rig

    settings = Settings(database_url=f"sqlite:///file:{db}?mode=ro&uri=true")
    out = []
    with Session(sa.create_engine(settings.database_url)) as session:
        for gid in session.scalars(sa.select(Game.id).order_by(Game.id)).all()[:games]:
            game = session.scalars(sa.select(Game).where(Game.id == gid).options(
                selectinload(Game.systems).selectinload(System.frames).options(
                    selectinload(Frame.calibration), selectinload(Frame.field_lines),
                    selectinload(Frame.players)))).one()
            out.append([[view_of_frame(f, settings) for f in s.frames] for s in game.systems if uses_rig(s)])
    return out


def wrapped(steps: list[tuple[Any, str, str]], seconds: defaultdict[str, float], calls: Counter[str]
            ) -> list[tuple[Any, str, Any]]:
    """Wrap each (owner, attribute, label) of ``steps`` in a timer adding to ``seconds`` and ``calls``; returns what
    to put back."""
    saved = []
    for owner, name, label in steps:
        fn = getattr(owner, name)
        saved.append((owner, name, fn))

        def timer(*args: Any, _fn: Callable[..., Any] = fn, _label: str = label, **kwargs: Any) -> Any:
            t0 = time.process_time()
            try:
                return _fn(*args, **kwargs)
            finally:
                seconds[_label] += time.process_time() - t0
                calls[_label] += 1

        setattr(owner, name, timer)
    return saved


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--db", type=Path, required=True, help="An imported database (read only).")
    p.add_argument("--games", type=int, default=20, help="The first N games (default 20).")
    args = p.parse_args(argv)

    from app.geometry.calibration import player_problem
    from app.geometry.calibration import players as geo
    from app.services.calibration import players as placing

    games = load_games(args.db, args.games)

    def run() -> None:
        for views in games:
            placing.place_in_game(views)

    run()  # numba's cached kernels and first imports: paid once, before any timing
    t0 = time.process_time()
    run()
    whole = time.process_time() - t0
    seconds: defaultdict[str, float] = defaultdict(float)
    calls: Counter[str] = Counter()
    problem = player_problem.PlayerProblem
    saved = wrapped([(placing, "fit_camera_to_players", "fit_camera_to_players"), (geo, "_rig_starts", "_rig_starts"),
                     (geo, "_best", "_best"), (problem, "fit", "PlayerProblem.fit"),
                     (problem, "rewhiten", "PlayerProblem.rewhiten"), (geo, "_judge", "_judge"),
                     (geo, "_accepted", "_accepted"), (geo, "_free_pose", "_free_pose"),
                     (geo, "_lines_retried", "_lines_retried"), (placing, "fields_of_fit", "fields_of_fit"),
                     (placing, "players_on_grass", "players_on_grass"), (placing, "feet_of", "feet_of"),
                     (placing, "_kept", "_kept"), (placing, "rig_of_views", "rig_of_views")], seconds, calls)
    t0 = time.process_time()
    try:
        run()
    finally:
        for owner, name, fn in saved:
            setattr(owner, name, fn)
    timed = time.process_time() - t0
    print(f"{len(games)} games; placement CPU {whole:.3f} s (with the timers: {timed:.3f} s)")
    print("| step | CPU s | share | calls | us a call |")
    print("|---|---|---|---|---|")
    for label, s in sorted(seconds.items(), key=lambda kv: -kv[1]):
        print(f"| {label} | {s:.3f} | {100 * s / timed:.0f} % | {calls[label]} | {1e6 * s / calls[label]:.0f} |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
