"""Review decisions: a system's, a view's ball and a view's calibration, each a guarded, audited write
(``app.services.curation.writing``) that recomputes nothing.
"""
from __future__ import annotations

from typing import Any, Optional

from sqlalchemy.orm import Session

from app.core.errors import InvalidInputError
from app.db.models import (
    Frame,
    ReviewDecision,
    ReviewStatus,
    System,
)
from app.db.types import utcnow
from app.services.curation import handoff
from app.services.curation.states import (
    calibration_review_state,
    review_state,
    system_review_state,
)
from app.services.curation.writing import (
    EditContext,
    EditPlan,
    Expected,
    Revert,
    check_undo_state,
    guarded_frame_write,
    guarded_write,
)


def decide_review(session: Session, *, system_id: int | None = None, frame_id: int | None = None,
                  status: ReviewStatus | str, comment: str = "", actor: Optional[str] = None,
                  expected: Expected = None, revert: Optional[Revert] = None,
                  undo: Optional[Revert] = None, edit: Optional[EditContext] = None,
                  fixed_by: Optional[int] = None, return_to: Optional[str] = None) -> ReviewDecision:
    """Record a review decision on a system or on a frame (exactly one of the two ids).

    Args:
        status: pending, accepted, rejected or needs_fix (enum or its value); a system's also fixed. A system's
            decision makes its hand-off (``app.services.curation.handoff.after_decision``: needs fix returns it to
            a person, fixed gives it back to the reviewer who asked), in the same transaction; who may send which is
            checked before (``handoff.check_fixed_allowed``).
        comment: free text (kept as given).
        actor, expected, revert: attribution and guard (module docstring; ``expected`` are versions of
            the system, which every write of its labels, lines, calibrations and decisions bumps, or of the frame);
            audited as ``system.review`` or ``view.review``. An accept of a system records the label doubts open at that
            moment (:func:`system_review_state`).
        undo: this write undoes audit entry ``undo.entry_id`` (:func:`check_undo_state`).
        edit: the write's context (``writing.EditContext``), filled with its audit entry's id.
        fixed_by: the id of the user sending a system's ``fixed``: it is applied only while the system is still
            returned to them, checked inside the write transaction under the lock
            (``handoff.check_fixed_in_write``), so that it never undoes a decision committed after the caller's own
            check; None (a revert, the machine) checks nothing.

    Returns:
        The committed :class:`ReviewDecision` (``decided_at`` is now, UTC).

    Raises:
        InvalidInputError: both or neither id, or an unknown status; a needs fix with no one to return it to, or
            ``return_to`` that is no enabled user or goes with another status (field ``assignee``).
        NotFoundError: no such system or frame.
        StaleVersionError: the version is not in ``expected``; nothing changed.
        ConflictError: a ``fixed`` of ``fixed_by`` on a system no longer returned to them; nothing changed.
    """
    if (system_id is None) == (frame_id is None):
        raise InvalidInputError("give exactly one of system_id and frame_id", field="system_id")
    status = _check_decision(status, comment)
    if frame_id is not None and return_to is not None:
        raise InvalidInputError("'assignee' goes with a system's needs fix; a view's decision goes to no one",
                                field="assignee")
    if frame_id is not None and status is ReviewStatus.FIXED:
        raise InvalidInputError("'fixed' is a system's status; a view's decision is pending, accepted, rejected or "
                                "needs_fix", field="status")

    def apply(subject: System | Frame) -> ReviewDecision:
        check_undo_state(undo, review_state(subject))
        if isinstance(subject, System) and status is ReviewStatus.FIXED and fixed_by is not None:
            handoff.check_fixed_in_write(session, subject, fixed_by)
        review = subject.review
        if review is None:
            review = ReviewDecision()
            subject.review = review
        review.status = status
        review.comment = comment
        review.decided_at = utcnow()
        review.reset_reason = None
        review.batch_id = None  # a person's decision (or its undo): no batch's
        if isinstance(subject, System):
            handoff.after_decision(session, subject, status, actor=actor, note=comment, return_to=return_to,
                                   required=revert is None and undo is None)
        return review

    undo_of = undo.entry_id if undo is not None else None
    if system_id is not None:
        plan = EditPlan("system.review", system_review_state, apply, actor, None, expected, revert, undo_of)
        return guarded_write(session, system_id, plan, edit=edit)
    view_plan = EditPlan("view.review", review_state, apply, actor, frame_id, expected, revert, undo_of)
    return guarded_frame_write(session, view_plan, edit=edit)


def _check_decision(status: ReviewStatus | str, comment: Any) -> ReviewStatus:
    """The status as the enum; raises :class:`InvalidInputError` (field "status" or "comment")."""
    try:
        status = ReviewStatus(status)
    except ValueError:
        raise InvalidInputError(f"unknown review status {status!r}; choose one of "
                                f"{[s.value for s in ReviewStatus]}", field="status") from None
    if not isinstance(comment, str):
        raise InvalidInputError("comment must be text", field="comment")
    return status


def decide_calibration(session: Session, frame_id: int, *, status: ReviewStatus | str, comment: str = "",
                       actor: Optional[str] = None, expected: Expected = None,
                       revert: Optional[Revert] = None, undo: Optional[Revert] = None,
                       edit: Optional[EditContext] = None) -> ReviewDecision:
    """Record the reviewer's decision on a view's calibration (its field lines and the camera fitted to
    them), beside the decision on its ball (:func:`decide_review`). Clears ``calibration_reset_reason``.
    Audited as ``view.calibration_review`` (``actor``, ``expected``: versions of the frame, ``revert``:
    module docstring; ``undo``: :func:`check_undo_state`). An edit of the view's field lines sets a decided calibration
    back to pending (:func:`reset_decisions_after_recalibration`).

    Returns:
        The committed :class:`ReviewDecision` of the frame (created with a pending ball decision when the
        view had none).

    Raises:
        InvalidInputError: an unknown status (field "status"), a comment that is not text.
        NotFoundError: no such frame.
        StaleVersionError: the frame's version is not in ``expected``; nothing changed.
    """
    status = _check_decision(status, comment)
    if status is ReviewStatus.FIXED:
        raise InvalidInputError("'fixed' is a system's status; a calibration's decision is pending, accepted, "
                                "rejected or needs_fix", field="status")

    def apply(frame: Frame) -> ReviewDecision:
        check_undo_state(undo, calibration_review_state(frame))
        review = frame.review
        if review is None:
            review = ReviewDecision(status=ReviewStatus.PENDING, comment="")
            frame.review = review
        review.calibration_status = status
        review.calibration_comment = comment
        review.calibration_decided_at = utcnow()
        review.calibration_reset_reason = None
        return review

    plan = EditPlan("view.calibration_review", calibration_review_state, apply, actor, frame_id, expected, revert,
                    undo.entry_id if undo is not None else None)
    return guarded_frame_write(session, plan, edit=edit)
