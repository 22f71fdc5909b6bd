"""Decisions back to pending after an edit: the one rule.

One rule for decisions after edits: an edit that changes a system's labels or 3D result sets the
system's decision and the touched view's decision (its ball decision; its calibration decision for field lines)
back to pending with the reason, in the edit's transaction (:func:`reset_decisions_after_edit`); an edit that
changes nothing resets nothing. ``undo`` (:func:`check_undo_state`) marks a write as the undo of an audit entry
(``app.services.curation.reverting.undo_entry``): audited under the edit's own action with ``reverts_id``, refused
(409) when the edited part is not the entry's ``after`` under the lock; an undo resets decisions as any edit.

And back: the undo (or revert) of an edit gives back the decisions that edit reset (:func:`restore_decisions`) when,
after it, the whole system's labels (every view's ball label, field lines and exclusion) are those the decisions
were made on, the labels just before the edit (a decided system's labels never change without a reset), and nobody
decided them since: a ball moved 1 px and moved back is accepted again, while an undo that leaves another view's
later edit in place, or follows a recompute, leaves them pending. The undo's own entry says so in words.
"""
from __future__ import annotations

from collections.abc import Sequence
from typing import Any, Callable, Optional

from sqlalchemy.orm import Session

from app.core.config import Settings
from app.db import scope
from app.db.models import (
    AuditEntry,
    Frame,
    ReviewStatus,
    System,
)
from app.db.types import utcnow
from app.services.audit import log as audit
from app.services.audit.summaries import summarize
from app.services.calibration.admission import admission_jac, is_admitted
from app.services.curation.states import (
    ball_state,
    calibration_review_state,
    excluded_state,
    lines_state,
    review_state,
    same_json,
)
from app.services.curation.writing import (
    EditContext,
    Restorable,
    Revert,
)


def reset_refitted_systems(session: Session, edited: System, refitted: Sequence[System], actor: Optional[str]) -> int:
    """The one rule for decisions after edits for the systems an edit changed beside its own: an
    ISSIA edit re-fits its sequence's trajectory, which moves the 3D ball of neighbouring frames (``refitted``: the
    systems whose place on it changed); each of those, other than ``edited`` (whose decisions the edit itself
    resets), that was decided goes back to pending with the reason and its own ``system.review`` audit entry, and
    every one of them, decided or not, has its version bumped: the re-fit wrote its trajectory point and doubts
    (in bulk statements the write unit's check does not see), so a decision sent with the version seen before is
    refused.

    Returns:
        How many systems were set back to pending.
    """
    who = audit.public_actor(actor)
    done = 0
    for other in refitted:
        if other.id == edited.id:
            continue  # the edited system's own version is bumped once, by its edit
        scope.changed(other)
        decision = other.review
        if decision is None or decision.status == ReviewStatus.PENDING:
            continue
        _system_back_to_pending(session, other, f"{other.name}: its 3D ball moved with the trajectory's re-fit after "
                                f"an edit of {edited.name} by {who}; decide it again", actor, utcnow())
        done += 1
    return done


def calibration_words(frame: Frame, settings: Settings) -> str:
    """The frame's calibration in a few words: "JaC@0.5 % 0.812, admitted" (the admission's gamma), or
    "not calibrated"."""
    cal = frame.calibration
    if cal is None or cal.camera is None:
        return "not calibrated"
    jac = admission_jac(cal, settings)
    pct = f"{100 * settings.admit_jac_gamma:g}"
    return (f"JaC@{pct} % {jac:.3f}" if jac is not None else f"JaC@{pct} % unknown") + (
        ", admitted" if is_admitted(cal, settings) else ", not admitted")


def reset_decisions_after_recalibration(session: Session, frame: Frame, before: tuple[dict[str, Any], str],
                                        verb: str, actor: Optional[str], settings: Settings) -> Optional[str]:
    """After ``frame``'s field lines changed (``before``: :func:`lines_state` and :func:`calibration_words`
    before the edit) and it was recalibrated, in the edit's transaction: a decided calibration decision of the view and
    a decided decision of its system go back to pending with the reason (``calibration_reset_reason``,
    ``reset_reason``), each with its own audit entry (``view.calibration_review``, ``system.review``: revertible) added
    before the edit's own, so the edit stays the frame's newest entry. Nothing changes when the lines did not.

    Returns:
        The reason (one sentence naming the view, the edit, who, and the calibration before and after), or
        None when nothing was reset.
    """
    lines_before, words_before = before
    if same_json(lines_before, lines_state(frame)):
        return None
    who = audit.public_actor(actor)
    reason = (f"{frame.name}: field lines {verb} by {who}, the view was recalibrated "
              f"({words_before} -> {calibration_words(frame, settings)}); decide it again")
    return reason if reset_decisions_after_edit(session, frame, reason, actor, calibration=True) else None


def reset_after_change(session: Session, frame: Frame, action: str, before: dict[str, Any], after: dict[str, Any],
                       actor: Optional[str], undo: Optional[Revert] = None) -> Optional[str]:
    """After an edit of ``frame``'s ball label or exclusion (``action``, its state ``before`` and ``after``, as
    :func:`ball_state` / :func:`excluded_state` give them): when the state changed, the view's ball decision and
    the system's decision go back to pending (:func:`reset_decisions_after_edit`) with the reason, the edit in
    words (the audit log's, ``app.services.audit.summaries.summarize``), who made it and, for an undo, which entry it
    undid.

    Returns:
        The reason, or None when the edit changed nothing or nothing was decided.
    """
    if same_json(before, after):
        return None
    words = summarize(action, before, after, view=audit.view_name(frame))
    undone = f" (undo of audit entry {undo.entry_id})" if undo is not None else ""
    reason = f"{frame.name}: {words}{undone} by {audit.public_actor(actor)}; decide it again"
    return reason if reset_decisions_after_edit(session, frame, reason, actor, calibration=False) else None


def reset_decisions_after_edit(session: Session, frame: Frame, reason: str, actor: Optional[str], *,
                               calibration: bool) -> bool:
    """One rule for decisions after an edit that changed a system's labels or 3D result, in
    the edit's transaction: the touched view's decision (its calibration decision when ``calibration``, i.e. a
    field-line edit; else its ball decision) and the system's decision, when decided, go back to pending with
    ``reason`` (``calibration_reset_reason`` / ``reset_reason``), each with its own audit entry
    (``view.calibration_review`` / ``view.review``, ``system.review``: revertible) added before the edit's own,
    so the edit stays the frame's newest entry (the edit bumps the system's version: a page that drew the old
    decision gets 412 on deciding).

    Returns:
        Whether anything was reset.
    """
    review, system = frame.review, frame.system
    if calibration:
        view_decided = review is not None and review.calibration_status != ReviewStatus.PENDING
    else:
        view_decided = review is not None and review.status != ReviewStatus.PENDING
    system_decided = system.review is not None and system.review.status != ReviewStatus.PENDING
    if not (view_decided or system_decided):
        return False
    now = utcnow()
    if view_decided and calibration:
        assert review is not None  # view_decided: the view has a decision
        before = calibration_review_state(frame)
        review.calibration_status = ReviewStatus.PENDING
        review.calibration_reset_reason = reason
        review.calibration_decided_at = now
        audit.record(session, actor=actor, action="view.calibration_review", frame=frame, before=before,
                     after=calibration_review_state(frame))
    elif view_decided:
        assert review is not None  # view_decided: the view has a decision
        before = review_state(frame)
        review.status = ReviewStatus.PENDING
        review.reset_reason = reason
        review.decided_at = now
        audit.record(session, actor=actor, action="view.review", frame=frame, before=before,
                     after=review_state(frame))
    if system_decided:
        _system_back_to_pending(session, system, reason, actor, now)
    return True


def _system_back_to_pending(session: Session, system: System, reason: str, actor: Optional[str], now: Any) -> None:
    """Set ``system``'s decided decision back to pending with ``reason`` and record the change (``system.review``,
    revertible)."""
    before = review_state(system)
    decision = system.review
    assert decision is not None  # the callers reset a decided decision only
    decision.status = ReviewStatus.PENDING
    decision.reset_reason = reason
    decision.batch_id = None  # pending: no batch's acceptance any more
    decision.decided_at = now
    audit.record(session, actor=actor, action="system.review", system=system, before=before,
                 after=review_state(system))


def jac_words(frame: Frame, settings: Settings) -> str:
    """The frame's calibration for an entry's summary: "JaC 0.909" (at the admission's gamma,
    :func:`~app.services.calibration.admission.admission_jac`), or "refused" (no camera, or no JaC)."""
    cal = frame.calibration
    jac = admission_jac(cal, settings) if cal is not None and cal.camera is not None else None
    return f"JaC {jac:.3f}" if jac is not None else "refused"


#: The edited parts of a view an entry's state may hold (the labels a decision is made on), each with its state.
LABEL_STATES: dict[str, Callable[[Frame], dict[str, Any]]] = {
    "ball": ball_state, "lines": lines_state, "excluded": excluded_state}
#: The decisions an entry's state may hold, each with its state.
DECISION_STATES: dict[str, Callable[[Any], dict[str, Any]]] = {
    "review": review_state, "calibration_review": calibration_review_state}
#: The most entries after an edit :func:`restorable_decisions` reads; beyond, its undo restores no decision.
RESTORE_HISTORY_MAX = 500


def _part(state: Optional[dict[str, Any]], parts: Any) -> Optional[str]:
    """Which of ``parts`` (a table's keys) an entry's ``state`` holds, or None."""
    return next((k for k in parts if state is not None and k in state), None)


def restorable_decisions(session: Session, entry: AuditEntry) -> Optional[Restorable]:
    """What the undo or revert of ``entry`` (an edit of a view's label: its state holds ``ball``, ``lines`` or
    ``excluded``) may give back (:class:`~app.services.curation.writing.Restorable`), read from the audit log before
    the undo's write: the decisions its write set back to pending that nobody decided since, the system's version
    after the entries written since, and the states the labels changed since had when the edit was made. None when
    there is nothing to give back, or when something since cannot be read as such (an entry recorded before versions
    were, a change of another shape, more than :data:`RESTORE_HISTORY_MAX` entries)."""
    own = _part(entry.before, LABEL_STATES)
    if own is None or entry.frame_id is None or entry.system_version is None:
        return None
    resets: list[tuple[str, Optional[int], dict[str, Any], dict[str, Any]]] = []
    for e in audit.entries_of_write(session, entry):
        decision = _part(e.before, DECISION_STATES)
        if decision is not None and e.before is not None and e.after is not None and decision in e.after:
            if (e.before[decision]["status"] != ReviewStatus.PENDING.value
                    and e.after[decision]["status"] == ReviewStatus.PENDING.value):
                resets.append((decision, e.frame_id, e.before, e.after))
    later = audit.entries_after(session, entry, RESTORE_HISTORY_MAX) if resets else None
    if later is None:
        return None
    labels: dict[tuple[int, str], Any] = {}
    decided: set[tuple[str, Optional[int]]] = set()
    version: int = entry.system_version
    for e in later:
        part, decision = _part(e.before, LABEL_STATES), _part(e.before, DECISION_STATES)
        if e.system_version is None or e.before is None:
            return None
        version = max(version, e.system_version)
        if part is not None and e.frame_id is not None:
            if (e.frame_id, part) != (entry.frame_id, own):  # the undo writes the edit's own part back itself
                labels.setdefault((e.frame_id, part), e.before[part])  # as it was when the edit was made
        elif decision is not None:
            decided.add((decision, e.frame_id))
        elif "assignee" not in e.before:
            return None  # a change this rule cannot read: the labels may differ from the decided ones
    kept = tuple(r for r in resets if (r[0], r[1]) not in decided)
    return Restorable(kept, version, labels) if kept else None


def restore_decisions(frame: Frame, revert: Optional[Revert], actor: Optional[str], edit: EditContext) -> list[str]:
    """In the write of an undo or revert (``revert``) of an edit of ``frame``'s system, after its change: give back
    the decisions that edit reset (``revert.decisions``, :func:`restorable_decisions`) when nothing of the system
    changed since they were read but decisions (``edit.version``, the system's version as the write read it, is
    theirs), every label changed since is back to its state when the edit was made (the undo put the edit's own back),
    and each decision is still the pending one its reset left. Each gets its status and comment back (decided now,
    no reset reason); the write's audit entry names them (``edit.facts["restored"]``). ``actor`` is the undoer.

    Returns:
        The decisions given back, in words ("system accepted (ok)"); empty when none.
    """
    plan = revert.decisions if revert is not None else None
    system = frame.system
    if plan is None or edit.version != plan.version:
        return []
    views = {f.id: f for f in system.frames}
    for (view_id, part), state in plan.labels.items():
        view = views.get(view_id)
        if view is None or not same_json(LABEL_STATES[part](view)[part], state):
            return []
    words = []
    now = utcnow()
    for decision, frame_id, before, after in plan.resets:
        subject: Frame | System | None = system if frame_id is None else views.get(frame_id)
        if subject is None or not same_json(DECISION_STATES[decision](subject), after):
            continue
        status, comment = ReviewStatus(before[decision]["status"]), before[decision]["comment"]
        review = subject.review
        assert review is not None  # its state is the reset's: a decision row exists
        if decision == "calibration_review":
            review.calibration_status, review.calibration_comment = status, comment
            review.calibration_reset_reason, review.calibration_decided_at = None, now
            action = "view.calibration_review"
        else:
            review.status, review.comment, review.reset_reason, review.decided_at = status, comment, None, now
            action = "view.review" if frame_id is not None else "system.review"
        name = audit.view_name(subject) if isinstance(subject, Frame) else None
        words.append(summarize(action, after, before, view=name))
    if words:
        edit.facts["restored"] = words
    return words
