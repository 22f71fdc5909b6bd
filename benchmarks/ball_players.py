"""What the ball's players check costs a recomputation: the systems of a database recomputed with the check on and
off in alternating blocks in one process (``recompute.recompute_system`` as an import runs it, a pair memo of its own
per system), CPU time (``time.process_time``) per system, the check's own share measured inside it on the same runs.

Off: ``ball.players_disagree`` answers "no disagreement" for every pair (what the ball was before the rule by
evidence read the players); the balls may then differ, which the timing ignores (nothing is written).

``--pairs``: every pair of calibrated views of every system (and each view against the other's mirrored camera, as
the mirror evidence asks), the compiled comparison (``pair_players_disagreement``) against the numpy functions it
replaced (:func:`numpy_pair_disagreement`): how many figures are equal to the bit, the largest relative difference,
whether any pair falls on the other side of ``LINES_CONTRADICTED_SIGMA``, and the CPU per pair of each in
alternating blocks in one process.

Usage (a database made by ``benchmarks/scale.py --import-only --games N --db PATH``, or any imported set)::

    .venv/bin/python benchmarks/ball_players.py --db PATH [--systems 400] [--blocks 6] [--profile out.prof]
    .venv/bin/python benchmarks/ball_players.py --db PATH --pairs [--systems 100000] [--blocks 6]
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
import numpy as np  # noqa: E402  # after the checkout is on the path
import sqlalchemy as sa  # noqa: E402  # after the checkout is on the path

from app.core.config import Settings  # noqa: E402  # after the checkout is on the path
from app.db.models import CalibrationStatus, System  # noqa: E402  # after the checkout is on the path
from app.db.session import make_engine, make_session_factory  # noqa: E402  # after the checkout is on the path
from app.geometry.calibration.grass import PlayerKey, players_on_grass  # noqa: E402  # after the checkout is on the path
from app.geometry.calibration.players import (  # noqa: E402  # after the checkout is on the path
    LINES_CONTRADICTED_SIGMA,
    pair_players_disagreement,
    players_disagreement,
)
from app.geometry.camera import Camera  # noqa: E402  # after the checkout is on the path
from app.geometry.triangulation import PairGeometryMemo  # noqa: E402  # after the checkout is on the path
from app.services.calibration.players import feet_of, frame_players  # noqa: E402  # after the checkout is on the path
from app.services.derivation import ball, cameras, recompute  # noqa: E402  # after the checkout is on the path
from app.services.derivation.cameras import mirrored_camera, stored_camera  # noqa: E402  # after the checkout is on the path

Feet = dict[PlayerKey, np.ndarray]
Pair = tuple[Camera, Feet, tuple[int, int], Camera, Feet, tuple[int, int]]


def numpy_pair_disagreement(camera_a: Camera, feet_a: Feet, size_a: tuple[int, int], camera_b: Camera, feet_b: Feet,
                            size_b: tuple[int, int], min_players: int = 3) -> float | None:
    """``pair_players_disagreement`` as the numpy functions compute it (what the compiled kernel replaced, kept as
    its reference): each direction's ``players_on_grass`` of the other view and ``players_disagreement``, the
    larger."""
    shared = [k for k in feet_a if k in feet_b]
    if len(shared) < min_players:
        return None
    worst = None
    for cam_x, feet_x, size_x, cam_y, feet_y in ((camera_a, feet_a, size_a, camera_b, feet_b),
                                                 (camera_b, feet_b, size_b, camera_a, feet_a)):
        grass = players_on_grass([(cam_y, {k: feet_y[k] for k in shared})])
        got = players_disagreement(cam_x, {k: feet_x[k] for k in shared}, grass, size_x[0], size_x[1], min_players)
        if got is not None:
            worst = got if worst is None else max(worst, got)
    return worst


def every_pair(systems: list[System]) -> list[Pair]:
    """Every pair of calibrated views of each system sharing at least three players with foot points, and each such
    pair with its second camera mirrored (``cameras.mirrored_camera``, the mirror evidence's)."""
    out: list[Pair] = []
    for s in systems:
        views = []
        for f in s.frames:
            cal = f.calibration
            if cal is None or cal.status is not CalibrationStatus.CALIBRATED or cal.camera is None:
                continue
            try:
                cam = stored_camera(cal.camera)
            except ValueError:
                continue
            views.append((cam, feet_of(frame_players(f), f.width, f.height), (f.width, f.height)))
        for i, (ca, fa, size_a) in enumerate(views):
            for cb, fb, sb in views[i + 1:]:
                if sum(1 for k in fa if k in fb) >= 3:
                    out += [(ca, fa, size_a, cb, fb, sb), (ca, fa, size_a, mirrored_camera(cb), fb, sb)]
    return out


def compare_pairs(pairs: list[Pair], blocks: int) -> None:
    """The compiled comparison against :func:`numpy_pair_disagreement` on ``pairs``: equality, then CPU per pair in
    alternating blocks."""
    equal = none = flipped = 0
    worst_rel = 0.0
    for p in pairs:
        ref, got = numpy_pair_disagreement(*p), pair_players_disagreement(*p)
        if ref is None or got is None:
            none += 1
            if (ref is None) != (got is None):
                raise SystemExit(f"one figure None, the other not: {ref} {got}")
            continue
        if ref == got or (np.isnan(ref) and np.isnan(got)):
            equal += 1
            continue
        worst_rel = max(worst_rel, abs(ref - got) / abs(ref))
        flipped += (ref > LINES_CONTRADICTED_SIGMA) != (got > LINES_CONTRADICTED_SIGMA)
    beyond = sum(1 for p in pairs if (f := pair_players_disagreement(*p)) is not None and f > LINES_CONTRADICTED_SIGMA)
    print(f"{len(pairs)} pairs ({none} without a figure, {beyond} beyond {LINES_CONTRADICTED_SIGMA:g} sigma): "
          f"{equal} of {len(pairs) - none} figures equal to the bit, largest relative difference {worst_rel:.2e}, "
          f"{flipped} on the other side of the threshold")
    per: dict[str, list[float]] = {"numpy": [], "compiled": []}
    for block in range(2 * blocks + 2):
        name, fn = ("numpy", numpy_pair_disagreement) if block % 2 else ("compiled", pair_players_disagreement)
        t0 = time.process_time()
        for p in pairs:
            fn(*p)
        if block >= 2:  # the first of each warms up
            per[name].append((time.process_time() - t0) * 1000 / len(pairs))
    ms = {k: statistics.median(v) for k, v in per.items()}
    print(f"CPU ms per pair, {blocks} blocks each: numpy {ms['numpy']:.3f}, compiled {ms['compiled']:.3f} "
          f"({ms['numpy'] / ms['compiled']:.1f}x)")


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


@contextmanager
def kernel(numpy: bool) -> Iterator[None]:
    """The pair comparison as compiled (the code as it is) or as the numpy functions compute it
    (:func:`numpy_pair_disagreement`), for every memo of the run."""
    real = cameras.pair_players_disagreement
    if numpy:
        cameras.pair_players_disagreement = numpy_pair_disagreement  # type: ignore[assignment]  # switched for the run
    try:
        yield
    finally:
        cameras.pair_players_disagreement = real


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--db", required=True)
    parser.add_argument("--systems", type=int, default=400)
    parser.add_argument("--blocks", type=int, default=6, help="blocks of each state, alternating")
    parser.add_argument("--profile", help="write a cProfile of the 'on' blocks here")
    parser.add_argument("--pairs", action="store_true", help="the compiled pair comparison against numpy's")
    args = parser.parse_args(argv)
    settings = Settings(_env_file=None, database_url=f"sqlite:///{args.db}")
    engine = make_engine(settings.database_url)
    prof = cProfile.Profile() if args.profile else None
    with make_session_factory(engine)() as session:
        ids = list(session.scalars(sa.select(System.id).order_by(System.id).limit(args.systems)))
        systems = list(recompute.load_for_recompute(session, ids, predictions=settings.max_predictions_per_frame)
                       .values())
        if args.pairs:
            compare_pairs(every_pair(systems), args.blocks)
            session.rollback()
            engine.dispose()
            return 0
        sources = {gid: recompute.rig_centres(session, gid, settings)
                   for gid in {s.game_id for s in systems if recompute.uses_rig(s)}}
        states = ("off", "compiled", "numpy")
        per_state: dict[str, list[float]] = {k: [] for k in states}
        inside = {k: Inside() for k in states}
        for block in range(len(states) * (args.blocks + 1)):
            state = states[block % len(states)]  # the first round warms the caches up and is not counted
            with players(state != "off", inside[state]), kernel(state == "numpy"):
                if state == "compiled" and prof:
                    prof.enable()
                t0 = time.process_time()
                for s in systems:
                    recompute.recompute_system(session, s, settings, sources.get(s.game_id),
                                               geometry=PairGeometryMemo())
                spent = time.process_time() - t0
                if state == "compiled" and prof:
                    prof.disable()
            if block >= len(states):
                per_state[state].append(spent * 1000 / len(systems))
        session.rollback()
    engine.dispose()
    ms = {k: statistics.median(v) for k, v in per_state.items()}
    print(f"{len(systems)} systems, {args.blocks} blocks each, CPU ms per system (the check inside, per system):")
    for k in states:
        runs = len(systems) * (args.blocks + 1)
        print(f"  {k:8s} {ms[k]:7.2f}  ({ms[k] - ms['off']:+.2f} against off; inside the check "
              f"{inside[k].seconds * 1000 / runs:.2f}, {inside[k].pairs / runs:.2f} pairs asked)")
    if prof and args.profile:
        prof.dump_stats(args.profile)
    return 0


if __name__ == "__main__":
    sys.exit(main())
