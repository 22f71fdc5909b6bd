"""The re-fit of an ISSIA sequence's trajectory after an edit: only the stretch the edit touches is fitted again,
so that an edit's answer stays as quick as a SoccerNet edit's.

An edit of a ball label or of a view's exclusion changes the labels of one frame. The re-fit
(:func:`refit_sequence`) reads from the database only what the stretch it touches needs, with light
column queries (no ORM graph of the sequence), none of which visits the whole sequence, so an edit
costs the same in a sequence of any length:

1. the motion pieces within :data:`~app.geometry.trajectory.REFIT_REACH` of the edit, from the piece
   documents stored on the :class:`~app.db.models.TrajectoryPoint` rows of a window of frames around it
   (:func:`_pieces_around`), from which :func:`app.geometry.trajectory.local_span` (the fast path) or
   :func:`~app.geometry.trajectory.refit_span` name the frames the re-fit reads and may change;
2. each camera's calibration (the first admitted view of each camera, as
   :func:`app.services.issia.trajectory.sequence_arrays`: :func:`sequence_columns` reads the first
   systems only), the labels of the frames it reads and the stored rows of those frames (the previous
   fit as a windowed :class:`~app.geometry.trajectory.TrajectoryFit`: positions, residuals, flags, each
   frame's own triangulation and kept labels);
3. :func:`app.geometry.trajectory.refit_local` re-fits the piece holding the edit, reading only that
   piece's frames (:func:`~app.geometry.trajectory.local_span`); when it does not apply (the edit near
   the stretch's ends, or the piece no longer explains its frames) the frames of ``refit_span`` are read
   and :func:`~app.geometry.trajectory.refit_window` segments the pieces around the edit again; both
   re-triangulate only the frames whose labels or kept labels changed;
4. only the columns that changed are written (executemany UPDATEs by primary key); the System objects
   are loaded (with what the recomputation reads) only for the edited frames and those whose kept labels
   changed, which the caller recomputes; the trajectory doubts of frames that only moved are replaced
   from their new rows (:func:`_refresh_trajectory_doubts`).

Every query selects the sequence's systems by a frame-index range (:func:`_in_sequence`). Nothing is
cached between requests: the per-frame triangulations reused are the stored rows, which every path that
changes their inputs rewrites (a label or exclusion edit re-triangulates its frame; a calibration edit
of the view that gives its camera to the sequence re-fits the whole sequence, see
``app.services.issia.sequences.refit_after_edit``), so several server processes never serve stale data. A window
with a frame never fitted makes the whole sequence fitted (:func:`app.services.issia.trajectory.fit_sequence`).

World: SoccerNet metres, z down; residuals px at 1920 width. Writes go to the session; the caller
commits (the edit's transaction).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any, cast

import numpy as np
import sqlalchemy as sa
from sqlalchemy.orm import Session

from app.core.config import Settings
from app.db.models import (
    JAC_COLUMNS,
    BallLabel,
    Calibration,
    CalibrationStatus,
    Doubt,
    Frame,
    ReviewDecision,
    System,
    SystemKind,
    TrajectoryPoint,
)
from app.db.types import json_loads, json_safe, utcnow
from app.geometry.camera import Camera
from app.geometry.trajectory import (
    REFIT_REACH,
    Piece,
    TrajectoryFit,
    local_span,
    refit_local,
    refit_span,
    refit_window,
)
from app.services.calibration.admission import is_admitted
from app.services.derivation.recompute import load_for_recompute
from app.services.issia.trajectory import (
    FPS,
    TRIANGULATION_FIELDS,
    Changed,
    DoubtFrame,
    fit_args,
    fit_sequence,
    flagged_label_doubts,
    piece_from_json,
    row_values,
)
from app.services.wording.doubt_words import doubt_message

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
    """The cameras of the ISSIA sequence ``game_id`` as :func:`~app.services.issia.trajectory.sequence_arrays`
    chooses them (camera order by view position then name; the camera of each camera's first admitted view
    in frame order), read without visiting the sequence in Python: the views of its first system with
    their calibrations (names, positions and widths: every system of a sequence has the same views, the
    importer makes one per camera for every frame), usually every camera's admitted view; for a camera
    whose first view is not admitted, the distinct calibrations of its views with the first frame of each
    (grouped by the database), the first admitted of them."""
    in_game = _in_sequence(game_id)
    start = sa.select(sa.func.min(System.frame_index)).where(*in_game).scalar_subquery()
    found = session.execute(
        sa.select(Frame.name, Frame.position, Frame.width, System.frame_index, *_ADMISSION_COLUMNS)
        .join(System, Frame.system_id == System.id).outerjoin(Calibration, Calibration.frame_id == Frame.id)
        .where(*in_game, System.frame_index == start).order_by(Frame.position, Frame.id)
    ).all()
    if not found:
        return SequenceColumns([], [], [], [])
    rows = sorted({(r[0], r[1], r[2]) for r in found}, key=lambda r: (r[1], r[0]))
    names = [r[0] for r in rows]
    col = {n: k for k, n in enumerate(names)}
    cameras: list[Camera | None] = [None] * len(names)
    first: list[int | None] = [None] * len(names)
    candidates = [(r[3], r[0], r[4:]) for r in found]
    missing = sorted({name for _, name, admission in candidates if not _admitted(admission, settings)})
    if missing:
        index = sa.func.min(System.frame_index)
        variants = (Calibration.status, sa.cast(Calibration.camera, sa.Text), sa.cast(Calibration.flags, sa.Text),
                    *_ADMISSION_COLUMNS[3:])
        candidates += [(i, name, (status, json_loads(cam) if cam else None, json_loads(flags) if flags else None, *jac))
                       for name, i, status, cam, flags, *jac in session.execute(
            sa.select(Frame.name, index, *variants).join(System, Frame.system_id == System.id)
            .join(Calibration, Calibration.frame_id == Frame.id)
            .where(System.game_id == game_id, System.kind == SystemKind.ISSIA, Frame.name.in_(missing),
                   Calibration.status == CalibrationStatus.CALIBRATED)
            .group_by(Frame.name, *variants))]
    for index, name, admission in sorted(candidates, key=lambda c: c[0]):
        k = col.get(name)
        if k is not None and cameras[k] is None and _admitted(admission, settings):
            cameras[k] = Camera.from_soccernet(admission[1])
            first[k] = index
    return SequenceColumns(names, [float(r[2]) for r in rows], cameras, first)


def _admitted(admission: tuple[Any, ...], settings: Settings) -> bool:
    """``is_admitted`` of a calibration given by its :data:`_ADMISSION_NAMES` columns (None: no calibration)."""
    if admission[0] is None:
        return False
    calibration = Calibration(**dict(zip(_ADMISSION_NAMES, admission, strict=True)))  # not added to the session
    return is_admitted(calibration, settings)


def _in_sequence(game_id: int) -> tuple[Any, ...]:
    """The WHERE terms of the systems of the ISSIA sequence ``game_id``, written so that a query adding a
    frame-index range reads only the systems of that range: ``game_id + 0`` is an expression, not a
    column, so SQLite (which plans without statistics, and would prefer the equality on the game's
    index, every system of the sequence, then filter the frame indices) uses the frame-index index;
    PostgreSQL plans from its statistics either way. Without it an edit's reads grow with the length of
    the sequence."""
    return (System.game_id + 0 == game_id, System.kind == SystemKind.ISSIA)


#: The calibration columns admission reads (``app.services.calibration.admission.is_admitted``).
_ADMISSION_NAMES = ("status", "camera", "flags", *JAC_COLUMNS.values())
_ADMISSION_COLUMNS = tuple(getattr(Calibration, n) for n in _ADMISSION_NAMES)
#: Frames on each side of an edit whose stored pieces :func:`_pieces_around` reads first (then twice as
#: many, and so on, until it has the pieces the re-fit needs).
_PIECES_WINDOW = 128


def _pieces_around(session: Session, game_id: int, first: int, last: int) -> tuple[Piece, ...]:
    """The stored pieces of the sequence around frames ``first..last``, in frame order: every piece within
    :data:`~app.geometry.trajectory.REFIT_REACH` pieces of those holding the edit (or, between pieces, of
    the two around it), or up to the sequence's ends. Read as the distinct piece documents of the stored
    rows of a window of frames around the edit (the pieces of a window's rows are every piece that
    overlaps it, whole), widened until it holds them. ``()`` when no stored row has a piece."""
    in_game = _in_sequence(game_id)
    width, bounds = _PIECES_WINDOW, None
    while True:
        lo, hi = first - width, last + width
        texts = session.scalars(
            sa.select(sa.cast(TrajectoryPoint.piece, sa.Text)).distinct()
            .join(System, TrajectoryPoint.system_id == System.id).where(*in_game, System.frame_index.between(lo, hi))
        ).all()
        seen: dict[tuple[int, int], Piece] = {}
        for text in texts:
            d = json_loads(text) if text is not None else None
            if d:
                seen[(d["first_frame"], d["last_frame"])] = piece_from_json(d)
        pieces = tuple(sorted(seen.values(), key=lambda p: p.first_frame))
        touched = any(p.last_frame >= first and p.first_frame <= last for p in pieces)
        need = REFIT_REACH + (0 if touched else 1)  # between pieces the nearest on each side is touched too
        enough_before = sum(p.last_frame < first for p in pieces) >= need
        enough_after = sum(p.first_frame > last for p in pieces) >= need
        if enough_before and enough_after:
            return pieces
        if bounds is None:
            bounds = (session.scalar(sa.select(sa.func.min(System.frame_index)).where(*in_game)),
                      session.scalar(sa.select(sa.func.max(System.frame_index)).where(*in_game)))
        low, high = bounds  # both None or neither: the least and greatest index of the same systems
        if low is None or high is None or ((enough_before or lo <= low) and (enough_after or hi >= high)):
            return pieces
        width *= 2


@dataclass
class _Window:
    """Frames ``first..last`` of a stored sequence: labels (points (n, K, 2), NaN for none or an excluded
    view), frame ids (n, K; -1 without the view), the stored rows by frame index and the system ids."""

    first: int
    points: np.ndarray
    frame_ids: np.ndarray
    stored: dict[int, dict[str, Any]]
    system_ids: dict[int, int]
    #: frame index -> the system's stored count of ``ball_off_consensus`` doubts, where it has some
    doubting: dict[int, int]

    @property
    def complete(self) -> bool:
        """Every system of the window has a stored trajectory point (else the sequence is fitted whole)."""
        return all(i in self.stored for i in range(self.first, self.first + len(self.points))
                   if (self.frame_ids[i - self.first] >= 0).any())


def _load_window(session: Session, game_id: int, first: int, last: int, columns: SequenceColumns) -> _Window:
    col = {n: k for k, n in enumerate(columns.names)}
    n, K = last - first + 1, len(columns.names)
    points = np.full((n, K, 2), np.nan)
    frame_ids = np.full((n, K), -1, dtype=int)
    in_window = (*_in_sequence(game_id), System.frame_index.between(first, last))
    for index, fid, name, box, point, excluded in session.execute(
        sa.select(System.frame_index, Frame.id, Frame.name, BallLabel.box, BallLabel.point, ReviewDecision.excluded)
        .join(System, Frame.system_id == System.id)
        .outerjoin(BallLabel, BallLabel.frame_id == Frame.id)
        .outerjoin(ReviewDecision, ReviewDecision.frame_id == Frame.id).where(*in_window)
    ):
        assert index is not None  # between() leaves out systems without a frame index
        r, k = index - first, col[name]
        frame_ids[r, k] = fid
        c = BallLabel.centre_of(box, point)
        if c is not None and not excluded:
            points[r, k] = c
    stored, system_ids, doubting = {}, {}, {}
    for row in session.execute(
        sa.select(System.frame_index, System.id, System.doubt_counts,
                  *(getattr(TrajectoryPoint, c) for c in _POINT_COLUMNS))
        .join(TrajectoryPoint, TrajectoryPoint.system_id == System.id).where(*in_window)
    ):
        index, sid, doubts, *values = row
        stored[index] = dict(zip(_POINT_COLUMNS, values, strict=True))
        system_ids[index] = sid
        if (doubts or {}).get("ball_off_consensus"):
            doubting[index] = int(doubts["ball_off_consensus"])
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


def refit_sequence(session: Session, game_id: int, first_frame: int, last_frame: int,
                   settings: Settings) -> list[Changed]:
    """Re-fit the stretch of the sequence ``game_id`` that an edit of frames ``first_frame..last_frame``
    touches (module docstring) and store the rows that changed; the whole sequence when a frame was
    never fitted (:func:`~app.services.issia.trajectory.fit_sequence`).

    Returns:
        The systems whose stored trajectory point changed (``labels`` when their kept labels or own
        triangulation changed), with their System objects loaded for the caller only when it must
        recompute them or judge their doubts again (kept labels changed, flagged labels, or a stored
        ``ball_off_consensus`` doubt); the others carry ``system=None``.
    """
    pieces = _pieces_around(session, game_id, first_frame, last_frame)
    if not pieces:
        return fit_sequence(session, game_id, settings)
    columns = sequence_columns(session, game_id, settings)
    fit, window, tried = None, None, False
    narrow = local_span(pieces, first_frame, last_frame)
    if narrow is not None:  # the edit inside one piece: its frames are enough unless the piece must be split
        tried = True
        window = _load_window(session, game_id, *narrow, columns)
        if not window.complete:
            return fit_sequence(session, game_id, settings)
        fit = refit_local(_previous_fit(window, pieces), window.points, columns.cameras, columns.widths,
                          first_frame, last_frame, **fit_args(settings))
    if fit is None:
        window = _load_window(session, game_id, *refit_span(pieces, first_frame, last_frame), columns)
        if not window.complete:
            return fit_sequence(session, game_id, settings)
        fit = refit_window(_previous_fit(window, pieces), window.points, columns.cameras, columns.widths,
                           first_frame, last_frame, fast_path=not tried, **fit_args(settings))
    assert window is not None  # whichever fit ran loaded its window
    return _store_rows(session, window, fit, (first_frame, last_frame), settings)


#: What ``recompute_system`` and ``update_doubts`` read of a system, loaded in a few queries instead of
#: one lazy load per view and relation.
def _store_rows(session: Session, window: _Window, fit: TrajectoryFit, edited: tuple[int, int],
                settings: Settings) -> list[Changed]:
    """Write the columns of the rows of ``fit`` whose values differ from the stored ones (executemany
    UPDATEs by primary key); load the systems of the ``edited`` frames and of the rows whose kept labels
    changed (``recompute.load_for_recompute``: the caller recomputes them); replace the trajectory doubts of the
    others that have flagged labels (:func:`_refresh_trajectory_doubts`: their labels, and so every other
    doubt, are unchanged, only their place on the trajectory moved)."""
    updates, changed = _changed_rows(window, fit)
    _write_rows(session, updates)
    ids = window.system_ids
    edits = {i for i in ids if edited[0] <= i <= edited[1]}
    # moved, labels unchanged, its stored trajectory doubts one per flagged label: those doubts alone change
    light = {i for i, labels, doubts, values in changed if doubts and not labels and i not in edits
             and window.doubting.get(i, 0) == len(values["flagged"])}
    wanted = [ids[i] for i, labels, doubts, _ in changed if (labels or doubts) and i not in edits | light]
    systems = load_for_recompute(session, wanted + [ids[i] for i in sorted(edits)],
                                 predictions=settings.max_predictions_per_frame)
    _refresh_trajectory_doubts(session, [(ids[i], i, values) for i, _, _, values in changed if i in light])
    return [Changed(systems.get(ids[i]), labels, ids[i]) for i, labels, _, _ in changed]


def _changed_rows(window: _Window, fit: TrajectoryFit
                  ) -> tuple[list[dict[str, Any]], list[tuple[int, bool, bool, dict[str, Any]]]]:
    """The UPDATE parameters of the rows of ``fit`` that differ from the stored ones (changed columns only,
    with ``system_id`` and ``computed_at``) and, per such frame, (frame index, its kept labels changed,
    it has flagged labels or a stored ``ball_off_consensus`` doubt, its new column values)."""
    updates, changed = [], []
    now = utcnow()
    frames = [i for i in fit.frames if i in window.stored]
    rows = row_values(fit, frames, window.frame_ids[np.asarray(frames, int) - window.first]) if frames else {}
    for i in frames:
        old = window.stored[i]
        values = rows[i]
        new = {k: v for k, v in values.items() if old[k] != v}
        if not new:
            continue
        labels = any(k in new for k in TRIANGULATION_FIELDS)
        updates.append({"system_id": window.system_ids[i], **new, "computed_at": now})
        changed.append((i, labels, bool(values["flagged"]) or bool(window.doubting.get(i)), values))
    return updates, changed


def _refresh_trajectory_doubts(session: Session, rows: list[tuple[int, int, dict[str, Any]]]) -> None:
    """Replace the stored ``ball_off_consensus`` doubts of systems whose trajectory point moved but whose
    kept and flagged labels did not (``(system id, frame index, new point values)``) by
    :func:`~app.services.issia.trajectory.flagged_label_doubts` of the new values: what
    ``update_doubts`` would store for them (the other doubts, the counts and their order are unchanged:
    the new rows come last, as ``merge_doubts`` puts them), without loading the systems."""
    if not rows:
        return
    sids = [sid for sid, _, _ in rows]
    flagged = {fid for _, _, v in rows for fid in v["flagged"] or []}
    views: dict[int, dict[int, DoubtFrame]] = {sid: {} for sid in sids}
    for fid, sid, name, width, height, camera in session.execute(
        sa.select(Frame.id, Frame.system_id, Frame.name, Frame.width, Frame.height, Calibration.camera)
        .outerjoin(Calibration, Calibration.frame_id == Frame.id).where(Frame.system_id.in_(sids))
    ):
        cam = Camera.from_soccernet(camera) if fid in flagged and camera is not None else None
        views[sid][fid] = DoubtFrame(name, width, height, cam)
    table = Doubt.__table__
    assert isinstance(table, sa.Table)  # a mapped class's own table
    stale = session.execute(sa.select(table.c.id, table.c.system_id).where(
        table.c.system_id.in_(sids), table.c.kind == "ball_off_consensus")).all()
    found = [(sid, d) for sid, index, values in rows for d in flagged_label_doubts(index, values, views[sid])]
    if stale:
        session.execute(sa.delete(table).where(table.c.id.in_([i for i, _ in stale])))
    if found:
        session.execute(sa.insert(table), [
            {"system_id": sid, "frame_id": d.view_id, "kind": d.kind, "accuses_label": d.accuses_label,
             "message": doubt_message(d, {d.view_id: views[sid][cast(int, d.view_id)].name}),  # a view of views[sid]
             "evidence": json_safe({**d.evidence, "code": d.code}),
             "suggestion": json_safe(d.suggestion) if d.suggestion else None} for sid, d in found])
    for doubt_id, _sid in stale:  # objects already in the session: gone, and their systems' lists reloaded
        obj = session.identity_map.get(session.identity_key(Doubt, doubt_id))
        if obj is not None:
            session.expunge(obj)
    for sid in sids:
        system = session.identity_map.get(session.identity_key(System, sid))
        if system is not None:
            session.expire(system, ["doubts"])


def _write_rows(session: Session, updates: list[dict[str, Any]]) -> None:
    """One executemany UPDATE (by primary key) per set of changed columns; objects already in the session
    are expired so that they read the new values."""
    table = TrajectoryPoint.__table__
    assert isinstance(table, sa.Table)  # a mapped class's own table
    for keys in {tuple(u) for u in updates}:
        stmt = sa.update(table).where(table.c.system_id == sa.bindparam("key_system_id")).values(
            {k: sa.bindparam(k) for k in keys if k != "system_id"})
        session.execute(stmt, [{**u, "key_system_id": u["system_id"]} for u in updates if tuple(u) == keys])
    for u in updates:
        tp = session.identity_map.get(session.identity_key(TrajectoryPoint, u["system_id"]))
        if tp is not None:
            session.expire(tp)


__all__ = ["SequenceColumns", "sequence_columns", "refit_sequence"]
