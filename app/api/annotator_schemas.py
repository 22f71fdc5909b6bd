"""Pydantic schemas of ``GET /api/stats/annotators`` (``app.api.routes.annotators``): each person's figures as an
annotator and as a reviewer (``app.services.evaluation.annotators``)."""
from __future__ import annotations

from typing import Optional

from pydantic import BaseModel, Field


class AnnotatorOut(BaseModel):
    """One person's figures as an annotator and as a reviewer (``docs/teams.md``)."""

    name: str
    edits: int = Field(description="Label edits (ball, field lines, mirror, exclusion) in the window.")
    systems_touched: int = Field(description="Systems those edits were on.")
    systems_decided: int = Field(description="Of those, the systems accepted or rejected now.")
    needs_fix_received: int = Field(description="Systems marked needs fix and returned to this person.")
    accepted_first_review: int = Field(description="Systems touched, accepted now and never returned to anyone.")
    median_edit_to_review_s: Optional[float] = Field(description="Median seconds from their last edit of a system to "
                                                     "the next system decision.")
    median_label_distance_px: Optional[float] = Field(description="Median distance of their ball labels from the ball "
                                                      "the other views agree on (px of a 1920-wide image).")
    accused_share: Optional[float] = Field(description="Share of their ball labels a label-accusing doubt names.")
    decisions: int = Field(description="As a reviewer: system decisions made in the window (undo and revert aside).")
    accepted: int = Field(description="Of those, the accepts.")
    rejected: int = Field(description="Of those, the rejections.")
    needs_fix: int = Field(description="Of those, the systems marked needs fix (returned to their annotator).")
    re_reviews: int = Field(description="Of those, decisions on a system that came back fixed.")


class AnnotatorsOut(BaseModel):
    """Every person's figures, by name."""

    items: list[AnnotatorOut]
