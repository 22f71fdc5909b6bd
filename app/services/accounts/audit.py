"""The audit log: one append-only entry per accepted write, recorded in the write's own transaction.

An entry says who (``actor``: the user's name, or ``cli:<os user>`` for work run on the machine, see
:func:`local_actor`), when (UTC), what (``action``, :data:`ACTIONS`) and the state of the edited part
before and after the write, as self-describing JSON: ``{"ball": {"box", "point"}}``,
``{"lines": {class: polylines}}``, ``{"excluded": bool}`` or ``{"review": {"status", "comment"}}``.
An import or a full recompute is one entry of its own (:func:`record_summary`: its counts in
``after``, no ``before``); they cannot be reverted (``app.services.curation.reverting``). Entries name their
frame, system and game by id without foreign keys, so history outlives the rows it talks about.
"""
from __future__ import annotations

import getpass
from dataclasses import dataclass
from typing import Any, Optional

import sqlalchemy as sa
from sqlalchemy.orm import Session

from app.db.models import AuditEntry, Frame, System
from app.db.types import json_safe

#: Every action an entry may record.
ACTIONS = ("ball.edit", "field_lines.replace", "field_lines.mirror", "view.exclusion", "view.review",
           "system.review", "import", "recompute", "revert")
#: Actions that change many rows at once and are never reverted.
SUMMARY_ACTIONS = ("import", "recompute")


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
           reverts_id: Optional[int] = None) -> AuditEntry:
    """Add one entry to the session (the caller's transaction commits it with the write).

    ``frame`` sets ``frame_id``, ``system_id`` and ``game_id``; ``system`` alone sets the last two.
    ``actor`` None is :func:`local_actor`. Raises ``ValueError`` for an action outside :data:`ACTIONS`.
    """
    if action not in ACTIONS:
        raise ValueError(f"unknown audit action {action!r}")
    system = frame.system if frame is not None else system
    entry = AuditEntry(
        actor=actor or local_actor(), action=action, frame_id=frame.id if frame is not None else None,
        system_id=system.id if system is not None else None, game_id=system.game_id if system is not None else None,
        before=json_safe(before) if before is not None else None, after=json_safe(after) if after is not None else None,
        reverts_id=reverts_id,
    )
    session.add(entry)
    return entry


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


def _conditions(frame_id: Optional[int], system_id: Optional[int], user: Optional[str]) -> list[Any]:
    out = []
    if frame_id is not None:
        out.append(AuditEntry.frame_id == frame_id)
    if system_id is not None:
        out.append(AuditEntry.system_id == system_id)
    if user is not None:
        out.append(AuditEntry.actor == user)
    return out


def list_entries(session: Session, *, frame_id: Optional[int] = None, system_id: Optional[int] = None,
                 user: Optional[str] = None, limit: int = 50, offset: int = 0) -> AuditPage:
    """Entries matching every given filter, newest first (by id, the commit order of their writes).

    ``system_id`` matches the system's own decisions and every edit of its views; ``user`` is an
    actor's exact name.
    """
    where = _conditions(frame_id, system_id, user)
    total = session.scalar(sa.select(sa.func.count()).select_from(AuditEntry).where(*where))
    rows = session.scalars(sa.select(AuditEntry).where(*where).order_by(AuditEntry.id.desc())
                           .limit(limit).offset(offset))
    return AuditPage(items=list(rows), total=int(total or 0))


def latest_entry(session: Session, *, frame_id: Optional[int] = None,
                 system_id: Optional[int] = None) -> Optional[AuditEntry]:
    """The newest entry of a frame (``frame_id``) or of a system's own decisions (``system_id`` alone:
    entries without a frame); None when there is none."""
    where = _conditions(frame_id, system_id, None)
    if frame_id is None:
        where.append(AuditEntry.frame_id.is_(None))
    entry = session.scalars(sa.select(AuditEntry).where(*where).order_by(AuditEntry.id.desc()).limit(1)).first()
    return entry
