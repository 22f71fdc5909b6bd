"""Work assignment: which person should review which systems.

A system has at most one assignee (``System.assignee_id``, with ``assigned_at`` and ``assigned_by``). Reviewers
and administrators assign (the API's role check); anyone may read assignments. One call assigns one or more
systems by id, every system of a game, or every system a queue filter matches (``SystemFilters``, the filters
of ``GET /api/systems``, across all its pages), to a user, or clears their assignee (``assignee`` None).

Every system whose assignee changes gets its own audit entry (action ``system.assign``, ``before`` /
``after`` ``{"assignee": name or None}``), in the write's transaction, so a system's history says who gave it
to whom; systems already assigned to that person are left as they are and not audited. An entry is reverted
like any other (``app.services.curation.reverting``): the system goes back to its previous assignee.

Assignment is a hint for people, not a permission: anyone with the role may still edit any system.
"""
from __future__ import annotations

import functools
from dataclasses import dataclass, field
from datetime import datetime
from typing import Optional

import sqlalchemy as sa
from sqlalchemy.orm import Session

from app.core.errors import ConflictError, InvalidInputError, NotFoundError
from app.db.models import Game, System, User
from app.db.types import utcnow
from app.db.unit import write_unit
from app.services.accounts.users import is_reserved_name
from app.services.audit import log as audit
from app.services.curation.queue import SystemFilters, matching_system_ids

#: The audit action of an assignment.
ACTION = "system.assign"
#: Ids per ``IN (...)`` list (SQLite's bound parameters are limited).
_CHUNK = 500


@dataclass(frozen=True)
class Assigned:
    """The outcome of :func:`assign`: ``matched`` systems were selected, ``changed`` of them (ids in
    ``system_ids``, ascending) got the new assignee (``assignee``, a name or None) and an audit entry each
    (``entry_ids``, in the same order)."""

    assignee: Optional[str]
    matched: int
    changed: int
    system_ids: list[int] = field(default_factory=list)
    entry_ids: list[int] = field(default_factory=list)


@dataclass(frozen=True)
class Assignment:
    """A system's assignment as shown: the assignee's name (None: unassigned), when and by whom."""

    system_id: int
    assignee: Optional[str]
    assigned_at: Optional[datetime]
    assigned_by: Optional[str]


def assignable_user(session: Session, name: str, field_name: str = "assignee") -> User:
    """The enabled user called ``name``, who may be given systems.

    Raises:
        InvalidInputError (``field_name``): no user of that name, a disabled one, or a name the assignee filter
            reads as a word (``me``, ``none``, but for case or trailing dots: a user so called, made before such
            names were refused, is given no system, so that ``assignee=none`` always means the unassigned ones).
    """
    if is_reserved_name(name):
        raise InvalidInputError(f"{name!r} is the assignee filter's word, no user's name", field=field_name)
    user = session.scalar(sa.select(User).where(User.name == name))
    if user is None:
        raise InvalidInputError(f"no user is called {name!r}", field=field_name)
    if user.disabled:
        raise InvalidInputError(f"user {name!r} is disabled and cannot be assigned systems", field=field_name)
    return user


def known_user(session: Session, name: str, field_name: str = "assignee") -> int:
    """The id of the user called ``name`` (enabled or not: a filter may name a former assignee).

    Raises:
        InvalidInputError (``field_name``): no user of that name.
    """
    user_id = session.scalar(sa.select(User.id).where(User.name == name))
    if user_id is None:
        raise InvalidInputError(f"no user is called {name!r}", field=field_name)
    return int(user_id)


def assignable_users(session: Session) -> list[User]:
    """Every enabled user, by name: the people systems may be assigned to."""
    return list(session.scalars(sa.select(User).where(User.disabled.is_(False)).order_by(User.name)))


def _chunks(ids: list[int]) -> list[list[int]]:
    return [ids[i:i + _CHUNK] for i in range(0, len(ids), _CHUNK)]


def _selected_ids(session: Session, system_ids: Optional[list[int]], game_id: Optional[int],
                  filters: Optional[SystemFilters]) -> list[int]:
    """The ids of the selected systems, ascending (one selector given, checked by :func:`assign`)."""
    if system_ids is not None:
        wanted = sorted(set(system_ids))
        found: set[int] = set()
        for chunk in _chunks(wanted):
            found.update(session.scalars(sa.select(System.id).where(System.id.in_(chunk))))
        missing = [i for i in wanted if i not in found]
        if missing:
            raise NotFoundError("system", missing[0])
        return wanted
    if game_id is not None:
        if session.get(Game, game_id) is None:
            raise NotFoundError("game", game_id)
        return list(session.scalars(sa.select(System.id).where(System.game_id == game_id).order_by(System.id)))
    return list(session.scalars(matching_system_ids(filters or SystemFilters())))


def assign(session: Session, *, assignee: Optional[str], system_ids: Optional[list[int]] = None,
           game_id: Optional[int] = None, filters: Optional[SystemFilters] = None, actor: Optional[str] = None,
           now: Optional[datetime] = None, expect: Optional[dict[int, Optional[int]]] = None,
           reverts_id: Optional[int] = None) -> Assigned:
    """Assign the selected systems to the user ``assignee`` (None: unassign them) and commit, one audit entry
    per system whose assignee changed.

    Args:
        assignee: an enabled user's name, or None to clear the assignee.
        system_ids, game_id, filters: exactly one: these systems, every system of this game, or every system
            these queue filters match (all pages).
        actor: the audit entries' actor (None: ``audit.local_actor()``; ``assigned_by`` then reads ``cli``).
        now: the time recorded as ``assigned_at`` (UTC; default now).
        expect, reverts_id: a revert's guard (``app.services.curation.reverting``): the assignee ids the
            systems must still have (else :class:`ConflictError`, nothing changed), and the entry reverted
            (the entries are then recorded as ``revert``).

    Returns:
        :class:`Assigned`.

    Raises:
        InvalidInputError: not exactly one selector (field ``system_ids``), an unknown or disabled assignee
            (field ``assignee``).
        NotFoundError: a system id or the game does not exist; nothing changed.
        ConflictError: ``expect`` does not hold; nothing changed.
    """
    given = [s for s in (system_ids, game_id, filters) if s is not None]
    if len(given) != 1:
        raise InvalidInputError("give exactly one of system_ids, game_id and filter", field="system_ids")
    now = now or utcnow()
    with write_unit(session):
        user = assignable_user(session, assignee) if assignee is not None else None
        new_id = user.id if user is not None else None
        ids = _selected_ids(session, system_ids, game_id, filters)
        systems: dict[int, System] = {}
        for chunk in _chunks(ids):  # locked in id order: two bulk assignments never wait for each other in a cycle
            systems.update((s.id, s) for s in session.scalars(
                sa.select(System).where(System.id.in_(chunk)).order_by(System.id).with_for_update()))
        ids = [i for i in ids if i in systems]  # (PostgreSQL: a system deleted between the selection and the lock)
        if expect is not None and any(i not in systems or systems[i].assignee_id != v for i, v in expect.items()):
            raise ConflictError("the system was assigned to someone else since this entry")
        changed = [i for i in ids if systems[i].assignee_id != new_id]
        names = _names(session, {v for i in changed if (v := systems[i].assignee_id) is not None})
        entries = []
        for i in changed:
            system = systems[i]
            old = system.assignee_id
            system.assignee_id, system.assigned_at, system.assigned_by = new_id, now, audit.public_actor(actor)
            entries.append(audit.record(session, actor=actor, action="revert" if reverts_id is not None else ACTION,
                                        system=system,
                                        before={"assignee": names.get(old) if old is not None else None},
                                        after={"assignee": assignee}, reverts_id=reverts_id))
    return Assigned(assignee=assignee, matched=len(ids), changed=len(changed), system_ids=changed,
                    entry_ids=[e.id for e in entries])


def _names(session: Session, user_ids: set[int]) -> dict[int, str]:
    if not user_ids:
        return {}
    return {int(i): n for i, n in session.execute(sa.select(User.id, User.name).where(User.id.in_(user_ids)))}


def assignment_of(session: Session, system: System) -> Assignment:
    """The assignment of a system the session holds loaded (its ``assignee_id``, ``assigned_at`` and ``assigned_by``
    as loaded): the assignee's name read only when it has one (a user by id, the session's own when it holds it).
    The system page and every edit's answer: most systems are unassigned, and their row is in memory already."""
    name = None
    if system.assignee_id is not None:
        user = session.get(User, system.assignee_id)
        name = user.name if user is not None else None
    return Assignment(system.id, name, system.assigned_at, system.assigned_by)


@functools.cache
def _assignments_statement() -> sa.Select:
    """The read of :func:`assignments_of`, taking ``ids`` (expanding): built once."""
    return (sa.select(System.id, User.name, System.assigned_at, System.assigned_by)
            .outerjoin(User, User.id == System.assignee_id).where(System.id.in_(sa.bindparam("ids", expanding=True))))


def assignments_of(session: Session, system_ids: list[int]) -> dict[int, Assignment]:
    """The assignment of each of ``system_ids`` (every id present; unassigned ones with ``assignee`` None).
    One read (the assignee's name joined), for a page of the queue or one system."""
    out: dict[int, Assignment] = {}
    for chunk in _chunks(sorted(set(system_ids))):
        rows = session.execute(_assignments_statement(), {"ids": chunk})
        for sid, name, at, by in rows:
            out[sid] = Assignment(sid, name, at, by)
    return out


def revert_assignment(session: Session, *, system_id: int, before: dict, after: dict, entry_id: int,
                      actor: Optional[str], force: bool) -> Assigned:
    """Give system ``system_id`` back the assignee of an entry's ``before`` (a name or None), audited as a
    ``revert`` of ``entry_id``; unless ``force``, only while its assignee is still the entry's ``after``.

    Raises:
        ConflictError: reassigned since the entry (and not ``force``); nothing changed.
        InvalidInputError: the previous assignee no longer exists or is disabled (field ``assignee``).
    """
    expect = None
    if not force:
        name = after.get("assignee")
        user_id = session.scalar(sa.select(User.id).where(User.name == name)) if name is not None else None
        expect = {system_id: user_id}
    return assign(session, assignee=before.get("assignee"), system_ids=[system_id], actor=actor, expect=expect,
                  reverts_id=entry_id)
