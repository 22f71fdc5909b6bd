"""Review passes: every system of a review queue once, in the order it had when the pass began.

A pass freezes the ids of every system of a queue (its filters and sort, :func:`~app.services.curation.queue.queue_ids`:
all its pages) when a user opens a system from it. The system page then moves within that frozen list: a fix
that moves a system in the queue's current order (a mirror fix changes its doubts, the doubts sort's key)
never reorders the pass. After a decision the page goes to the **next pending** system of the pass: the
first one after the current one whose *current* review status (read when asked, never copied into the pass)
is pending, wrapping round to the pass's start (a pass resumed in its middle still visits the systems left
pending before), so a system decided meanwhile, by this user or another, is skipped. When none is left the pass
is finished. Its counts are the pass owner's own decisions in it (the newest system decision they made on each
system since the pass began, read from the audit log: another reviewer's decisions, or older ones, are not theirs),
then the systems sent back as fixed (to re-review), those decided by others or before the pass, and ``skipped``:
still pending, visited or stepped over without a decision.

A pass belongs to the user who began it (``user_name``) and is stored on the server, so it resumes after a
reload or in another browser (:func:`list_passes`); ``position`` is the index of the system the user last
opened (:func:`visit`). Opening a system from the same queue again continues the user's newest unfinished
pass of that queue which holds the system (:func:`start_pass`) instead of freezing a new one. A user keeps at
most ``keep`` passes (``V3D_MAX_PASSES_PER_USER``): each stores every system id of its queue (about 77 KB at
SoccerNet-v3's size), so beginning one more drops the user's least recently visited ones beyond it, in the same
transaction; one user's passes cannot grow the database without bound.
"""
from __future__ import annotations

import dataclasses
import enum
from dataclasses import dataclass
from typing import Any, Optional

import sqlalchemy as sa
from sqlalchemy.orm import Session

from app.core.errors import ForbiddenError, InvalidInputError, found
from app.db.models import AuditEntry, ReviewPass, ReviewStatus, System
from app.db.types import utcnow
from app.db.unit import write_unit
from app.services.curation.queue import DEFAULT_SORT, SystemFilters, SystemSort, queue_ids

#: The counts of a pass: its owner's decisions in it by status; ``sent_back``: systems their annotator sent back as
#: fixed (waiting for a decision again), ``by_others``: decided, not by the owner in this pass (another reviewer, or
#: before it began); ``skipped``: still pending.
COUNT_KEYS = ("accepted", "rejected", "needs_fix", "sent_back", "by_others", "skipped")
#: The owner's decisions a pass counts.
_DECISIONS = ("accepted", "rejected", "needs_fix")
#: No filter: every system (the default queue of a pass; frozen, so one instance serves every call).
ALL_SYSTEMS = SystemFilters()


@dataclass(frozen=True)
class PassPlace:
    """Where a system stands in a pass, with the pass's statuses read now.

    ``index``: the system's index in the pass (None: not one of its systems; the neighbours are then those
    of the pass's stored position). ``prev_id`` / ``next_id``: the systems before / after it in the pass's
    order (None at either end). ``next_pending_id``: the first system after it whose current status is
    pending, wrapping round to the pass's start (None: no other system of the pass is pending), and
    ``next_pending_index`` its index (the page shows its place before the visit answers); ``first_pending_id``: the
    first pending one of the whole pass. ``counts``: :data:`COUNT_KEYS` over the pass. ``finished``: no other system
    of the pass is pending."""

    pass_id: int
    index: Optional[int]
    total: int
    prev_id: Optional[int]
    next_id: Optional[int]
    next_pending_id: Optional[int]
    next_pending_index: Optional[int]
    first_pending_id: Optional[int]
    counts: dict[str, int]
    finished: bool


def filters_json(filters: SystemFilters) -> dict[str, Any]:
    """The queue filters as stored in a pass: the fields of :class:`SystemFilters` that are set (an enum, the status
    or the ball evidence, by value)."""
    out = {}
    for f in dataclasses.fields(filters):
        value = getattr(filters, f.name)
        if value is not None:
            out[f.name] = value.value if isinstance(value, enum.Enum) else value
    return out


def start_pass(session: Session, user: str, filters: SystemFilters = ALL_SYSTEMS, sort: SystemSort = DEFAULT_SORT,
               system_id: Optional[int] = None, fresh: bool = False, keep: int = 50) -> ReviewPass:
    """Begin a pass over the queue ``filters`` + ``sort`` for ``user``, or continue one, and commit.

    Continues (answers unchanged) the user's newest pass of the same filters and sort that holds
    ``system_id`` (any of its systems when None) and still has a pending system, unless ``fresh``.
    Otherwise freezes the queue's ids now (all pages, in order) into a new pass whose position is
    ``system_id``'s index (0 when it is not in the queue), and deletes the user's least recently visited passes
    beyond the newest ``keep`` (``V3D_MAX_PASSES_PER_USER``; the new one is kept).

    Raises:
        ValueError: an unknown ``sort`` (the API validates it first).
    """
    stored = filters_json(filters)
    if not fresh:
        candidates = session.scalars(sa.select(ReviewPass).where(ReviewPass.user_name == user, ReviewPass.sort == sort)
                                     .order_by(ReviewPass.id.desc()).limit(20))
        for rp in candidates:
            if rp.filters != stored or (system_id is not None and system_id not in rp.system_ids):
                continue
            statuses = _statuses(session, rp.system_ids)
            if any(s in _TO_DO for s in statuses.values()):
                return rp
    ids = queue_ids(session, filters, sort)
    with write_unit(session):
        rp = ReviewPass(user_name=user, filters=stored, sort=sort, system_ids=ids,
                        position=ids.index(system_id) if system_id in ids else 0)
        session.add(rp)
        session.flush()
        _drop_beyond(session, user, keep, rp.id)
    return rp


def start_listed_pass(session: Session, user: str, filters: dict[str, Any], sort: str, ids: list[int],
                      keep: int = 50) -> ReviewPass:
    """A pass of ``user`` over a list of systems no queue orders (a batch's sample, ``app.services.curation.batches``),
    stored with ``filters`` and ``sort`` naming where the list comes from: the user's newest pass of the same
    ``filters`` and ``sort``, else a new one over ``ids`` in their order (committed; the user's passes beyond the newest
    ``keep`` dropped, as :func:`start_pass` does)."""
    for rp in session.scalars(sa.select(ReviewPass).where(ReviewPass.user_name == user, ReviewPass.sort == sort)
                              .order_by(ReviewPass.id.desc()).limit(20)):
        if rp.filters == filters and rp.system_ids == ids:
            return rp
    with write_unit(session):
        rp = ReviewPass(user_name=user, filters=filters, sort=sort, system_ids=ids, position=0)
        session.add(rp)
        session.flush()
        _drop_beyond(session, user, keep, rp.id)
    return rp


def _drop_beyond(session: Session, user: str, keep: int, newest_id: int) -> None:
    """Delete ``user``'s passes beyond the ``keep`` most recently visited (ties: the newer first), never the pass
    ``newest_id`` just begun; under the caller's write lock."""
    kept = sa.select(ReviewPass.id).where(ReviewPass.user_name == user).order_by(
        (ReviewPass.id == newest_id).desc(), ReviewPass.visited_at.desc(), ReviewPass.id.desc()).limit(keep)
    session.execute(sa.delete(ReviewPass)
                    .where(ReviewPass.user_name == user, ReviewPass.id.not_in(kept.scalar_subquery()))
                    .execution_options(synchronize_session=False))


def get_pass(session: Session, pass_id: int) -> ReviewPass:
    """The pass with this id. Raises :class:`~app.core.errors.NotFoundError`."""
    return found(session.get(ReviewPass, pass_id), "review pass", pass_id)


def list_passes(session: Session, user: Optional[str] = None, limit: int = 20) -> list[ReviewPass]:
    """The newest ``limit`` passes, of ``user`` only unless None."""
    stmt = sa.select(ReviewPass).order_by(ReviewPass.id.desc()).limit(limit)
    if user is not None:
        stmt = stmt.where(ReviewPass.user_name == user)
    return list(session.scalars(stmt))


_PENDING = ReviewStatus.PENDING.value
#: The statuses a pass still visits: pending, and sent back as fixed (a decision is wanted again).
_TO_DO = (_PENDING, ReviewStatus.FIXED.value)


def _statuses(session: Session, ids: list[int]) -> dict[int, str]:
    """The current review status (its value) of each system of ``ids`` that still exists (a re-import may
    have removed some). Two Core statements on the id range of the pass, whatever its length: the ids that
    exist (the primary key's index), and the decided systems among them (pending is the rest), so a long
    pass costs what has been decided, not an ``IN`` of every id (12,800 ids as ``IN`` lists of ORM rows
    took about 0.4 s a read; these two about 0.15 s for the whole read at 12,800 ids on the loaded 2-core
    machine, load average 14)."""
    if not ids:
        return {}
    lo, hi = min(ids), max(ids)
    conn = session.connection()
    systems = System.__table__
    exist = set(conn.execute(sa.select(systems.c.id).where(systems.c.id.between(lo, hi))).scalars())
    # IN: the status index answers it. A system sent back as fixed waits for a decision again: a pass visits it as it
    # visits a pending one (:data:`_TO_DO`)
    done = [st for st in ReviewStatus if st is not ReviewStatus.PENDING]
    decided = {i: ReviewStatus(st).value
               for i, st in conn.execute(sa.select(systems.c.id, systems.c.review_status).where(
        systems.c.review_status.in_(done), systems.c.id.between(lo, hi)))}
    return {i: decided.get(i, _PENDING) for i in ids if i in exist}


def pass_counts(session: Session, rp: ReviewPass) -> dict[str, int]:
    """:data:`COUNT_KEYS` of the pass's systems (module docstring)."""
    return _counts(_statuses(session, rp.system_ids), _own_decisions(session, rp))


def _own_decisions(session: Session, rp: ReviewPass) -> dict[int, str]:
    """The status of the newest system decision the pass's owner made on each of its systems since the pass began
    (audit action ``system.review``; an undo of one is such an entry too, back to pending): one range read of the
    audit log's index on (action, time)."""
    if not rp.system_ids:
        return {}
    ids = set(rp.system_ids)
    entries = session.scalars(sa.select(AuditEntry).where(
        AuditEntry.action == "system.review", AuditEntry.at >= rp.created_at, AuditEntry.actor == rp.user_name,
        AuditEntry.system_id.between(min(ids), max(ids))).order_by(AuditEntry.id))
    own: dict[int, str] = {}
    for entry in entries:
        review = (entry.after or {}).get("review") if entry.system_id in ids else None
        if isinstance(review, dict) and isinstance(review.get("status"), str):
            own[int(entry.system_id)] = review["status"]  # type: ignore[arg-type]  # in ids: not None
    return own


def _counts(statuses: dict[int, str], own: dict[int, str]) -> dict[str, int]:
    counts = dict.fromkeys(COUNT_KEYS, 0)
    for system_id, status in statuses.items():
        mine = own.get(system_id)
        if mine in _DECISIONS and mine == status:  # still the decision it made (not undone, not decided again since)
            counts[mine] += 1
        elif status == ReviewStatus.FIXED.value:
            counts["sent_back"] += 1
        elif status == _PENDING:
            counts["skipped"] += 1
        else:
            counts["by_others"] += 1
    return counts


def place(session: Session, rp: ReviewPass, system_id: int) -> PassPlace:
    """Where ``system_id`` stands in the pass ``rp`` (:class:`PassPlace`), statuses read now."""
    statuses = _statuses(session, rp.system_ids)
    ids = [i for i in rp.system_ids if i in statuses]  # systems removed since the pass began are gone from it
    index = ids.index(system_id) if system_id in statuses and system_id in ids else None
    anchor = index
    if anchor is None:  # a system outside the pass (an ISSIA neighbour frame): from the stored position
        stored = rp.system_ids[rp.position] if 0 <= rp.position < len(rp.system_ids) else None
        anchor = ids.index(stored) if stored in ids else -1
    pending = [j for j, i in enumerate(ids) if statuses[i] in _TO_DO]
    # after it first, then from the start of the pass: a pass resumed late still reaches the systems left pending
    # before its resume point
    wrapped = [j for j in pending if j > anchor] + [j for j in pending if j < anchor]
    next_pending = wrapped[0] if wrapped else None
    return PassPlace(
        pass_id=rp.id, index=index, total=len(ids),
        prev_id=ids[anchor - 1] if anchor is not None and anchor > 0 else None,
        next_id=ids[anchor + 1] if anchor + 1 < len(ids) else None,
        next_pending_id=ids[next_pending] if next_pending is not None else None, next_pending_index=next_pending,
        first_pending_id=ids[pending[0]] if pending else None,
        counts=_counts(statuses, _own_decisions(session, rp)), finished=next_pending is None,
    )


def visit(session: Session, rp: ReviewPass, system_id: int, user: str) -> PassPlace:
    """Record that ``user`` (the pass's owner) opened ``system_id``: the pass's position becomes its index
    (unchanged for a system outside the pass); commit and answer its :func:`place`.

    Raises:
        ForbiddenError: ``user`` is not the pass's owner (another user reads a pass, never moves it).
        InvalidInputError: ``system_id`` is not an id (field ``system_id``).
    """
    if rp.user_name != user:
        raise ForbiddenError(f"review pass {rp.id} is {rp.user_name}'s: only they move it")
    if not isinstance(system_id, int) or isinstance(system_id, bool):
        raise InvalidInputError("system_id must be a system id", field="system_id")
    if system_id in rp.system_ids:
        pass_id = rp.id
        with write_unit(session):
            rp = get_pass(session, pass_id)
            rp.position = rp.system_ids.index(system_id)
            rp.visited_at = utcnow()
    return place(session, rp, system_id)
