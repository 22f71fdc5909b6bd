"""Request and response bodies of ``/api/batches`` (vouched systems accepted after a random sample,
``app.services.curation.batches``)."""
from __future__ import annotations

from datetime import datetime
from typing import Any, Optional

from pydantic import BaseModel, Field

from app.api.pass_schemas import PassFilterIn
from app.api.schemas import ErrorOut, _In
from app.db.models import ReviewBatch
from app.services.curation.batches import Stop, Undone, batch_plan


class BatchIn(_In):
    """Make a batch of the pending vouched systems a queue's filters select, and draw its sample."""

    filter: PassFilterIn = Field(default_factory=PassFilterIn, description=(
        "The queue's filters, as GET /api/systems takes them (game_id, jac_min, error_max, doubt, assignee, ...); "
        "`status` may only be pending, `sort` is ignored."))
    confidence: float = Field(0.95, gt=0.0, lt=1.0, description=(
        "How sure one may be, when no sampled system is wrong, that at most `max_wrong_share` of the batch is "
        "(a fraction: 0.95 for 95 %)."))
    max_wrong_share: float = Field(0.05, gt=0.0, lt=1.0, description=(
        "The largest share of wrong systems the plan tolerates (a fraction: 0.05 for 5 %)."))


class StopOut(BaseModel):
    """A system that stops a batch's accept: its id, in words; ``final``: it stops the batch for good (a rejection,
    a change), else the batch waits for it (a sampled system not decided yet)."""

    system_id: int
    words: str
    final: bool

    @classmethod
    def of(cls, stop: Stop) -> "StopOut":
        return cls(system_id=stop.system_id, words=stop.words, final=stop.final)


class BatchOut(BaseModel):
    """A batch: who made it and when, from which filters and plan; ``systems`` (ids of the pending vouched systems
    the filters selected, in id order), ``sample`` (the random subset a person reviews), ``plan`` in words, its
    ``state`` (open, accepted, refused, undone), ``refusal`` (the words that refused it), ``accepted`` (how many
    systems it accepted) and, for an open batch, ``stops``: what stops its accept now (empty: it may be accepted)."""

    id: int
    created_by: str
    created_at: datetime
    filter: dict[str, Any]
    confidence: float
    max_wrong_share: float
    systems: list[int]
    sample: list[int]
    plan: str
    state: str
    refusal: Optional[str]
    accepted: int
    decided_by: Optional[str]
    decided_at: Optional[datetime]
    stops: list[StopOut]

    @classmethod
    def of(cls, facts: dict[str, Any]) -> "BatchOut":
        """From ``app.services.curation.batches.batch_facts``."""
        return cls.model_validate(facts)


class AcceptedOut(BaseModel):
    """How many systems a batch's accept accepted (its unsampled ones)."""

    accepted: int


class UndoneOut(BaseModel):
    """An undone batch: ``undone`` systems back to pending; ``kept``: those a person decided since, left as they
    are."""

    undone: int
    kept: list[StopOut]

    @classmethod
    def of(cls, undone: Undone) -> "UndoneOut":
        return cls(undone=undone.undone, kept=[StopOut.of(s) for s in undone.kept])


#: OpenAPI ``responses`` of a batch's accept and undo.
REFUSED: dict[int | str, dict[str, Any]] = {
    409: {"model": ErrorOut, "description": "The batch cannot be accepted (or undone) now: the message names each "
                                            "system that stops it by id, or says the batch's state."}}


class BatchAcceptanceOut(BaseModel):
    """How a batch accepted the system after a random sample (``app.services.curation.batches``): the batch's id, who
    made it and who accepted it, when, and its zero-acceptance plan in numbers and in words."""

    batch_id: int
    created_by: str
    decided_by: Optional[str] = Field(description="Who accepted the batch (its accept's actor).")
    decided_at: Optional[datetime]
    confidence: float = Field(description="The plan's confidence (a fraction).")
    max_wrong_share: float = Field(description="The largest share of wrong systems the plan tolerates (a fraction).")
    sample: int = Field(description="How many of the batch's systems a person reviewed and accepted (the sample).")
    systems: int = Field(description="How many systems the batch took (the sample included).")
    plan: str = Field(description="The plan in words: 'if none of these 59 is wrong, you can be 95 % sure that at "
                      "most 5 % of the 240 are'.")

    @classmethod
    def of(cls, batch: ReviewBatch) -> "BatchAcceptanceOut":
        return cls(batch_id=batch.id, created_by=batch.created_by, decided_by=batch.decided_by,
                   decided_at=batch.decided_at, confidence=batch.confidence, max_wrong_share=batch.max_wrong_share,
                   sample=len(batch.sample_ids), systems=len(batch.system_ids), plan=batch_plan(batch))
