"""Read-only queries behind the API: the games, the review queue of systems, the frames, the system
view JSON the system page draws (``docs/architecture.md``), and where a frame's image is read from.

Nothing here writes, and nothing is aggregated per request: the queue reads the per-system figures that
every recomputation stores on ``System`` (``app.services.recompute.update_summary``; aggregates over the
**admitted** views, the ones the 3D ball is made of, method.md sections 4 and 5): ``lowest_jac``
(JaC@0.5 %), ``worst_error_px`` (the largest reprojection error of the fused ball, px of the view's own
image, SoccerNet-v3D's ``rep_error``), ``views_flagged`` (every view flagged probably mirrored),
``views_above_tau`` (by ``app.geometry.triangulation.error_above_tau``, the rule the system view's
per-view ``error_above_tau`` uses too: queue and system page cannot disagree), and the doubt counts.

Queue order (``sort``): ``doubts`` (the stored count of label-accusing doubts, ties by the largest
reprojection error), ``worst_error``, ``lowest_jac`` or ``name``, descending with a leading ``-``;
systems without the sort value (no 3D ball, no admitted view) always come last, ties break by id (in the
sort's direction). The
default, :data:`DEFAULT_SORT`, puts the systems with the most doubts first: the labels the geometry
accuses are reviewed first. ``name`` orders by game, then system name with numeric names in numeric
order (2.png before 10.png). The ``doubt`` filter keeps systems with a doubt of one kind (or any
label-accusing one); doubts and their counts are stored by the recomputation
(``app.services.doubts``), never computed here.
"""
from __future__ import annotations

import functools
import json
import mimetypes
import zipfile
from collections.abc import Iterator
from dataclasses import dataclass
from datetime import datetime
from pathlib import Path
from typing import Any, Literal, Optional

import numpy as np
import sqlalchemy as sa
from sqlalchemy.orm import Session, joinedload, selectinload

from app.db.models import (
    BallLabel, BallReprojection, Calibration, CalibrationStatus, Doubt, Frame, Game, OptimisedBox, ReviewDecision,
    ReviewStatus, System, Triangulation,
)
from app.geometry.calibration.frame import MIRROR_FLAG
from app.geometry.camera import Camera
from app.geometry.projection import project_pitch_polylines
from app.geometry.triangulation import error_above_tau, rule_reference_width_px, scaled_error_px
from app.datasets.files import is_safe_member
from app.services.errors import NotFoundError, ServiceError
from app.services.doubts import doubt_json
from app.services.versions import frame_etag, system_etag

SystemSort = Literal["doubts", "-doubts", "worst_error", "-worst_error", "lowest_jac", "-lowest_jac", "name", "-name"]
FrameSort = Literal["error", "-error", "jac", "-jac", "name", "-name"]
#: The review queue's default order: the most label doubts first (then the largest reprojection error).
DEFAULT_SORT: SystemSort = "-doubts"
#: Pitch sampling for drawing (metres between samples on lines and on circles): about 1,500 points
#: per view, smooth at 1920 px, a tenth of the JaC sampling.
_DRAW_DIST_M = 0.5
_DRAW_DIST_CIRCLES_M = 0.25
#: Pixel coordinates sent to the UI are rounded to this many decimals.
_PX_DECIMALS = 2
_CHUNK = 64 * 1024


# ----- filters and pages ---------------------------------------------------------------------------
@dataclass(frozen=True)
class SystemFilters:
    """Filters of the review queue; None means "any". Ranges are inclusive."""

    game_id: Optional[int] = None
    status: Optional[ReviewStatus] = None
    jac_min: Optional[float] = None
    jac_max: Optional[float] = None
    error_min: Optional[float] = None
    error_max: Optional[float] = None
    #: Only systems with a doubt of this kind (``app.geometry.doubts``), or ``"any"``: with at least
    #: one label-accusing doubt; ``"none"``: with none.
    doubt: Optional[str] = None


@dataclass(frozen=True)
class FrameFilters:
    """Filters of the frame list; None means "any". ``calibration`` is a status or ``"none"`` (no
    calibration row yet). JaC is JaC@0.5 %; error is the view's reprojection error in px."""

    game_id: Optional[int] = None
    system_id: Optional[int] = None
    calibration: Optional[Literal["calibrated", "refused", "none"]] = None
    admitted: Optional[bool] = None
    jac_min: Optional[float] = None
    jac_max: Optional[float] = None
    error_min: Optional[float] = None
    error_max: Optional[float] = None


@dataclass(frozen=True)
class SystemSummary:
    """One row of the review queue."""

    system: System
    game: Game
    review_status: ReviewStatus
    review_comment: str
    review_decided_at: Optional[datetime]
    ball3d: Optional[list[float]]
    views_total: int
    views_calibrated: int
    views_admitted: int
    views_labelled: int
    lowest_jac: Optional[float]
    worst_error_px: Optional[float]
    views_flagged: int = 0
    views_above_tau: int = 0
    doubt_counts: Optional[dict[str, int]] = None
    label_doubts: int = 0

    def as_json(self) -> dict[str, Any]:
        """The queue row as the API sends it."""
        g = self.game
        return {
            "id": self.system.id, "name": self.system.name, "kind": self.system.kind.value,
            "game": {"id": g.id, "league": g.league, "season": g.season, "match": g.match},
            "review": {"status": self.review_status.value, "comment": self.review_comment,
                       "decided_at": self.review_decided_at.isoformat() if self.review_decided_at else None},
            "ball3d": self.ball3d, "views_total": self.views_total, "views_calibrated": self.views_calibrated,
            "views_admitted": self.views_admitted, "views_labelled": self.views_labelled,
            "lowest_jac": self.lowest_jac, "worst_error_px": self.worst_error_px,
            "views_flagged": self.views_flagged, "views_above_tau": self.views_above_tau,
            "doubt_counts": dict(self.doubt_counts or {}), "label_doubts": self.label_doubts,
        }


@dataclass(frozen=True)
class SystemPage:
    """One page of the queue: ``total`` rows match the filters; ``counts`` are per review status over
    the same filters except the status one (the progress of the whole filtered queue)."""

    items: list[SystemSummary]
    total: int
    counts: dict[str, int]


@dataclass(frozen=True)
class FramePage:
    """One page of frames and how many match the filters."""

    items: list[dict[str, Any]]
    total: int


def _review_status() -> Any:
    """A system's review status: the copy stored on the system (pending without a decision)."""
    return System.review_status


def _queue_from() -> sa.Select[Any]:
    """The queue's rows: each system with its game, review and 3D ball; the per-system figures are
    the stored ``System`` columns (no aggregation here)."""
    return (
        sa.select(
            System, Game, System.review_status.label("review_status"),
            sa.func.coalesce(ReviewDecision.comment, "").label("review_comment"),
            ReviewDecision.decided_at.label("review_decided_at"), Triangulation.ball3d,
        )
        .join(Game, Game.id == System.game_id)
        .outerjoin(ReviewDecision, ReviewDecision.system_id == System.id)
        .outerjoin(Triangulation, Triangulation.system_id == System.id)
    )


def _range(column: Any, lo: Optional[float], hi: Optional[float]) -> list[sa.ColumnElement[bool]]:
    out = []
    if lo is not None:
        out.append(column >= lo)
    if hi is not None:
        out.append(column <= hi)
    return out


def _system_conditions(filters: SystemFilters, with_status: bool = True) -> list[Any]:
    conds: list[Any] = []
    if filters.game_id is not None:
        conds.append(System.game_id == filters.game_id)
    if with_status and filters.status is not None:
        conds.append(_review_status() == filters.status)
    conds += _range(System.lowest_jac, filters.jac_min, filters.jac_max)
    conds += _range(System.worst_error_px, filters.error_min, filters.error_max)
    if filters.doubt == "any":
        conds.append(System.label_doubts > 0)
    elif filters.doubt == "none":
        conds.append(System.label_doubts == 0)
    elif filters.doubt is not None:
        conds.append(sa.exists().where(Doubt.system_id == System.id, Doubt.kind == filters.doubt))
    return conds


def _natural_name(column: Any) -> list[Any]:
    # numeric names ("2.png", "10.png") in numeric order: shorter first, then text
    return [sa.func.length(column), column]


@dataclass(frozen=True)
class _SortKey:
    """One key of the queue's order: an SQL expression, its direction, and whether NULLs come last
    (the stored aggregates are NULL without a 3D ball or an admitted view)."""

    expr: Any
    desc: bool = False
    nulls_last: bool = False

    def clause(self, reverse: bool = False) -> Any:
        desc = self.desc != reverse
        c = self.expr.desc() if desc else self.expr.asc()
        if self.nulls_last:
            c = c.nulls_first() if reverse else c.nulls_last()
        return c

    def equal(self, value: Any) -> Any:
        return self.expr.is_(None) if value is None else self.expr == value

    def before(self, value: Any) -> Any:
        """SQL: a row's key sorts strictly before ``value`` (the current row's)."""
        if self.nulls_last and value is None:
            return self.expr.is_not(None)
        return self.expr > value if self.desc else self.expr < value

    def after(self, value: Any) -> Any:
        """SQL: a row's key sorts strictly after ``value``."""
        if self.nulls_last and value is None:
            return sa.false()
        beyond = self.expr < value if self.desc else self.expr > value
        return sa.or_(self.expr.is_(None), beyond) if self.nulls_last else beyond


def _sort_keys(sort: SystemSort) -> list[_SortKey]:
    """The queue's order as keys; the system id comes last, in the sort's direction, so that the order
    is strict and a descending sort is an index scanned backwards (no sort of the whole queue)."""
    desc = sort.startswith("-")
    key = sort.lstrip("-")
    tie = _SortKey(System.id, desc)
    if key == "name":
        cols = [Game.league, Game.season, Game.match, *_natural_name(System.name)]
        return [_SortKey(c, desc) for c in cols] + [tie]
    if key == "doubts":  # ties by the largest reprojection error
        return [_SortKey(System.label_doubts, desc), _SortKey(System.worst_error_px, True, True), tie]
    column = {"worst_error": System.worst_error_px, "lowest_jac": System.lowest_jac}.get(key)
    if column is None:
        raise ValueError(f"unknown sort {sort!r}")
    return [_SortKey(column, desc, True), tie]


def _system_order(sort: SystemSort) -> list[Any]:
    return [k.clause() for k in _sort_keys(sort)]


def list_games(session: Session) -> list[tuple[Game, int]]:
    """Every game with its number of systems, in (league, season, match) order."""
    n = sa.func.count(System.id)
    stmt = (
        sa.select(Game, n).outerjoin(System, System.game_id == Game.id)
        .group_by(Game.id).order_by(Game.league, Game.season, Game.match, Game.id)
    )
    return [(g, int(c)) for g, c in session.execute(stmt).all()]


def has_games(session: Session) -> bool:
    """True when the database holds at least one game."""
    return session.execute(sa.select(Game.id).limit(1)).first() is not None


def list_systems(session: Session, filters: SystemFilters = SystemFilters(), sort: SystemSort = DEFAULT_SORT,
                 limit: int = 50, offset: int = 0) -> SystemPage:
    """One page of the review queue.

    Args:
        filters: see :class:`SystemFilters` (JaC as a fraction, errors in px).
        sort: one of :data:`SystemSort` (module docstring).
        limit, offset: the page (``limit >= 1``, ``offset >= 0``).

    Returns:
        :class:`SystemPage`.

    Raises:
        ValueError: an unknown ``sort``.
    """
    order = _system_order(sort)
    conds = _system_conditions(filters)
    rows = session.execute(_queue_from().where(*conds).order_by(*order).limit(limit).offset(offset)).all()
    items = [
        SystemSummary(
            system=r.System, game=r.Game, review_status=r.review_status, review_comment=r.review_comment,
            review_decided_at=r.review_decided_at, ball3d=r.ball3d, views_total=r.System.views_total,
            views_calibrated=r.System.views_calibrated, views_admitted=r.System.views_admitted,
            views_labelled=r.System.views_labelled, lowest_jac=r.System.lowest_jac,
            worst_error_px=r.System.worst_error_px, views_flagged=r.System.views_flagged,
            views_above_tau=r.System.views_above_tau, doubt_counts=dict(r.System.doubt_counts or {}),
            label_doubts=r.System.label_doubts,
        )
        for r in rows
    ]
    # one indexed GROUP BY on the stored status gives the progress and the total (no window over the queue)
    status = _review_status()
    by_status = session.execute(
        sa.select(status, sa.func.count(System.id)).where(*_system_conditions(filters, with_status=False))
        .group_by(status)
    ).all()
    counts = {s.value: 0 for s in ReviewStatus}
    for s, n in by_status:
        counts[ReviewStatus(s).value] += int(n)
    total = counts[ReviewStatus(filters.status).value] if filters.status is not None else sum(counts.values())
    return SystemPage(items=items, total=int(total), counts=counts)


def queue_neighbours(session: Session, system_id: int, filters: SystemFilters = SystemFilters(),
                     sort: SystemSort = DEFAULT_SORT) -> tuple[Optional[int], Optional[int]]:
    """``(prev_id, next_id)`` of a system in the queue ``filters`` + ``sort`` (None at either end, or
    for an unknown id).

    The system itself need not match the filters (it may just have been reviewed out of a
    "pending" queue): its neighbours are then those it would have if it did.
    """
    keys = _sort_keys(sort)
    base = (sa.select(System.id).join(Game, Game.id == System.game_id)
            .outerjoin(ReviewDecision, ReviewDecision.system_id == System.id))
    current = session.execute(base.with_only_columns(*(k.expr for k in keys)).where(System.id == system_id)).first()
    if current is None:
        return None, None
    conds = _system_conditions(filters)

    def neighbour(side: str) -> Optional[int]:
        # keyset: the nearest row strictly before (after) the current one in the order; two indexed
        # LIMIT 1 queries instead of ranking the whole queue
        alternatives = [sa.and_(*(k.equal(v) for k, v in zip(keys[:i], current)), getattr(keys[i], side)(current[i]))
                        for i in range(len(keys))]
        order = [k.clause(reverse=side == "before") for k in keys]
        return session.scalar(base.where(*conds, sa.or_(*alternatives)).order_by(*order).limit(1))

    return neighbour("before"), neighbour("after")


def list_frames(session: Session, filters: FrameFilters = FrameFilters(), sort: FrameSort = "name",
                limit: int = 50, offset: int = 0) -> FramePage:
    """One page of frames (calibration, label and reprojection loaded).

    ``sort``: ``error`` (the view's reprojection error), ``jac`` (JaC@0.5 %) or ``name`` (game,
    system, position), descending with a leading ``-``; missing values last, ties by id.

    Raises:
        ValueError: an unknown ``sort``.
    """
    conds: list[Any] = []
    if filters.game_id is not None:
        conds.append(System.game_id == filters.game_id)
    if filters.system_id is not None:
        conds.append(Frame.system_id == filters.system_id)
    if filters.calibration == "none":
        conds.append(Calibration.frame_id.is_(None))
    elif filters.calibration is not None:
        conds.append(Calibration.status == CalibrationStatus(filters.calibration))
    if filters.admitted is not None:
        conds.append(sa.func.coalesce(Calibration.admitted, False).is_(filters.admitted))
    conds += _range(Calibration.jac_0005, filters.jac_min, filters.jac_max)
    conds += _range(BallReprojection.error_px, filters.error_min, filters.error_max)
    base = (
        sa.select(Frame).join(System, System.id == Frame.system_id).join(Game, Game.id == System.game_id)
        .outerjoin(Calibration, Calibration.frame_id == Frame.id)
        .outerjoin(BallReprojection, BallReprojection.frame_id == Frame.id)
        .where(*conds)
    )
    desc = sort.startswith("-")
    key = sort.lstrip("-")
    if key == "name":
        cols = [Game.league, Game.season, Game.match, *_natural_name(System.name), Frame.position]
        order = [c.desc() if desc else c.asc() for c in cols]
    elif key in ("error", "jac"):
        col = BallReprojection.error_px if key == "error" else Calibration.jac_0005
        order = [(col.desc() if desc else col.asc()).nulls_last()]
    else:
        raise ValueError(f"unknown sort {sort!r}")
    total = session.scalar(sa.select(sa.func.count()).select_from(base.with_only_columns(Frame.id).subquery()))
    stmt = base.order_by(*order, Frame.id).limit(limit).offset(offset).options(
        selectinload(Frame.calibration), selectinload(Frame.ball_label), selectinload(Frame.reprojection),
        selectinload(Frame.review),
    )
    return FramePage(items=[frame_summary(f) for f in session.scalars(stmt)], total=int(total or 0))


# ----- the system view -----------------------------------------------------------------------------
def _px(values: Any) -> Any:
    """Round pixel coordinates (nested lists or arrays) for JSON."""
    return np.round(np.asarray(values, dtype=float), _PX_DECIMALS).tolist()


def review_json(decision: Optional[ReviewDecision]) -> dict[str, Any]:
    """``{"status", "comment", "decided_at", "excluded"}`` of a decision; pending when there is none.
    ``excluded`` (views only) says the view is excluded from its system's triangulation."""
    if decision is None:
        return {"status": ReviewStatus.PENDING.value, "comment": "", "decided_at": None, "excluded": False}
    return {
        "status": decision.status.value,
        "comment": decision.comment,
        "decided_at": decision.decided_at.isoformat() if decision.decided_at else None,
        "excluded": bool(decision.excluded),
    }


def frame_has_image(frame: Frame) -> bool:
    """True when the frame says where its pixels are (a zip member or a file)."""
    return bool(frame.image_path) or bool(frame.image_zip and frame.image_member)


def image_url(frame: Frame) -> Optional[str]:
    """The API address of the frame's image, None when it has none (the UI draws a blank canvas)."""
    return f"/api/frames/{frame.id}/image" if frame_has_image(frame) else None


def pitch_lines(camera_json: Optional[dict[str, Any]], width: int, height: int) -> list[dict[str, Any]]:
    """The pitch model projected by a stored camera and clipped to its image (``[{"class", "points"}]``,
    pixels rounded for JSON), for drawing. It depends only on the calibration, so it is computed once
    per calibration and image size and kept (:func:`_projected_pitch`, an LRU cache keyed by the camera
    JSON), not on every request."""
    if not camera_json:
        return []
    return _projected_pitch(json.dumps(camera_json, sort_keys=True), int(width), int(height))


@functools.lru_cache(maxsize=4096)
def _projected_pitch(camera_key: str, width: int, height: int) -> list[dict[str, Any]]:
    camera = Camera.from_soccernet(json.loads(camera_key))
    runs = project_pitch_polylines(camera, width, height, _DRAW_DIST_M, _DRAW_DIST_CIRCLES_M, mode="clip")
    return [{"class": cls, "points": _px(run)} for cls, polys in runs.items() for run in polys if len(run) >= 2]


def _calibration_json(cal: Optional[Calibration]) -> Optional[dict[str, Any]]:
    if cal is None:
        return None
    return {
        "status": cal.status.value, "source": cal.source.value, "camera": cal.camera, "jac": cal.jac(),
        "admitted": cal.admitted, "reason": cal.reason, "flags": list(cal.flags or []),
        "probably_mirrored": MIRROR_FLAG in (cal.flags or []),
        "residuals_px": dict(cal.residuals_px or {}), "mirror_evidence": cal.mirror_evidence,
    }


def _ball_json(label: Optional[BallLabel]) -> dict[str, Any]:
    if label is None:
        return {"kind": None, "box": None, "point": None, "original_box": None, "original_point": None,
                "edited": False}
    return {
        "kind": label.kind.value if label.kind is not None else None, "box": label.box, "point": label.point,
        "original_box": label.original_box, "original_point": label.original_point, "edited": label.edited,
    }


def _optimised_json(opt: Optional[OptimisedBox]) -> Optional[dict[str, Any]]:
    if opt is None:
        return None
    return {"box": _px(opt.box), "d_px": opt.d_opt_px, "error_m": opt.error_m}


def _view_json(frame: Frame, tri: Optional[Triangulation]) -> dict[str, Any]:
    cal = frame.calibration
    calibrated = cal is not None and cal.status == CalibrationStatus.CALIBRATED and bool(cal.camera)
    rep = frame.reprojection
    lines = frame.field_lines.lines if frame.field_lines is not None else {}
    return {
        "frame_id": frame.id,
        "name": frame.name,
        "role": frame.role.value,
        "width": frame.width,
        "height": frame.height,
        "image_url": image_url(frame),
        "calibration": _calibration_json(cal),
        "pitch_lines": pitch_lines(cal.camera if calibrated else None, frame.width, frame.height),
        "field_lines": lines,
        "ball": _ball_json(frame.ball_label),
        "optimised_box": _optimised_json(frame.optimised_box),
        "reprojected_ball": _px(rep.point) if rep is not None else None,
        "reprojection_error_px": rep.error_px if rep is not None else None,
        "reprojection_error_scaled_px": scaled_error_px(rep.error_px, frame.width, tri.rule)
        if rep is not None and tri is not None else None,
        "error_above_tau": rep is not None and tri is not None and error_above_tau(
            rep.error_px, frame.width, tri.tau_px, tri.rule),
        "camera_position": [float(v) for v in cal.camera["position_meters"]] if calibrated else None,
        "review": review_json(frame.review),
        "etag": frame_etag(frame),
    }


def frame_view(session: Session, frame_id: int) -> dict[str, Any]:
    """One frame as the system view draws it (its ``views`` item: ball, lines, calibration, review,
    reprojection, ``etag``) plus its ``system_id``: ``GET /api/frames/{id}`` and the current state a
    stale write (412) answers.

    Raises:
        NotFoundError: no frame has this id.
    """
    stmt = sa.select(Frame).where(Frame.id == frame_id).options(
        selectinload(Frame.system).selectinload(System.triangulation),
        selectinload(Frame.field_lines), selectinload(Frame.calibration), selectinload(Frame.ball_label),
        selectinload(Frame.reprojection), selectinload(Frame.optimised_box), selectinload(Frame.review),
    )
    frame = session.scalars(stmt).first()
    if frame is None:
        raise NotFoundError("frame", frame_id)
    return {**_view_json(frame, frame.system.triangulation), "system_id": frame.system_id}


def frame_summary(frame: Frame) -> dict[str, Any]:
    """A frame's row in the frame list: identity, calibration, label, reprojection error, review."""
    rep = frame.reprojection
    return {
        "id": frame.id, "system_id": frame.system_id, "name": frame.name, "role": frame.role.value,
        "width": frame.width, "height": frame.height,
        "image_url": image_url(frame),
        "calibration": _calibration_json(frame.calibration), "ball": _ball_json(frame.ball_label),
        "reprojection_error_px": rep.error_px if rep is not None else None, "review": review_json(frame.review),
    }


def _triangulation_json(tri: Optional[Triangulation]) -> Optional[dict[str, Any]]:
    if tri is None:
        return None
    return {
        "status": tri.status.value, "tau_px": tri.tau_px, "rule": tri.rule,
        "reference_width_px": rule_reference_width_px(tri.rule), "min_baseline_m": tri.min_baseline_m,
        "pairs": [
            {"view_a": p.frame_a_id, "view_b": p.frame_b_id, "point": p.point, "error_px": p.error_px,
             "parallax_deg": p.parallax_deg, "baseline_m": p.baseline_m, "kept": p.kept, "reason": p.reason}
            for p in tri.pairs
        ],
    }


def _load_system(session: Session, system_id: int) -> System:
    """The system with every relation the view draws loaded in a few queries.

    Raises:
        NotFoundError: no system has this id.
    """
    # one-to-one rows joined to their parent (one query for the system, one for its views), the lists
    # (pairs, doubts) one query each: four queries whatever the number of views
    stmt = sa.select(System).where(System.id == system_id).options(
        joinedload(System.game), joinedload(System.review),
        joinedload(System.triangulation).selectinload(Triangulation.pairs),
        selectinload(System.frames).options(
            joinedload(Frame.field_lines), joinedload(Frame.calibration), joinedload(Frame.ball_label),
            joinedload(Frame.reprojection), joinedload(Frame.optimised_box), joinedload(Frame.review),
        ),
        selectinload(System.doubts),
    )
    system = session.scalars(stmt).unique().first()
    if system is None:
        raise NotFoundError("system", system_id)
    return system


def system_view(session: Session, system_id: int, filters: SystemFilters = SystemFilters(),
                sort: SystemSort = DEFAULT_SORT) -> dict[str, Any]:
    """The system view JSON of ``docs/architecture.md`` (the UI contract).

    Per view: the pitch model projected at the image's resolution and clipped to it, the annotated
    field lines, the ball label and its optimised box, the reprojected 3D ball and its error, the
    camera centre, and ``error_above_tau`` (:func:`error_above_tau`, the rule the queue's
    ``views_above_tau`` counts by). ``prev_id`` / ``next_id`` follow the queue ``filters`` + ``sort`` (by default the
    whole queue in its default order). Triangulation pairs name their views by frame id.

    Raises:
        NotFoundError: no system has this id.
    """
    system = _load_system(session, system_id)
    prev_id, next_id = queue_neighbours(session, system_id, filters, sort)
    tri = system.triangulation
    game = system.game
    names = {f.id: f.name for f in system.frames}
    return {
        "id": system.id,
        "name": system.name,
        "kind": system.kind.value,
        "frame_index": system.frame_index,
        "game": {"id": game.id, "league": game.league, "season": game.season, "match": game.match},
        "review": review_json(system.review),
        "etag": system_etag(system),
        "prev_id": prev_id,
        "next_id": next_id,
        "ball3d": tri.ball3d if tri is not None else None,
        "triangulation": _triangulation_json(tri),
        "views": [_view_json(f, tri) for f in system.frames],
        "doubts": [doubt_json(d, names) for d in system.doubts],
    }


# ----- frame images --------------------------------------------------------------------------------
class ImageUnavailable(ServiceError, LookupError):
    """A frame's image cannot be served: the dataset has none, or its file or member is gone."""


@dataclass(frozen=True)
class FrameImage:
    """Where a frame's image bytes are and how to describe them over HTTP.

    ``etag`` is strong and cheap: the member's CRC-32 and size for a zip member (read from the
    archive's directory, no decompression), the file's modification time and size for a file.
    """

    media_type: str
    etag: str
    size: int
    zip_path: Optional[Path] = None
    member: Optional[str] = None
    path: Optional[Path] = None
    #: Bytes decoded on demand (a frame of a video or frame folder, ``app.services.issia``).
    data: Optional[bytes] = None

    def chunks(self) -> Iterator[bytes]:
        """The image bytes in 64 KiB chunks, read from the file or straight out of the archive."""
        if self.data is not None:
            yield from (self.data[i:i + _CHUNK] for i in range(0, len(self.data), _CHUNK))
            return
        if self.path is not None:
            with self.path.open("rb") as fh:
                yield from iter(lambda: fh.read(_CHUNK), b"")
            return
        assert self.zip_path is not None and self.member is not None
        with zipfile.ZipFile(self.zip_path) as zf, zf.open(self.member) as fh:
            yield from iter(lambda: fh.read(_CHUNK), b"")


def _media_type(name: str) -> str:
    return mimetypes.guess_type(name)[0] or "application/octet-stream"


def frame_image(frame: Frame) -> FrameImage:
    """Locate a frame's image without reading it (zip members are never extracted).

    Raises:
        ImageUnavailable: the frame has no image (SoccerNet-calibration imports ship none), its
            member name is unsafe, or the archive, member or file is missing.
    """
    where = f"frame {frame.id}"
    if frame.media_frame is not None and frame.image_path:
        return _media_frame_image(frame, where)
    if frame.image_zip and frame.image_member:
        member = frame.image_member
        if not is_safe_member(member):
            raise ImageUnavailable(f"{where}: refusing unsafe archive member name {member!r}")
        zip_path = Path(frame.image_zip)
        try:
            with zipfile.ZipFile(zip_path) as zf:
                info = zf.getinfo(member)
        except FileNotFoundError:
            raise ImageUnavailable(f"{where}: image archive {zip_path} is missing") from None
        except KeyError:
            raise ImageUnavailable(f"{where}: {member!r} is not in {zip_path}") from None
        except (zipfile.BadZipFile, OSError) as exc:
            raise ImageUnavailable(f"{where}: cannot read image archive {zip_path} ({exc})") from None
        return FrameImage(
            media_type=_media_type(member), etag=f'"{info.CRC:08x}-{info.file_size:x}"', size=info.file_size,
            zip_path=zip_path, member=member,
        )
    if frame.image_path:
        path = Path(frame.image_path)
        try:
            st = path.stat()
        except OSError:
            raise ImageUnavailable(f"{where}: image file {path} is missing") from None
        return FrameImage(
            media_type=_media_type(path.name), etag=f'"{st.st_mtime_ns:x}-{st.st_size:x}"', size=st.st_size,
            path=path,
        )
    raise ImageUnavailable(
        f"{where} has no image (its dataset ships none, e.g. SoccerNet-calibration): "
        f"draw on a blank {frame.width}x{frame.height} canvas"
    )


def _media_frame_image(frame: Frame, where: str) -> FrameImage:
    """A frame of a video or frame folder (ISSIA), decoded and resized to the frame's own size, PNG."""
    from app.services.errors import DatasetError
    from app.services.issia import read_video_frame

    path = Path(frame.image_path or "")
    try:
        st = path.stat()
        data = read_video_frame(frame)
    except (OSError, DatasetError) as exc:
        raise ImageUnavailable(f"{where}: cannot read frame {frame.media_frame} of {path} ({exc})") from None
    etag = f'"{st.st_mtime_ns:x}-{st.st_size:x}-{frame.media_frame:x}-{int(frame.media_flipped)}-{frame.width}x{frame.height}"'
    return FrameImage(media_type="image/png", etag=etag, size=len(data), data=data)
