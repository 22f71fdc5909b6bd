"""The guarded, audited write every edit and decision goes through, and its one locking design.

Every write is described by an :class:`EditPlan` and is attributed and guarded, in one transaction: it checks the
version its client expected (the ``If-Match`` of the frame or of the system, ``app.services.curation.versions``; 412
when stale), applies the change, recomputes what it implies (the plan's explicit ``recompute`` flag), and records one
audit entry (``app.services.audit.log``, by the plan's ``actor``, None meaning
:func:`~app.services.audit.log.local_actor`) with the edited part's state before and after. ``revert`` marks the
write as the revert of an audit entry (``app.services.curation.reverting``): it is recorded as action ``revert``, and
refused with :class:`~app.core.errors.ConflictError` when the state it read is not ``revert.expect``.

Concurrency: optimistic, with a version column (:func:`guarded_write`). What an edit of a system reads is declared in
``app.db.scope``; ``System.version`` covers the system's rows and ``Game.version`` its game's rig and
camera prior, each bumped in the transaction of every write of what it covers.

1. **Read.** The edit loads its system (``recompute.load_for_recompute``: the system with its version, its views,
   their rows, pairs, doubts and its game with its version) and, when it recomputes, its game's rig rows, then ends
   that read-only transaction (``app.db.session.end_reads``): its connection goes back to the pool.
2. **Compute** in memory, holding no connection: the edit's change, its recomputation (the edited frame's calibration
   with its rig or prior retry, admission, mirror evidence, triangulation, reprojections, boxes, doubts, queue
   figures), the decisions it resets, and the new versions (``scope.changed``, the frame's ``edit_version``).
3. **Lock, compare, write.** The write transaction begins (``app.db.session.begin_write``: SQLite's ``BEGIN
   IMMEDIATE``); an edit that read its game's rig locks the game's row and compares its version; the flush writes the
   changed rows, its ``UPDATE`` of the system comparing the version the system was read with (SQLAlchemy's version
   counter, ``WHERE version = <as read>``, which also takes the system's row lock on PostgreSQL); the audit entry;
   the commit. Either version changed (another write of what the edit read committed meanwhile): everything is
   rolled back and the edit runs again from step 1 (:data:`OPTIMISTIC_ATTEMPTS` times in all), then once more under
   the lock: the lock first (the game's row, then the system's), then steps 1 and 2, then the write.

Kinds whose edit re-fits beyond the system (ISSIA's trajectory: ``KindPolicy.computes_before_lock`` False) and writes
that recompute nothing (decisions) run under the lock at once. The lock is held only to compare and write, so waits
are short: a served process waits at most ``V3D_WRITE_LOCK_TIMEOUT_S`` (SQLite busy timeout, PostgreSQL
``lock_timeout``) and the API answers 503 with ``Retry-After`` beyond it (``app.api.errors``). Two edits of one
system's views therefore never lose each other's label: the later one finds the earlier one's version and computes
again. Within one server process the recomputing edits take turns (:class:`EditSlots`): their work holds the GIL, so
edits computing side by side in one process only stretch each other.

Each edit carries its state down the call chain in an explicit :class:`EditContext` (the process's turns, the audit
facts its change notes, the rig rows it read) and answers back in it (its audit entry's id, how it was stored).
"""
from __future__ import annotations

import contextlib
import functools
import json
import logging
import threading
from collections.abc import Collection, Iterator
from dataclasses import dataclass, field
from typing import Any, Callable, Generic, Literal, Optional, TypeVar

import numpy as np
import sqlalchemy as sa
from sqlalchemy.orm import Session
from sqlalchemy.orm.exc import StaleDataError

from app.core.config import Settings
from app.core.errors import ConflictError, NotFoundError, StaleVersionError, found
from app.core.metrics import count_edit
from app.db import scope
from app.db.models import AuditEntry, Frame, Game, System
from app.db.session import begin_write, end_reads, reads_on_their_own
from app.db.unit import write_unit
from app.services.audit import log as audit
from app.services.curation.states import same_json
from app.services.curation.system_page import load_frame
from app.services.curation.versions import check_expected
from app.services.derivation.loading import load_view_players
from app.services.derivation.recompute import load_for_recompute, system_rig_rows
from app.services.kinds import kind_of, policy

T = TypeVar("T")
log = logging.getLogger(__name__)

Expected = Optional[Collection[int]]
#: How an edit was stored (:attr:`EditContext.outcome`): computed once after its reads and written under the lock
#: unchanged ("computed"), computed again after another write of what it read committed first ("recomputed"), or
#: computed while holding the lock ("under_lock").
Outcome = Literal["computed", "recomputed", "under_lock"]
#: How many times an edit computes after its reads before it computes under the lock: several annotators on the
#: views of one system take turns at the lock without computing there, unless they keep colliding.
OPTIMISTIC_ATTEMPTS = 2


@dataclass(frozen=True)
class Restorable:
    """The decisions an edit set back to pending, which the undo or revert of that edit gives back when it brings the
    whole system's labels back to those they were decided on (``app.services.curation.resets``): ``resets`` are the
    edit's write's reset entries ``(action, frame id or None, before, after)``; ``version`` the system's version once
    every entry after the edit was written; ``labels`` the state each view's label changed since must have again,
    ``(frame id, part) -> state`` (part "ball", "lines" or "excluded"): the one it had when the edit was made."""

    resets: tuple[tuple[str, Optional[int], dict[str, Any], dict[str, Any]], ...]
    version: int
    labels: dict[tuple[int, str], Any] = field(default_factory=dict)


@dataclass(frozen=True)
class Revert:
    """An edit that reverts audit entry ``entry_id``: recorded as action ``revert``; refused (409) when
    the edited part's state it read is not ``expect`` (the entry's ``after``; None: forced). ``decisions``: what it
    may restore of the decisions the entry's edit reset (:class:`Restorable`), None when nothing."""

    entry_id: int
    expect: Optional[dict[str, Any]] = None
    decisions: Optional[Restorable] = None


class EditSlots:
    """Turns of the recomputing edits of one process: at most ``slots`` compute at once; another waits for a turn at
    most ``wait_s`` seconds, then computes beside them. ``slots`` 0: no limit. The app makes one from
    ``Settings.edit_slots`` and ``Settings.edit_slot_wait_s`` and hands it to each edit (:class:`EditContext`); an edit
    without (a command line, a test of the services) takes no turn.

    Raises:
        ValueError: a negative ``slots`` or ``wait_s``.
    """

    def __init__(self, slots: int, wait_s: float) -> None:
        if slots < 0 or wait_s < 0:
            raise ValueError(f"edit slots need slots >= 0 and wait_s >= 0, not {slots} and {wait_s}")
        self.slots, self.wait_s = int(slots), float(wait_s)
        self._turns = threading.BoundedSemaphore(self.slots) if self.slots else None

    @contextlib.contextmanager
    def turn(self) -> Iterator[bool]:
        """Hold a turn for the block, when one is free within ``wait_s`` (none without a limit, or once the wait ran
        out: the block runs beside the others); true when the edit waited behind another edit of the process, which
        may have committed meanwhile (what the edit read before is read again)."""
        turns = self._turns
        got = waited = False
        if turns is not None:
            got = turns.acquire(blocking=False)
            if not got:
                waited = True
                got = turns.acquire(timeout=self.wait_s)
        try:
            yield waited
        finally:
            if got and turns is not None:
                turns.release()


@dataclass
class EditContext:
    """One edit's state, passed down explicitly from its caller (a route makes one with the process's
    :class:`EditSlots`; a service called without one makes its own) and read back once the edit returned.

    Down: ``slots``, the process's turns. While it runs: ``facts``, what its change notes for its audit entry's summary
    (``calibration=(before, after)`` in words); ``rig``, its game's rig rows (``rigs.rig_rows``) read with its system,
    None when its kind reads none; ``version``, its system's version as it read it. Back: ``entry_id``, its audit
    entry's id; ``outcome`` (:data:`Outcome`); ``attempts``, how many times it computed."""

    slots: Optional[EditSlots] = None
    facts: dict[str, Any] = field(default_factory=dict)
    rig: Optional[list[tuple[int, np.ndarray, bool]]] = None
    version: Optional[int] = None
    entry_id: Optional[int] = None
    outcome: Optional[Outcome] = None
    attempts: int = 0

    def turn(self) -> contextlib.AbstractContextManager[bool]:
        """A turn of the process's recomputing edits (:meth:`EditSlots.turn`: true when it waited), or none without
        slots."""
        return self.slots.turn() if self.slots is not None else contextlib.nullcontext(False)


@dataclass(frozen=True)
class EditPlan(Generic[T]):
    """What one guarded write does (:func:`guarded_write`), described before it runs.

    ``frame_id``: the write's subject, that view of the system (its version ``Frame.edit_version`` guarded), or None:
    the system itself (``System.version``); ``expected``: the versions the client expected of it (``If-Match``,
    :func:`~app.services.curation.versions.expected_versions`; None accepts any). ``state``: the edited part's state
    of the subject, recorded before and after; ``apply``: the change of the subject and the recomputation it asks for
    (its answer is the write's). ``action``: the audit entry's action (``revert`` when ``revert``), by ``actor``
    (None: the local actor); ``undo_of``: the entry this write undoes (its ``reverts_id``, under its own action).

    ``recompute``: the explicit flag of a write that recomputes its system with ``settings`` (an edit: it reads its
    game's rig rows with it, takes a turn of :class:`EditSlots`, computes before the lock and compares under it);
    False: it recomputes nothing and runs under the lock at once (a decision; ``settings`` unused). ``players``: it may
    place a view by its players (the mirror fix of a view they placed): its views' person boxes are read with them.

    Raises:
        ValueError: ``recompute`` without ``settings``.
    """

    action: str
    state: Callable[[Any], dict[str, Any]]
    apply: Callable[[Any], T]
    actor: Optional[str] = None
    frame_id: Optional[int] = None
    expected: Expected = None
    revert: Optional[Revert] = None
    undo_of: Optional[int] = None
    recompute: bool = False
    settings: Optional[Settings] = None
    players: bool = False

    def __post_init__(self) -> None:
        if self.recompute and self.settings is None:
            raise ValueError("a write that recomputes needs the settings it recomputes with")

    @property
    def reads_with(self) -> Optional[Settings]:
        """The settings its reads and recomputation use: None for a write that recomputes nothing (a decision reads
        neither predictions nor rig)."""
        return self.settings if self.recompute else None

    def subject(self, system: System) -> Frame | System:
        """The subject in the loaded ``system``: its view ``frame_id`` (:func:`view_of`) or the system."""
        return view_of(system, self.frame_id) if self.frame_id is not None else system


@dataclass(frozen=True)
class _Computed(Generic[T]):
    """What an attempt computed holding no connection: the subject, its state before and after, ``apply``'s answer."""

    subject: Frame | System
    before: dict[str, Any]
    after: dict[str, Any]
    result: T


class _Collided(Exception):
    """Another write of what the edit read committed between its reads and its lock: it runs again."""


class _MustLock(Exception):
    """The edit's kind re-fits beyond its system (``KindPolicy.computes_before_lock`` False): it runs under the lock."""


def guarded_write(session: Session, system_id: int, plan: EditPlan[T], *, edit: Optional[EditContext] = None) -> T:
    """The guarded, audited write of system ``system_id`` every edit and decision goes through (module docstring),
    doing what ``plan`` describes (:class:`EditPlan`). ``edit``: the edit's context (:class:`EditContext`), filled
    with its entry's id and outcome.

    A recomputing write takes a turn of its process's edits, then makes its attempts (:func:`_attempts`), each the
    plain sequence of :func:`_attempt`: read, compute holding no connection, lock, compare, write, commit.

    Raises:
        NotFoundError: no such system (or subject).
        StaleVersionError: the subject's version is not expected (rolled back; its current state described).
        ConflictError: a revert of a state that changed since.
        What ``plan.apply`` raises (rolled back).
    """
    edit = edit if edit is not None else EditContext()
    with edit.turn() if plan.recompute else contextlib.nullcontext(False) as waited:
        if waited:  # another edit of the process may have committed meanwhile: what was read before is read again
            end_reads(session)
        try:
            return _attempts(session, system_id, plan, edit)
        except StaleVersionError as exc:  # rolled back by its write unit
            _describe_current(session, exc)
            raise


def _attempts(session: Session, system_id: int, plan: EditPlan[T], edit: EditContext) -> T:
    """The retry rule: a recomputing write computes before the lock up to :data:`OPTIMISTIC_ATTEMPTS` times, again
    each time it met another write of what it read, then once more under the lock (at once for a write that
    recomputes nothing, or whose kind re-fits beyond its system); each stored write counted (``count_edit``)."""
    for attempt in range(OPTIMISTIC_ATTEMPTS if plan.recompute else 0):
        try:
            result = _attempt(session, system_id, plan, edit, locked=False)
        except _Collided:
            log.info("an edit of system %s met another write of what it read; computing again", system_id)
            continue
        except _MustLock:
            edit.attempts -= 1  # it read, it did not compute
            break
        edit.outcome = "computed" if attempt == 0 else "recomputed"
        count_edit(plan.action, edit.outcome)
        return result
    result = _attempt(session, system_id, plan, edit, locked=True)
    edit.outcome = "under_lock" if edit.attempts == 1 else "recomputed"
    count_edit(plan.action, edit.outcome if plan.recompute else "decided")
    return result


def _attempt(session: Session, system_id: int, plan: EditPlan[T], edit: EditContext, *, locked: bool) -> T:
    """One attempt, in one write unit (rolled back when it raises: a collision, a refusal, a failure): read the inputs
    and the versions, compute holding no connection, take the write lock and compare the versions, write the change
    and its audit entry, commit. ``locked``: the lock is taken first (the last attempt), so nothing is compared."""
    edit.attempts += 1
    edit.facts, edit.rig = {}, None
    with write_unit(session, lock=False):
        system, game_version = _read(session, system_id, plan, edit, locked=locked)
        computed = _compute(session, system, plan)
        if not locked:
            _lock_and_compare(session, system, game_version)
        entry = _write(session, plan, computed, edit, locked=locked)
    edit.entry_id = entry.id
    return computed.result


def _read(session: Session, system_id: int, plan: EditPlan[Any], edit: EditContext, *,
          locked: bool) -> tuple[System, Optional[int]]:
    """Step 1: the system with its version, its views, their rows and its game (``load_for_recompute``), and, for a
    recomputing write, its game's rig rows (``edit.rig``); then the read-only transaction ends (its connection back
    to the pool) unless ``locked``, when the write lock (game first, then system) is taken before anything is read.
    Returns the system and its game's version as read. Raises :class:`_MustLock` for a kind that computes under the
    lock only, :class:`NotFoundError` for no such system."""
    if locked:
        begin_write(session)
        lock_system(session, system_id, game=plan.recompute)
    else:  # the version is read first, with the system row: anything committed after it makes the compare fail
        reads_on_their_own(session)
    settings = plan.reads_with
    per_frame = settings.max_predictions_per_frame if settings is not None else None
    system = found(load_for_recompute(session, [system_id], predictions=per_frame, with_game=True).get(system_id),
                   "system", system_id)
    if not locked and not kind_of(system).computes_before_lock:
        raise _MustLock()
    game_version = system.game.version if system.game is not None else None
    edit.version = system.version
    edit.rig = system_rig_rows(session, system, settings) if settings is not None else None
    if plan.players:
        load_view_players(session, list(system.frames))
    if not locked:
        end_reads(session)  # the connection goes back to the pool while the edit computes
    return system, game_version


def _compute(session: Session, system: System, plan: EditPlan[T]) -> _Computed[T]:
    """Step 2, holding no connection (no autoflush): check the subject's version (412) and bump a view's, its state
    before, a revert's check (409), the change and its recomputation, its state after, the new versions
    (``scope.changed``: not for a view's decision, which changes the view's version alone) and the resets' stamps."""
    subject = plan.subject(system)
    with session.no_autoflush:
        _check_and_bump(plan, subject)
        before = plan.state(subject)
        _check_revert(plan.revert, before)
        result = plan.apply(subject)
        after = plan.state(subject)
        if plan.recompute or isinstance(subject, System):
            scope.changed(system)
        audit.stamp_versions(session, system)  # the resets it recorded while computing, before the bump
    return _Computed(subject, before, after, result)


def _check_and_bump(plan: EditPlan[Any], subject: Frame | System) -> None:
    """Raise :class:`StaleVersionError` when the subject's version is not expected; bump a view's version (its flush
    compares the version it was read with; a system's is bumped by every write of its labels, lines, exclusions,
    calibrations or decision, ``scope.changed``)."""
    if isinstance(subject, Frame):
        check_expected("frame", subject.id, subject.edit_version, plan.expected)
        subject.edit_version += 1
    else:
        check_expected("system", subject.id, subject.version, plan.expected)


def _lock_and_compare(session: Session, system: System, game_version: Optional[int]) -> None:
    """Step 3: begin the write transaction (``begin_write``: refuses a session that read while computing, a row
    outside ``scope``) and compare the game's version under its row lock; raise :class:`_Collided` when it changed
    (the system's version is compared by the flush of :func:`_write`). An edit that changes its game's rig (a
    recalibration bumped the game's version) locks the game's row alone; the others share it: they need only that
    nobody changes the rig until they commit."""
    begin_write(session)
    changes_rig = system.game is not None and system.game.version != game_version
    with session.no_autoflush:
        if _game_version(session, system.game_id, lock="update" if changes_rig else "share") != game_version:
            raise _Collided()  # its game's rig or camera prior changed since it was read


def _write(session: Session, plan: EditPlan[Any], computed: _Computed[Any], edit: EditContext, *,
           locked: bool) -> AuditEntry:
    """Step 4: the audit entry, and the flush writing the changed rows, its ``UPDATE`` of the system comparing the
    version it was read with (:class:`_Collided` when another write committed since, unless ``locked``: then
    nothing else could). Returns the entry."""
    subject = computed.subject
    entry = audit.record(session, actor=plan.actor, action="revert" if plan.revert is not None else plan.action,
                         frame=subject if isinstance(subject, Frame) else None,
                         system=subject if isinstance(subject, System) else None,
                         before=computed.before, after=computed.after,
                         reverts_id=plan.revert.entry_id if plan.revert is not None else plan.undo_of,
                         facts=edit.facts)
    try:
        session.flush()
    except StaleDataError:
        if locked:
            raise
        raise _Collided() from None
    return entry


def _check_revert(revert: Optional[Revert], before: dict[str, Any]) -> None:
    """Refuse a revert whose resource's state (``before``) is no longer what its entry left (409)."""
    if revert is not None and revert.expect is not None and not same_json(before, revert.expect):
        raise ConflictError(f"audit entry {revert.entry_id} cannot be reverted: its resource changed since "
                            f"(it is now {json.dumps(before)[:300]}); revert the newer entries first, or force it",
                            current=before)


def _game_version(session: Session, game_id: int, *, lock: Literal["update", "share"]) -> Optional[int]:
    """The stored version of game ``game_id``, its row locked until the transaction ends (PostgreSQL's ``FOR UPDATE``
    for a write that changes the game, ``FOR SHARE`` for one that only needs it unchanged until it commits: such
    writes of one game do not wait for each other; SQLite's write transaction holds the database already). Each
    transaction takes one of the two once, before it writes the game, so none waits to upgrade its lock."""
    return session.execute(_game_version_statement(lock), {"id": game_id}).scalar()


@functools.cache
def _game_version_statement(lock: Literal["update", "share"]) -> Any:
    """:func:`_game_version`'s statement for ``lock``, taking the game's id as ``id``: built once, of the table's
    columns (an ORM statement was built and compiled by the ORM on every edit, several times what running it costs)."""
    g = Game.__table__.c
    return sa.select(g.version).where(g.id == sa.bindparam("id")).with_for_update(read=lock == "share")


def lock_system(session: Session, system_id: int, *, game: bool = False) -> None:
    """Lock the system's row (and its game's row first when ``game``, a write that recomputes and so reads the game's
    rig or prior, or when its kind's edits change other systems of its game) until the transaction ends, in a write
    transaction (``begin_write``), before the caller reads what it changes under the lock.

    PostgreSQL: ``SELECT ... FOR UPDATE`` makes concurrent writes of one system (one game's rig, one ISSIA
    sequence) wait for each other. Rows are always locked game first, then system (as an edit's flush writes
    them): no two writes wait for each other in a cycle. SQLite has no ``FOR UPDATE`` (its ``BEGIN IMMEDIATE``, which
    every write transaction begins with, already serialises them): the statements read the rows only.

    Raises:
        NotFoundError: no system has this id.
    """
    row = session.execute(sa.select(System.game_id, System.kind).where(System.id == system_id)).one_or_none()
    if row is None:
        raise NotFoundError("system", system_id)
    if game or policy(row.kind).edit_locks_game:
        _game_version(session, row.game_id, lock="update")
    session.execute(sa.select(System.id).where(System.id == system_id).with_for_update())


def _describe_current(session: Session, exc: StaleVersionError) -> None:
    """Fill a stale write's current state: the frame loaded for its view, or the system and its review with the
    entries written since the version its client saw (``exc.changes``: its views' edits and its decisions, the newest
    of them its last change)."""
    if exc.kind == "frame":
        exc.current = load_frame(session, exc.ident)
        exc.last_change = audit.latest_entry(session, frame_id=exc.ident)
    else:
        system = get_system(session, exc.ident)
        _ = system.review  # loaded now: the answer is shaped after the session is gone
        exc.current = system
        exc.changes = list(audit.entries_since(session, exc.ident, exc.seen)) if exc.seen is not None else []
        exc.last_change = exc.changes[-1] if exc.changes else audit.latest_entry(session, system_id=exc.ident)


def guarded_frame_write(session: Session, plan: EditPlan[T], *, system_id: Optional[int] = None,
                        edit: Optional[EditContext] = None) -> T:
    """:func:`guarded_write` of the view ``plan.frame_id`` (its system ``system_id``, looked up when None:
    :func:`frame_facts`). Raises :class:`NotFoundError` for an unknown frame, ``ValueError`` for a plan without
    ``frame_id``, and what ``guarded_write`` raises."""
    if plan.frame_id is None:
        raise ValueError("a view's write names its view (plan.frame_id)")
    if system_id is None:
        system_id = frame_facts(session, plan.frame_id).system_id
    return guarded_write(session, system_id, plan, edit=edit)


def view_of(system: System, frame_id: int) -> Frame:
    """The view ``frame_id`` of the loaded ``system`` (no query). Raises :class:`NotFoundError` when it has none (the
    frame moved to another system since its facts were read)."""
    return found(next((f for f in system.frames if f.id == frame_id), None), "frame", frame_id)


def get_frame(session: Session, frame_id: int) -> Frame:
    """The frame with this id. Raises :class:`NotFoundError`."""
    return found(session.get(Frame, frame_id), "frame", frame_id)


@dataclass(frozen=True)
class FrameFacts:
    """What an edit checks of its frame before it computes: its system and image size (pixels)."""

    id: int
    system_id: int
    width: int
    height: int


def frame_facts(session: Session, frame_id: int) -> FrameFacts:
    """The frame's :class:`FrameFacts`, read by one statement built once (no ORM object: the edit loads the frame
    with its system next, ``recompute.load_for_recompute``), without a transaction of its own on PostgreSQL
    (``reads_on_their_own``: the edit compares the versions it reads next under its lock, and validates its input
    against the frame it writes again). Raises :class:`NotFoundError`."""
    reads_on_their_own(session)
    row = session.execute(_frame_facts_statement(), {"id": frame_id}).one_or_none()
    return FrameFacts(*found(row, "frame", frame_id))


@functools.cache
def _frame_facts_statement() -> Any:
    F = Frame.__table__
    return sa.select(F.c.id, F.c.system_id, F.c.width, F.c.height).where(F.c.id == sa.bindparam("id"))


def get_system(session: Session, system_id: int) -> System:
    """The system with this id. Raises :class:`NotFoundError`."""
    return found(session.get(System, system_id), "system", system_id)


def check_undo_state(undo: Optional[Revert], state: dict[str, Any]) -> None:
    """An undo restores exactly only what nothing changed since: refuse it (:class:`ConflictError`, 409) when
    the edited part's state the write read (``state``) is not the undone entry's ``after`` (``undo.expect``).
    Nothing to check without an undo."""
    if undo is None or undo.expect is None or same_json(state, undo.expect):
        return
    raise ConflictError(f"audit entry {undo.entry_id} cannot be undone: its resource changed since (it is now "
                        f"{json.dumps(state)[:300]}); undo the newer entries first", current=state)
