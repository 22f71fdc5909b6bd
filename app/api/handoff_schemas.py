"""Schemas of the hand-off of systems marked needs fix (``app.api.routes.handoffs``): a system decision's answer with
the hand-off it made, what waits for the caller, and a system's newest hand-off."""
from __future__ import annotations

from typing import Optional

from pydantic import BaseModel, Field

from app.api.schemas import ReviewIn
from app.api.view_schemas import CalibrationReviewOut, ReviewOut


class SystemReviewIn(ReviewIn):
    """A system's decision; a needs fix may name whom it goes to."""

    assignee: Optional[str] = Field(None, max_length=200, description=(
        "needs_fix only: the enabled user the system is returned to, chosen by the reviewer. Without it the system "
        "goes to the last editor of its labels, else its assignee; when there is neither the decision is refused "
        "(400 naming this field): it is never returned to nobody."))


class DecisionOut(ReviewOut):
    """A system decision's answer: the decision, and for needs_fix / fixed the hand-off it made
    (``app.services.curation.handoff``)."""

    returned_to: Optional[str] = Field(None, description="needs_fix / fixed only: the user the system went to (the "
                                       "person who fixes it, or the reviewer who re-reviews it); null when nobody "
                                       "(``handoff`` says why).")
    handoff: Optional[str] = Field(None, description="That hand-off in words: \"returned to ana by rev: the box "
                                   "sits on the shadow\".")


# ReviewOut names its views' calibration decision by a forward reference: resolved here, where the subclass lives
DecisionOut.model_rebuild(_types_namespace={"CalibrationReviewOut": CalibrationReviewOut})


class MyWorkOut(BaseModel):
    """What waits for the caller."""

    to_fix: int = Field(description="Systems returned to you (marked needs fix), still open.")
    to_re_review: int = Field(description="Systems you returned that came back fixed (status fixed, assigned to you).")
    to_fix_ids: list[int] = Field(description="The systems to fix, the oldest hand-off first (at most 200): the "
                                  "list the system page walks after each 'Send back as fixed'.")


class HandOffOut(BaseModel):
    """A system's newest hand-off."""

    returned_to: Optional[str] = Field(description="Who it was returned to (null: nobody could be found).")
    returned_by: str = Field(description="The reviewer who marked it needs fix.")
    fixed: bool = Field(description="Sent back as fixed (then assigned to the reviewer again).")
    open: bool = Field(description="Still returned to that person (an edit meanwhile does not close it).")
    words: str = Field(description="The hand-off in words.")
    may_send_fixed: bool = Field(description="The caller is the person it is returned to, and may send fixed.")
