"""Request and response bodies of ``/api/passes`` (review passes, ``app.services.curation.passes``)."""
from __future__ import annotations

from datetime import datetime
from typing import Any, Optional

from pydantic import BaseModel, ConfigDict, Field

from app.api.schemas import DbInt, QueueQuery, _In
from app.db.models import ReviewPass
from app.services.curation.passes import PassPlace
from app.services.curation.queue import SystemSort


class PassFilterIn(QueueQuery):
    """:class:`QueueQuery` as a field of a JSON body: unknown fields are refused (the query string's are ignored, as
    a page may forward its own state); a boolean for a number is refused by the body holding it (``_In``)."""

    model_config = ConfigDict(allow_inf_nan=False, extra="forbid")



class PassIn(_In):
    """Begin (or continue) a pass over a review queue."""

    filter: PassFilterIn = Field(default_factory=PassFilterIn, description=(
        "The queue's filters, as GET /api/systems takes them (game_id, status, jac_min, jac_max, error_min, "
        "error_max, doubt); a `sort` here is overridden by the body's `sort`."))
    sort: Optional[SystemSort] = Field(None, description="The queue's order (GET /api/systems' `sort`); default: the "
                                "filter's sort, else the work to do first, the most severe doubt first.")
    system_id: Optional[DbInt] = Field(None, description="The system opened: the pass starts there, and an open "
                                       "pass of the same queue holding it is continued.")
    fresh: bool = Field(False, description="true: freeze a new pass even when one of this queue is open.")


class VisitIn(_In):
    """The system the pass's owner opened."""

    system_id: DbInt


class PassCounts(BaseModel):
    """The pass's systems (``app.services.curation.passes.COUNT_KEYS``): the owner's own decisions in this pass, then
    the rest by their current status."""

    accepted: int = Field(description="Accepted by the pass's owner in this pass (and still so).")
    rejected: int = Field(description="Rejected by the pass's owner in this pass.")
    needs_fix: int = Field(description="Returned for a fix by the pass's owner in this pass.")
    sent_back: int = Field(description="Sent back as fixed by the annotator it was returned to: to decide again.")
    by_others: int = Field(description="Decided, not by the pass's owner in this pass (another reviewer, or before).")
    skipped: int = Field(description="Still pending: visited or stepped over without a decision.")


class PassOut(BaseModel):
    """A review pass: its queue (``filter``, ``sort``), the frozen ``systems`` (ids, in the order the queue
    had when the pass began, every page), the ``position`` (index in ``systems``) last opened by its owner."""

    id: int
    user: str
    filter: dict[str, Any]
    sort: str
    systems: list[int]
    position: int
    total: int
    counts: PassCounts
    created_at: datetime
    visited_at: datetime

    @classmethod
    def of(cls, rp: ReviewPass, counts: dict[str, int], with_systems: bool = True) -> "PassOut":
        return cls(id=rp.id, user=rp.user_name, filter=dict(rp.filters), sort=rp.sort,
                   systems=list(rp.system_ids) if with_systems else [], position=rp.position,
                   total=len(rp.system_ids), counts=PassCounts(**counts), created_at=rp.created_at,
                   visited_at=rp.visited_at)


class PassPlaceOut(BaseModel):
    """Where a system stands in a pass (statuses read now): ``index`` (null: not in the pass), its
    neighbours in the pass's order, the next system after it that is still pending (wrapping round to the pass's
    start) and its index, the first pending one of the pass, the counts, and ``finished`` (no other system of the
    pass is pending)."""

    pass_id: int
    index: Optional[int]
    total: int
    prev_id: Optional[int]
    next_id: Optional[int]
    next_pending_id: Optional[int]
    next_pending_index: Optional[int]
    first_pending_id: Optional[int]
    counts: PassCounts
    finished: bool

    @classmethod
    def of(cls, p: PassPlace) -> "PassPlaceOut":
        return cls(pass_id=p.pass_id, index=p.index, total=p.total, prev_id=p.prev_id, next_id=p.next_id,
                   next_pending_id=p.next_pending_id, next_pending_index=p.next_pending_index,
                   first_pending_id=p.first_pending_id,
                   counts=PassCounts(**p.counts), finished=p.finished)
