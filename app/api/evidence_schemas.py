"""What backs a system's 3D ball as the system view and the queue's rows answer it (``docs/api.md``): the tier the
recomputation stored (``System.ball_evidence``, ``app.geometry.ball_evidence``) and its reasons."""
from __future__ import annotations

from typing import Any

from pydantic import BaseModel, Field

from app.db.models import BallEvidence, System


class BallEvidenceFields(BaseModel):
    """The two fields a model of a system answers beside its 3D ball."""

    ball_evidence: BallEvidence = Field(
        BallEvidence.NONE, description="What backs the 3D ball (app.geometry.ball_evidence): vouched (no label doubt, "
        "and evidence beside its two rays agrees), unconfirmed (nothing but its views' own agreement), doubted (a "
        "label doubt names a view it uses), none (no 3D ball).")
    ball_evidence_reasons: list[str] = Field(
        default_factory=list, description="Why, as short phrases (\"three views agree\", \"only two views: nothing "
        "else checks it\"); empty without a ball.")


def evidence_fields(system: System) -> dict[str, Any]:
    """:class:`BallEvidenceFields` of ``system``, as stored by its last recomputation."""
    return {"ball_evidence": system.ball_evidence, "ball_evidence_reasons": list(system.ball_evidence_reasons or [])}
