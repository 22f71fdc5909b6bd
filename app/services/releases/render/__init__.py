"""Release rendering, one module per release document version (``render/v1.py``: what a version 1 release exports
in every format, and the rule for keeping it so when a live writer changes).

This package also holds what a release records of the settings its exports are rendered with
(:class:`ExportSettings`, the row's ``releases.export_settings``): chosen when exporting, not computed into the
stored rows, so without the record a changed setting would change an old release's YOLO and COCO files. The record
lives in the release's row, not in its documents: their digests, and so the release's hash, are what they were.
"""
from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, Literal

from app.core.config import Settings


@dataclass(frozen=True)
class ExportSettings:
    """The settings a release's exports are rendered with: ``ball_diameter_m`` (phi, m: the refined box's sphere,
    ``Settings.ball_diameter_m``) and ``ball_box`` (the detector exports' ball box, "refined" or "optimised":
    ``Settings.export_ball_box``)."""

    ball_diameter_m: float
    ball_box: Literal["refined", "optimised"]

    @classmethod
    def of(cls, settings: Settings) -> ExportSettings:
        """The export settings of ``settings`` (the process's, when a release is made)."""
        return cls(settings.ball_diameter_m, settings.export_ball_box)

    def as_json(self) -> dict[str, Any]:
        """As a release row records them: by the settings' names (``{"ball_diameter_m", "export_ball_box"}``)."""
        return {"ball_diameter_m": self.ball_diameter_m, "export_ball_box": self.ball_box}

    @classmethod
    def from_json(cls, data: Mapping[str, Any]) -> ExportSettings:
        """What :meth:`as_json` recorded.

        Raises:
            KeyError: a key missing (a damaged record). ValueError: a ball box no version knows.
        """
        box = data["export_ball_box"]
        if box not in ("refined", "optimised"):
            raise ValueError(f"recorded export_ball_box {box!r} is none of 'refined', 'optimised'")
        return cls(float(data["ball_diameter_m"]), box)
