"""``/api/batches``: accept the vouched systems of a queue after a random sample (``app.services.curation.batches``):
make a batch and its sample, review the sample in a pass, accept the rest, undo."""
from __future__ import annotations

from fastapi import APIRouter, status

from app.api.auth import PrincipalDep, ReviewerDep
from app.api.batch_schemas import REFUSED, AcceptedOut, BatchIn, BatchOut, UndoneOut
from app.api.deps import SessionDep, SettingsDep
from app.api.pass_schemas import PassOut
from app.api.schemas import INVALID, NOT_FOUND, DbInt
from app.db.models import ReviewBatch
from app.services.curation import batches, passes

router = APIRouter(prefix="/batches", tags=["batches"])


def _out(session: SessionDep, batch: ReviewBatch) -> BatchOut:
    return BatchOut.of(batches.batch_facts(session, batch))


@router.post("", response_model=BatchOut, status_code=status.HTTP_201_CREATED, responses=INVALID)
def create_batch(session: SessionDep, principal: ReviewerDep, body: BatchIn) -> BatchOut:
    """Make a batch of the pending systems whose ball is vouched for that the queue's ``filter`` selects, with a
    random ``sample`` of the zero-acceptance plan's size, ``min(N, ceil(ln(1 - confidence) / ln(1 - max_wrong_share)))``
    (59 for 95 % and 5 %), and the ``plan`` in words. Batches may overlap; making one reserves nothing. Reviewers and
    admins."""
    batch = batches.create_batch(session, principal.name, body.filter.filters(me=principal.name), body.confidence,
                                 body.max_wrong_share)
    return _out(session, batch)


@router.get("/{batch_id}", response_model=BatchOut, responses=NOT_FOUND)
def read_batch(session: SessionDep, principal: PrincipalDep, batch_id: DbInt) -> BatchOut:
    """A batch, and for an open one what stops its accept now (``stops``, empty when it may be accepted)."""
    return _out(session, batches.get_batch(session, batch_id))


@router.post("/{batch_id}/accept", response_model=AcceptedOut, responses={**NOT_FOUND, **REFUSED})
def accept_batch(session: SessionDep, principal: ReviewerDep, batch_id: DbInt) -> AcceptedOut:
    """Accept the batch's unsampled systems in one write, each with its audit entry (``after.review.batch_id``),
    when every sampled system was accepted by a person since the batch was made and no system changed since but
    for a sampled one's decision; otherwise 409 naming each system that stops it ("system 42 was rejected"): a
    rejected or changed system refuses the batch for good, a sample not yet decided only waits."""
    return AcceptedOut(accepted=batches.accept_batch(session, batch_id, principal.name))


@router.post("/{batch_id}/undo", response_model=UndoneOut, responses={**NOT_FOUND, **REFUSED})
def undo_batch(session: SessionDep, principal: ReviewerDep, batch_id: DbInt) -> UndoneOut:
    """Put the systems the batch accepted back to pending, each with its audit entry; those a person decided since
    are kept as they are (``kept``). 409 for a batch that accepted nothing."""
    return UndoneOut.of(batches.undo_batch(session, batch_id, principal.name))


@router.post("/{batch_id}/pass", response_model=PassOut, status_code=status.HTTP_201_CREATED, responses=NOT_FOUND)
def sample_pass(session: SessionDep, settings: SettingsDep, principal: ReviewerDep, batch_id: DbInt) -> PassOut:
    """The caller's review pass over the batch's sample (its newest one, else a new one): what the system page walks
    through, one decision at a time."""
    batch = batches.get_batch(session, batch_id)
    rp = batches.sample_pass(session, batch, principal.name, keep=settings.max_passes_per_user)
    return PassOut.of(rp, passes.pass_counts(session, rp))
