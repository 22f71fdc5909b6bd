"""A release's documents as the rows and systems the export writers read: typed values built from a version 1
document (``app.services.releases.document``), in the place of the stored rows a live export reads.

The writers are the live export's own (``exporting.exported_game``, ``detector_export.views_of``,
``issia.export.rows_of``, ``cameras_export.write_camera_sets``) so that a release exports as the database did when
it was made; what each of them reads of a row, a system or a frame is an attribute here, typed, so that mypy checks
every value handed on. The golden files of ``tests/services/releases/golden`` pin the bytes each format writes from
a stored document: a change of a live writer that would change them must render the older documents with a copy of
the writer as it was, here.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Optional, Union

from app.db.models import BallLabel, CalibrationSource, CalibrationStatus, Frame, FrameRole, ReviewStatus, SystemKind
from app.db.types import json_loads
from app.services.releases.document import FrameDocument, GameDocument, SystemDocument, TrajectoryDocument


def stored_json(text: Optional[str]) -> Any:
    """A document's stored JSON text as its value (None for SQL NULL or JSON null)."""
    return None if text in (None, "null") else json_loads(text)


@dataclass(frozen=True)
class ReleasedRow:
    """A released view as ``exporting.frame_row_select`` reads it (the SoccerNet-v3D export's row): its system's
    columns, then the view's (:class:`~app.services.releases.document.FrameDocument`, enums as the live ones)."""

    game_id: int
    system_id: int
    system_name: str
    ball3d: Optional[str]
    review_status: Optional[ReviewStatus]
    frame_id: int
    name: str
    role: FrameRole
    width: int
    height: int
    frame_split: Optional[str]
    cal_source: Optional[CalibrationSource]
    cal_status: Optional[CalibrationStatus]
    camera_json: Optional[str]
    reason: Optional[str]
    flags_json: Optional[str]
    residuals_json: Optional[str]
    uncertainty_json: Optional[str]
    admitted: Optional[bool]
    jac_0005: Optional[float]
    jac_001: Optional[float]
    jac_002: Optional[float]
    lines_json: Optional[str]
    original_json: Optional[str]
    label_frame: Optional[int]
    ball_kind: Optional[str]
    ball_box: Optional[str]
    ball_point: Optional[str]
    original_box: Optional[str]
    original_point: Optional[str]
    opt_box: Optional[str]
    opt_d_px: Optional[float]
    opt_error_m: Optional[float]
    rep_error_px: Optional[float]
    release_json: Optional[str]


def released_row(system: SystemDocument, f: FrameDocument) -> ReleasedRow:
    """The export row of the view ``f`` of the released ``system``."""
    return ReleasedRow(
        game_id=system.game_id, system_id=system.system_id, system_name=system.name, ball3d=system.ball3d,
        review_status=None if system.review_status is None else ReviewStatus(system.review_status),
        frame_id=f.frame_id, name=f.name, role=FrameRole(f.role), width=f.width, height=f.height,
        frame_split=f.frame_split,
        cal_source=None if f.cal_source is None else CalibrationSource(f.cal_source),
        cal_status=None if f.cal_status is None else CalibrationStatus(f.cal_status),
        camera_json=f.camera_json, reason=f.reason, flags_json=f.flags_json, residuals_json=f.residuals_json,
        uncertainty_json=f.uncertainty_json, admitted=f.admitted, jac_0005=f.jac_0005, jac_001=f.jac_001,
        jac_002=f.jac_002, lines_json=f.lines_json, original_json=f.original_json, label_frame=f.label_frame,
        ball_kind=f.ball_kind, ball_box=f.ball_box, ball_point=f.ball_point, original_box=f.original_box,
        original_point=f.original_point, opt_box=f.opt_box, opt_d_px=f.opt_d_px, opt_error_m=f.opt_error_m,
        rep_error_px=f.rep_error_px, release_json=f.release_json)


@dataclass(frozen=True)
class ReleasedLabel:
    """A released view's ball label as ``BallLabel`` is read by the detector exports: box ``[x1, y1, x2, y2]`` px
    or None, kind, centre ``[x, y]`` px or None. ``suggested`` is always False: a document never holds an
    unconfirmed placement (``frame_row_select`` reads one as no label)."""

    box: Optional[list[float]]
    kind: Optional[str]
    centre: Optional[list[float]]
    suggested: bool = False


@dataclass(frozen=True)
class ReleasedCalibration:
    """A released view's calibration: its SoccerNet camera (or None) and whether the triangulation admitted it."""

    camera: Optional[dict[str, Any]]
    admitted: bool


@dataclass(frozen=True)
class ReleasedBox:
    """A released view's optimised box ``[x1, y1, x2, y2]`` px."""

    box: list[float]


@dataclass(frozen=True)
class ReleasedReprojection:
    """A released view's reprojection error of its system's 3D ball, px."""

    error_px: float


@dataclass(frozen=True)
class ReleasedPair:
    """One pair of admitted views of a released triangulation, and whether it was kept."""

    frame_a_id: int
    frame_b_id: int
    kept: bool


@dataclass(frozen=True)
class ReleasedTriangulation:
    """A released system's triangulated ball (world metres ``[x, y, z]``, z down, or None) and its pairs."""

    ball3d: Optional[list[float]]
    pairs: list[ReleasedPair]


@dataclass(frozen=True)
class NoImage:
    """The image source of a released view whose stored frame is gone: no image (the view is counted without)."""

    image_path: None = None
    image_zip: None = None
    image_member: None = None


@dataclass(eq=False)
class ReleasedFrame:
    """A released view as ``Frame`` is read by the detector and ISSIA-3D exports. ``image_source`` is the stored
    frame of that id (its image as imported) or :class:`NoImage`."""

    id: int
    name: str
    width: int
    height: int
    split: Optional[str]
    position: int
    system: ReleasedSystem
    release: Any
    image_source: Union[Frame, NoImage]
    ball_label: Optional[ReleasedLabel]
    calibration: Optional[ReleasedCalibration]
    optimised_box: Optional[ReleasedBox]
    reprojection: Optional[ReleasedReprojection]


@dataclass(eq=False)
class ReleasedSystem:
    """A released system as ``System`` is read by the detector and ISSIA-3D exports (its frames in order)."""

    id: int
    name: str
    kind: SystemKind
    game: GameDocument
    frame_index: Optional[int]
    triangulation: Optional[ReleasedTriangulation]
    trajectory_point: Optional[TrajectoryDocument]
    frames: list[ReleasedFrame] = field(default_factory=list)


def released_system(doc: SystemDocument, game: GameDocument, stored: dict[int, Frame]) -> ReleasedSystem:
    """The released system ``doc`` of ``game``, its frames' images those of ``stored`` (frame id -> stored frame;
    a frame not in it has :class:`NoImage`)."""
    tri = doc.triangulation
    system = ReleasedSystem(
        id=doc.system_id, name=doc.name, kind=SystemKind(doc.kind), game=game, frame_index=doc.frame_index,
        triangulation=None if tri is None else ReleasedTriangulation(
            ball3d=stored_json(doc.ball3d), pairs=[ReleasedPair(a, b, k) for a, b, k in tri.pairs]),
        trajectory_point=doc.trajectory)
    for position, f in enumerate(doc.frames):
        opt_box = stored_json(f.opt_box)
        system.frames.append(ReleasedFrame(
            id=f.frame_id, name=f.name, width=f.width, height=f.height, split=f.frame_split, position=position,
            system=system, release=stored_json(f.release_json), image_source=stored.get(f.frame_id, NoImage()),
            ball_label=None if f.label_frame is None else ReleasedLabel(
                box=stored_json(f.ball_box), kind=f.ball_kind,
                centre=BallLabel.centre_of(stored_json(f.ball_box), stored_json(f.ball_point))),
            calibration=None if f.cal_source is None else ReleasedCalibration(
                camera=stored_json(f.camera_json), admitted=bool(f.admitted)),
            optimised_box=None if opt_box is None else ReleasedBox(opt_box),
            reprojection=None if f.rep_error_px is None else ReleasedReprojection(f.rep_error_px)))
    return system
