"""Validated dataset input, nothing stored yet: the plain records every reader of ``app.datasets``
produces and ``app.services.importing`` stores (games, multi-view systems, frames with their field
lines in pixels, ball labels and, for exports, calibrations)."""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from app.db.models import BallKind, FrameRole, ReviewStatus, SystemKind
from app.services.calibrating import CalibrationFields


@dataclass(frozen=True)
class ImportedCalibration:
    """A calibration read from a SoccerNet-v3D export (stored with source "imported")."""

    fields: CalibrationFields


@dataclass(frozen=True)
class FrameRecord:
    """One validated frame: size, image source, field lines (JSON lists, pixels), ball label."""

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
    calibration: ImportedCalibration | None = None
    #: Exports carry the imported originals too (``None``: the current values are the originals).
    original_lines: dict[str, Any] | None = None
    original_ball: tuple[BallKind | None, list[float] | None, list[float] | None] | None = None


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
