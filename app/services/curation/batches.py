"""Accept the vouched systems after a random sample: a batch, its zero-acceptance sampling plan, its accept and undo.

A reviewer makes a **batch** from the review queue's filters: the pending systems those filters select whose 3D ball
is vouched for (``System.ball_evidence == "vouched"``: independent evidence agrees with it and no label doubt names
its views), frozen with their versions (``System.version``) at that moment. The server draws a random **sample** of
them (``random.SystemRandom``: nobody chooses which systems are looked at) of the size of the zero-acceptance sampling
plan (:func:`sample_size`): if none of the ``n`` sampled systems is wrong, one may say with confidence ``c`` that at
most a share ``p`` of the batch is. The sample is reviewed through the ordinary review (a review pass over it,
:func:`sample_pass`), one decision at a time, by people.

The batch's accept (:func:`accept_batch`) accepts the batch's other systems in one write unit when, read under the
write lock (:func:`stops`):

* every sampled system was accepted by a person after the batch was made (its decision is a person's, not a batch's,
  and no decision of it since the batch was made rejected it or returned it for a fix, even one undone later);
* no sampled system changed but for its decision since (no audit entry of it other than decisions, hand-offs,
  assignments and comments, and its version moved by exactly its decisions);
* no unsampled system changed since (its version is the one the batch froze: any write of it bumps it).

Otherwise it is refused (409) in words naming each system that stops it ("system 42 was rejected"), and a refused
batch stays refused: once a sampled system was found wrong, fixing that system does not make the rest any more
right. A sample not yet fully decided only waits (409, the batch stays open). Batches may overlap and making one
reserves nothing: a system another batch or a person decided meanwhile stops this one as any change does.

Each system a batch accepts gets a decision marked with the batch (``ReviewDecision.batch_id``, cleared by any
person's later decision) and an audit entry ``system.review`` whose ``after.review.batch_id`` is the batch's id.
:func:`undo_batch` puts back to pending the systems whose decision is still the batch's.

The plan is the zero-acceptance-number (c = 0) single sampling plan, the finite-population form of the "rule of
three" (Hanley and Lippman-Hand, "If nothing goes wrong, is everything all right? Interpreting zero numerators",
JAMA 249(13), 1983; Squeglia, *Zero Acceptance Number Sampling Plans*, ASQ Quality Press): ``n = ceil(ln(1 - c) /
ln(1 - p))`` draws, all right. Drawn without replacement from a batch of ``N`` holding ``D >= pN`` wrong systems, the
chance that none of the ``n`` is wrong is ``prod_i (N - D - i) / (N - i) <= (1 - p)^n <= 1 - c``: the binomial size
is conservative for a finite batch (docs/review.md).
"""
from __future__ import annotations

import contextlib
import dataclasses
import math
import random
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from typing import Any, Optional, cast

import sqlalchemy as sa
from sqlalchemy.orm import Session

from app.core.errors import ConflictError, InvalidInputError, found
from app.db.models import (
    AuditEntry,
    BallEvidence,
    ReviewBatch,
    ReviewDecision,
    ReviewHandoff,
    ReviewPass,
    ReviewStatus,
    System,
)
from app.db.types import utcnow
from app.db.unit import write_unit
from app.services.audit import log as audit
from app.services.curation.passes import filters_json, start_listed_pass
from app.services.curation.queue import SystemFilters, matching_system_ids

#: The ball evidence a batch takes (``System.ball_evidence``): the systems independent evidence vouches for.
VOUCHED = BallEvidence.VOUCHED
#: A batch's states (``ReviewBatch.state``).
OPEN, ACCEPTED, REFUSED, UNDONE = "open", "accepted", "refused", "undone"
#: The sort a sample's review pass stores (``ReviewPass.sort``): the sample's order, no queue's.
SAMPLE_SORT = "sample"
#: Audit actions that leave a sampled system's content as it was: decisions (a view's changes its frame's version,
#: a system's its system's), hand-offs, assignments, comments.
_UNCHANGING = frozenset({"system.review", "view.review", "view.calibration_review", "system.handoff",
                         "system.assign", "comment.add", "comment.resolve", "comment.reopen"})
#: Ids read per statement (below every database's bound on an ``IN`` list).
_CHUNK = 500


def sample_size(confidence: float, max_wrong_share: float, total: int) -> int:
    """How many of ``total`` systems the zero-acceptance plan samples: ``min(total, ceil(ln(1 - c) / ln(1 - p)))``
    (module docstring; Hanley and Lippman-Hand 1983).

    A quotient that is an integer but for rounding (``ln 0.25 / ln 0.5``) is that integer; a share too small to show
    in a sample short of the whole batch (``5e-324``) samples all of it.

    >>> sample_size(0.95, 0.05, 240), sample_size(0.95, 0.05, 12), sample_size(0.75, 0.5, 100)
    (59, 12, 2)

    Raises:
        InvalidInputError: ``confidence`` or ``max_wrong_share`` outside (0, 1) (field named).
    """
    _check_share(confidence, "confidence")
    _check_share(max_wrong_share, "max_wrong_share")
    per_draw = math.log1p(-max_wrong_share)
    if per_draw == 0.0:  # a share too small for a double to tell 1 - p from 1: no sample short of all shows it
        return total
    needed = math.log1p(-confidence) / per_draw
    if not math.isfinite(needed) or needed >= total:
        return total
    return min(total, max(math.ceil(needed - 1e-9), 1))


def _check_share(value: float, field: str) -> None:
    if not isinstance(value, (int, float)) or isinstance(value, bool) or not 0.0 < value < 1.0:
        raise InvalidInputError(f"{field} must be a fraction strictly between 0 and 1, not {value!r}", field=field)


def percent(share: float) -> str:
    """A fraction as a person reads it: ``0.95`` -> ``"95 %"``, ``0.995`` -> ``"99.5 %"``.

    >>> percent(0.95), percent(0.995), percent(0.05)
    ('95 %', '99.5 %', '5 %')
    """
    return f"{round(share * 100, 6):g} %"


def plan_words(sampled: int, total: int, confidence: float, max_wrong_share: float) -> str:
    """The sampling plan in words.

    >>> plan_words(59, 240, 0.95, 0.05)
    'if none of these 59 is wrong, you can be 95 % sure that at most 5 % of the 240 are'
    >>> plan_words(1, 2, 0.5, 0.5)
    'if this one is not wrong, you can be 50 % sure that at most 50 % of the 2 are'
    >>> plan_words(3, 3, 0.95, 0.05)
    'all 3 are in the sample: if none of them is wrong, none of the 3 is'
    >>> plan_words(0, 0, 0.95, 0.05)
    'no pending vouched system matches these filters: nothing to sample'
    """
    if total == 0:
        return "no pending vouched system matches these filters: nothing to sample"
    if sampled >= total:
        return f"all {total} are in the sample: if none of them is wrong, none of the {total} is"
    which = "this one is not wrong" if sampled == 1 else f"none of these {sampled} is wrong"
    return (f"if {which}, you can be {percent(confidence)} sure that at most {percent(max_wrong_share)} of the "
            f"{total} are")


@dataclass(frozen=True)
class Stop:
    """A system that stops a batch's accept, in ``words``; ``final``: it stops the batch for good (a rejection, a
    change), else the batch only waits for it (a sampled system not decided yet)."""

    system_id: int
    words: str
    final: bool


def batch_facts(session: Session, batch: ReviewBatch) -> dict[str, Any]:
    """A batch as the API and the command line show it (``app.api.batch_schemas.BatchOut``'s fields): who made it,
    when, from which filters and plan, its systems and sample ids, the plan in words, its state, refusal, how many it
    accepted, and, while open, what stops its accept now (:func:`stops`, as dicts)."""
    found_stops = stops(session, batch) if batch.state == OPEN else []
    return {"id": batch.id, "created_by": batch.created_by, "created_at": batch.created_at,
            "filter": dict(batch.filters), "confidence": batch.confidence, "max_wrong_share": batch.max_wrong_share,
            "systems": list(batch.system_ids), "sample": list(batch.sample_ids), "plan": batch_plan(batch),
            "state": batch.state, "refusal": batch.refusal, "accepted": len(batch.accepted_ids or []),
            "decided_by": batch.decided_by, "decided_at": batch.decided_at,
            "stops": [dataclasses.asdict(s) for s in found_stops]}


def batch_plan(batch: ReviewBatch) -> str:
    """:func:`plan_words` of a stored batch."""
    return plan_words(len(batch.sample_ids), len(batch.system_ids), batch.confidence, batch.max_wrong_share)


def vouched_pending(session: Session, filters: SystemFilters) -> list[int]:
    """The ids of the pending systems the queue ``filters`` select whose ball is vouched for, in id order.

    Raises:
        InvalidInputError: a status filter other than pending (field ``filter.status``: a batch takes pending systems
            only) or a ball evidence filter other than vouched (field ``filter.ball_evidence``).
    """
    if filters.status not in (None, ReviewStatus.PENDING):
        raise InvalidInputError(f"a batch takes pending systems only, not status {filters.status.value!r}",
                                field="filter.status")
    if filters.ball_evidence not in (None, VOUCHED):
        raise InvalidInputError(f"a batch takes vouched systems only, not {filters.ball_evidence.value!r} ones",
                                field="filter.ball_evidence")
    stmt = matching_system_ids(dataclasses.replace(filters, status=ReviewStatus.PENDING, ball_evidence=VOUCHED))
    return [int(i) for i in session.scalars(stmt)]


def create_batch(session: Session, user: str, filters: SystemFilters, confidence: float, max_wrong_share: float,
                 rng: Optional[random.Random] = None) -> ReviewBatch:
    """Make a batch (module docstring) of the pending vouched systems ``filters`` select, with its random sample,
    and commit.

    Args:
        user: who makes it (a reviewer's name).
        confidence, max_wrong_share: the plan's ``c`` and ``p``, fractions in (0, 1).
        rng: the sample's source of randomness (None: the operating system's, ``random.SystemRandom``).

    Returns:
        The committed batch; ``sample_ids`` in id order.

    Raises:
        InvalidInputError: a fraction outside (0, 1), a status filter other than pending.
    """
    sample_size(confidence, max_wrong_share, 0)  # checks both fractions before anything is read
    with write_unit(session):  # the versions frozen are those of the ids selected, in one snapshot
        ids = vouched_pending(session, filters)
        versions = _versions(session, ids)
        n = sample_size(confidence, max_wrong_share, len(ids))
        sample = sorted((rng or random.SystemRandom()).sample(ids, n))
        batch = ReviewBatch(created_by=user, created_at=utcnow(), filters=filters_json(filters),
                            confidence=float(confidence), max_wrong_share=float(max_wrong_share), system_ids=ids,
                            versions=[versions[i] for i in ids], sample_ids=sample, state=OPEN)
        session.add(batch)
    return batch


def _versions(session: Session, ids: Sequence[int], *, lock: bool = False) -> dict[int, int]:
    """``System.version`` of each of ``ids`` that exists (its row locked until the transaction ends when ``lock``,
    on PostgreSQL)."""
    out: dict[int, int] = {}
    for start in range(0, len(ids), _CHUNK):
        stmt = sa.select(System.id, System.version).where(System.id.in_(ids[start:start + _CHUNK]))
        out.update((int(i), int(v or 0)) for i, v in session.execute(stmt.with_for_update() if lock else stmt))
    return out


def _lock_rows(session: Session, ids: Sequence[int]) -> None:
    """On PostgreSQL, lock the systems ``ids`` until the transaction ends (``SELECT ... FOR UPDATE``): nobody writes
    them between the checks and the write. SQLite has no row locks and needs none: the write unit's ``BEGIN
    IMMEDIATE`` already holds the database's one write lock (there the read cost about a second at 12,800 systems for
    nothing)."""
    if session.get_bind().dialect.name == "postgresql":
        _versions(session, ids, lock=True)


def get_batch(session: Session, batch_id: int) -> ReviewBatch:
    """The batch with this id. Raises :class:`~app.core.errors.NotFoundError`."""
    return found(session.get(ReviewBatch, batch_id), "batch", batch_id)


def stops(session: Session, batch: ReviewBatch) -> list[Stop]:
    """What stops ``batch``'s accept now (module docstring), in the batch's id order; empty when it may be accepted.
    Reads only."""
    versions = _versions(session, batch.system_ids)
    decisions = {int(r.system_id): r for r in _rows(session, sa.select(
        ReviewDecision.system_id, ReviewDecision.status, ReviewDecision.batch_id, ReviewDecision.decided_at),
        ReviewDecision.system_id, batch.sample_ids)}
    history = _history(session, batch)
    sampled = set(batch.sample_ids)
    out: list[Stop] = []
    for sid, then in zip(batch.system_ids, batch.versions, strict=True):
        now = versions.get(sid)
        if now is None:
            out.append(Stop(sid, f"system {sid} no longer exists", True))
        elif sid in sampled:
            stop = _sampled_stop(batch, sid, then, now, decisions.get(sid), history.get(sid, []))
            if stop is not None:
                out.append(stop)
        elif now != then:
            out.append(Stop(sid, f"system {sid} changed since the batch was made", True))
    return out


def _rows(session: Session, stmt: Any, column: Any, ids: Sequence[int]) -> list[Any]:
    """``stmt`` filtered on ``column`` in ``ids``, a chunk at a time."""
    rows: list[Any] = []
    for start in range(0, len(ids), _CHUNK):
        rows += session.execute(stmt.where(column.in_(ids[start:start + _CHUNK]))).all()
    return rows


def _history(session: Session, batch: ReviewBatch) -> dict[int, list[AuditEntry]]:
    """The audit entries of the batch's sampled systems written since the batch was made, per system, oldest first."""
    out: dict[int, list[AuditEntry]] = {}
    if not batch.sample_ids:
        return out
    stmt = sa.select(AuditEntry).where(AuditEntry.at >= batch.created_at).order_by(AuditEntry.id)
    for start in range(0, len(batch.sample_ids), _CHUNK):
        chunk = batch.sample_ids[start:start + _CHUNK]
        for entry in session.scalars(stmt.where(AuditEntry.system_id.in_(chunk))):
            out.setdefault(int(entry.system_id), []).append(entry)  # type: ignore[arg-type]  # in chunk: not None
    for entries in out.values():
        entries.sort(key=lambda e: e.id)
    return out


def _decided(entry: AuditEntry) -> Optional[str]:
    """The status a system decision entry set (its own, or a revert's or undo's of one), None for any other entry."""
    if entry.frame_id is not None or entry.action not in ("system.review", "revert"):
        return None
    review = (entry.after or {}).get("review")
    return review.get("status") if isinstance(review, dict) and isinstance(review.get("status"), str) else None


#: How a stop names a status a sampled system was given.
_STATUS_WORDS = {ReviewStatus.REJECTED.value: "was rejected", ReviewStatus.NEEDS_FIX.value: "was returned for a fix",
                 ReviewStatus.FIXED.value: "was returned for a fix"}


def _sampled_stop(batch: ReviewBatch, sid: int, then: int, now: int, decision: Any,
                  entries: list[AuditEntry]) -> Optional[Stop]:
    """What stops the batch at its sampled system ``sid`` (version ``then`` when the batch was made, ``now`` now;
    its current decision row and its audit entries since), or None when a person accepted it and nothing else
    changed it."""
    decided = [s for s in (_decided(e) for e in entries) if s is not None]
    wrong = next((s for s in decided if s in _STATUS_WORDS), None)
    if wrong is not None:
        return Stop(sid, f"system {sid} {_STATUS_WORDS[wrong]}", True)
    other = next((e.action for e in entries if e.action not in _UNCHANGING and _decided(e) is None), None)
    if other is not None or now - then != len(decided):
        why = f" ({other})" if other is not None else ""
        return Stop(sid, f"system {sid} changed since the batch was made{why}, beyond its decision", True)
    status = decision.status.value if decision is not None else ReviewStatus.PENDING.value
    if status != ReviewStatus.ACCEPTED.value:
        return Stop(sid, f"system {sid} of the sample is not decided yet", False)
    if decision.batch_id is not None:
        return Stop(sid, f"system {sid} was accepted in batch {decision.batch_id}, not by a person", True)
    return None


def stop_words(found_stops: Sequence[Stop]) -> str:
    """The stops as one sentence: "system 42 was rejected; system 7 changed since the batch was made"."""
    return "; ".join(s.words for s in found_stops)


def accept_batch(session: Session, batch_id: int, actor: Optional[str]) -> int:
    """Accept the batch's unsampled systems (module docstring) in one write unit, each with its audit entry
    (``after.review.batch_id``), and commit; answers how many it accepted.

    Raises:
        NotFoundError: no such batch.
        ConflictError: the batch is not open (refused, accepted or undone before: its words), or a system stops it
            (:func:`stops`, named by id): a stop for good refuses the batch, stored and committed before this is
            raised; a sample not fully decided leaves it open.
    """
    refused: Optional[str] = None
    with write_unit(session):
        batch = get_batch(session, batch_id)
        _check_open(batch)
        _lock_rows(session, batch.system_ids)
        found_stops = stops(session, batch)
        if any(s.final for s in found_stops):
            refused = f"batch {batch.id} is refused: {stop_words([s for s in found_stops if s.final])}"
            batch.state, batch.refusal = REFUSED, refused
            batch.decided_by, batch.decided_at = audit.public_actor(actor), utcnow()
        elif found_stops:
            raise ConflictError(f"batch {batch.id} waits for its sample: {stop_words(found_stops)}",
                                current={"state": batch.state})
        else:
            sampled = set(batch.sample_ids)
            others = [sid for sid in batch.system_ids if sid not in sampled]
            _accept(session, batch, others, actor)
            batch.state, batch.accepted_ids = ACCEPTED, others
            batch.decided_by, batch.decided_at = audit.public_actor(actor), utcnow()
            return len(others)
    raise ConflictError(refused, current={"state": REFUSED})


def _check_open(batch: ReviewBatch) -> None:
    """Raise :class:`ConflictError` for a batch that is not open, in words."""
    if batch.state == REFUSED:
        raise ConflictError(batch.refusal or f"batch {batch.id} was refused", current={"state": batch.state})
    if batch.state == ACCEPTED:
        raise ConflictError(f"batch {batch.id} was accepted already ({len(batch.accepted_ids or [])} systems)",
                            current={"state": batch.state})
    if batch.state == UNDONE:
        raise ConflictError(f"batch {batch.id} was undone: make a new batch", current={"state": batch.state})


#: A system's decision as the batch's writes read it: ``(system id, game id, version, decision row id or None,
#: status, comment, batch id)``.
_Decision = tuple[int, int, int, Optional[int], Optional[ReviewStatus], str, Optional[int]]


def _decisions(session: Session, ids: Sequence[int]) -> list[_Decision]:
    """Each of ``ids``' game, version and decision (:data:`_Decision`), a chunk at a time."""
    stmt = (sa.select(System.id, System.game_id, System.version, ReviewDecision.id, ReviewDecision.status,
                      ReviewDecision.comment, ReviewDecision.batch_id)
            .outerjoin(ReviewDecision, ReviewDecision.system_id == System.id).order_by(System.id))
    return [(int(r[0]), int(r[1]), int(r[2] or 0), r[3], r[4], r[5] or "", r[6])
            for r in _rows(session, stmt, System.id, ids)]


def _state(status: ReviewStatus | None, comment: str, batch_id: Optional[int]) -> dict[str, Any]:
    """``states.review_state`` of a system from its decision's columns."""
    review: dict[str, Any] = {"status": (status or ReviewStatus.PENDING).value, "comment": comment}
    if batch_id is not None:
        review["batch_id"] = batch_id
    return {"review": review}


def _set_decisions(session: Session, chosen: sa.Select[Any], status: ReviewStatus, batch_id: Optional[int],
                   now: Any) -> None:
    """Write ``status`` (by ``batch_id``, None: no batch's) as the decision of the systems ``chosen`` selects (a
    select of their ids), bump their versions and the queue's copy of their status: four set-based statements
    whatever the number of systems (the version invariant's listener sees ORM changes only: these writers bump the
    versions themselves, as ``app.db.unit`` asks)."""
    session.execute(sa.update(System).where(System.id.in_(chosen))
                    .values(version=System.version + 1, review_status=status)
                    .execution_options(synchronize_session=False))
    session.execute(sa.update(ReviewDecision).where(ReviewDecision.system_id.in_(chosen))
                    .values(status=status, comment="", decided_at=now, reset_reason=None, batch_id=batch_id)
                    .execution_options(synchronize_session=False))
    ids = chosen.subquery().c[0]
    missing = (sa.select(ids, sa.literal(status, type_=ReviewDecision.status.type), sa.literal(""),
                         sa.literal(now, type_=ReviewDecision.decided_at.type),
                         sa.literal(batch_id, type_=ReviewDecision.batch_id.type))
               .where(~sa.exists().where(ReviewDecision.system_id == ids)))
    session.execute(sa.insert(cast(sa.Table, ReviewDecision.__table__)).from_select(
        ["system_id", "status", "comment", "decided_at", "batch_id"], missing))


#: The ids a batch's set-based write reads and writes (:func:`_chosen`): a temporary table of this connection, made
#: and dropped inside the write unit (a rollback drops it too: both databases' DDL is transactional).
_CHOSEN = sa.Table("v3d_batch_chosen", sa.MetaData(), sa.Column("id", sa.Integer, primary_key=True),
                   prefixes=["TEMPORARY"], postgresql_on_commit="DROP")


@contextlib.contextmanager
def _chosen(session: Session, ids: Sequence[int]) -> Iterator[sa.Select[Any]]:
    """``ids`` as a table the set-based statements select from (:data:`_CHOSEN`): one multi-row insert, where an
    ``IN`` list of bound ids would cost a statement and its compilation per 500 ids. Yields the select of its ids."""
    connection = session.connection()
    _CHOSEN.create(connection)
    if ids:
        session.execute(sa.insert(_CHOSEN), [{"id": int(i)} for i in ids])
    yield sa.select(_CHOSEN.c.id)
    _CHOSEN.drop(connection)


def _matches(column: Any, value: Any) -> Any:
    """``column`` equals ``value``, NULL matching None."""
    return column.is_(None) if value is None else column == value


def _accept(session: Session, batch: ReviewBatch, ids: Sequence[int], actor: Optional[str]) -> None:
    """Give each of ``ids`` (pending, unchanged since the batch was made: checked by the caller under the lock) the
    batch's acceptance, its version bumped and its audit entry recorded; close the hand-offs left open on them (any
    decision but needs fix closes one, ``handoff.after_decision``). Set-based: the whole batch is one write holding
    the write lock, so it costs a handful of statements whatever its size (an audit ``INSERT ... SELECT`` per
    distinct decision the systems had before, one in practice: pending), never a row or a bound id per system."""
    now = utcnow()
    with _chosen(session, ids) as chosen:
        decided = sa.outerjoin(System, ReviewDecision, ReviewDecision.system_id == System.id)
        comment = sa.func.coalesce(ReviewDecision.comment, "")
        befores = session.execute(sa.select(ReviewDecision.status, comment, ReviewDecision.batch_id)
                                  .select_from(decided).where(System.id.in_(chosen)).distinct()).all()
        for status, said, was in befores:  # before the writes below: the states and versions they replace
            audit.record_selected(
                session, actor=actor, action="system.review",
                systems=sa.select(System.id, System.game_id, System.version + 1).select_from(decided).where(
                    System.id.in_(chosen), _matches(ReviewDecision.status, status), comment == (said or ""),
                    _matches(ReviewDecision.batch_id, was)),
                before=_state(status, said or "", was), after=_state(ReviewStatus.ACCEPTED, "", batch.id))
        _set_decisions(session, chosen, ReviewStatus.ACCEPTED, batch.id, now)
        session.execute(sa.update(ReviewHandoff).where(ReviewHandoff.system_id.in_(chosen),
                                                       ReviewHandoff.closed_at.is_(None))
                        .values(closed_at=now).execution_options(synchronize_session=False))


@dataclass(frozen=True)
class Undone:
    """What an undo of a batch did: ``undone`` systems back to pending; ``kept``: those whose decision is no longer
    the batch's (a person decided them since), left as they are, in words."""

    undone: int
    kept: list[Stop]


def undo_batch(session: Session, batch_id: int, actor: Optional[str]) -> Undone:
    """Put the systems ``batch_id`` accepted back to pending (their decision still the batch's), each with its audit
    entry (an undo of the batch's entry of that system, ``reverts_id``), in one write unit of bulk statements, and
    commit.

    Raises:
        NotFoundError: no such batch.
        ConflictError: the batch accepted nothing (open, refused, or undone already).
    """
    with write_unit(session):
        batch = get_batch(session, batch_id)
        if batch.state != ACCEPTED:
            raise ConflictError(f"batch {batch.id} accepted nothing to undo (it is {batch.state})",
                                current={"state": batch.state})
        accepted = list(batch.accepted_ids or [])
        _lock_rows(session, accepted)
        rows = _decisions(session, accepted)
        still = [r for r in rows if r[6] == batch.id and r[4] is ReviewStatus.ACCEPTED]
        kept = [Stop(r[0], f"system {r[0]} was decided since the batch accepted it: kept", False)
                for r in rows if not (r[6] == batch.id and r[4] is ReviewStatus.ACCEPTED)]
        gone = sorted(set(accepted) - {r[0] for r in rows})
        kept += [Stop(sid, f"system {sid} no longer exists", False) for sid in gone]
        entries = _newest_decisions(session, [r[0] for r in still])
        with _chosen(session, [r[0] for r in still]) as chosen:
            _set_decisions(session, chosen, ReviewStatus.PENDING, None, utcnow())
        audit.record_many(session, actor=actor, action="system.review", changes=[
            audit.SystemChange(sid, gid, version + 1, _state(status, comment, was),
                               _state(ReviewStatus.PENDING, "", None), reverts_id=entries.get(sid))
            for sid, gid, version, _, status, comment, was in still])
        batch.state, batch.undone_at = UNDONE, utcnow()
    return Undone(len(still), sorted(kept, key=lambda s: s.system_id))


def _newest_decisions(session: Session, ids: Sequence[int]) -> dict[int, int]:
    """The id of the newest system decision entry (``system.review``) of each of ``ids``: for a system whose decision
    is still a batch's, the batch's acceptance, which its undo names (``reverts_id``: an undo, no person's decision)."""
    out: dict[int, int] = {}
    stmt = (sa.select(AuditEntry.system_id, sa.func.max(AuditEntry.id)).where(AuditEntry.action == "system.review")
            .group_by(AuditEntry.system_id))
    for start in range(0, len(ids), _CHUNK):
        rows = session.execute(stmt.where(AuditEntry.system_id.in_(ids[start:start + _CHUNK])))
        out.update((int(s), int(e)) for s, e in rows if s is not None and e is not None)
    return out


def sample_pass(session: Session, batch: ReviewBatch, user: str, keep: int = 50) -> ReviewPass:
    """The review pass of ``user`` over ``batch``'s sample, in its order (``app.services.curation.passes``): their
    newest one of this batch, else a new one (committed)."""
    return start_listed_pass(session, user, {"batch_id": batch.id}, SAMPLE_SORT, list(batch.sample_ids), keep=keep)
