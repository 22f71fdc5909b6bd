"""ISSIA multi-view systems: one frame index of a sequence seen by six static cameras around the pitch.

The sequence's physical trajectory (``app.services.issia.trajectory``) chooses the labels a system's
triangulation uses and judges them; an edit re-fits the stretch of the trajectory it touches, which may
recompute other systems of the sequence (``app.services.issia.sequences.refit_after_edit``), so an edit
locks the sequence's game row first.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Sequence

from app.db.models import Frame, System, SystemKind
from app.services.kinds.base import KindPolicy

if TYPE_CHECKING:
    from sqlalchemy.orm import Session

    from app.core.config import Settings
    from app.geometry.camera import Camera
    from app.geometry.doubts import Doubt as DoubtFinding
    from app.geometry.triangulation import BallObservation


@dataclass(frozen=True)
class IssiaPolicy(KindPolicy):
    """Static cameras on every side of the pitch: no broadcast priors, no game rig; the trajectory."""

    def consensus_observations(self, system: System, observations: list[BallObservation],
                               settings: Settings) -> list[BallObservation]:
        """The labels the sequence's trajectory keeps that agree (``app.services.issia.trajectory``)."""
        from app.services.issia.trajectory import consensus_observations
        return consensus_observations(system, observations, settings)

    def judge_doubts(self, system: System, found: list[DoubtFinding],
                     cameras: dict[int, Camera] | None) -> list[DoubtFinding]:
        """The multi-view doubts merged with the trajectory's judgement of the labels (issue 9)."""
        from app.services.issia.trajectory import merge_doubts
        return merge_doubts(system, found, cameras)

    def refit_after_edit(self, session: Session, system: System, settings: Settings,
                         recalibrated: Frame | None = None) -> Sequence[System]:
        """Re-fit the trajectory's stretch the edit touches and recompute the systems whose place on it
        changed (``app.services.issia.sequences.refit_after_edit``)."""
        from app.services.issia.sequences import refit_after_edit
        return refit_after_edit(session, system, settings, recalibrated=recalibrated)


ISSIA = IssiaPolicy(
    kind=SystemKind.ISSIA,
    import_formats=("issia",),
    exports=frozenset({"soccernet-v3d", "yolo", "coco", "monocular", "issia-3d"}),
    broadcast_priors=False,
    edit_locks_game=True,
)
