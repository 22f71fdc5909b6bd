"""Revert an audited write: restore its ``before`` state through the service function of the original
edit (so the system is recomputed as after any edit), itself audited as action ``revert``.

The edited part is read from the entry's self-describing state (``app.services.audit.log``): ``ball`` ->
:func:`~app.services.curation.editing.update_ball_label`, ``lines`` ->
:func:`~app.services.curation.editing.replace_field_lines` (also for a mirroring: the lines before it are restored as
they were), ``excluded`` -> :func:`~app.services.curation.editing.set_view_excluded`, ``system`` (an import's
merge of a stored system) -> :func:`~app.services.curation.editing.restore_imported_system`, ``calibration_review`` ->
:func:`~app.services.curation.decisions.decide_calibration`, ``review`` ->
:func:`~app.services.curation.decisions.decide_review` (its ``decided_at`` becomes now). A revert is refused (409) when
the resource changed since the entry (its current state, read under the write's lock, is not the entry's ``after``)
unless ``force``. Restoring field lines recalibrates the frame: an imported camera (source "imported") becomes a
computed one.

:func:`undo_entry` is the page's undo (and redo) of any edit, annotators' own included: the same restore, audited
as the edit's own action with ``reverts_id``, never forced. The undo or revert of a label's edit that brings the
system's labels back to those its decisions were made on also gives back the decisions that edit set back to pending,
in its own write and entry (``app.services.curation.resets.restore_decisions``).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Optional

import sqlalchemy as sa
from sqlalchemy.orm import Session

from app.core.config import Settings
from app.core.errors import ForbiddenError, InvalidInputError, found
from app.db.models import AuditEntry
from app.services.audit.log import TEAM_ACTIONS, revertible, shown_actor
from app.services.curation import assignment, decisions, editing, resets, writing


@dataclass(frozen=True)
class Reverted:
    """What a revert changed: the system to show again, and the resource (``kind`` "frame" or "system",
    ``ident``) whose ETag changed."""

    system_id: int
    kind: str
    ident: int


def revert_entry(session: Session, entry_id: int, *, settings: Settings, actor: Optional[str] = None,
                 force: bool = False, edit: Optional[writing.EditContext] = None) -> Reverted:
    """Restore audit entry ``entry_id``'s ``before`` state and commit, with its own audit entry (its id in
    ``edit.entry_id``).

    Raises:
        NotFoundError: no such entry, or its frame or system no longer exists.
        InvalidInputError: an entry that cannot be reverted: an import or a recompute, or a change of a user
            or a token (field "id").
        ConflictError: the resource changed since the entry (not forced); nothing changed.
    """
    entry = _revertible_entry(session, entry_id)
    guard = writing.Revert(entry_id, expect=None if force else entry.after,
                           decisions=resets.restorable_decisions(session, entry))
    return _restore(session, entry, settings, {"actor": actor, "revert": guard},
                    edit if edit is not None else writing.EditContext())


def _frame_id(entry: AuditEntry) -> int:
    """The view an entry of a view's edit names (``audit.record`` is given the frame of every such edit)."""
    assert entry.frame_id is not None, f"audit entry {entry.id} names no view"
    return entry.frame_id


def _system_id(entry: AuditEntry) -> int:
    """The system an entry of a system's edit names (``audit.record`` is given the system of every such edit)."""
    assert entry.system_id is not None, f"audit entry {entry.id} names no system"
    return int(entry.system_id)


def _restore(session: Session, entry: AuditEntry, settings: Settings, common: dict[str, Any],
             edit: writing.EditContext) -> Reverted:
    """Write back ``entry``'s ``before`` state through the service of its edit (``common``: the actor and the
    ``revert`` or ``undo`` guard; ``edit``: the write's context, given its entry's id)."""
    common = {**common, "edit": edit}
    before = entry.before
    entry_id = entry.id
    assert isinstance(before, dict)
    if "review" in before:
        review = before["review"]
        if entry.frame_id is None:
            system_id = _system_id(entry)
            decisions.decide_review(session, system_id=system_id, status=review["status"],
                                  comment=review["comment"], **common)
            return Reverted(system_id, "system", system_id)
        decisions.decide_review(session, frame_id=entry.frame_id, status=review["status"], comment=review["comment"],
                              **common)
    elif "calibration_review" in before:
        review = before["calibration_review"]
        decisions.decide_calibration(session, _frame_id(entry), status=review["status"], comment=review["comment"],
                                   **common)
    elif "ball" in before:
        ball = before["ball"]
        editing.update_ball_label(session, _frame_id(entry), box=ball["box"], point=ball["point"],
                                  provenance=ball.get("provenance"), settings=settings, **common)
    elif "lines" in before:
        editing.replace_field_lines(session, _frame_id(entry), before["lines"], settings=settings, **common)
    elif "assignee" in before:
        guard = common.get("revert")  # an undo (no revert guard) is never forced: the assignee must be what it left
        system_id = _system_id(entry)
        assigned = assignment.revert_assignment(session, system_id=system_id, before=before,
                                                after=entry.after or {}, entry_id=entry_id, actor=common.get("actor"),
                                                force=guard is not None and guard.expect is None)
        edit.entry_id = assigned.entry_ids[-1] if assigned.entry_ids else None
        return Reverted(system_id, "system", system_id)
    elif "excluded" in before:
        editing.set_view_excluded(session, _frame_id(entry), bool(before["excluded"]), settings=settings, **common)
    elif "system" in before:
        system_id = _system_id(entry)
        editing.restore_imported_system(session, system_id, before, settings=settings, **common)
        return Reverted(system_id, "system", system_id)
    else:
        raise InvalidInputError(f"audit entry {entry_id} records no state this version can restore", field="id")
    frame = writing.get_frame(session, _frame_id(entry))
    return Reverted(frame.system_id, "frame", frame.id)


def undo_entry(session: Session, entry_id: int, *, settings: Settings, actor: str, may_review: bool,
               edit: Optional[writing.EditContext] = None) -> Reverted:
    """Undo audit entry ``entry_id`` (the page's Ctrl+Z): write back its ``before`` state through the service of
    its edit, audited as that edit (the same action; a mirroring's undo as ``field_lines.replace``) with
    ``reverts_id`` naming the entry, and committed. The redo of an undo is the undo of the undo's entry. The
    state comes back exactly (labels, camera, 3D ball) because it is refused unless the edited part is, under
    the write's lock, still what the entry left (``after``): an undo never overwrites a newer change.

    Who may: a reviewer (``may_review``) any edit's entry; an annotator only their own (``actor`` is the entry's)
    when no one else wrote that resource (the frame, or the system's own decisions) since (a comment pinned on the
    view, or its resolution, is no write of it), and never a system
    decision (a reviewer's edit, so its undo is a reviewer's).

    Raises:
        NotFoundError: no such entry, or its frame or system no longer exists.
        InvalidInputError: an import, a recompute, a change of a user or a token (field "id").
        ForbiddenError: an annotator undoing a system decision, another's entry, or an entry someone else's
            write of the same resource followed.
        ConflictError: the resource changed since the entry; nothing changed.
    """
    entry = _revertible_entry(session, entry_id)
    if not may_review:
        if entry.frame_id is None:
            raise ForbiddenError(f"audit entry {entry_id} is a change of the whole system (a decision or an import): "
                                 "only a reviewer may undo it")
        if entry.actor != actor:
            raise ForbiddenError(f"audit entry {entry_id} is {shown_actor(entry.actor, admin=False)}'s edit: an "
                                 "annotator undoes only their own")
        # what counts is another person's write of the view (its labels, lines, exclusion or a decision on it); a
        # comment pinned on the view or its resolution writes none of them and does not take the undo away
        other = session.scalars(sa.select(AuditEntry.actor).where(
            AuditEntry.id > entry.id, AuditEntry.frame_id == entry.frame_id, AuditEntry.actor != actor,
            AuditEntry.action.not_in(TEAM_ACTIONS)
        ).limit(1)).first()
        if other is not None:
            raise ForbiddenError(f"audit entry {entry_id} cannot be undone by an annotator: "
                                 f"{shown_actor(other, admin=False)} changed the view since (a reviewer may revert it "
                                 "from the history)")
    guard = writing.Revert(entry_id, expect=entry.after, decisions=resets.restorable_decisions(session, entry))
    return _restore(session, entry, settings, {"actor": actor, "undo": guard},
                    edit if edit is not None else writing.EditContext())


def _revertible_entry(session: Session, entry_id: int) -> AuditEntry:
    """The entry, when a revert or an undo can restore it. Raises NotFoundError, InvalidInputError (field "id")."""
    entry = found(session.get(AuditEntry, entry_id), "audit entry", entry_id)
    if not revertible(entry.action) or not isinstance(entry.before, dict):
        what = ("it changed many rows at once" if entry.action in ("import", "recompute")
                else "it changed a user or a token")
        raise InvalidInputError(f"audit entry {entry_id} is {'an' if entry.action[0] in 'aeiou' else 'a'} "
                                f"{entry.action}: {what} and cannot be reverted", field="id")
    return entry
