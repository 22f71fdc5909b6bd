"""The write unit every writer of v3d goes through: one transaction that begins, commits, or rolls back.

``with write_unit(session) as unit:`` begins the write transaction (``app.db.session.begin_write``: SQLite's ``BEGIN
IMMEDIATE``, its turn at the write lock) unless ``lock=False``; the block reads and changes rows; leaving it commits,
and any exception (``BaseException``: an interrupted request too) rolls everything back and propagates. A writer that
computes before it locks (an edit: read, compute holding no connection, lock, compare, write) opens the unit with
``lock=False`` and calls :meth:`WriteUnit.lock` once it has computed.

While the unit is open it keeps two rules of the schema at every flush (a listener on this one session, removed when
the unit ends):

* **one review status**: ``System.review_status``, the review queue's copy of the system's decision, is written here
  and only here, from each system decision (``ReviewDecision`` with a system) the transaction adds or changes, and
  for each system it writes whose decision is loaded (a recomputation: a database migrated before the copy existed
  gets it with its systems' recomputation);
* **the version invariant** (checked when :data:`CHECK_VERSIONS` is on: the tests turn it on, production leaves it off
  and pays nothing for it): a transaction that changes what a game's version covers (``app.db.scope.GAME_COLUMNS``:
  its rig's calibrations, its camera prior) bumps ``Game.version``, and one that adds, changes or deletes a row a
  system's version covers
  (``app.db.scope.system_tables``) bumps that system's version (``System.version``), except a view's decision (its
  review row and its frame's row) which bumps its frame's version (``Frame.edit_version``) instead; and the columns
  no version covers (``app.db.scope.UNVERSIONED_COLUMNS``: a system's assignment, a view's split...) need no bump. It
  sees the ORM's changes (the session's new, dirty and deleted objects), not bulk statements sent with
  ``Session.execute``, whose writers bump the versions themselves (``app.services.transfer.predictions``). A commit
  that breaks it raises :class:`VersionNotBumped` and rolls back, so a writer added later cannot forget the bump the
  edits' optimistic concurrency relies on.
"""
from __future__ import annotations

import contextlib
from collections.abc import Iterator
from typing import Any, Callable, Optional, TypeVar

from sqlalchemy import event, inspect
from sqlalchemy.exc import OperationalError
from sqlalchemy.orm import Session

from app.db.models import Calibration, Frame, Game, ReviewDecision, ReviewStatus, System
from app.db.scope import GAME_COLUMNS, RIG_KINDS, UNVERSIONED_COLUMNS, system_tables
from app.db.session import begin_write, is_lock_timeout

T = TypeVar("T")

#: Check the version invariant at every flush of a write unit (module docstring). Off in production; the tests'
#: configuration (``tests/conftest.py``) turns it on for the whole suite.
CHECK_VERSIONS = False
#: Tables of a view's decision: its frame's version covers them (``Frame.edit_version``).
_VIEW_DECISION_TABLES = frozenset({Frame.__tablename__, ReviewDecision.__tablename__})


class VersionNotBumped(RuntimeError):
    """A write unit changed rows a system's version covers without bumping that version (module docstring)."""


class WriteUnit:
    """One open write transaction of ``session`` (:func:`write_unit`)."""

    def __init__(self, session: Session) -> None:
        self.session = session
        self._versions = _VersionCheck() if CHECK_VERSIONS else None

    def lock(self) -> None:
        """Begin the write transaction now (``begin_write``: the write lock on SQLite), for a unit opened with
        ``lock=False`` that read and computed first. Raises ``RuntimeError`` when the session read in its current
        transaction while holding changes (``begin_write``)."""
        begin_write(self.session)

    def before_flush(self, session: Session, _context: Any, _instances: Any) -> None:
        """Write the queue's copy of each changed system decision; note what the flush changes for the version
        check."""
        for obj in (*session.new, *session.dirty):
            if isinstance(obj, ReviewDecision) and obj.system is not None:
                _copy_status(obj.system, obj)
            elif isinstance(obj, System) and "review" in obj.__dict__:  # its decision loaded: no query
                _copy_status(obj, obj.review)
        if self._versions is not None:
            self._versions.note(session)

    def check(self) -> None:
        """Raise :class:`VersionNotBumped` when the unit changed a system's rows without bumping its version (only
        when :data:`CHECK_VERSIONS` is on)."""
        if self._versions is not None:
            self._versions.note(self.session)
            self._versions.check()


@contextlib.contextmanager
def write_unit(session: Session, *, lock: bool = True) -> Iterator[WriteUnit]:
    """One write transaction of ``session`` (module docstring): begun with the write lock when ``lock`` (else
    :meth:`WriteUnit.lock` takes it later; a unit that never takes it commits what autobegun transaction it has),
    committed when the block ends, rolled back when it raises (the exception propagates).

    Raises:
        VersionNotBumped: :data:`CHECK_VERSIONS` on and the block changed a system's rows without bumping its version.
        What ``begin_write`` or the block raises.
    """
    unit = WriteUnit(session)
    event.listen(session, "before_flush", unit.before_flush)
    try:
        if lock:
            unit.lock()
        yield unit
        session.flush()
        unit.check()
        session.commit()
    except BaseException:
        session.rollback()
        raise
    finally:
        event.remove(session, "before_flush", unit.before_flush)


def computed_then_written(session: Session, work: Callable[[], T], undo: Callable[[], None]) -> T:
    """``work()`` in a write unit that reads and computes before it writes (``lock=False``: other writers go on
    meanwhile); when its writing fails because the write lock is another's (SQLite: another connection committed
    after this transaction's first read, and WAL cannot upgrade a stale snapshot, or held the lock past the busy
    timeout; :func:`app.db.session.is_lock_timeout`), everything is rolled back, ``undo()`` puts back what ``work``
    changed outside the database, and ``work()`` runs once more in a unit holding the write lock from its start,
    where no other writer can land: the other writers wait for it (or answer 503 past their timeout), and it never
    fails for them. What else ``work`` raises propagates, rolled back.

    Raises:
        What the second ``work()`` or its write unit raises.
    """
    try:
        with write_unit(session, lock=False):
            return work()
    except OperationalError as exc:
        if not is_lock_timeout(exc):
            raise
    undo()
    with write_unit(session):
        return work()


class _VersionCheck:
    """What a write unit changed in systems' scopes and which versions it bumped, accumulated over its flushes."""

    def __init__(self) -> None:
        self.covered = system_tables()
        self.changed: dict[int, str] = {}  # system id -> a table it changed, needing its version bumped
        self.views: dict[int, tuple[int, str]] = {}  # frame id -> (system id, table): a view's decision
        self.bumped: set[int] = set()
        self.frames_bumped: set[int] = set()
        self.games_changed: dict[int, str] = {}  # game id -> what it changed of what its version covers
        self.games_bumped: set[int] = set()
        self.new_games: set[int] = set()  # ``id()`` of the games this unit inserts

    def note(self, session: Session) -> None:
        for obj in (*session.new, *session.dirty, *session.deleted):
            table = inspect(obj).mapper.local_table.name
            if table in GAME_COLUMNS:
                self._note_game(session, obj, table)
            if table not in self.covered:
                continue
            state = inspect(obj)
            modified = ({a.key for a in state.mapper.column_attrs if state.attrs[a.key].history.has_changes()}
                        if state.persistent else None)  # columns only: a relationship's change writes its other side
            if isinstance(obj, System) and (state.pending or "version" in (modified or ())):
                self.bumped.add(id(obj) if obj.id is None else obj.id)
                continue
            if isinstance(obj, Frame) and (state.pending or "edit_version" in (modified or ())):
                if obj.id is not None:
                    self.frames_bumped.add(obj.id)
            if modified is not None and obj in session.dirty and modified <= UNVERSIONED_COLUMNS.get(table, set()):
                continue  # nothing written, or only columns no version covers
            if isinstance(obj, System):
                if obj not in session.deleted:  # a removed system's rows go with it: no version to keep
                    self.changed[obj.id] = f"{table} ({', '.join(sorted(modified or ()))})"
                continue
            system, frame = _owners(obj)
            if system is None or system.id is None or inspect(system).pending or system in session.deleted:
                continue  # a new system (its rows are inserted with it) or a removed one
            if table in _VIEW_DECISION_TABLES and frame is not None and frame.id is not None \
                    and (table != Frame.__tablename__ or (modified or set()) <= {"edit_version"}):
                self.views[frame.id] = (system.id, table)
            else:
                self.changed[system.id] = f"{table} ({', '.join(sorted(modified))})" if modified else table

    def _note_game(self, session: Session, obj: Any, table: str) -> None:
        """A change of what ``Game.version`` covers (``app.db.scope.GAME_COLUMNS``), or the bump of a game's version."""
        state = inspect(obj)
        modified = ({a.key for a in state.mapper.column_attrs if state.attrs[a.key].history.has_changes()}
                    if state.persistent else None)
        if isinstance(obj, Game):
            if state.pending:
                self.new_games.add(id(obj))  # inserted by this unit: nothing an earlier edit read of it
            elif "version" in (modified or ()):
                self.games_bumped.add(obj.id)
            elif obj not in session.deleted and modified and modified & GAME_COLUMNS[table]:
                self.games_changed[obj.id] = f"{table} ({', '.join(sorted(modified & GAME_COLUMNS[table]))})"
            return
        if modified is not None and not modified & GAME_COLUMNS[table]:
            return  # nothing written, or only columns no edit of another system reads
        assert isinstance(obj, Calibration)
        frame = obj.frame
        system = frame.system if frame is not None else None
        game = system.game if system is not None else None
        owners: tuple[Any, ...] = (frame, system, game)
        if game is None or game.id is None or id(game) in self.new_games or system.kind not in RIG_KINDS \
                or any(inspect(o).pending or o in session.deleted for o in owners):
            return  # a new view, system or game (its rows are inserted with it) or a removed one
        self.games_changed[game.id] = f"{table} ({', '.join(sorted(modified or ()))})" if modified else table

    def check(self) -> None:
        games = {gid: table for gid, table in self.games_changed.items() if gid not in self.games_bumped}
        if games:
            raise VersionNotBumped("a write changed what a game's version covers (its rig's calibrations, its camera "
                                   "prior) without bumping it (Game.version, app.db.scope.game_changed): "
                                   + "; ".join(f"game {gid}: {table}" for gid, table in sorted(games.items())))
        missing = {sid: table for sid, table in self.changed.items() if sid not in self.bumped}
        missing.update({sid: table for fid, (sid, table) in self.views.items()
                        if fid not in self.frames_bumped and sid not in self.bumped})
        if missing:
            raise VersionNotBumped("a write changed rows of systems without bumping their versions (System.version, "
                                   "or Frame.edit_version for a view's decision): "
                                   + "; ".join(f"system {sid}: {table}" for sid, table in sorted(missing.items())))


def _copy_status(system: System, decision: Optional[ReviewDecision]) -> None:
    """The queue's copy of ``system``'s decision (pending without one, or before its status is set)."""
    status = decision.status if decision is not None and decision.status is not None else ReviewStatus.PENDING
    if system.review_status is not status:
        system.review_status = status


def _owners(obj: Any) -> tuple[Optional[System], Optional[Frame]]:
    """The system and the view (None when it is no view's row) a row of a system's scope belongs to, through its
    ``system``, ``frame`` or ``triangulation`` relationship."""
    if isinstance(obj, Frame):
        return obj.system, obj
    relationships = inspect(obj).mapper.relationships
    if "frame" in relationships and obj.frame is not None:
        return obj.frame.system, obj.frame
    if "system" in relationships and obj.system is not None:
        return obj.system, None
    if "triangulation" in relationships and obj.triangulation is not None:
        return obj.triangulation.system, None
    return None, None
