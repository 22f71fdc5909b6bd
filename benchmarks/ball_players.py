"""What the ball's players check costs a recomputation: the systems of a database recomputed with the check on and
off in alternating blocks in one process (``recompute.recompute_system`` as an import runs it, a pair memo of its own
per system), CPU time (``time.process_time``) per system, the check's own share measured inside it on the same runs.

Off: ``ball.players_disagree`` answers "no disagreement" for every pair (what the ball was before the rule by
evidence read the players); the balls may then differ, which the timing ignores (nothing is written).

Usage (a database made by ``benchmarks/scale.py --import-only --games N --db PATH``)::

    .venv/bin/python benchmarks/ball_players.py --db PATH [--systems 400] [--blocks 6] [--profile out.prof]
"""
from __future__ import annotations

import argparse
import cProfile
import statistics
import sys
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from typing import Any

sys.path.insert(0, ".")
import sqlalchemy as sa  # noqa: E402  # after the checkout is on the path

from app.core.config import Settings  # noqa: E402  # after the checkout is on the path
from app.db.models import System  # noqa: E402  # after the checkout is on the path
from app.db.session import make_engine, make_session_factory  # noqa: E402  # after the checkout is on the path
from app.geometry.triangulation import PairGeometryMemo  # noqa: E402  # after the checkout is on the path
from app.services.derivation import ball, recompute  # noqa: E402  # after the checkout is on the path


class Inside:
    """CPU seconds spent inside the players check (building its closure and answering its pairs)."""

    def __init__(self) -> None:
        self.seconds = 0.0
        self.pairs = 0
        self._real = ball.players_disagree

    def players_disagree(self, *args: Any, **kwargs: Any) -> Callable[[Any, Any], bool]:
        t0 = time.process_time()
        real = self._real(*args, **kwargs)
        self.seconds += time.process_time() - t0

        def timed(a: Any, b: Any) -> bool:
            t1 = time.process_time()
            try:
                return real(a, b)
            finally:
                self.seconds += time.process_time() - t1
                self.pairs += 1

        return timed


@contextmanager
def players(on: bool, inside: Inside) -> Iterator[None]:
    """The check as it is (timed inside), or answering "no disagreement" for every pair."""
    real = ball.players_disagree
    ball.players_disagree = inside.players_disagree if on else (  # type: ignore[assignment]  # switched for the run
        lambda *args, **kwargs: (lambda a, b: False))
    try:
        yield
    finally:
        ball.players_disagree = real  # type: ignore[assignment]  # the switch undone


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--db", required=True)
    parser.add_argument("--systems", type=int, default=400)
    parser.add_argument("--blocks", type=int, default=6, help="blocks of each state, alternating")
    parser.add_argument("--profile", help="write a cProfile of the 'on' blocks here")
    args = parser.parse_args(argv)
    settings = Settings(_env_file=None, database_url=f"sqlite:///{args.db}")
    engine = make_engine(settings.database_url)
    inside = Inside()
    prof = cProfile.Profile() if args.profile else None
    with make_session_factory(engine)() as session:
        ids = list(session.scalars(sa.select(System.id).order_by(System.id).limit(args.systems)))
        systems = list(recompute.load_for_recompute(session, ids, predictions=settings.max_predictions_per_frame)
                       .values())
        sources = {gid: recompute.rig_centres(session, gid, settings)
                   for gid in {s.game_id for s in systems if recompute.uses_rig(s)}}
        per_state: dict[bool, list[float]] = {True: [], False: []}
        for block in range(2 * args.blocks + 1):
            on = block % 2 == 1  # a first block off warms the caches up and is not counted
            with players(on, inside):
                if on and prof:
                    prof.enable()
                t0 = time.process_time()
                for s in systems:
                    recompute.recompute_system(session, s, settings, sources.get(s.game_id),
                                               geometry=PairGeometryMemo())
                spent = time.process_time() - t0
                if on and prof:
                    prof.disable()
            if block:
                per_state[on].append(spent * 1000 / len(systems))
        session.rollback()
    engine.dispose()
    on_ms, off_ms = statistics.median(per_state[True]), statistics.median(per_state[False])
    share = inside.seconds * 1000 / (len(systems) * args.blocks)
    print(f"{len(systems)} systems, {args.blocks} blocks each: CPU ms per system on {on_ms:.2f}, off {off_ms:.2f}, "
          f"difference {on_ms - off_ms:.2f} ({(on_ms - off_ms) / off_ms:+.1%}); inside the check {share:.2f} ms per "
          f"system, {inside.pairs / (len(systems) * args.blocks):.2f} pairs asked per system")
    if prof and args.profile:
        prof.dump_stats(args.profile)
    return 0


if __name__ == "__main__":
    sys.exit(main())
