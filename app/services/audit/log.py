"""The audit log: one append-only entry per accepted write, recorded in the write's own transaction.

An entry says who (``actor``: the user's name, or ``cli:<os user>`` for work run on the machine, see
:func:`local_actor`), when (UTC), what (``action``, :data:`ACTIONS`) and the state of the edited part
before and after the write, as self-describing JSON: ``{"ball": {"box", "point"}}``,
``{"lines": {class: polylines}}``, ``{"excluded": bool}``, ``{"review": {"status", "comment"}}`` or
``{"calibration_review": {"status", "comment"}}`` (a view's calibration decision) or ``{"assignee": name}``
(a system's assignee, ``app.services.curation.assignment``).
An import or a full recompute is one entry of its own (:func:`record_summary`: its counts in
``after``, no ``before``); they cannot be reverted (``app.services.audit.reverting``), nor can an
administrator's change of a user or a token (:data:`ADMIN_ACTIONS`, listed to admins only). Entries name their
frame, system and game by id without foreign keys, so history outlives the rows it talks about.
"""
from __future__ import annotations

import getpass
from collections.abc import Iterator
from dataclasses import dataclass
from typing import Any, Optional

import sqlalchemy as sa
from sqlalchemy.orm import Session

from app.db.models import AuditEntry, Frame, System
from app.db.types import json_safe, utcnow
from app.services.audit.summaries import summarize

#: The response header naming the audit entry of a write (what a later undo names).
AUDIT_ENTRY_HEADER = "X-V3D-Audit-Entry"
#: Actions that change many rows at once and are never reverted.
SUMMARY_ACTIONS = ("import", "recompute")
#: An administrator's changes of users and tokens (``app.services.accounts.users``): listed to admins only,
#: never reverted (``after`` names the user and the token id, never a secret).
ADMIN_ACTIONS = ("user.create", "user.role", "user.disable", "user.enable", "token.issue", "token.revoke")
#: Every action an entry may record.
ACTIONS = ("ball.edit", "field_lines.replace", "field_lines.mirror", "view.exclusion", "view.review",
           "view.calibration_review", "system.review", "system.assign", *SUMMARY_ACTIONS, "revert", *ADMIN_ACTIONS)


def revertible(action: str) -> bool:
    """Whether an entry of ``action`` can be reverted: an edit of one resource, not an import or a
    recompute (many rows) nor an administrator's change of a user or a token.

    >>> revertible("ball.edit"), revertible("import"), revertible("token.revoke")
    (True, False, False)
    """
    return action not in SUMMARY_ACTIONS and action not in ADMIN_ACTIONS


def local_actor() -> str:
    """``cli:<os user>``: the actor of writes made on the machine (CLI, scripts calling the services),
    whose owner needs no v3d account."""
    try:
        user = getpass.getuser()
    except (KeyError, OSError):  # no user name in a bare container
        user = "unknown"
    return f"cli:{user}"


def record(session: Session, *, actor: Optional[str], action: str, frame: Optional[Frame] = None,
           system: Optional[System] = None, before: Any = None, after: Any = None,
           reverts_id: Optional[int] = None, facts: Optional[dict[str, Any]] = None) -> AuditEntry:
    """Add one entry to the session (the caller's transaction commits it with the write) and return it.

    ``reverts_id``: the entry this write undoes: a revert (action ``revert``), or a page's undo of its own edit,
    audited as that edit's action (``app.services.curation.editing.replace_field_lines``' ``undo_of``).
    ``frame`` sets ``frame_id``, ``system_id`` and ``game_id``; ``system`` alone sets the last two.
    ``facts``: what only the running write knows, for the summary (``calibration=(before, after)`` in words,
    ``app.services.audit.summaries.summarize``). ``actor`` None is :func:`local_actor`. Raises ``ValueError`` for an
    action outside :data:`ACTIONS`.
    """
    if action not in ACTIONS:
        raise ValueError(f"unknown audit action {action!r}")
    system = frame.system if frame is not None else system
    before = json_safe(before) if before is not None else None
    after = json_safe(after) if after is not None else None
    entry = AuditEntry(
        at=utcnow(), actor=actor or local_actor(), action=action, frame_id=frame.id if frame is not None else None,
        system_id=system.id if system is not None else None, game_id=system.game_id if system is not None else None,
        before=before, after=after, reverts_id=reverts_id,
        summary=summarize(action, before, after, view=view_name(frame) if frame is not None else None,
                          reverts_id=reverts_id, facts=facts,
                          redo=action != "revert" and _is_undo(session, reverts_id))[:SUMMARY_MAX],
    )
    session.add(entry)
    return entry


#: The longest summary stored (characters; ``audit_entries.summary``).
SUMMARY_MAX = 300


def _is_undo(session: Session, entry_id: Optional[int]) -> bool:
    """Whether entry ``entry_id`` is an undo (an edit naming the entry it undoes) and not itself a redo: an undo
    of it is then a redo. Follows the chain of undos (undo, redo, undo, ...) back to the edit."""
    depth = 0
    while entry_id is not None and depth < 1000:
        row = session.execute(
            sa.select(AuditEntry.action, AuditEntry.reverts_id).where(AuditEntry.id == entry_id)).first()
        if row is None or row.action == "revert" or row.reverts_id is None:
            break
        depth += 1
        entry_id = row.reverts_id
    return depth % 2 == 1


def view_name(frame: Frame) -> str:
    """The view's name on the system page: "V<n>", n its place among its system's views (``Frame.position``
    order, as the page lists them), 1-based."""
    frames = frame.system.frames if frame.system is not None else []
    index = next((i for i, f in enumerate(frames) if f.id == frame.id), None)
    return f"V{index + 1}" if index is not None else f"frame {frame.id}"


def entry_summary(entry: AuditEntry, view: Optional[str] = None) -> str:
    """The entry's stored summary, or (an entry recorded before summaries were) the one computed from its
    states by the same function (``view``: its view's name on the page, when known)."""
    if entry.summary:
        return entry.summary
    return summarize(entry.action, entry.before, entry.after, view=view, reverts_id=entry.reverts_id)[:SUMMARY_MAX]


def view_names(session: Session, entries: list[AuditEntry]) -> dict[int, str]:
    """Frame id -> "V<n>" for the frames the ``entries`` name (one query over their systems' views)."""
    systems = {e.system_id for e in entries if e.frame_id is not None and e.system_id is not None}
    if not systems:
        return {}
    rows = session.execute(sa.select(Frame.id, Frame.system_id).where(Frame.system_id.in_(systems))
                           .order_by(Frame.system_id, Frame.position, Frame.id)).all()
    out: dict[int, str] = {}
    place: dict[int, int] = {}
    for frame_id, system_id in rows:
        place[system_id] = place.get(system_id, 0) + 1
        out[frame_id] = f"V{place[system_id]}"
    return out


def record_summary(session: Session, action: str, counts: dict[str, Any], *, actor: Optional[str] = None,
                   game_id: Optional[int] = None) -> AuditEntry:
    """One entry for a whole import or recompute (``action`` in :data:`SUMMARY_ACTIONS`), its ``counts``
    (e.g. source, games, systems, frames) in ``after``; added to the session of the batch that commits last."""
    if action not in SUMMARY_ACTIONS:
        raise ValueError(f"{action!r} is not a summary action")
    entry = AuditEntry(actor=actor or local_actor(), action=action, game_id=game_id, after=json_safe(counts))
    session.add(entry)
    return entry


@dataclass(frozen=True)
class AuditPage:
    """One page of entries, newest first, and how many match."""

    items: list[AuditEntry]
    total: int


def _conditions(frame_id: Optional[int], system_id: Optional[int], user: Optional[str],
                include_admin: bool = True) -> list[Any]:
    out: list[sa.ColumnElement[bool]] = [] if include_admin else [AuditEntry.action.not_in(ADMIN_ACTIONS)]
    if frame_id is not None:
        out.append(AuditEntry.frame_id == frame_id)
    if system_id is not None:
        out.append(AuditEntry.system_id == system_id)
    if user is not None:
        out.append(AuditEntry.actor == user)
    return out


@dataclass(frozen=True)
class EntryFilter:
    """Which entries a listing takes: every given filter holds. ``system_id`` matches the system's own decisions and
    every edit of its views; ``user`` is an actor's exact name; ``include_admin`` False leaves out
    :data:`ADMIN_ACTIONS` (for non-admins)."""

    frame_id: Optional[int] = None
    system_id: Optional[int] = None
    user: Optional[str] = None
    include_admin: bool = True

    def conditions(self) -> list[Any]:
        """The filters as SQL conditions on ``AuditEntry``."""
        return _conditions(self.frame_id, self.system_id, self.user, self.include_admin)


def list_entries(session: Session, *, frame_id: Optional[int] = None, system_id: Optional[int] = None,
                 user: Optional[str] = None, limit: int = 50, offset: int = 0,
                 include_admin: bool = True) -> AuditPage:
    """Entries matching every given filter (:class:`EntryFilter`), newest first (by id, the commit order of their
    writes), and how many match."""
    which = EntryFilter(frame_id, system_id, user, include_admin)
    items = [e for batch in entry_batches(session, which, limit=limit, offset=offset) for e in batch]
    return AuditPage(items=items, total=count_entries(session, which))


def count_entries(session: Session, which: EntryFilter) -> int:
    """How many entries ``which`` takes."""
    return int(session.scalar(sa.select(sa.func.count()).select_from(AuditEntry).where(*which.conditions())) or 0)


#: Entries read from the database at a time by :func:`entry_batches`.
ENTRY_BATCH = 8


def entry_batches(session: Session, which: EntryFilter, *, limit: int = 50,
                  offset: int = 0) -> Iterator[list[AuditEntry]]:
    """The entries ``which`` takes, newest first, from the ``offset``-th, at most ``limit``, read :data:`ENTRY_BATCH`
    at a time from the database (a server-side cursor on PostgreSQL): a caller that stops early (an answer full at
    its byte cap) never loads the rest, and the entries it is done with can be freed while it reads on."""
    stmt = (sa.select(AuditEntry).where(*which.conditions()).order_by(AuditEntry.id.desc()).limit(limit)
            .offset(offset).execution_options(yield_per=ENTRY_BATCH))
    result = session.scalars(stmt)
    try:
        for batch in result.partitions():
            yield list(batch)
    finally:
        result.close()


def latest_entry(session: Session, *, frame_id: Optional[int] = None,
                 system_id: Optional[int] = None) -> Optional[AuditEntry]:
    """The newest entry of a frame (``frame_id``) or of a system's own decisions (``system_id`` alone:
    entries without a frame); None when there is none."""
    where = _conditions(frame_id, system_id, None)
    if frame_id is None:
        where.append(AuditEntry.frame_id.is_(None))
    entry = session.scalars(sa.select(AuditEntry).where(*where).order_by(AuditEntry.id.desc()).limit(1)).first()
    return entry
