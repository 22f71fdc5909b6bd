"""The guarded, audited write every edit and decision goes through, and its one locking design.

Every write is attributed and guarded, in its transaction: it first claims its resource
(``app.services.curation.versions``: compare-and-set of the frame's ``edit_version`` or the system's
``review_version`` against ``expected``, the versions of the client's ``If-Match``; None accepts any),
raising :class:`~app.core.errors.StaleVersionError` (with the resource's current rows and its
newest audit entry) when another write came first; then it applies the change, recomputes, and records
one audit entry (``app.services.audit.log``, by ``actor``, None meaning :func:`~app.services.audit.log.local_actor`)
with the edited part's state before and after. ``revert`` marks the write as the revert of an audit
entry (``app.services.audit.reverting``): it is recorded as action ``revert``, and refused with
:class:`~app.core.errors.ConflictError` when the state under the lock is not ``revert.expect``.

Concurrency (several server processes, issues 7 and 27): one locking design for every edit
(:func:`guarded_write`). Nobody waits on another's geometry:

1. **Compute before the lock.** An edit that recomputes (``ball.edit``, ``field_lines.replace``,
   ``field_lines.mirror``, ``view.exclusion``) first runs its ``apply`` in a read snapshot
   (``app.db.session.begin_snapshot``: SQLite's deferred ``BEGIN`` under WAL, PostgreSQL ``REPEATABLE READ``; no
   lock, nothing flushed, :func:`_compute_before_lock`). Each recomputation it asks for (:func:`_recompute_planned`:
   the edited frame's calibration with its rig or prior retry, admission, mirror evidence, triangulation,
   reprojections, boxes, doubts, queue figures) is computed there, and the digest of every input it read
   (``recompute.recompute_inputs``: every view's ball label, field lines, exclusion and calibration of the
   system, its review status, the game's rig rows or learned camera prior) is kept with its results as plain
   values (``recompute.system_results``). The snapshot is rolled back; audit entries and decision resets made
   there are never written.
2. **Compare and write under the lock.** Then the write transaction begins (``begin_write``: SQLite's
   ``BEGIN IMMEDIATE``) and locks the edited system's row (:func:`lock_system`: ``SELECT ... FOR UPDATE`` on
   PostgreSQL, the game's row first for an ISSIA system) before it reads anything it changes; the objects loaded
   earlier are expired. Under the lock the edit claims its version (412), checks a revert (409), applies its
   change again and, at each recomputation, loads the system in a few queries and digests its inputs: equal to
   the digest computed from, the kept results are stored (``recompute.store_system_results``); different (another
   edit of the system, or of its game's rig, committed meanwhile), it is recomputed under the lock from what the
   other committed. The audit entry and the decision resets are written in the same transaction, as before.
   ``session.info[LAST_RECOMPUTATION]`` says which happened ("precomputed", "recomputed", "under_lock").

Two edits of one system's views therefore never lose each other's label: the later one finds the earlier one's
label under the lock and recomputes. Kinds whose edit re-fits beyond the system (ISSIA's trajectory:
``KindPolicy.computes_before_lock`` False) and writes that recompute nothing (review decisions) compute under the
lock as before. The lock is held only to compare and write, so waits are short: a served process waits at most
``V3D_WRITE_LOCK_TIMEOUT_S`` (SQLite busy timeout, PostgreSQL ``lock_timeout``) and the API answers 503 with
``Retry-After`` beyond it (``app.api.errors``).
"""
from __future__ import annotations


import json
from collections.abc import Collection
from dataclasses import dataclass, field
from typing import Any, Callable, Optional, TypeVar

from sqlalchemy import event, select
from sqlalchemy.orm import Session

from app.core.config import Settings
from app.db.models import (
    Frame, Game, System,
)
from app.db.session import begin_snapshot, begin_write
from app.services.audit import log as audit
from app.core.errors import ConflictError, NotFoundError, StaleVersionError, found
from app.services.kinds import kind_of, policy
from app.services.derivation.recompute import (
    SystemResults, load_for_recompute, recompute_inputs, store_system_results,
    system_results, system_rig_rows,
)
from app.services.curation.system_page import load_frame
from app.services.curation.versions import claim_frame
from app.services.curation.states import (
    same_json,
)


T = TypeVar("T")


Expected = Optional[Collection[int]]


@dataclass(frozen=True)
class Revert:
    """An edit that reverts audit entry ``entry_id``: recorded as action ``revert``; refused (409) when
    the edited part's state under the lock is not ``expect`` (the entry's ``after``; None: forced)."""

    entry_id: int
    expect: Optional[dict[str, Any]] = None


def lock_system(session: Session, system_id: int) -> None:
    """Lock the system's row (and, for an ISSIA system, its game's row first) until the transaction
    ends, then expire every loaded object so that what the caller reads next is read under the lock.

    PostgreSQL: ``SELECT ... FOR UPDATE`` makes concurrent edits of one system (one sequence for ISSIA,
    whose edits re-fit the trajectory of the whole game) wait for each other, so no recomputation is
    computed from labels another transaction is changing and then overwrites that transaction's result.
    Rows are always locked game first, then system: no two edits wait for each other in a cycle. Systems
    of other games, and other systems of a SoccerNet game, are edited in parallel. SQLite ignores
    ``FOR UPDATE``; its ``BEGIN IMMEDIATE`` already serialises every write transaction.

    Raises:
        NotFoundError: no system has this id.
    """
    row = session.execute(select(System.game_id, System.kind).where(System.id == system_id)).one_or_none()
    if row is None:
        raise NotFoundError("system", system_id)
    if policy(row.kind).edit_locks_game:
        session.execute(select(Game.id).where(Game.id == row.game_id).with_for_update())
    session.execute(select(System.id).where(System.id == system_id).with_for_update())
    session.expire_all()


# ----- the one locking design of the edit path (module docstring, "Concurrency") ---------------------------
#: ``session.info`` key of the running edit's :class:`_Plan`.
_PLAN = "v3d.edit.plan"


#: ``session.info`` key: how the last edit's recomputation was stored: "precomputed" (computed before the lock,
#: its inputs unchanged under it), "recomputed" (an input changed meanwhile: computed again under the lock) or
#: "under_lock" (computed under the lock only: the kind re-fits beyond its system, or nothing was computed before).
LAST_RECOMPUTATION = "v3d.edit.recomputation"


#: The audited actions whose edits recompute their system, hence compute before the lock.
_RECOMPUTING = frozenset({"ball.edit", "field_lines.replace", "field_lines.mirror", "view.exclusion"})


@dataclass
class _Plan:
    """An edit's recomputations as computed before the write lock: per recomputation, in order, the digest of
    the inputs it read (``recompute.recompute_inputs``) and its results (``recompute.system_results``)."""

    capturing: bool = True
    entries: list[tuple[str, SystemResults]] = field(default_factory=list)
    used: int = 0
    recomputed: int = 0


class _NoWriteBeforeLock(Exception):
    """Raised by a flush while an edit computes before its lock: what follows the recomputation (audit entries,
    decision resets) is written under the lock only."""


@event.listens_for(Session, "before_flush")
def _no_flush_before_lock(session: Session, _context: Any, _instances: Any) -> None:
    plan = session.info.get(_PLAN)
    if plan is not None and plan.capturing:
        raise _NoWriteBeforeLock()


def computed_before_lock(system_id: int) -> None:
    """Called once an edit of system ``system_id`` has computed its recomputation, before it asks for the write
    lock (a hook: does nothing; the concurrency tests hold an edit here while another commits)."""


def _compute_before_lock(session: Session, system_id: int, subject: Callable[[], Any],
                         apply: Callable[[Any], Any]) -> Optional[_Plan]:
    """Run the edit's ``apply`` on ``subject()`` in a read snapshot (``begin_snapshot``: no lock, nothing
    flushed), keep what each of its recomputations read and found (:func:`recompute_planned`), then roll the
    snapshot back. None when there is nothing to reuse: the system's kind re-fits beyond it
    (``KindPolicy.computes_before_lock``), the session holds unwritten changes of its caller, or nothing was
    computed. Whatever fails here is decided again under the lock (the same error, or none if the state changed)."""
    try:
        begin_snapshot(session)
    except RuntimeError:
        return None
    plan = _Plan()
    session.info[_PLAN] = plan
    try:
        with session.no_autoflush:
            if kind_of(get_system(session, system_id)).computes_before_lock:
                apply(subject())
    except Exception:  # noqa: BLE001  # _NoWriteBeforeLock once the recomputation is done; anything else: under the lock
        pass
    finally:
        session.info.pop(_PLAN, None)
        audit.recorded_entry_id(session)  # an entry apply added here is never written
        session.rollback()
    computed_before_lock(system_id)
    plan.capturing = False
    return plan if plan.entries else None


def recompute_planned(session: Session, system: System, settings: Settings,
                       compute: Callable[[Optional[list[tuple[int, Any, bool]]]], Any]) -> None:
    """Run the recomputation ``compute`` of ``system`` within the running edit's plan: what it reads is loaded
    first (``load_for_recompute``, after a flush under the lock); before the lock it is computed and its inputs'
    digest and results kept; under the lock its results are stored when the inputs' digest is the one computed
    from (``store_system_results``), else it is computed again. Without a plan it is computed. ``compute(rig)`` takes
    the game's rig rows the digest read (``recompute.system_rig_rows``; None: not read), so it reads them once."""
    plan: Optional[_Plan] = session.info.get(_PLAN)
    if plan is None or not plan.capturing:
        session.flush()
    load_for_recompute(session, [system.id])  # what it reads, in a few queries (not one per relation and view)
    if plan is None or not kind_of(system).computes_before_lock:
        compute(None)
        return
    rig = system_rig_rows(session, system, settings)
    inputs = recompute_inputs(session, system, settings, rig)
    if plan.capturing:
        compute(rig)
        plan.entries.append((inputs, system_results(system)))
        return
    i, plan.used = plan.used, plan.used + 1
    if i < len(plan.entries) and plan.entries[i][0] == inputs:
        store_system_results(session, system, plan.entries[i][1])
    else:  # a view's label, lines, exclusion or calibration, or the game's rig, changed since: compute again
        plan.recomputed += 1
        compute(rig)


def _in_transaction(session: Session, work: Callable[[], T], *, system_id: int) -> T:
    """Run ``work`` as one write unit of work on the system ``system_id`` and commit; roll back and
    re-raise on any error. The write transaction begins (``begin_write``) and the system is locked
    (:func:`lock_system`) before ``work`` reads anything, so ``work`` reads fresh rows under the lock.
    A stale version (:class:`StaleVersionError`) gets the resource's current JSON and newest audit
    entry, read after the rollback."""
    try:
        begin_write(session)
        lock_system(session, system_id)
        result = work()
        session.commit()
        return result
    except BaseException as exc:
        session.rollback()
        if isinstance(exc, StaleVersionError):
            _describe_current(session, exc)
        raise


def _describe_current(session: Session, exc: StaleVersionError) -> None:
    """Fill a stale write's current state: the frame loaded for its view, or the system and its review."""
    if exc.kind == "frame":
        exc.current = load_frame(session, exc.ident)
        exc.last_change = audit.latest_entry(session, frame_id=exc.ident)
    else:
        system = get_system(session, exc.ident)
        system.review  # loaded now: the answer is shaped after the session is gone
        exc.current = system
        exc.last_change = audit.latest_entry(session, system_id=exc.ident)


def guarded_write(session: Session, system_id: int, claim: Callable[[], None], subject: Callable[[], Frame | System],
           state: Callable[[Any], dict[str, Any]], apply: Callable[[Any], T], action: str,
           actor: Optional[str], revert: Optional[Revert], undo_of: Optional[int] = None) -> T:
    """The guarded, audited write every edit goes through (module docstring), in one write transaction
    holding the lock of system ``system_id`` (:func:`_in_transaction`): ``claim`` (compare-and-set),
    ``state`` of ``subject()`` before, ``apply`` (change and recompute), ``state`` after, one audit entry
    (``undo_of``: the entry this edit undoes, recorded as its ``reverts_id`` under the edit's own action)."""

    def work() -> T:
        claim()
        target = subject()
        before = state(target)
        if revert is not None and revert.expect is not None and not same_json(before, revert.expect):
            raise ConflictError(f"audit entry {revert.entry_id} cannot be reverted: its resource changed since "
                                f"(it is now {json.dumps(before)[:300]}); revert the newer entries first, or force it",
                                current=before)
        result = apply(target)
        session.flush()
        frame = target if isinstance(target, Frame) else None
        audit.record(session, actor=actor, action="revert" if revert is not None else action, frame=frame,
                     system=target if frame is None else None, before=before, after=state(target),
                     reverts_id=revert.entry_id if revert is not None else undo_of)
        return result

    plan = _compute_before_lock(session, system_id, subject, apply) if action in _RECOMPUTING else None
    if plan is not None:
        session.info[_PLAN] = plan
    try:
        result = _in_transaction(session, work, system_id=system_id)
    finally:
        session.info.pop(_PLAN, None)
    session.info[LAST_RECOMPUTATION] = ("under_lock" if plan is None or plan.used == 0
                                        else "recomputed" if plan.recomputed else "precomputed")
    return result


def guarded_frame_write(session: Session, frame_id: int, expected: Expected, state: Callable[[Frame], dict[str, Any]],
                 apply: Callable[[Frame], T], action: str, actor: Optional[str], revert: Optional[Revert],
                 undo_of: Optional[int] = None) -> T:
    system_id = get_frame(session, frame_id).system_id
    return guarded_write(session, system_id, lambda: claim_frame(session, frame_id, expected),
                  lambda: get_frame(session, frame_id), state, apply, action, actor, revert, undo_of)


def get_frame(session: Session, frame_id: int) -> Frame:
    """The frame with this id. Raises :class:`NotFoundError`."""
    return found(session.get(Frame, frame_id), "frame", frame_id)


def get_system(session: Session, system_id: int) -> System:
    """The system with this id. Raises :class:`NotFoundError`."""
    return found(session.get(System, system_id), "system", system_id)


def check_undo_state(undo: Optional[Revert], state: dict[str, Any]) -> None:
    """An undo restores exactly only what nothing changed since: refuse it (:class:`ConflictError`, 409) when
    the edited part's state under the write's lock (``state``) is not the undone entry's ``after``
    (``undo.expect``). Nothing to check without an undo."""
    if undo is None or undo.expect is None or same_json(state, undo.expect):
        return
    raise ConflictError(f"audit entry {undo.entry_id} cannot be undone: its resource changed since (it is now "
                        f"{json.dumps(state)[:300]}); undo the newer entries first", current=state)
