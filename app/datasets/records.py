"""Validated dataset input, nothing stored yet: the plain records every reader of ``app.datasets``
produces and ``app.services.transfer.importing`` stores (games, multi-view systems, frames with their field
lines in pixels, ball labels and, for exports, calibrations)."""
from __future__ import annotations

from dataclasses import dataclass, field
from datetime import datetime
from typing import Any

from app.db.models import BallKind, CalibrationStatus, FrameRole, ReviewStatus, SystemKind


@dataclass(frozen=True)
class CalibrationFields:
    """What is stored of a calibration: plain values, picklable across processes.

    Attributes:
        status: calibrated or refused.
        camera: SoccerNet camera JSON (method.md section 2) at the frame's resolution, or None.
        jac: JaC at the gammas of ``JAC_GAMMAS`` (None where not computed).
        residuals_px: class -> residual in pixels.
        flags: warnings raised by calibration (e.g. probable mirrored labels).
        reason: why calibration was refused (None when calibrated).
        elapsed_ms: wall time of the calibration, rig positions and mirrored-labels check included
            (not stored; import reports use it).
        rms_px: RMS distance (px) of every labelled point to its model element under the camera, or
            under the best rejected one (not stored): how a rig retry is compared with the first
            result (:func:`app.services.calibration.rigs.with_rig_retry`).
        mirror_evidence: for a frame refused even with the game's rig whose mirrored labels fit a
            rig position (``app.geometry.mirror.mirrored_fit_at_rig``), that evidence (JSON); the
            flag ``MIRROR_FLAG`` is then in ``flags``. Calibrated frames get theirs from
            ``recompute_system``.
        uncertainty: standard deviations of the camera's parameters from the line fit
            (``app.geometry.calibration.CalibrationUncertainty.to_json``), None when refused or imported.
    """

    status: CalibrationStatus
    camera: dict[str, Any] | None
    jac: tuple[float | None, float | None, float | None]
    residuals_px: dict[str, Any] = field(default_factory=dict)
    flags: list[str] = field(default_factory=list)
    reason: str | None = None
    refusal: str | None = None
    elapsed_ms: float | None = None
    mirror_evidence: dict[str, Any] | None = None
    uncertainty: dict[str, Any] | None = None
    rms_px: float | None = None
    #: A camera the players placed: what it was fitted to (``Calibration.players``); None for a camera from lines.
    players: dict[str, Any] | None = None


@dataclass(frozen=True)
class ImportedCalibration:
    """A calibration read from a SoccerNet-v3D export (stored with source "imported")."""

    fields: CalibrationFields


@dataclass(frozen=True)
class FrameRecord:
    """One validated frame: size, image source, field lines (JSON lists, pixels), ball label.

    The image source is the dataset's folder ``image_root`` (absolute, resolved) and, relative to it
    (POSIX), a zip ``image_zip`` with its member ``image_member`` or a file ``image_path``; the readers
    checked that it resolves inside ``image_root`` (``app.datasets.files.inside_dataset``)."""

    name: str
    role: FrameRole
    width: int
    height: int
    lines: dict[str, Any]
    ball_box: list[float] | None = None
    ball_point: list[float] | None = None
    image_zip: str | None = None
    image_member: str | None = None
    image_path: str | None = None
    image_root: str | None = None
    #: The image's type read from its header ("png" or "jpeg", ``app.datasets.files.image_header``).
    image_type: str | None = None
    calibration: ImportedCalibration | None = None
    #: Exports carry the imported originals too (``None``: the current values are the originals).
    original_lines: dict[str, Any] | None = None
    original_ball: tuple[BallKind | None, list[float] | None, list[float] | None] | None = None
    #: What a release carries of the frame that v3d does not edit (stored as ``frames.release``): the frame's
    #: entry of the labels file as imported, every key (``imageMetadata``, every ``bboxes`` entry with the
    #: imported ball's, ``linked_replays`` / ``linked_action``, ...), without ``lines`` when the stored field
    #: lines give them back (``app.datasets.soccernet_v3.release_entry``); None for formats without one.
    release: dict[str, Any] | None = None
    #: The people the dataset boxed besides the ball (``app.datasets.soccernet_v3.v3_players``): ``(class, ID or
    #: None, [x1, y1, x2, y2] px)`` each, in the file's order, at most the reader's cap of them.
    players: tuple[tuple[str, str | None, tuple[float, float, float, float]], ...] = ()
    #: The ``bboxes`` entries besides the ball beyond the reader's cap (``V3D_MAX_PLAYERS_PER_FRAME``): counted, never
    #: read, kept or released.
    players_dropped: int = 0


@dataclass(frozen=True)
class SystemRecord:
    """One system: its name, kind and frames (the action first)."""

    name: str
    kind: SystemKind
    frames: list[FrameRecord]
    review: ReviewStatus | None = None


@dataclass(frozen=True)
class GameRecord:
    """One game and its systems."""

    league: str
    season: str
    match: str
    source_path: str
    systems: list[SystemRecord]
    #: What the labels file carries beside its systems (stored as ``games.release``): its top-level keys other
    #: than ``actions`` and ``replays`` (``GameMetadata``, every key), and under ``replays`` the replays no
    #: action links (they belong to no system); None for formats without one.
    release: dict[str, Any] | None = None
    #: The time of the game's newest change the file holds (UTC; a SoccerNet-v3D export's ``GameMetadata.v3d_as_of``),
    #: None for a release or a file without one: what a ``keep-newer`` merge compares the stored changes with.
    as_of: datetime | None = None
