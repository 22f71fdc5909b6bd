"""What a release of document version 1 exports, in every format: the one place that decides it.

A release promises that its files never change: an export of it in a format that existed when it was made is byte
for byte the same after any upgrade (``tests/services/releases/golden/v1``: a stored version 1 release and its
exact export per format). This module renders version 1 documents (``app.services.releases.document``); the
orchestration that reads a release's documents and stored frames in order is ``app.services.releases.export``,
version-independent.

What version 1 owns here, frozen: the typed rows and systems the writers read, built from the documents (each value
the writers read is a typed attribute, so mypy checks every value handed on); which kinds each format takes
(:data:`KINDS`, the live list when version 1 was written, so a kind added to a format later stays out of older
releases); and the settings of the releases made before releases recorded theirs (:data:`EXPORT_SETTINGS`).

**The seam.** The bytes themselves are written by the live export's functions, called only here and listed in
:data:`SEAM`: each is a pure function of the typed values of this module and of explicit arguments (the refined box's
``ball_diameter_m`` and ``export_ball_box`` come from the release, :func:`export_settings`, never from the process's
settings), reads no database and no clock. Sharing them keeps one writer per format instead of a copy per version
while none has changed. **The rule:** a change to a function of :data:`SEAM` that changes what it writes for these
inputs keeps the function as it was for version 1: copy it (and what it calls that changes) into this package
(``render/v1_<format>.py``), point this module at the copy, then change the live one. The golden tests fail until
that is done; they are the check, this module is the place for the old code. A new document version adds
``render/v<N>.py`` (its rows, kinds and seam) beside this one and leaves this one as it is.
"""
from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal, Optional, Union

from sqlalchemy.orm import Session

from app.db.models import (
    JAC_COLUMNS,
    BallLabel,
    CalibrationSource,
    CalibrationStatus,
    Frame,
    FrameRole,
    Release,
    ReviewStatus,
    SystemKind,
)
from app.db.types import json_loads
from app.services.issia.export import Issia3DExport, rows_of, write_sequence
from app.services.kinds import POLICIES
from app.services.releases.document import FrameDocument, GameDocument, SystemDocument, TrajectoryDocument
from app.services.releases.render import ExportSettings
from app.services.storage.datasets import DatasetFiles
from app.services.transfer.cameras_export import CamerasExport, CameraView, pooled_lines, write_camera_sets
from app.services.transfer.detector_export import DetectorExportReport, export_detector
from app.services.transfer.exporting import ExportedGame, exported_game, safe_component

#: The live export's functions version 1 renders through (module docstring: each a pure function of this module's
#: typed values and explicit arguments; a change to one that changes its output keeps a copy for version 1 here).
#: ``POLICIES``: the kinds' ``view_stem`` and ``split`` (a view's file name and split from its game and frame).
#: ``tests/services/releases/test_render.py`` checks that this module calls no other function of the live exports.
SEAM = (exported_game, export_detector, rows_of, write_sequence, write_camera_sets, pooled_lines, safe_component,
        POLICIES, BallLabel.centre_of)

#: Per format, the kinds (``SystemKind`` values) whose released systems it writes: the live lists
#: (``app.services.kinds.kinds_exported_by``) when version 1 was written, kept here so that a kind given a format
#: later stays out of the releases made before.
KINDS: dict[str, frozenset[str]] = {
    "soccernet-v3d": frozenset({"soccernet-v3"}),
    "yolo": frozenset({"soccernet-v3", "single-view", "issia"}),
    "coco": frozenset({"soccernet-v3", "single-view", "issia"}),
    "cameras": frozenset({"soccernet-v3", "single-view"}),
    "issia-3d": frozenset({"issia"}),
}

#: The export settings of a release made before releases recorded theirs (``releases.export_settings`` NULL): the
#: defaults when version 1 was written (phi 0.22 m, the refined box), written here as values, never read from the
#: live defaults, which may change.
EXPORT_SETTINGS = ExportSettings(ball_diameter_m=0.22, ball_box="refined")


def export_settings(release: Release) -> ExportSettings:
    """The settings ``release``'s exports are rendered with: those it recorded when made, else
    :data:`EXPORT_SETTINGS`."""
    recorded = release.export_settings
    return EXPORT_SETTINGS if recorded is None else ExportSettings.from_json(recorded)


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


def soccernet_game(game: GameDocument, systems: Sequence[SystemDocument],
                   marker: dict[str, str]) -> Optional[ExportedGame]:
    """The SoccerNet-v3D export of one released game (``exporting.exported_game`` of its systems' rows, the game as
    of its document's ``as_of``), ``GameMetadata.v3d_release`` the release's ``marker`` (``{"name", "hash"}``);
    None when none of its systems is of a kind the format takes (:data:`KINDS`)."""
    rows = [released_row(s, f) for s in systems if s.kind in KINDS["soccernet-v3d"] for f in s.frames]
    if not rows:
        return None
    exported = exported_game(game, rows, game.as_of)
    exported.doc["GameMetadata"]["v3d_release"] = marker
    return exported


@dataclass(frozen=True)
class _CameraFrame:
    """What a kind's view name and split read of a view of the cameras export."""

    name: str
    split: Optional[str]


@dataclass(frozen=True)
class _CameraSystem:
    """What a kind's split reads of a view's system: its game."""

    game: GameDocument


def camera_views(game: GameDocument, system: SystemDocument) -> list[CameraView]:
    """The views of the cameras export (``cameras_export.camera_views``) of one released system of ``game``: each
    view with field lines or an admitted camera, named and split as the kind names them (none for a kind the format
    does not take, :data:`KINDS`)."""
    if system.kind not in KINDS["cameras"]:
        return []
    policy = POLICIES[SystemKind(system.kind)]
    holder = _CameraSystem(game)
    out = []
    for f in system.frames:
        camera = stored_json(f.camera_json) if f.cal_source is not None and f.admitted else None
        stored = stored_json(f.lines_json)
        if camera is None and not stored:
            continue
        frame = _CameraFrame(f.name, f.frame_split)
        jac = {str(g): getattr(f, col) if f.cal_source is not None else None for g, col in JAC_COLUMNS.items()}
        out.append(CameraView(policy.view_stem(game, frame), policy.split(holder, frame),  # type: ignore[arg-type]  # the documents' game and frame stand in for the rows
                              game.path, f.name, system.kind, f.width, f.height, camera,
                              pooled_lines(stored, f.width, f.height) if stored else None, jac))
    return out


def cameras(out_dir: Path, views: Iterable[CameraView]) -> CamerasExport:
    """The cameras export of a release's views (:func:`camera_views`) under ``out_dir``
    (``cameras_export.write_camera_sets``).

    Raises:
        InvalidInputError: two views of one name, or a name that cannot be a file name (nothing written).
    """
    return write_camera_sets(out_dir, views)


def issia_3d(out_dir: Path, systems: Iterable[ReleasedSystem]) -> Issia3DExport:
    """The ISSIA-3D export of released ISSIA systems under ``out_dir`` (``issia.export``: per sequence, by match then
    game id, ``ISSIA-3D.csv`` of its frames in frame order, ``split.json`` and the cameras, each camera the admitted
    one of its view at the first released frame index that has one).

    Raises:
        InvalidInputError: a match that cannot be a folder name.
    """
    report = Issia3DExport(out_dir)
    per_game: dict[int, list[ReleasedSystem]] = {}
    for system in systems:
        if system.kind.value in KINDS["issia-3d"]:
            per_game.setdefault(system.game.game_id, []).append(system)
    for sequence in sorted(per_game.values(), key=lambda ss: (ss[0].game.match, ss[0].game.game_id)):
        sequence.sort(key=lambda s: (s.frame_index is None, s.frame_index or 0, s.id))
        rows = rows_of(sequence)
        if not rows:
            continue
        found: dict[str, Any] = {}
        for s in sequence:
            for f in s.frames:
                if f.calibration is not None and f.calibration.admitted and f.calibration.camera is not None:
                    found.setdefault(f.name, f.calibration.camera)
        write_sequence(out_dir / safe_component(sequence[0].game.match, "match"), rows, dict(sorted(found.items())),
                       report)
        report.sequences += 1
        report.rows += len(rows)
    return report


def detector(session: Session, fmt: Literal["yolo", "coco"], out_dir: Path, systems: Iterable[ReleasedSystem],
             marker: dict[str, str], settings: ExportSettings, files: DatasetFiles) -> DetectorExportReport:
    """The YOLO or COCO export of released systems under ``out_dir`` (``detector_export.export_detector``), their
    ball boxes chosen with the release's ``settings`` (:func:`export_settings`), never the process's; the release
    named by ``marker`` (``{"name", "hash"}``); ``files``: where the stored frames' images are read."""
    wanted = (s for s in systems if s.kind.value in KINDS[fmt])
    return export_detector(session, fmt, out_dir, False, settings.ball_diameter_m, settings.ball_box,
                           systems=wanted, release=marker, files=files)
