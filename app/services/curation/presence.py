"""Presence: who has a system open, as soft claims that expire.

A page that opens a system claims it (:func:`claim`) and keeps claiming it while it stays open (the page's
heartbeat, every :data:`HEARTBEAT` or so). Others see the live claims (:func:`open_on`): "ana has this system
open (since 2 min)" on the system page and in the queue, so that two people rarely edit one system at once
(a 412 conflict was how they used to learn of each other). A claim is a hint, never a lock: nothing refuses
an edit because someone else has the system open.

Writes, for several workers on one SQLite file: a heartbeat reads the claim and writes only when it is due,
i.e. when the claim is missing, lapsed or older than :data:`REFRESH_AFTER` (30 s of its :data:`TTL` of 50 s).
An open page therefore writes once when it opens, then once every 30 s (2 writes a minute), whatever its
heartbeat; the heartbeat's other calls are one indexed read each. A page that goes away without releasing
(a closed laptop, a killed browser) lapses after at most :data:`TTL`: short, so that "ana has this system open"
does not outlive ana's page by more than the time of a glance.

Expired claims need no cleanup job: every read filters on ``expires_at > now``, and every claim written
deletes the lapsed rows of every system in the same transaction (an index range on ``expires_at``), so the
table holds about one row per open page.

Time is passed in (``now``, timezone-aware UTC; :func:`app.db.types.utcnow` by default) so that tests control
the clock.
"""
from __future__ import annotations

import functools
from dataclasses import dataclass
from datetime import datetime, timedelta
from typing import Optional, cast

import sqlalchemy as sa
from sqlalchemy.engine import CursorResult
from sqlalchemy.exc import IntegrityError
from sqlalchemy.orm import Session

from app.core.errors import NotFoundError
from app.db.models import System, SystemPresence, User
from app.db.session import begin_write
from app.db.types import utcnow
from app.db.unit import write_unit

#: How long a claim lives without a refresh.
TTL = timedelta(seconds=50)
#: A claim older than this is refreshed by the next heartbeat (the only heartbeat that writes).
REFRESH_AFTER = timedelta(seconds=30)
#: How often a page should call :func:`claim` while it has the system open (the UI's heartbeat): three
#: heartbeats fit in the slack ``TTL - REFRESH_AFTER`` + one, so two lost ones lose no claim.
HEARTBEAT = timedelta(seconds=10)


@dataclass(frozen=True)
class Presence:
    """One live claim: ``name`` (the user) has ``system_id`` open since ``since`` (UTC) until ``expires_at``
    unless refreshed."""

    system_id: int
    user_id: int
    name: str
    since: datetime
    expires_at: datetime


@dataclass(frozen=True)
class Claimed:
    """What a heartbeat answers: the caller's own claim and the others' live claims on the system (oldest
    first); ``wrote`` says whether this call wrote the database (False for a heartbeat within
    :data:`REFRESH_AFTER` of the last write)."""

    mine: Presence
    others: list[Presence]
    wrote: bool


@functools.cache
def _open_on_statement(excluding: bool) -> sa.Select:
    """The read of :func:`open_on`, taking ``ids`` (expanding), ``now`` and, ``excluding``, ``user``: built once, of
    the tables' columns (the claims are read as values: the ORM's compilation and loading of the mapped class's
    statement was most of what this read cost every system page)."""
    claims, users = (cast(sa.Table, m.__table__) for m in (SystemPresence, User))
    p, u = claims.c, users.c
    stmt = (sa.select(p.system_id, p.user_id, p.since, p.expires_at, u.name).join_from(claims, users, u.id == p.user_id)
            .where(p.system_id.in_(sa.bindparam("ids", expanding=True)), p.expires_at > sa.bindparam("now"))
            .order_by(p.since, u.name))
    return stmt.where(p.user_id != sa.bindparam("user")) if excluding else stmt


def open_on(session: Session, system_ids: list[int], now: Optional[datetime] = None,
            exclude_user: Optional[int] = None) -> dict[int, list[Presence]]:
    """The live claims on each of ``system_ids`` (systems nobody has open are absent), oldest first.

    One indexed read (the claims' primary key starts with ``system_id``); ``exclude_user`` leaves that user's
    own claims out. Reads only: lapsed rows are skipped, never deleted here.
    """
    if not system_ids:
        return {}
    params = {"ids": list(system_ids), "now": now or utcnow()}
    if exclude_user is not None:
        params["user"] = exclude_user
    stmt = _open_on_statement(exclude_user is not None)
    out: dict[int, list[Presence]] = {}
    for system_id, user_id, since, expires_at, name in session.execute(stmt, params):
        out.setdefault(system_id, []).append(Presence(system_id, user_id, name, since, expires_at))
    return out


def _due(row: Optional[SystemPresence], now: datetime) -> bool:
    """Whether a heartbeat must write: no claim, a lapsed one, or one last written REFRESH_AFTER ago."""
    return row is None or row.expires_at <= now or row.expires_at - TTL + REFRESH_AFTER <= now


def claim(session: Session, system_id: int, user_id: int, now: Optional[datetime] = None) -> Claimed:
    """Claim (or keep claiming) that ``user_id`` has ``system_id`` open; commit when it wrote.

    Reads the caller's claim first; writes only when it is due (module docstring), in one short write
    transaction that also deletes every lapsed claim. A claim that was still live keeps its ``since``; a
    lapsed one starts again at ``now``.

    Returns:
        :class:`Claimed`: the caller's claim and the others' live ones.

    Raises:
        NotFoundError: no system ``system_id``, or no user ``user_id``.
    """
    now = now or utcnow()
    row = session.get(SystemPresence, (system_id, user_id))
    wrote = _due(row, now)
    if wrote:
        try:
            with write_unit(session):
                row = _write_claim(session, system_id, user_id, now)
        except IntegrityError:  # the same user's other tab wrote this claim a moment ago (PostgreSQL); rolled back
            wrote = False
            row = session.get(SystemPresence, (system_id, user_id))
    if row is None:  # only after a lost race with the user's own release
        raise NotFoundError("presence of user on system", f"{user_id}/{system_id}")
    name = session.scalar(sa.select(User.name).where(User.id == user_id)) or ""
    mine = Presence(system_id, user_id, name, row.since, row.expires_at)
    others = open_on(session, [system_id], now, exclude_user=user_id).get(system_id, [])
    return Claimed(mine, others, wrote)


def _write_claim(session: Session, system_id: int, user_id: int, now: datetime) -> SystemPresence:
    """The write of :func:`claim` (uncommitted): the caller's claim until ``now + TTL``, its ``since`` kept
    while it was live, and every lapsed claim deleted."""
    begin_write(session)
    if session.get(System, system_id) is None:
        raise NotFoundError("system", system_id)
    if session.get(User, user_id) is None:
        raise NotFoundError("user", user_id)
    row = session.get(SystemPresence, (system_id, user_id))  # again, under the write lock
    since = row.since if row is not None and row.expires_at > now else now
    if row is not None:
        session.expunge(row)
    session.execute(sa.delete(SystemPresence).where(
        sa.or_(SystemPresence.expires_at <= now,
               sa.and_(SystemPresence.system_id == system_id, SystemPresence.user_id == user_id))),
        execution_options={"synchronize_session": False})
    row = SystemPresence(system_id=system_id, user_id=user_id, since=since, expires_at=now + TTL)
    session.add(row)
    session.flush()
    return row


def release(session: Session, system_id: int, user_id: int) -> bool:
    """End ``user_id``'s claim on ``system_id`` (the page closed or moved on); commit. True when there was one."""
    with write_unit(session):
        done = cast(CursorResult, session.execute(sa.delete(SystemPresence).where(
            SystemPresence.system_id == system_id, SystemPresence.user_id == user_id)))
    return bool(done.rowcount)
