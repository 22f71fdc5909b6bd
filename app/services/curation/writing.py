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

Concurrency (several server processes, issues 7, 27 and 29): one locking design for every edit
(:func:`guarded_write`). Nobody waits on another's geometry, and an edit loads what it recomputes once:

1. **Compute before the lock.** An edit that recomputes (``ball.edit``, ``field_lines.replace``,
   ``field_lines.mirror``, ``view.exclusion``) first runs in a read snapshot (``app.db.session.begin_snapshot``:
   SQLite's deferred ``BEGIN`` under WAL, PostgreSQL ``REPEATABLE READ``; no lock, nothing flushed,
   :func:`_compute_before_lock`): its state before, its ``apply`` (the change, the recomputation it asks for
   through :func:`recompute_planned`: the edited frame's calibration with its rig or prior retry, admission, mirror
   evidence, triangulation, reprojections, boxes, doubts, queue figures; the decision resets) and its state after,
   all in memory. The recomputation loads its system in a few queries (``recompute.load_for_recompute``) and
   reads, in the same snapshot, the digest of every stored row it loaded (``recompute.stored_state_digest``: the
   system, its views and their one-to-one rows, triangulation, pairs, doubts, reviews, the game and its rig
   rows) and, on SQLite, the database's ``data_version``.
2. **Compare and write under the lock.** The snapshot ends without expiring anything
   (``app.db.session.begin_write_keeping_objects``: the same connection, ``BEGIN IMMEDIATE`` on SQLite) and the
   edited system's row is locked (:func:`lock_system`: ``SELECT ... FOR UPDATE`` on PostgreSQL, the game's row
   first for an ISSIA system). Under the lock the stored rows are compared with what was read: on SQLite an
   unchanged ``data_version`` says that no other connection committed anything since; otherwise the digest is
   read again. Equal, the objects in memory are the stored rows plus this edit's changes: the edit claims its
   version (412), checks a revert (409), writes only the attributes that changed (the label, new rows and the audit
   entry through the unit of work; then the derived rows the recomputation changed, in place, as one ``UPDATE`` per
   table and columns: ``derivation.rows.writing_directly``), and the answer is drawn from the same objects. On
   PostgreSQL the statements that do not wait for each other's answers go in one round trip (``app.db.together``):
   the lock, the rig rows, the digest and the claim; the derived rows' updates and the digest (and rig rows) of what
   was written. An edit of a system this process kept and trusts (``kept.KeptSystems.take_trusted``, PostgreSQL)
   reads nothing before its lock: the kept digest stands for the snapshot's. Different (another edit of the system,
   or of its game's rig, committed meanwhile),
   everything is rolled back (objects expired) and the edit computes again before the lock from what the other
   committed (:data:`_ATTEMPTS_BEFORE_LOCK` times in all); colliding again, it runs under the lock: claim, change,
   recompute, audit.
   ``session.info[LAST_RECOMPUTATION]`` says which happened ("precomputed", "recomputed", "under_lock").
3. **One edit computes at a time per process.** The recomputing edits of one server process take turns
   (:class:`EditSlots`, ``Settings.edit_slots``, handed to the sessions by the app): their work holds the GIL, so
   edits computing side by side in one process only stretch each other, widen the window in which a sibling commits
   first, and slow the one holding the write lock while the other processes wait for it. An edit waits at most
   ``Settings.edit_slot_wait_s`` for its turn, then computes anyway: a long geometry delays the others by no more.

Two edits of one system's views therefore never lose each other's label: the later one finds the earlier one's
label under the lock and recomputes. Kinds whose edit re-fits beyond the system (ISSIA's trajectory:
``KindPolicy.computes_before_lock`` False) and writes that recompute nothing (review decisions) compute under the
lock as before. The lock is held only to compare and write, so waits are short: a served process waits at most
``V3D_WRITE_LOCK_TIMEOUT_S`` (SQLite busy timeout, PostgreSQL ``lock_timeout``) and the API answers 503 with
``Retry-After`` beyond it (``app.api.errors``).
"""
from __future__ import annotations


import contextlib
import functools
import json
import threading
from collections.abc import Collection, Iterator, Sequence
from dataclasses import dataclass, field
from typing import Any, Callable, Optional, TypeVar

from sqlalchemy import bindparam, event, select
from sqlalchemy import exc as sa_exc
from sqlalchemy.orm import Session

from app.core.config import Settings
from app.db.models import (
    AuditEntry, Frame, Game, System,
)
from app.db.session import begin_snapshot, begin_write, begin_write_keeping_objects, data_version
from app.services.audit import log as audit
from app.core.errors import ConflictError, NotFoundError, StaleVersionError, found
from app.services.kinds import kind_of, policy
from app.db.together import Call, calls_after_writes, keep_answers_after_writes, send_together
from app.services.derivation.recompute import (
    load_for_recompute, read_stored_state, rig_game_of, rows_digest_call, rows_digest_of, state_digest,
    stored_rows_digest, system_rig_rows,
)
from app.services.calibration.rigs import rig_call, rig_rows_of
from app.services.derivation.rows import DirectWrites, writing_directly
from app.services.curation.kept import KEPT_SYSTEMS, KeptSystems
from app.services.curation.system_page import load_frame
from app.services.curation.versions import Claim
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
    ends (:func:`lock_calls`), then expire every loaded object so that what the caller reads next is read under the
    lock. (An edit that carries its objects from its snapshot sends :func:`lock_calls` with its reads instead.)

    Raises:
        NotFoundError: no system has this id.
    """
    send_together(session, lock_calls(session, system_id, autoflush=True))
    session.expire_all()


def lock_calls(session: Session, system_id: int, *, loaded: Optional[System] = None,
               autoflush: bool = False) -> list[Call]:
    """The statements that lock the system's row (and, for an ISSIA system, its game's row first) until the
    transaction ends, to be sent (``app.db.together.send_together``) before what the caller reads under the lock, in
    the same round trip on PostgreSQL. An edit that carries its objects from its snapshot (:func:`_write_carried`)
    passes the system it loaded (``loaded``), whose kind and game (never changed once stored) spare looking them up;
    the session's changes are flushed by that lookup only with ``autoflush`` (they are kept in memory otherwise).

    PostgreSQL: ``SELECT ... FOR UPDATE`` makes concurrent edits of one system (one sequence for ISSIA,
    whose edits re-fit the trajectory of the whole game) wait for each other, so no recomputation is
    computed from labels another transaction is changing and then overwrites that transaction's result.
    Rows are always locked game first, then system: no two edits wait for each other in a cycle. Systems
    of other games, and other systems of a SoccerNet game, are edited in parallel. SQLite has no ``FOR UPDATE``
    (its ``BEGIN IMMEDIATE``, which every write transaction begins with, already serialises them): no statement.

    Raises:
        NotFoundError: no system has this id.
    """
    with session.no_autoflush if not autoflush else contextlib.nullcontext():
        if loaded is not None:
            kind, game_id = loaded.kind, loaded.game_id
        else:
            row = session.execute(select(System.game_id, System.kind).where(System.id == system_id)).one_or_none()
            if row is None:
                raise NotFoundError("system", system_id)
            kind, game_id = row.kind, row.game_id
    if session.get_bind().dialect.name == "sqlite":
        return []
    calls = [Call(_LOCK_GAME, {"game_id": game_id})] if policy(kind).edit_locks_game else []
    return [*calls, Call(_LOCK_SYSTEM, {"system_id": system_id})]


#: The row locks of :func:`lock_calls` (PostgreSQL), built once.
_LOCK_GAME = select(Game.id).where(Game.id == bindparam("game_id")).with_for_update()
_LOCK_SYSTEM = select(System.id).where(System.id == bindparam("system_id")).with_for_update()


# ----- the one locking design of the edit path (module docstring, "Concurrency") ---------------------------
#: ``session.info`` key of the running edit's :class:`_Plan`.
_PLAN = "v3d.edit.plan"


#: ``session.info`` key: how the last edit's recomputation was stored: "precomputed" (computed before the lock,
#: the stored rows unchanged under it), "recomputed" (a stored row changed after its first computation: computed
#: again, before the lock or under it) or "under_lock" (computed under the lock only: the kind re-fits beyond its
#: system, or nothing was computed before).
LAST_RECOMPUTATION = "v3d.edit.recomputation"


#: The audited actions whose edits recompute their system, hence compute before the lock.
_RECOMPUTING = frozenset({"ball.edit", "field_lines.replace", "field_lines.mirror", "view.exclusion"})
#: How many times an edit computes before the lock when another edit of its system commits between its computation
#: and its lock each time; then it computes under the lock (several annotators on the views of one system take
#: turns at the lock without computing there, unless they keep colliding).
_ATTEMPTS_BEFORE_LOCK = 2


class EditSlots:
    """Turns of the recomputing edits of one process (module docstring, "Concurrency", 3): at most ``slots`` compute
    at once; another waits for a turn at most ``wait_s`` seconds, then computes beside them. ``slots`` 0: no limit.
    The app factory makes one from ``Settings.edit_slots`` and ``Settings.edit_slot_wait_s`` and hands it to every
    session of its factory (``session.info[EDIT_SLOTS]``); a session without (a command line, a test of the services)
    takes no turn.

    Raises:
        ValueError: a negative ``slots`` or ``wait_s``.
    """

    def __init__(self, slots: int, wait_s: float) -> None:
        if slots < 0 or wait_s < 0:
            raise ValueError(f"edit slots need slots >= 0 and wait_s >= 0, not {slots} and {wait_s}")
        self.slots, self.wait_s = int(slots), float(wait_s)
        self._turns = threading.BoundedSemaphore(self.slots) if self.slots else None

    @contextlib.contextmanager
    def turn(self) -> Iterator["Turn"]:
        """Hold a turn for the block: a :class:`Turn`, true when one was free within ``wait_s``, false when the block
        runs without (no limit, or the wait ran out); ``waited`` when another edit held the last turn on asking."""
        turns = self._turns
        got = waited = False
        if turns is not None:
            got = turns.acquire(blocking=False)
            if not got:
                waited = True
                got = turns.acquire(timeout=self.wait_s)
        try:
            yield Turn(got, waited)
        finally:
            if got:
                turns.release()  # type: ignore[union-attr]


@dataclass(frozen=True)
class Turn:
    """An edit's turn (:meth:`EditSlots.turn`): ``got`` one (its truth value), and ``waited`` for it behind another
    edit of the process, which may have committed meanwhile: what the edit read before is read again
    (``app.db.session.begin_snapshot(fresh=True)``)."""

    got: bool
    waited: bool

    def __bool__(self) -> bool:
        return self.got


#: ``session.info`` key of the :class:`EditSlots` of the session's process (set by the app's session factory).
EDIT_SLOTS = "v3d.edit.slots"


def _edit_turn(session: Session) -> contextlib.AbstractContextManager[Turn]:
    """The turn of a recomputing edit in ``session``'s process (:class:`EditSlots`), or none (a :class:`Turn` neither
    got nor waited for) without slots."""
    slots: Optional[EditSlots] = session.info.get(EDIT_SLOTS)
    return slots.turn() if slots is not None else contextlib.nullcontext(Turn(False, False))


@dataclass
class _Plan:
    """What an edit computing before its lock read (:func:`recompute_planned`): per recomputed system, the digest of
    its stored rows as the snapshot saw them (``recompute.stored_state_digest``), the snapshot's SQLite
    ``data_version`` (None on PostgreSQL), the settings it computed with, and the system loaded for it (``preloaded``:
    held here, so that the session's identity map, which holds objects weakly, keeps the whole load)."""

    digests: dict[int, str] = field(default_factory=dict)
    data_version: Optional[int] = None
    settings: Optional[Settings] = None
    preloaded: Optional[System] = None
    direct: Optional[DirectWrites] = None
    rows_digest: Optional[str] = None  # ``recompute.stored_rows_digest`` of the preloaded system, read in the snapshot
    rig: Optional[tuple[Settings, Any]] = None  # the settings and rig rows read with ``rows_digest`` (kept system)
    trusted: bool = False  # the kept system was used without reading anything first (``kept.KeptSystems.take_trusted``)


@dataclass
class _Carried:
    """An edit computed in its snapshot, in memory, to be written under the lock when nothing it read changed:
    its subject, state before and after, result and plan."""

    target: Any
    before: dict[str, Any]
    after: dict[str, Any]
    result: Any
    plan: _Plan


class _NoWriteBeforeLock(Exception):
    """Raised by a flush while an edit computes before its lock: everything is written under the lock only."""


@event.listens_for(Session, "before_flush")
def _no_flush_before_lock(session: Session, _context: Any, _instances: Any) -> None:
    if session.info.get(_PLAN) is not None:
        raise _NoWriteBeforeLock()


def computed_before_lock(system_id: int) -> None:
    """Called once an edit of system ``system_id`` has computed its recomputation, before it asks for the write
    lock (a hook: does nothing; the concurrency tests hold an edit here while another commits)."""


def _compute_before_lock(session: Session, system_id: int, subject: Callable[[], Any],
                         state: Callable[[Any], dict[str, Any]], apply: Callable[[Any], Any],
                         fresh: bool = False) -> Optional[_Carried]:
    """Run the edit in a read snapshot (``begin_snapshot``: no lock, nothing flushed; the one the edit's lookups read,
    unless ``fresh``: it waited for its turn): ``state`` of ``subject()`` before, ``apply``, ``state`` after, all in
    memory, with what its recomputation read (:func:`recompute_planned`).
    The snapshot stays open (the caller ends it keeping the objects, :func:`_write_carried`). None, with the
    snapshot rolled back, when there is nothing to carry: the system's kind re-fits beyond it
    (``KindPolicy.computes_before_lock``), the session holds unwritten changes of its caller, the edit recomputed
    nothing or something else than its system, or it failed (whatever fails here is decided again under the
    lock: the same error, or none if the state changed)."""
    try:
        begin_snapshot(session, fresh=fresh)
    except RuntimeError:
        return None
    plan = _Plan()
    carried = None
    session.info[_PLAN] = plan
    try:
        with session.no_autoflush, writing_directly(session) as direct:
            # the one load of the edit: what the subject, its state and the recomputation read, in a few queries, or
            # the objects the last edit of the system in this process committed, when its rows are still those
            plan.preloaded = _kept_system(session, system_id, plan)
            if plan.preloaded is None:
                plan.preloaded = load_for_recompute(session, [system_id], with_game=True).get(system_id)
            if plan.preloaded is not None and kind_of(plan.preloaded).computes_before_lock:
                target = subject()
                before = state(target)
                result = apply(target)  # the derived rows' changes collected (rows.writing_directly), not flushed
                if set(plan.digests) == {system_id}:
                    plan.direct = direct
                    carried = _Carried(target, before, state(target), result, plan)
    except Exception:  # noqa: BLE001  # decided again under the lock
        carried = None
    finally:
        session.info.pop(_PLAN, None)
        if carried is None:
            audit.recorded_entry_id(session)  # an entry apply added here is never written
            session.rollback()
    computed_before_lock(system_id)
    return carried


def _kept_system(session: Session, system_id: int, plan: _Plan) -> Optional[System]:
    """The objects of system ``system_id`` as the last edit of this process committed them (``kept.KeptSystems``),
    attached to ``session``, when the stored rows are still those (the rows' digest, read here in the edit's snapshot
    and kept in ``plan``) and the session holds nothing yet; None otherwise (the edit loads the system)."""
    kept: Optional[KeptSystems] = session.info.get(KEPT_SYSTEMS)
    if kept is None or not kept.holds(system_id) or session.identity_map or session.new:
        return None
    if session.get_bind().dialect.name == "postgresql" and (trusted := kept.take_trusted(system_id)) is not None:
        # PostgreSQL, objects trusted: nothing read before the lock (each read a round trip); the rows' digest and the
        # rig rows as the last edit wrote them, compared under the lock with the stored ones (_write_carried)
        system, plan.rows_digest, trusted_reads = trusted
        if trusted_reads is not None and trusted_reads.rig_written is not None:
            plan.rig = (trusted_reads.settings, trusted_reads.rig_written[0])
        plan.trusted = True
        return _attached(session, system)
    reads: Optional[_KeptReads] = kept.reads_of(system_id)
    if reads is not None:  # the rig rows the recomputation reads, with the digest (one round trip on PostgreSQL)
        plan.rows_digest, rig, _ = read_stored_state(session, system_id, reads.rig_game_id, reads.settings)
        plan.rig = (reads.settings, rig)
    else:
        plan.rows_digest = stored_rows_digest(session, system_id)
    system = kept.take(system_id, plan.rows_digest)
    return _attached(session, system) if system is not None else None


def _attached(session: Session, system: System) -> Optional[System]:
    """``system`` (kept objects) attached to ``session``: persistent again, with everything it had loaded (cascades to
    its views and rows); None when an object is still leaving the session that committed it (the edit loads)."""
    try:
        session.add(system)
    except sa_exc.InvalidRequestError:
        session.expunge_all()
        return None
    return system


def _write_derived_and_keep(session: Session, system_id: int, plan: _Plan, with_writes: Sequence[Call] = ()
                            ) -> tuple[list[Any], Optional[Callable[[], None]]]:
    """Under the lock, after the unit of work flushed the edit's share: the derived rows the recomputation changed
    (``plan.direct``: one UPDATE per table and columns), the calls ``with_writes`` (the audit entry's insert), when
    the session's process keeps systems, the digest of the rows as written, and the reads the request's answer asked
    to make after the writes (``app.db.together.read_after_writes``), in one round trip on PostgreSQL; answers
    the answers of ``with_writes`` and what keeps the edit's objects for the next edit of the system once the
    transaction committed (``kept.KeptSystems.keep``; None when the process keeps none)."""
    kept: Optional[KeptSystems] = session.info.get(KEPT_SYSTEMS)
    keeping = kept is not None and plan.preloaded is not None
    postgresql = session.get_bind().dialect.name == "postgresql"
    system = plan.preloaded
    rig_game_id = rig_game_of(system) if keeping and plan.settings is not None else None
    after = [*with_writes]
    if keeping and postgresql:  # the rows' digest and the rig rows as written, for the next edit's trusted use
        after += [rows_digest_call(system_id), *([rig_call(rig_game_id, plan.settings)] if rig_game_id is not None
                                                 else [])]
    answer_reads = calls_after_writes(session, plan.preloaded)  # the answer's own reads (its queue neighbours)
    answers = plan.direct.write(session, after + answer_reads) if plan.direct is not None else \
        send_together(session, after + answer_reads)
    keep_answers_after_writes(session, answers)
    answers = answers[:len(after)]
    written, answers = answers[:len(with_writes)], answers[len(with_writes):]
    if not keeping:
        return written, None
    rows = rows_digest_of(answers[0]) if postgresql else stored_rows_digest(session, system_id)
    rig_written = None
    if postgresql and plan.settings is not None:
        rig_written = (rig_rows_of(answers[1]) if rig_game_id is not None else None,)
    reads = _KeptReads(rig_game_id, plan.settings, rig_written) if plan.settings is not None else None
    return written, lambda: kept.keep(system, rows, list(session.identity_map.values()), reads)


@dataclass(frozen=True)
class _KeptReads:
    """What the next edit of a kept system reads with its digest: its game's rig rows (``rig_game_id``; None: its kind
    reads none) under the admission rule of ``settings``."""

    rig_game_id: Optional[int]
    settings: Settings
    #: PostgreSQL: ``(rig rows,)`` as the edit wrote them (None inside: its kind reads none), for an edit using the
    #: kept objects without reading first (``kept.KeptSystems.take_trusted``); None: read them with the digest.
    rig_written: Optional[tuple[Any]] = None


def recompute_planned(session: Session, system: System, settings: Settings,
                       compute: Callable[[Optional[list[tuple[int, Any, bool]]]], Any]) -> None:
    """Run the recomputation ``compute`` of ``system``: what it reads is loaded first, in a few queries
    (``load_for_recompute``; after a flush, under the lock; an edit computing before its lock loaded it already).
    Within an edit computing before its lock (:func:`_compute_before_lock`) the digest of the stored rows it loaded
    is kept for the comparison under the lock (``recompute.stored_state_digest``), in the same snapshot.
    ``compute(rig)`` takes the game's rig rows read here (``recompute.system_rig_rows``; None: the kind uses no
    rig), so they are read once."""
    plan: Optional[_Plan] = session.info.get(_PLAN)
    if plan is None:
        session.flush()
    if plan is None or plan.preloaded is not system:  # what it reads, in a few queries (not one per relation and view)
        load_for_recompute(session, [system.id])
    if plan is None:
        rig = system_rig_rows(session, system, settings)
    else:
        if plan.preloaded is system and plan.rig is not None and plan.rig[0] is settings:  # read with the kept digest
            rows, rig = plan.rows_digest, plan.rig[1]
        else:  # the rig rows and the stored rows' digest (unless read in this snapshot already) in one round trip
            known = plan.rows_digest if plan.preloaded is system else None
            rows, rig, _ = read_stored_state(session, system.id, rig_game_of(system), settings, rows=known)
        plan.digests[system.id] = state_digest(rows, rig)  # type: ignore[arg-type]
        plan.data_version, plan.settings = data_version(session), settings
    compute(rig)


def _write_carried(session: Session, system_id: int, carried: _Carried, claim: Claim,
                   check: Callable[[dict[str, Any]], None],
                   record: Callable[[Any, dict[str, Any], dict[str, Any]], AuditEntry]) -> bool:
    """Write an edit computed before the lock (:func:`_compute_before_lock`) under it, in one transaction: end the
    snapshot keeping its objects (``begin_write_keeping_objects``), lock the system, and compare its stored rows with
    what the snapshot read (SQLite's ``data_version`` unchanged, or the digest read again equal; on PostgreSQL the
    lock, the rig rows, the digest and the claim of the version in one round trip, ``app.db.together``); then settle
    the claim, ``check`` the state before (a revert's), ``record`` the audit entry, flush what the unit of work writes
    (new and deleted rows), send the derived rows that changed and the edited label with the entry's insert and the
    digest of the rows as written (one round trip on PostgreSQL, :func:`_write_derived_and_keep`) and commit.
    False, with everything rolled back, when a stored row changed meanwhile (the caller runs the edit under the
    lock). Raises what ``claim`` and ``check`` raise (rolled back; a stale version described)."""
    try:
        begin_write_keeping_objects(session)
        plan = carried.plan
        with session.no_autoflush:
            lock = lock_calls(session, system_id, loaded=plan.preloaded)  # PostgreSQL's FOR UPDATE; none on SQLite
            claimed: Optional[list[Any]] = None
            if lock:  # PostgreSQL: the lock, the rig rows, the digest and the claim (after the digest, which reads the
                # rows as they were before it) in one round trip; the claim is rolled back with the rest when the
                # digest differs
                dialect = session.get_bind().dialect
                rows, rig, answers = read_stored_state(session, system_id, rig_game_of(plan.preloaded), plan.settings,
                                                       before=lock,
                                                       after=[claim.call(dialect)] if dialect.update_returning else [])
                claimed = answers[0] if answers else None
                unchanged = state_digest(rows, rig) == plan.digests[system_id]
            else:  # SQLite: nobody committed since the snapshot if its data_version says so; else the digest again
                unchanged = plan.data_version is not None and data_version(session) == plan.data_version
                if not unchanged:
                    rows, rig, _ = read_stored_state(session, system_id, rig_game_of(plan.preloaded), plan.settings)
                    unchanged = state_digest(rows, rig) == plan.digests[system_id]
            if not unchanged:
                session.rollback()
                if plan.trusted and (kept := session.info.get(KEPT_SYSTEMS)) is not None:
                    kept.doubt(system_id)  # another process wrote the system: its next kept objects are checked first
                return False
            if claimed is not None:
                claim.settle(session, claimed, expire=False)
            else:
                claim(session, expire=False)
            check(carried.before)
            entry = record(carried.target, carried.before, carried.after)
            # the audit entry goes with the derived rows' updates (one round trip on PostgreSQL), where the database
            # answers an INSERT's new id (RETURNING): else through the unit of work
            with_writes = [audit.insert_call(session, entry)] if session.get_bind().dialect.insert_returning else []
            session.flush()  # the unit of work's share: the edited label, new and deleted rows (the audit entry)
            answers, keep = _write_derived_and_keep(session, system_id, plan, with_writes)
            if with_writes:
                audit.inserted(entry, answers[0])
        session.commit()
        if keep is not None:
            keep()
        return True
    except BaseException as exc:
        _rolled_back(session, exc)
        raise


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
        _rolled_back(session, exc)
        raise


def _rolled_back(session: Session, exc: BaseException) -> None:
    """Roll a failed write back; a stale version (:class:`StaleVersionError`) gets the resource's current state
    (:func:`_describe_current`), read after the rollback."""
    session.rollback()
    if isinstance(exc, StaleVersionError):
        _describe_current(session, exc)


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


def guarded_write(session: Session, system_id: int, claim: Claim, subject: Callable[[], Frame | System],
           state: Callable[[Any], dict[str, Any]], apply: Callable[[Any], T], action: str,
           actor: Optional[str], revert: Optional[Revert], undo_of: Optional[int] = None) -> T:
    """The guarded, audited write every edit goes through (module docstring), in one write transaction
    holding the lock of system ``system_id``: ``claim`` (the compare-and-set of ``versions.Claim``; an edit written
    under the lock after computing before it keeps the session's objects), ``state`` of ``subject()`` before,
    ``apply`` (change and recompute), ``state`` after, one audit entry (``undo_of``: the entry this edit undoes, recorded as its ``reverts_id`` under the edit's own
    action). An edit that recomputes is computed before the lock and written under it when nothing it read
    changed (:func:`_compute_before_lock`, :func:`_write_carried`); otherwise, and for every other write, it runs
    under the lock (:func:`_in_transaction`)."""

    def check(before: dict[str, Any]) -> None:
        if revert is not None and revert.expect is not None and not same_json(before, revert.expect):
            raise ConflictError(f"audit entry {revert.entry_id} cannot be reverted: its resource changed since "
                                f"(it is now {json.dumps(before)[:300]}); revert the newer entries first, or force it",
                                current=before)

    def record(target: Any, before: dict[str, Any], after: dict[str, Any]) -> AuditEntry:
        frame = target if isinstance(target, Frame) else None
        return audit.record(session, actor=actor, action="revert" if revert is not None else action, frame=frame,
                            system=target if frame is None else None, before=before, after=after,
                            reverts_id=revert.entry_id if revert is not None else undo_of)

    def work() -> T:
        claim(session)
        target = subject()
        before = state(target)
        check(before)
        result = apply(target)
        session.flush()
        record(target, before, state(target))
        return result

    recomputes = action in _RECOMPUTING
    with _edit_turn(session) if recomputes else contextlib.nullcontext(Turn(False, False)) as turn:
        changed = False
        attempts = 0
        while recomputes and attempts < _ATTEMPTS_BEFORE_LOCK:
            carried = _compute_before_lock(session, system_id, subject, state, apply, fresh=turn.waited)
            if carried is None:
                break
            if _write_carried(session, system_id, carried, claim, check, record):
                session.info[LAST_RECOMPUTATION] = "recomputed" if changed else "precomputed"
                return carried.result
            changed = True  # another edit of the system committed meanwhile: compute again from what it committed
            # kept objects used without reading first and found stale count no attempt: the next one reads (at most
            # one such attempt per edit, as the objects are no longer kept)
            attempts += 0 if carried.plan.trusted else 1
        result = _in_transaction(session, work, system_id=system_id)
        session.info[LAST_RECOMPUTATION] = "recomputed" if changed else "under_lock"
        return result


def guarded_frame_write(session: Session, frame_id: int, expected: Expected, state: Callable[[Frame], dict[str, Any]],
                 apply: Callable[[Frame], T], action: str, actor: Optional[str], revert: Optional[Revert],
                 undo_of: Optional[int] = None, *, system_id: Optional[int] = None) -> T:
    """:func:`guarded_write` of frame ``frame_id`` (its system ``system_id``, looked up when None: :func:`frame_facts`),
    claiming the frame's version. Raises :class:`NotFoundError` for an unknown frame, and what ``guarded_write``
    raises."""
    if system_id is None:
        system_id = frame_facts(session, frame_id).system_id
    # guarded_write locks the system before it claims the frame
    return guarded_write(session, system_id, Claim.frame(frame_id, expected), lambda: get_frame(session, frame_id),
                         state, apply, action, actor, revert, undo_of)


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


def frame_facts(session: Session, frame_id: int, *, snapshot: bool = False) -> FrameFacts:
    """The frame's :class:`FrameFacts`, read by one statement built once (no ORM object: the edit loads the frame
    with its system next, ``recompute.load_for_recompute``), sent with the ``BEGIN`` of its transaction in one round
    trip on PostgreSQL (``app.db.together``). ``snapshot``: read in the read snapshot the edit then
    computes in (``begin_snapshot``, begun here unless the session has written): on PostgreSQL the lookup would
    otherwise be a transaction of its own, rolled back before the snapshot (a rollback and a connection more). On
    PostgreSQL the facts of a frame of a system this process kept and trusts come from the kept objects
    (``kept.KeptSystems.trusted_frame``): its edit reads nothing before its lock, which compares the kept digest
    (covering the frame's row) with the stored one; an edit validates its input against the frame it writes again
    when that frame's size is not the one of its facts (``editing``). Raises :class:`NotFoundError`."""
    kept: Optional[KeptSystems] = session.info.get(KEPT_SYSTEMS)
    if snapshot and kept is not None and session.get_bind().dialect.name == "postgresql" and \
            (trusted := kept.trusted_frame(frame_id)) is not None:
        return FrameFacts(frame_id, *trusted)
    if snapshot:
        with contextlib.suppress(RuntimeError):  # the session has written: its caller's transaction goes on
            begin_snapshot(session)
    rows = send_together(session, [Call(_frame_facts_statement(), {"id": frame_id})])[0]  # with its BEGIN on PostgreSQL
    return FrameFacts(*found(rows[0] if rows else None, "frame", frame_id))


@functools.cache
def _frame_facts_statement() -> Any:
    F = Frame.__table__
    return select(F.c.id, F.c.system_id, F.c.width, F.c.height).where(F.c.id == bindparam("id"))


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
