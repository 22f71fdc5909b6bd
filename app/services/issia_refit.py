"""The re-fit of an ISSIA sequence's trajectory after an edit (issue 9: "edits re-fit the affected
stretch within the edit round-trip targets").

An edit of a ball label or of a view's exclusion changes the labels of one frame. The re-fit
(:func:`refit_sequence`) reads from the database only what the stretch it touches needs, with light
column queries (no ORM graph of the whole sequence):

1. the motion pieces stored on the sequence's :class:`~app.db.models.TrajectoryPoint` rows (one small
   JSON per frame), from which :func:`app.geometry.trajectory.local_span` (the fast path) or
   :func:`~app.geometry.trajectory.refit_span` name the frames the re-fit reads and may change;
2. the labels of the frames it reads, the stored rows of those frames (the previous fit as a windowed
   :class:`~app.geometry.trajectory.TrajectoryFit`: positions, residuals, flags, each frame's own
   triangulation and kept labels), and each camera's calibration (the first admitted view of each
   camera, as :func:`app.services.issia_trajectory.sequence_arrays`; the query stops there);
3. :func:`app.geometry.trajectory.refit_local` re-fits the piece holding the edit, reading only that
   piece's frames (:func:`~app.geometry.trajectory.local_span`); when it does not apply (the edit near a
   break, or the piece no longer explains its frames) the frames of ``refit_span`` are read and
   :func:`~app.geometry.trajectory.refit_window` segments the pieces around the edit again; both
   re-triangulate only the frames whose labels or kept labels changed;
4. only the columns that changed are written (executemany UPDATEs by primary key), and the System
   objects are loaded (with what the recomputation reads) only for the edited frames and those the
   caller must recompute or judge again.

Nothing is cached between requests: the per-frame triangulations reused are the stored rows, which
every path that changes their inputs rewrites (a label or exclusion edit re-triangulates its frame; a
calibration edit of the view that gives its camera to the sequence re-fits the whole sequence, see
``app.services.issia.refit_after_edit``). A sequence with a frame never fitted is fitted whole
(:func:`app.services.issia_trajectory.fit_sequence`).

World: SoccerNet metres, z down; residuals px at 1920 width. Writes go to the session; the caller
commits (the edit's transaction).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
import sqlalchemy as sa
from sqlalchemy.orm import Session, joinedload, selectinload

from app.core.config import Settings
from app.db.models import (
    BallLabel, Calibration, Frame, ReviewDecision, System, SystemKind, TrajectoryPoint, Triangulation,
)
from app.db.types import utcnow
from app.geometry.camera import Camera
from app.geometry.trajectory import Piece, TrajectoryFit, local_span, refit_local, refit_span, refit_window
from app.services.issia_trajectory import (
    FPS, TRIANGULATION_FIELDS, Changed, fit_args, fit_sequence, piece_from_json, row_values,
)

_POINT_COLUMNS = ("ball3d", "ball3d_smoothed", "source", "piece", "cam_list", "residuals_px", "flagged")


@dataclass
class SequenceColumns:
    """The cameras of a stored sequence: view names in camera order, each camera's image width (px), the
    camera of its first admitted view (None if none) and that view's frame index (None if none)."""

    names: list[str]
    widths: list[float]
    cameras: list[Camera | None]
    first_admitted: list[int | None]


def sequence_columns(session: Session, game_id: int, settings: Settings) -> SequenceColumns:
    """The cameras of the ISSIA sequence ``game_id`` as :func:`~app.services.issia_trajectory.sequence_arrays`
    chooses them (camera order by view position then name; the camera of each camera's first admitted view
    in frame order), read with a name query and a calibration query streamed in frame order that stops
    as soon as every camera has its admitted view."""
    from app.services.calibrating import is_admitted

    rows = session.execute(
        sa.select(Frame.name, sa.func.min(Frame.position), sa.func.max(Frame.width))
        .join(System, Frame.system_id == System.id)
        .where(System.game_id == game_id, System.kind == SystemKind.ISSIA).group_by(Frame.name)
    ).all()
    rows.sort(key=lambda r: (r[1], r[0]))
    names = [r[0] for r in rows]
    col = {n: k for k, n in enumerate(names)}
    cameras: list[Camera | None] = [None] * len(names)
    first: list[int | None] = [None] * len(names)
    missing = len(names)
    result = session.execute(
        sa.select(Frame.name, System.frame_index, Calibration)
        .join(System, Frame.system_id == System.id).join(Calibration, Calibration.frame_id == Frame.id)
        .where(System.game_id == game_id, System.kind == SystemKind.ISSIA)
        .order_by(System.frame_index, Frame.position, Frame.id)
        .execution_options(yield_per=4 * max(len(names), 1))
    )
    try:
        for name, index, cal in result:
            k = col[name]
            if cameras[k] is None and is_admitted(cal, settings):
                cameras[k] = Camera.from_soccernet(cal.camera)  # type: ignore[arg-type]
                first[k] = index
                missing -= 1
                if not missing:
                    break
    finally:
        result.close()
    return SequenceColumns(names, [float(r[2]) for r in rows], cameras, first)


def _stored_pieces(session: Session, game_id: int) -> tuple[tuple[Piece, ...], dict[int, int], bool]:
    """(pieces in frame order, frame index -> system id, every system has a stored point)."""
    rows = session.execute(
        sa.select(System.id, System.frame_index, TrajectoryPoint.system_id, TrajectoryPoint.piece)
        .outerjoin(TrajectoryPoint, TrajectoryPoint.system_id == System.id)
        .where(System.game_id == game_id, System.kind == SystemKind.ISSIA, System.frame_index.is_not(None))
    ).all()
    seen: dict[tuple[int, int], Piece] = {}
    for _, _, _, d in rows:
        if d and (d["first_frame"], d["last_frame"]) not in seen:
            seen[(d["first_frame"], d["last_frame"])] = piece_from_json(d)
    pieces = tuple(sorted(seen.values(), key=lambda p: p.first_frame))
    return pieces, {int(i): sid for sid, i, _, _ in rows}, all(tp is not None for _, _, tp, _ in rows)


@dataclass
class _Window:
    """Frames ``first..last`` of a stored sequence: labels (points (n, K, 2), NaN for none or an excluded
    view), frame ids (n, K; -1 without the view), the stored rows by frame index and the system ids."""

    first: int
    points: np.ndarray
    frame_ids: np.ndarray
    stored: dict[int, dict[str, Any]]
    system_ids: dict[int, int]
    doubting: set[int]


def _load_window(session: Session, game_id: int, first: int, last: int, columns: SequenceColumns) -> _Window:
    col = {n: k for k, n in enumerate(columns.names)}
    n, K = last - first + 1, len(columns.names)
    points = np.full((n, K, 2), np.nan)
    frame_ids = np.full((n, K), -1, dtype=int)
    in_window = (System.game_id == game_id, System.kind == SystemKind.ISSIA, System.frame_index.between(first, last))
    for index, fid, name, box, point, excluded in session.execute(
        sa.select(System.frame_index, Frame.id, Frame.name, BallLabel.box, BallLabel.point, ReviewDecision.excluded)
        .join(System, Frame.system_id == System.id)
        .outerjoin(BallLabel, BallLabel.frame_id == Frame.id)
        .outerjoin(ReviewDecision, ReviewDecision.frame_id == Frame.id).where(*in_window)
    ):
        r, k = index - first, col[name]
        frame_ids[r, k] = fid
        c = BallLabel.centre_of(box, point)
        if c is not None and not excluded:
            points[r, k] = c
    stored, system_ids, doubting = {}, {}, set()
    for row in session.execute(
        sa.select(System.frame_index, System.id, System.doubt_counts, *(getattr(TrajectoryPoint, c) for c in _POINT_COLUMNS))
        .join(TrajectoryPoint, TrajectoryPoint.system_id == System.id).where(*in_window)
    ):
        index, sid, doubts, *values = row
        stored[index] = dict(zip(_POINT_COLUMNS, values))
        system_ids[index] = sid
        if (doubts or {}).get("ball_off_consensus"):
            doubting.add(index)
    return _Window(first, points, frame_ids, stored, system_ids, doubting)


def _previous_fit(window: _Window, pieces: tuple[Piece, ...]) -> TrajectoryFit:
    """The stored rows of the window as the windowed fit they were stored from (store_fit's inverse for
    what the re-fit reads: positions, residuals, flags, the frame's own triangulation, kept labels)."""
    n, K = window.frame_ids.shape
    positions, ball = np.full((n, 3), np.nan), np.full((n, 3), np.nan)
    residuals, outliers = np.full((n, K), np.nan), np.zeros((n, K), bool)
    sources: list[str | None] = [None] * n
    cam_lists: list[tuple[int, ...]] = [()] * n
    for index, v in window.stored.items():
        r = index - window.first
        col = {int(fid): k for k, fid in enumerate(window.frame_ids[r]) if fid >= 0}
        if v["ball3d_smoothed"] is not None:
            positions[r] = v["ball3d_smoothed"]
        if v["ball3d"] is not None:
            ball[r] = v["ball3d"]
        sources[r] = v["source"]
        for fid, px in (v["residuals_px"] or {}).items():
            if int(fid) in col:
                residuals[r, col[int(fid)]] = px
        for fid in v["flagged"] or []:
            if fid in col:
                outliers[r, col[fid]] = True
        cam_lists[r] = tuple(col[fid] for fid in v["cam_list"] or [] if fid in col)
    return TrajectoryFit(FPS, pieces, positions, tuple(sources), residuals, outliers, ball, tuple(cam_lists),
                         first_frame=window.first)


def refit_sequence(session: Session, game_id: int, first_frame: int, last_frame: int, settings: Settings) -> list[Changed]:
    """Re-fit the stretch of the sequence ``game_id`` that an edit of frames ``first_frame..last_frame``
    touches (module docstring) and store the rows that changed; the whole sequence when a frame was
    never fitted (:func:`~app.services.issia_trajectory.fit_sequence`).

    Returns:
        The systems whose stored trajectory point changed (``labels`` when their kept labels or own
        triangulation changed), with their System objects loaded for the caller only when it must
        recompute them or judge their doubts again (kept labels changed, flagged labels, or a stored
        ``ball_off_consensus`` doubt); the others carry ``system=None``.
    """
    pieces, _, complete = _stored_pieces(session, game_id)
    if not pieces or not complete:
        return fit_sequence(session, game_id, settings)
    columns = sequence_columns(session, game_id, settings)
    fit, window = None, None
    narrow = local_span(pieces, first_frame, last_frame)
    if narrow is not None:  # the edit inside one piece: its frames are enough unless the piece must be split
        window = _load_window(session, game_id, *narrow, columns)
        fit = refit_local(_previous_fit(window, pieces), window.points, columns.cameras, columns.widths,
                          first_frame, last_frame, **fit_args(settings))
    if fit is None:
        window = _load_window(session, game_id, *refit_span(pieces, first_frame, last_frame), columns)
        fit = refit_window(_previous_fit(window, pieces), window.points, columns.cameras, columns.widths,
                           first_frame, last_frame, **fit_args(settings))
    return _store_rows(session, window, fit, (first_frame, last_frame))


#: What ``recompute_system`` and ``update_doubts`` read of a system, loaded in a few queries instead of
#: one lazy load per view and relation.
RECOMPUTE_LOADS = (
    selectinload(System.frames).options(joinedload(Frame.calibration), joinedload(Frame.ball_label),
                                        joinedload(Frame.review), joinedload(Frame.reprojection),
                                        joinedload(Frame.optimised_box), joinedload(Frame.field_lines)),
    joinedload(System.triangulation).selectinload(Triangulation.pairs),
    selectinload(System.doubts), joinedload(System.trajectory_point), joinedload(System.review),
)


def _store_rows(session: Session, window: _Window, fit: TrajectoryFit, edited: tuple[int, int]) -> list[Changed]:
    """Write the columns of the rows of ``fit`` whose values differ from the stored ones (executemany
    UPDATEs by primary key); load the systems of the ``edited`` frames and of the changed rows the caller
    must recompute or judge again (:data:`RECOMPUTE_LOADS`)."""
    updates, changed = [], []
    now = utcnow()
    for i in fit.frames:
        old = window.stored.get(i)
        if old is None:
            continue
        values = row_values(fit, i, window.frame_ids[i - window.first])
        new = {k: v for k, v in values.items() if old[k] != v}
        if not new:
            continue
        labels = any(k in new for k in TRIANGULATION_FIELDS)
        updates.append({"system_id": window.system_ids[i], **new, "computed_at": now})
        changed.append((i, labels, bool(values["flagged"]) or i in window.doubting))
    for keys in {tuple(u) for u in updates}:  # one executemany per set of changed columns
        session.execute(sa.update(TrajectoryPoint), [u for u in updates if tuple(u) == keys])
    for u in updates:  # objects already in the session see the new values on next access
        tp = session.identity_map.get(session.identity_key(TrajectoryPoint, u["system_id"]))  # type: ignore[arg-type]
        if tp is not None:
            session.expire(tp)
    wanted = [window.system_ids[i] for i, labels, doubts in changed if labels or doubts]
    wanted += [sid for i, sid in window.system_ids.items() if edited[0] <= i <= edited[1]]
    systems = {s.id: s for s in session.scalars(
        sa.select(System).where(System.id.in_(wanted)).options(*RECOMPUTE_LOADS)).unique()}
    return [Changed(systems.get(window.system_ids[i]), labels) for i, labels, _ in changed]


__all__ = ["SequenceColumns", "sequence_columns", "refit_sequence"]
