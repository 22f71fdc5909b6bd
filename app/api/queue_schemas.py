"""Response models of the review queue (``GET /api/systems``, ``docs/api.md``): a page of rows, each a system's stored
figures with its game, review decision, 3D ball, assignment and who has it open. Shaped from a system loaded as ORM
objects (:meth:`SystemSummaryOut.of`) or from the plain row the queue reads (:meth:`SystemSummaryOut.of_row`); world
metres (SoccerNet: origin at the centre spot, z down), JaC as fractions in [0, 1], errors in px.
"""
from __future__ import annotations

from collections.abc import Mapping
from typing import Any, Optional

from pydantic import BaseModel, ConfigDict, Field

from app.api.assignment_schemas import AssignmentOut, PresenceOut
from app.api.evidence_schemas import BallEvidenceFields
from app.api.view_schemas import GameRef, Point3, ReviewOut
from app.db.models import ReviewStatus, System, SystemKind

_ORM = ConfigDict(from_attributes=True)


class SystemSummaryOut(BallEvidenceFields):
    """A row of the review queue: figures stored by the system's last recomputation (aggregates over the
    admitted views, ``app.services.derivation.recompute.update_summary``)."""

    model_config = _ORM

    id: int
    name: str
    kind: SystemKind
    game: GameRef
    review: ReviewOut
    ball3d: Optional[Point3]
    ball_sigma_m: Optional[float] = Field(None, description="The 3D ball's sigma (m, its least certain direction).")
    views_total: int
    views_calibrated: int
    views_admitted: int
    views_labelled: int
    lowest_jac: Optional[float] = Field(description="Lowest JaC@0.5% among admitted views.")
    worst_error_px: Optional[float] = Field(description="Largest reprojection error among admitted views, px.")
    views_flagged: int = Field(description="Views whose field-line labels are flagged probably mirrored.")
    views_above_tau: int = Field(
        description="Admitted labelled views whose reprojection error is above tau (the system view's "
        "error_above_tau rule: error scaled to the rule's reference width, compared with the stored tau).")
    doubt_counts: dict[str, int] = Field(description="Stored doubts of the system per kind.")
    label_doubts: int = Field(description="How many of its doubts accuse a label.")
    assignment: Optional[AssignmentOut] = Field(None, description="Who the system is assigned to.")
    open_by: list[PresenceOut] = Field(default_factory=list,
                                       description="Who has the system open now (live claims, oldest first).")

    @classmethod
    def of(cls, system: System, assignment: Optional[AssignmentOut] = None,
           open_by: Optional[list[PresenceOut]] = None) -> "SystemSummaryOut":
        """A queue row from a system loaded with its game, review and triangulation, with its assignment and
        presence when given."""
        tri = system.triangulation
        shaped = ("game", "review", "ball3d", "ball_sigma_m", "assignment", "open_by")
        return cls.model_validate({
            **{name: getattr(system, name) for name in cls.model_fields if name not in shaped},
            "game": system.game, "review": ReviewOut.of(system.review),
            "ball3d": None if tri is None else tri.ball3d, "ball_sigma_m": None if tri is None else tri.sigma_m,
            "doubt_counts": system.doubt_counts or {}, "assignment": assignment, "open_by": open_by or [],
        })

    @classmethod
    def of_row(cls, row: Mapping[Any, Any], assignment: Optional[AssignmentOut] = None,
               open_by: Optional[list[PresenceOut]] = None) -> "SystemSummaryOut":
        """A queue row from the plain row of ``app.services.curation.queue.SUMMARY_COLUMNS`` (``list_system_rows``):
        what :meth:`of` answers for the same system loaded as ORM objects (a system never decided: a pending
        ``review``; without a triangulation: no ball, no sigma), validated from plain values."""
        return cls.model_validate({
            **{name: row[name] for name in _SUMMARY_PLAIN},
            "game": {"id": row["game_id"], "league": row["league"], "season": row["season"], "match": row["match"]},
            "review": {} if row["review_id"] is None else {
                "status": row["review_status"], "comment": row["review_comment"],
                "decided_at": row["review_decided_at"], "excluded": row["review_excluded"],
                "reset_reason": row["review_reset_reason"], "batch_id": row["review_batch_id"]},
            "ball3d": row["ball3d"], "ball_sigma_m": row["sigma_m"],
            "doubt_counts": row["doubt_counts"] or {}, "assignment": assignment, "open_by": open_by or [],
        })


#: The fields of :class:`SystemSummaryOut` a queue row holds under their own names (the others are shaped).
_SUMMARY_PLAIN = tuple(name for name in SystemSummaryOut.model_fields
                       if name not in ("game", "review", "ball3d", "ball_sigma_m", "doubt_counts", "assignment",
                                       "open_by"))


class SystemPageOut(BaseModel):
    """A page of the queue; ``counts`` per review status over the filters other than ``status``."""

    items: list[SystemSummaryOut]
    total: int
    limit: int
    #: The offset asked for; None for a page asked by cursor (``after`` / ``before``).
    offset: Optional[int]
    counts: dict[ReviewStatus, int]
    #: ``after=`` this for the next page, ``before=`` this for the previous; None at either end.
    next_cursor: Optional[str] = None
    prev_cursor: Optional[str] = None
