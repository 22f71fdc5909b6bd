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


class KeptSystems:
    """Per system id, the objects of its last committed edit in this process and the digest of its stored rows as that
    edit committed them (module docstring). Safe to share between threads: :meth:`take` hands a system to one
    edit only."""

    def __init__(self, max_systems: int = KEPT_SYSTEMS_MAX) -> None:
        if max_systems < 1:
            raise ValueError(f"KeptSystems: max_systems must be at least 1, got {max_systems}")
        self.max_systems = max_systems
        self._kept: "OrderedDict[int, _Kept]" = OrderedDict()
        self._lock = threading.Lock()
        self.taken = 0
        self.missed = 0

    def keep(self, system: System, rows_digest: str, objects: list[Any], reads: Any = None) -> None:
        """Keep ``system`` (its loaded relations) as committed, with ``rows_digest`` (``stored_rows_digest`` read under
        the lock after its writes) and ``objects``, every object its session holds (checked detached on take);
        ``reads``: what the next edit of the system reads beside the digest (its game's rig, :meth:`reads_of`)."""
        with self._lock:
            self._kept.pop(system.id, None)
            self._kept[system.id] = _Kept(rows_digest, system, tuple(objects), reads)
            while len(self._kept) > self.max_systems:
                self._kept.popitem(last=False)

    def take(self, system_id: int, rows_digest: str) -> Optional[System]:
        """The kept objects of system ``system_id`` when its stored rows' digest is still ``rows_digest`` and the
        session that committed them is closed, with nothing changed in memory since; None otherwise. The entry is
        removed either way: one edit at a time owns it."""
        with self._lock:
            kept = self._kept.pop(system_id, None)
        if kept is None or kept.rows_digest != rows_digest or not all(_untouched(o) for o in kept.objects):
            self.missed += 1
            return None
        self.taken += 1
        return kept.system

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
