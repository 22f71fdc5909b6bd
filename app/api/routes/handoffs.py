"""The hand-off of systems marked needs fix (``app.services.curation.handoff``), as the pages read it.

* ``GET /api/handoffs/mine``: what waits for the caller: ``to_fix`` (systems returned to them) and ``to_re_review``
  (systems they returned that came back fixed): the queue page's **To fix** and **To re-review** counts.
* ``GET /api/systems/{id}/handoff``: the system's newest hand-off in words, and whether the caller may send it back
  as fixed (``POST /api/systems/{id}/review`` ``{"status": "fixed"}``).
"""
from __future__ import annotations

from typing import Optional

from fastapi import APIRouter
from pydantic import BaseModel, Field

from app.api.auth import PrincipalDep
from app.api.deps import SessionDep, SystemDep
from app.api.schemas import NOT_FOUND
from app.api.view_schemas import CalibrationReviewOut, ReviewOut
from app.services.curation import handoff

router = APIRouter(tags=["assignments"])


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


class HandOffOut(BaseModel):
    """A system's newest hand-off."""

    returned_to: Optional[str] = Field(description="Who it was returned to (null: nobody could be found).")
    returned_by: str = Field(description="The reviewer who marked it needs fix.")
    fixed: bool = Field(description="Sent back as fixed (then assigned to the reviewer again).")
    open: bool = Field(description="Still returned to that person (an edit meanwhile does not close it).")
    words: str = Field(description="The hand-off in words.")
    may_send_fixed: bool = Field(description="The caller is the person it is returned to, and may send fixed.")


@router.get("/handoffs/mine", response_model=MyWorkOut)
def my_work(session: SessionDep, principal: PrincipalDep) -> MyWorkOut:
    """The caller's **To fix** and **To re-review** counts (0 when nothing waits)."""
    work = handoff.my_work(session, principal.user_id)
    return MyWorkOut(to_fix=work.to_fix, to_re_review=work.to_re_review)


@router.get("/systems/{system_id}/handoff", response_model=Optional[HandOffOut], responses=NOT_FOUND)
def system_handoff(session: SessionDep, principal: PrincipalDep, system: SystemDep) -> Optional[HandOffOut]:
    """The system's newest hand-off, or null when it was never marked needs fix."""
    made = handoff.latest_handoff(session, system.id)
    if made is None:
        return None
    return HandOffOut(returned_to=made.returned_to, returned_by=made.returned_by, fixed=made.fixed, open=made.open,
                      words=made.words,
                      may_send_fixed=handoff.returned_to_user(session, system.id, principal.user_id))
