"""The temporal 3D ball of an ISSIA sequence in the service: stored rows <-> the pure fit.

An ISSIA sequence is a game whose systems (kind ``issia``) are frame indices (``System.frame_index``)
and whose views are static cameras (``Frame.name`` "cam<k>"). This module

* gathers the sequence's current ball labels and admitted cameras into the arrays of
  :func:`app.geometry.trajectory.fit_trajectory` (:func:`sequence_arrays`);
* fits the whole sequence (:func:`fit_sequence`; after an edit only the stretch it touches is
  re-fitted, ``app.services.issia.refit``) and stores each frame's place on the trajectory
  (:class:`~app.db.models.TrajectoryPoint`: ``ball_3D``, ``ball_3D_smoothed`` and its source, the kept labels, the
  residuals, the flagged labels);
* gives the per-frame triangulation of an ISSIA system its semantics (:func:`consensus_observations`:
  labels the trajectory flags are left out, then the labels that agree on one ball are chosen, as
  :func:`app.geometry.trajectory.triangulate_frame`), used by ``app.services.derivation.recompute``;
* turns flagged labels into ``ball_off_consensus`` doubts naming the camera, with the residual, the
  fitted position and the fix (:func:`trajectory_doubts`, used by ``app.services.derivation.doubts``).

World: SoccerNet metres, z down. Residuals: px at 1920 width. Writes go to the session only; the
caller commits (the importer, or the edit's transaction).
"""
from __future__ import annotations

import bisect
from dataclasses import dataclass
from typing import Any, Sequence

import numpy as np
import sqlalchemy as sa
from sqlalchemy.orm import Session, selectinload

from app.core.config import Settings
from app.datasets.issia import FPS
from app.db import scope
from app.db.models import Frame, System, SystemKind, TrajectoryPoint
from app.db.types import json_safe, utcnow
from app.geometry.camera import Camera
from app.geometry.doubts import Doubt as JudgedDoubt
from app.geometry.pair_error import REFERENCE_WIDTH_PX
from app.geometry.trajectory import Piece, TrajectoryFit, fit_trajectory, triangulate_frame
from app.geometry.triangulation import BallObservation
from app.services.calibration.admission import is_admitted
from app.services.derivation.doubts import is_excluded


@dataclass
class SequenceArrays:
    """A stored sequence as the fit sees it.

    Attributes:
        systems: the ISSIA systems by frame index.
        camera_names: view names in camera order ("cam1".."cam6").
        points: (F, K, 2) current labels (px of each view), NaN without a label or for an excluded view;
            F = last frame index + 1.
        cameras: K cameras (the camera of the first admitted view of each camera), None if none.
        widths: K image widths, px.
        frame_ids: (F, K) frame ids, -1 where the frame has no such view.
    """

    systems: dict[int, System]
    camera_names: list[str]
    points: np.ndarray
    cameras: list[Camera | None]
    widths: list[float]
    frame_ids: np.ndarray


def load_sequence(session: Session, game_id: int) -> list[System]:
    """The ISSIA systems of a game with their views, labels, calibrations and trajectory points."""
    return list(session.scalars(
        sa.select(System).where(System.game_id == game_id, System.kind == SystemKind.ISSIA)
        .order_by(System.frame_index)
        .options(selectinload(System.frames).selectinload(Frame.calibration),
                 selectinload(System.frames).selectinload(Frame.ball_label),
                 selectinload(System.frames).selectinload(Frame.review),
                 selectinload(System.trajectory_point))
    ))


def sequence_arrays(systems: Sequence[System], settings: Settings) -> SequenceArrays:
    """Current labels and admitted cameras of a stored sequence (see :class:`SequenceArrays`)."""
    by_index = {s.frame_index: s for s in systems if s.frame_index is not None}
    names: dict[str, int] = {}
    for s in by_index.values():
        for f in s.frames:
            names.setdefault(f.name, f.position)
    camera_names = sorted(names, key=lambda n: (names[n], n))
    col = {n: k for k, n in enumerate(camera_names)}
    F, K = (max(by_index) + 1 if by_index else 0), len(camera_names)
    points = np.full((F, K, 2), np.nan)
    frame_ids = np.full((F, K), -1, dtype=int)
    cameras: list[Camera | None] = [None] * K
    widths = [1920.0] * K
    for i, s in by_index.items():
        for f in s.frames:
            k = col[f.name]
            frame_ids[i, k] = f.id
            widths[k] = float(f.width)
            if cameras[k] is None and is_admitted(f.calibration, settings):
                cameras[k] = Camera.from_soccernet(f.calibration.camera)  # type: ignore[union-attr,arg-type]  # admitted: a calibration with a camera
            c = f.ball_label.centre if f.ball_label is not None else None
            if c is not None and not is_excluded(f):
                points[i, k] = c
    return SequenceArrays(by_index, camera_names, points, cameras, widths, frame_ids)


def piece_json(p: Piece) -> dict[str, Any]:
    """The stored form of a :class:`Piece` (``TrajectoryPoint.piece``): kind, frames, params, cost and the
    other model's params (``alternative``, where an edit's re-fit starts that model; null if none)."""
    return {"kind": p.kind, "first_frame": int(p.first_frame), "last_frame": int(p.last_frame),
            "params": [float(v) for v in p.params], "cost": float(p.cost),
            "alternative": [float(v) for v in p.alternative] if p.alternative is not None else None}


def piece_from_json(d: dict[str, Any]) -> Piece:
    """:func:`piece_json`'s inverse (a piece stored before ``alternative`` existed has none)."""
    alt = d.get("alternative")
    return Piece(d["kind"], int(d["first_frame"]), int(d["last_frame"]), np.asarray(d["params"], float),
                 float(d["cost"]), np.asarray(alt, float) if alt is not None else None)


#: The fields of a :class:`TrajectoryPoint` the system's triangulation depends on (the labels it keeps).
TRIANGULATION_FIELDS = ("ball3d", "cam_list", "flagged")


@dataclass
class Changed:
    """A system whose stored trajectory point changed; ``labels`` when the labels it keeps (and so its
    triangulation) changed, not only its place on the trajectory. ``system`` is None when the re-fit
    of an edit did not load it (``app.services.issia.refit``: neither recomputed nor judged again)."""

    system: System | None
    labels: bool
    #: the system's id (also when ``system`` was not loaded)
    system_id: int | None = None


def row_values(fit: TrajectoryFit, frames: Sequence[int], ids: np.ndarray) -> dict[int, dict[str, Any]]:
    """The :class:`TrajectoryPoint` column values of sequence frames ``frames`` of ``fit`` (a whole or
    windowed fit holding them), by frame; ``ids`` (len(frames), K) the frame ids of each frame's views,
    -1 where it has none. The rows of one piece share its document (:func:`piece_json`); residuals are
    rounded to 1e-4 px."""
    rows = np.asarray(frames, int) - fit.first_frame
    ball = fit.ball_3d[rows]
    pos = fit.positions[rows]
    ball_ok, pos_ok = np.isfinite(ball).all(axis=1).tolist(), np.isfinite(pos).all(axis=1).tolist()
    ball_l, pos_l = ball.tolist(), pos.tolist()
    ids = np.asarray(ids)
    has = ids >= 0
    measured = (np.isfinite(fit.residuals_px[rows]) & has).tolist()
    flagged = (fit.outliers[rows] & has).tolist()
    res_l, ids_l = fit.residuals_px[rows].tolist(), ids.tolist()
    starts = [p.first_frame for p in fit.pieces]
    documents: dict[int, dict[str, Any]] = {}
    out = {}
    for j, frame in enumerate(frames):
        i = rows[j]
        before: int = bisect.bisect_right(starts, frame) - 1  # the piece holding the frame, if one does
        at = before if before >= 0 and fit.pieces[before].last_frame >= frame else None
        if at is not None and at not in documents:
            documents[at] = piece_json(fit.pieces[at])
        fid = ids_l[j]
        out[frame] = dict(
            ball3d=ball_l[j] if ball_ok[j] else None, ball3d_smoothed=pos_l[j] if pos_ok[j] else None,
            source=fit.sources[i], piece=documents.get(at) if at is not None else None,
            cam_list=[fid[k] for k in fit.cam_lists[i]],
            residuals_px={str(fid[k]): round(r, 4) for k, r in enumerate(res_l[j]) if measured[j][k]},
            flagged=[fid[k] for k, f in enumerate(flagged[j]) if f],
        )
    return out


def store_fit(arrays: SequenceArrays, fit: TrajectoryFit) -> list[Changed]:
    """Write each system's :class:`TrajectoryPoint` from ``fit`` (a fit of the whole sequence); returns
    the systems whose stored point changed."""
    changed = []
    frames = list(arrays.systems)
    rows = row_values(fit, frames, arrays.frame_ids[frames])
    for i, s in arrays.systems.items():
        values = rows[i]
        tp = s.trajectory_point
        if tp is None:
            tp = TrajectoryPoint()
            s.trajectory_point = tp
            labels = True
        elif all(getattr(tp, k) == v for k, v in values.items()):
            continue
        else:
            labels = any(getattr(tp, k) != values[k] for k in TRIANGULATION_FIELDS)
        for k, v in values.items():
            setattr(tp, k, v)
        tp.computed_at = utcnow()
        scope.changed(s)  # its trajectory point is in what its version covers: a page that showed the old one is stale
        changed.append(Changed(s, labels, s.id))
    return changed


def fit_args(settings: Settings) -> dict[str, Any]:
    """The keyword arguments of the trajectory fit taken from the settings (its per-frame triangulation's)."""
    return {"tau_px": settings.triangulation_tau_px, "rule": settings.pair_error_rule,
            "min_baseline_m": settings.min_baseline_m, "min_parallax_deg": settings.min_parallax_deg}


def fit_sequence(session: Session, game_id: int, settings: Settings) -> list[Changed]:
    """Fit the whole sequence of ``game_id`` from scratch and store it (:func:`store_fit`); returns the
    systems whose trajectory point changed."""
    systems = load_sequence(session, game_id)
    arrays = sequence_arrays(systems, settings)
    if not arrays.systems:
        return []
    fit = fit_trajectory(arrays.points, arrays.cameras, arrays.widths, FPS, **fit_args(settings))
    return store_fit(arrays, fit)


def consensus_observations(system: System,
                           observations: list[BallObservation], settings: Settings) -> list[BallObservation]:
    """The labels of an ISSIA system that its 3D ball is made of: those the stored trajectory does not
    flag, then the ones that agree on one ball (:func:`app.geometry.trajectory.triangulate_frame`:
    robust to a wrong camera; none when two labels disagree or two camps agree equally)."""
    tp = system.trajectory_point
    flagged = set(tp.flagged or []) if tp is not None else set()
    obs = [o for o in observations if o.view_id not in flagged]
    tri = triangulate_frame(obs, **fit_args(settings))
    kept = set(tri.kept)
    return [o for o in obs if o.view_id in kept]


@dataclass(frozen=True)
class DoubtFrame:
    """What a trajectory doubt says of a view: its name, image size (px) and camera (None if none)."""

    name: str
    width: int
    height: int
    camera: Camera | None


def trajectory_doubts(system: System, cameras: dict[int, Camera] | None = None) -> list[JudgedDoubt]:
    """``ball_off_consensus`` doubts of the labels of ``system`` that break the sequence's trajectory
    (stored ``TrajectoryPoint.flagged``; :func:`flagged_label_doubts` of its stored rows; ``cameras``:
    frame id -> camera already built, else each view's stored calibration)."""
    tp = system.trajectory_point
    if tp is None or not tp.flagged:
        return []
    cameras = cameras or {}
    views = {}
    for f in system.frames:
        cam = cameras.get(f.id)
        if cam is None and f.id in tp.flagged and f.calibration is not None and f.calibration.camera is not None:
            cam = Camera.from_soccernet(f.calibration.camera)
        views[f.id] = DoubtFrame(f.name, f.width, f.height, cam)
    return flagged_label_doubts(system.frame_index, {c: getattr(tp, c) for c in DOUBT_POINT_COLUMNS}, views)


#: The :class:`TrajectoryPoint` columns a trajectory doubt is made of.
DOUBT_POINT_COLUMNS = ("flagged", "residuals_px", "ball3d_smoothed", "source")


def flagged_label_doubts(frame_index: int | None, point: dict[str, Any],
                         views: dict[int, DoubtFrame]) -> list[JudgedDoubt]:
    """The ``ball_off_consensus`` doubt of each flagged label of a frame: evidence the residual (px at
    1920 width), the fitted position (m) and the frame index; fix ``snap_point`` to where the trajectory
    projects when that is inside the image (with ``point_sigma_px``, :func:`_trajectory_sigma_px`, and
    ``alternatives`` ``["exclude_view"]``), else ``exclude_view``.

    Args:
        frame_index: the system's frame index.
        point: the frame's trajectory point (:data:`DOUBT_POINT_COLUMNS` as stored).
        views: frame id -> :class:`DoubtFrame` of the system's views.
    """
    out = []
    for fid in point["flagged"] or []:
        f = views.get(fid)
        if f is None:
            continue
        res = (point["residuals_px"] or {}).get(str(fid))
        suggestion: dict[str, Any] = {"action": "exclude_view"}
        projected = None
        if f.camera is not None and point["ball3d_smoothed"] is not None:
            uv, front = f.camera.project(np.asarray(point["ball3d_smoothed"], float).reshape(1, 3))
            if front[0]:
                projected = [round(float(uv[0, 0]), 2), round(float(uv[0, 1]), 2)]
                if 0 <= projected[0] <= f.width and 0 <= projected[1] <= f.height:
                    suggestion = {"action": "snap_point", "point": projected,
                                  "point_sigma_px": _trajectory_sigma_px(point, f.width),
                                  "alternatives": ["exclude_view"]}
        out.append(JudgedDoubt(
            "ball_off_consensus", fid, "trajectory",
            json_safe({"residual_px_1920": res, "fitted_position_m": point["ball3d_smoothed"],
                       "source": point["source"], "frame_index": frame_index, "projected_px": projected,
                       "by": "trajectory"}),
            suggestion))
    return out


def _trajectory_sigma_px(point: dict[str, Any], width: int) -> float | None:
    """The uncertainty (px of a ``width``-px-wide view, one standard deviation) of where the trajectory's
    ball projects: the RMS of the residuals (px at 1920 width) of the frame's labels it does not flag (how
    well the trajectory fits the labels it keeps); None when it keeps none."""
    flagged = {str(f) for f in point["flagged"] or []}
    kept = [float(r) for k, r in (point["residuals_px"] or {}).items()
            if k not in flagged and isinstance(r, (int, float)) and np.isfinite(r)]
    if not kept:
        return None
    return round(float(np.sqrt(np.mean(np.square(kept)))) * width / REFERENCE_WIDTH_PX, 2)


def merge_doubts(system: System, judged: list[JudgedDoubt],
                 cameras: dict[int, Camera] | None = None) -> list[JudgedDoubt]:
    """For an ISSIA system with a stored trajectory, the trajectory decides which labels are off:
    the single-frame ``ball_off_consensus`` doubts are replaced by :func:`trajectory_doubts`, and a
    single-frame ``views_disagree`` (two labels that miss, culprit unknown) is dropped when the
    trajectory names the culprit: the time axis is what decides it."""
    if system.kind is not SystemKind.ISSIA or system.trajectory_point is None:
        return judged
    from_trajectory = trajectory_doubts(system, cameras)
    replaced = {"ball_off_consensus", "views_disagree"} if from_trajectory else {"ball_off_consensus"}
    return [d for d in judged if d.kind not in replaced] + from_trajectory
