"""What each shortcut left on the edit path is worth: a paired comparison, on and off in one process.

Each mechanism is switched off by replacing it with the plain computation it stands for, and one annotator's ball
edits (the service's ``update_ball_label`` and the system page its answer draws, as a served edit runs them, minus
HTTP) are timed in blocks that alternate on and off, so that a slow phase of the machine falls on both. The figure is
the median CPU time (``time.process_time``) per edit of each state and their difference; a mechanism stays only when
that difference is at least a tenth of a served ball edit's server CPU (``benchmarks/request_cpu.py``).

* ``cameras``: the process's camera objects and pair memo (``app.services.derivation.cameras``); off: every edit
  builds its cameras and pairs anew.
* ``players``: the process's memo of how far each pair's cameras disagree on their players (``cameras.PAIR_PLAYERS``,
  asked by the ball judged by evidence); off: every edit compares its pairs anew.
* ``only-changed``: ``rows.put_values`` leaves a value equal to the stored one unset, so the flush writes only what
  changed; off: every derived value is set, every derived row written.
* ``answer-from-edit``: the page an edit answers is drawn from the objects it committed
  (``system_page._loaded_system``); off: the page loads the system again.
* ``lean-players``: the views' person boxes read as plain rows and each view's foot points made once per edit
  (``loading.load_view_players``, ``calibration.players.frame_feet``); off: the boxes loaded as ORM objects
  (``Frame.players``) and the foot points made on every ask.
* ``jacobian``: the projection's Jacobian (``spread.projection_jacobian``, sixteen an edit of a 4-view system under the
  rule by evidence) from the offsets made once per step and ``Camera.project_in_front``; off: the six points stacked
  one by one and projected by ``Camera.project`` (the same numbers, ``tests/geometry/test_spread.py``).

Usage (from the checkout)::

    .venv/bin/python benchmarks/edit_mechanisms.py --blocks 8 --edits 10 [--only lean-players ...]
"""
from __future__ import annotations

import argparse
import contextlib
import statistics
import sys
import time
from collections.abc import Callable, Iterator
from typing import Any

sys.path.insert(0, ".")
import numpy as np
import sqlalchemy as sa
from sqlalchemy import select
from sqlalchemy.orm.attributes import set_committed_value

from app.db.models import PlayerBox
from app.geometry import evidence, spread
from app.geometry.camera import Camera
from app.geometry.triangulation import PairGeometryMemo
from app.services.calibration.players import feet_of, frame_players
from app.services.curation import editing, system_page, writing
from app.services.derivation import ball, cameras, doubts, loading, recompute, rows
from benchmarks.load import demo_ball_edit


@contextlib.contextmanager
def cameras_off() -> Iterator[None]:
    """Every camera built from its JSON and every pair computed anew (a new memo per edit)."""
    real = recompute.stored_camera
    recompute.stored_camera = lambda camera_json: Camera.from_soccernet(camera_json)  # type: ignore[assignment]  # patched for the run
    real_memo = cameras.PAIR_GEOMETRY
    try:
        yield
    finally:
        recompute.stored_camera = real  # type: ignore[assignment]  # the patch undone
        cameras.PAIR_GEOMETRY = real_memo


def _fresh_memo() -> None:
    cameras.PAIR_GEOMETRY = PairGeometryMemo(max_entries=cameras.PAIRS)


@contextlib.contextmanager
def players_off() -> Iterator[None]:
    """Every pair's players compared anew (a new memo per edit)."""
    real = cameras.PAIR_PLAYERS
    try:
        yield
    finally:
        cameras.PAIR_PLAYERS = real


def _fresh_players() -> None:
    cameras.PAIR_PLAYERS = cameras.PairPlayersMemo(max_entries=cameras.PAIRS)


@contextlib.contextmanager
def only_changed_off() -> Iterator[None]:
    """Every derived value set, equal or not."""
    def put_all(row: Any, values: dict[str, Any]) -> Any:
        for key, value in values.items():
            if value is None and not rows.sa.inspect(type(row)).columns[key].nullable:
                continue
            setattr(row, key, value)
        return row
    saved = rows.put_values, recompute.put_values, editing.put_values
    rows.put_values = recompute.put_values = editing.put_values = put_all  # type: ignore[assignment]  # patched for the run
    try:
        yield
    finally:
        rows.put_values, recompute.put_values, editing.put_values = saved  # type: ignore[assignment]  # the patch undone


@contextlib.contextmanager
def answer_from_edit_off() -> Iterator[None]:
    """The answer's page loaded again."""
    real = system_page._loaded_system
    system_page._loaded_system = lambda session, system_id: None  # type: ignore[assignment]  # patched for the run
    try:
        yield
    finally:
        system_page._loaded_system = real  # type: ignore[assignment]  # the patch undone


def _orm_view_players(session: Any, frames: Any) -> None:
    """The person boxes as ORM objects handed to ``Frame.players`` (what ``load_view_players`` did before)."""
    wanted = [f for f in frames if sa.inspect(f).persistent and "players" in sa.inspect(f).unloaded]
    if not wanted:
        return
    found: dict[int, list[PlayerBox]] = {f.id: [] for f in wanted}
    for p in session.scalars(select(PlayerBox).where(PlayerBox.frame_id.in_(found)).order_by(PlayerBox.id)):
        found[p.frame_id].append(p)
    for f in wanted:
        if "players" in sa.inspect(f).unloaded:
            set_committed_value(f, "players", found[f.id])


@contextlib.contextmanager
def lean_players_off() -> Iterator[None]:
    """The boxes as ORM objects, the foot points made on every ask."""
    saved = loading.load_view_players, writing.load_view_players, doubts.load_view_players, ball.frame_feet
    loading.load_view_players = writing.load_view_players = doubts.load_view_players = _orm_view_players  # type: ignore[assignment]  # patched for the run
    ball.frame_feet = lambda f: feet_of(frame_players(f), f.width, f.height)  # type: ignore[assignment]  # patched for the run
    try:
        yield
    finally:
        loading.load_view_players, writing.load_view_players, doubts.load_view_players, ball.frame_feet = saved  # type: ignore[assignment]  # the patch undone


def _stacked_jacobian(o: Any, point_world: Any, step_m: float = 1e-3) -> Any:
    """``spread.projection_jacobian`` as first written: each offset point made alone, the six stacked and projected
    by ``Camera.project``."""
    X = np.asarray(point_world, float).reshape(3)
    k = spread.REFERENCE_WIDTH_PX / o.image_width
    uv, front = o.camera.project(np.stack([X + d for d in np.vstack([np.eye(3), -np.eye(3)]) * step_m]))
    if not bool(np.all(front)):
        return None
    return np.asarray((uv[:3] - uv[3:]).T * k / (2 * step_m), float)


@contextlib.contextmanager
def jacobian_off() -> Iterator[None]:
    """The Jacobian's points stacked one by one and projected by ``Camera.project``."""
    saved = spread.projection_jacobian, evidence.projection_jacobian
    spread.projection_jacobian = evidence.projection_jacobian = _stacked_jacobian  # type: ignore[assignment]  # patched for the run
    try:
        yield
    finally:
        spread.projection_jacobian, evidence.projection_jacobian = saved  # type: ignore[assignment]  # the patch undone


MECHANISMS: dict[str, Callable[[], contextlib.AbstractContextManager[None]]] = {
    "cameras": cameras_off, "players": players_off, "only-changed": only_changed_off,
    "answer-from-edit": answer_from_edit_off, "lean-players": lean_players_off, "jacobian": jacobian_off}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--blocks", type=int, default=8, help="blocks per state and mechanism")
    ap.add_argument("--edits", type=int, default=10, help="edits per block")
    ap.add_argument("--only", nargs="*", choices=list(MECHANISMS), help="these mechanisms only (default: every one)")
    args = ap.parse_args()
    with demo_ball_edit() as (settings, factory, fid, sid, box):
        step = [0]

        def edit(off: bool) -> None:
            step[0] += 1
            dx = 2.0 + (step[0] % 2)
            if off and current == "cameras":
                _fresh_memo()
            if off and current == "players":
                _fresh_players()
            with factory() as s:
                editing.update_ball_label(s, fid, box=[box[0] + dx, box[1], box[2] + dx, box[3]], settings=settings)
                system_page.system_page(s, sid)

        for current, switch in MECHANISMS.items():
            if args.only and current not in args.only:
                continue
            per: dict[bool, list[float]] = {False: [], True: []}
            for _ in range(2):
                edit(False)  # warm
            for block in range(2 * args.blocks):
                off = block % 2 == 1
                with switch() if off else contextlib.nullcontext():
                    t0 = time.process_time()
                    for _ in range(args.edits):
                        edit(off)
                    per[off].append((time.process_time() - t0) * 1000 / args.edits)
            on_ms, off_ms = statistics.median(per[False]), statistics.median(per[True])
            print(f"{current:18s} on {on_ms:6.2f} ms/edit  off {off_ms:6.2f} ms/edit  gain {off_ms - on_ms:+6.2f} ms")


if __name__ == "__main__":
    main()
