"""The systems this process's edits last committed, kept in memory for the next edit of the same system (issue 29:
an edit loads what it recomputes once; the next edit of that system need not load it at all).

An annotator edits one system many times in a row (a box nudged, a line point dragged and released). An edit that
computed before its lock (``app.services.curation.writing``) ends with its system's objects in memory equal to the
rows it committed: it reads the digest of those rows under its lock, after its writes
(``app.services.derivation.recompute.stored_rows_digest``), and :meth:`KeptSystems.keep` keeps the objects with it.
The next edit of that system in this process reads the digest of the stored rows in its own read snapshot (as it
must anyway, to compare under its lock) and :meth:`KeptSystems.take` hands the objects over only when the digests
are equal (nothing another edit, a decision, an assignment or an import wrote since) and the session that used them
is closed (every object detached): the edit attaches them to its session instead of loading them. Anything else
(another digest, objects still in use, a session holding objects of its caller) is a miss, and the edit loads as
before: the kept objects only ever spare a load of rows that are exactly those objects.

On PostgreSQL every read before the lock is a round trip (several, with the read snapshot's ``BEGIN`` and
``COMMIT``), and after a pause each costs up to a millisecond on a 2-core machine. There the next edit uses
**trusted** kept objects without reading anything first (:meth:`KeptSystems.take_trusted`): it computes from them
and compares, under its lock, the digest it reads there anyway with the kept one (and the rig rows as the last edit
wrote them). When they differ (another process wrote the system meanwhile) the attempt is rolled back and computed
again from the stored rows, and the system's next kept objects are checked before use (:meth:`KeptSystems.doubt`)
until a check finds them current: a system that two processes edit in turn pays a digest read per edit, as before,
not a wasted computation.

The app makes one per process (:class:`KeptSystems` of :data:`KEPT_SYSTEMS_MAX` systems) and hands it to every
session of its factory (``session.info[KEPT_SYSTEMS]``); a session without one (a command line, a test of the
services) keeps nothing.
"""
from __future__ import annotations

import threading
from collections import OrderedDict
from dataclasses import dataclass
from typing import Any, Optional

import sqlalchemy as sa

from app.db.models import System

#: ``session.info`` key of the :class:`KeptSystems` of the session's process (set by the app's session factory).
KEPT_SYSTEMS = "v3d.edit.kept"
#: Systems kept per process at most (the least recently kept dropped): each is a few dozen objects, about 100 kB.
KEPT_SYSTEMS_MAX = 64


@dataclass(frozen=True)
class _Kept:
    rows_digest: str
    system: System
    objects: tuple[Any, ...]  # every object the committing session held: all detached once it closed
    reads: Any = None  # what the next edit reads with the digest (``KeptSystems.keep``)
    trusted: bool = True  # the next edit may use the objects before reading anything (``KeptSystems.take_trusted``)


class KeptSystems:
    """Per system id, the objects of its last committed edit in this process and the digest of its stored rows as that
    edit committed them (module docstring). Safe to share between threads: :meth:`take` hands a system to one
    edit only."""

    def __init__(self, max_systems: int = KEPT_SYSTEMS_MAX) -> None:
        if max_systems < 1:
            raise ValueError(f"KeptSystems: max_systems must be at least 1, got {max_systems}")
        self.max_systems = max_systems
        self._kept: "OrderedDict[int, _Kept]" = OrderedDict()
        self._frames: dict[int, tuple[int, int, int]] = {}  # frame id -> (its kept system's id, width, height)
        self._doubted: set[int] = set()  # systems whose kept objects were last found stale
        self._lock = threading.Lock()
        self.taken = 0
        self.missed = 0

    def keep(self, system: System, rows_digest: str, objects: list[Any], reads: Any = None) -> None:
        """Keep ``system`` (its loaded relations) as committed, with ``rows_digest`` (``stored_rows_digest`` read under
        the lock after its writes) and ``objects``, every object its session holds (checked detached on take);
        ``reads``: what the next edit of the system reads beside the digest (its game's rig, :meth:`reads_of`).
        The objects are trusted (:meth:`take_trusted`) unless the last kept objects of the system were found stale
        (:meth:`doubt`, or a :meth:`take` whose digest differed): another process writes the system too."""
        with self._lock:
            self._drop(system.id)
            trusted = system.id not in self._doubted
            self._doubted.discard(system.id)
            self._kept[system.id] = _Kept(rows_digest, system, tuple(objects), reads, trusted)
            self._frames.update((f.id, (system.id, f.width, f.height)) for f in system.__dict__.get("frames", ()))
            while len(self._kept) > self.max_systems:
                self._drop(next(iter(self._kept)))

    def _drop(self, system_id: int) -> Optional[_Kept]:
        """Remove the entry of ``system_id`` and its frames (under the lock)."""
        kept = self._kept.pop(system_id, None)
        if kept is not None:
            for f in kept.system.__dict__.get("frames", ()):
                if self._frames.get(f.id, (None,))[0] == system_id:
                    del self._frames[f.id]
        return kept

    def take(self, system_id: int, rows_digest: str) -> Optional[System]:
        """The kept objects of system ``system_id`` when its stored rows' digest is still ``rows_digest`` and the
        session that committed them is closed, with nothing changed in memory since; None otherwise. The entry is
        removed either way: one edit at a time owns it."""
        with self._lock:
            kept = self._drop(system_id)
            if kept is not None and kept.rows_digest != rows_digest:
                self._doubt(system_id)
        if kept is None or kept.rows_digest != rows_digest or not all(_untouched(o) for o in kept.objects):
            self.missed += 1
            return None
        self.taken += 1
        return kept.system

    def take_trusted(self, system_id: int) -> Optional[tuple[System, str, Any]]:
        """``(system, rows digest, reads)`` of system ``system_id`` when its objects are trusted (:meth:`keep`) and
        untouched, without reading the database first: the edit computes from them and compares the digest it reads
        under its lock with the kept one (PostgreSQL, where every read before is a round trip); when they differ it
        calls :meth:`doubt` and computes again from the stored rows. None, leaving the entry for :meth:`take`,
        otherwise."""
        with self._lock:
            kept = self._kept.get(system_id)
            if kept is None or not kept.trusted or not all(_untouched(o) for o in kept.objects):
                return None
            self._drop(system_id)
        self.taken += 1
        return kept.system, kept.rows_digest, kept.reads

    def doubt(self, system_id: int) -> None:
        """The objects of system ``system_id`` taken by :meth:`take_trusted` were stale (another process wrote the
        system since): the next ones kept are checked against the stored rows before they are used."""
        with self._lock:
            self._doubt(system_id)

    def _doubt(self, system_id: int) -> None:
        if len(self._doubted) >= 16 * self.max_systems:  # bounded: systems doubted and never kept again
            self._doubted.clear()
        self._doubted.add(system_id)

    def trusted_frame(self, frame_id: int) -> Optional[tuple[int, int, int]]:
        """``(system id, width, height)`` (pixels) of frame ``frame_id`` when it belongs to a kept system whose objects
        are trusted (:meth:`take_trusted`), else None: its edit reads nothing before its lock, its lookup included.
        The edit's lock compares the kept digest, which covers the frame's row, with the stored one: equal, these
        facts were the stored ones; different, the edit computes again from the stored rows."""
        with self._lock:
            facts = self._frames.get(frame_id)
            kept = self._kept.get(facts[0]) if facts is not None else None
            return facts if kept is not None and kept.trusted else None

    def reads_of(self, system_id: int) -> Any:
        """The ``reads`` kept with system ``system_id`` (None when none is kept), without taking it: the next edit
        reads them with the digest it compares (:meth:`take`), in the same round trip."""
        with self._lock:
            kept = self._kept.get(system_id)
        return kept.reads if kept is not None else None

    def holds(self, system_id: int) -> bool:
        """Whether objects of system ``system_id`` are kept (to be checked by :meth:`take`)."""
        return system_id in self._kept

    def __len__(self) -> int:
        return len(self._kept)


def _untouched(obj: Any) -> bool:
    """True for an object its session let go as it committed it: detached, nothing changed in memory since."""
    state = sa.inspect(obj)
    return state.detached and not state.modified
