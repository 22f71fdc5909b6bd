"""Reviewer edits: ball labels, field lines and review decisions.

Every edit and the recomputation it implies (``app.services.recompute``) happen in one transaction:
the function commits when everything succeeded and rolls back otherwise, so a failing
recomputation leaves the edit unstored too. Invalid input raises
:class:`~app.services.errors.InvalidInputError` before anything changes; an unknown id raises
:class:`~app.services.errors.NotFoundError`.

* ball label -> the system's triangulation, reprojections and optimised boxes; for an ISSIA system
  also the re-fit of the sequence's trajectory around its frame and the systems it changes;
* field lines -> the frame's calibration -> the same system-level recomputation (also the
  one-click fix of mirrored labels, :func:`apply_mirrored_labels`);
* a view's exclusion from the triangulation (:func:`set_view_excluded`, the fix of a doubt that
  names a view that adds nothing or disagrees) -> the system-level recomputation.

Every system-level recomputation also replaces the system's doubts (``app.services.doubts``).
"""
from __future__ import annotations

from typing import Any, Callable, Mapping, TypeVar

from sqlalchemy.orm import Session

from app.core.config import Settings
from app.db.models import BallKind, BallLabel, FieldLineAnnotation, Frame, ReviewDecision, ReviewStatus, System
from app.db.types import utcnow
from app.geometry.annotations import AnnotationError, lines_from_json_lists, lines_to_json_lists, mirror_lines
from app.services._labels import LabelError, check_box, check_point
from app.services.errors import InvalidInputError, NotFoundError
from app.services.issia import refit_after_edit
from app.services.recompute import recompute_frame, recompute_system

T = TypeVar("T")


def _in_transaction(session: Session, work: Callable[[], T]) -> T:
    """Run ``work`` and commit; roll back and re-raise on any error."""
    try:
        result = work()
        session.commit()
        return result
    except BaseException:
        session.rollback()
        raise


def get_frame(session: Session, frame_id: int) -> Frame:
    """The frame with this id. Raises :class:`NotFoundError`."""
    frame = session.get(Frame, frame_id)
    if frame is None:
        raise NotFoundError("frame", frame_id)
    return frame


def get_system(session: Session, system_id: int) -> System:
    """The system with this id. Raises :class:`NotFoundError`."""
    system = session.get(System, system_id)
    if system is None:
        raise NotFoundError("system", system_id)
    return system


def update_ball_label(session: Session, frame_id: int, box: Any = None, point: Any = None, *,
                      settings: Settings) -> Frame:
    """Set a frame's ball label to a box or a point, or remove it, then recompute its system.

    Args:
        frame_id: the frame.
        box: ``[x1, y1, x2, y2]`` pixels of the frame (may be partly outside the image).
        point: ``[x, y]`` pixels inside the image. Give at most one of ``box`` and ``point``; giving
            neither removes the label (the ball is not visible in this view).
        settings: admission and triangulation parameters.

    Returns:
        The frame, with its ``ball_label`` and its system's derived rows updated and committed.

    Raises:
        NotFoundError: no such frame.
        InvalidInputError: both box and point, non-finite numbers, a degenerate box, a box entirely
            outside the image, a point outside it (field "box" or "point").
    """
    if box is not None and point is not None:
        raise InvalidInputError("give a box or a point, not both", field="box")
    frame = get_frame(session, frame_id)
    try:
        new_box = check_box(box, frame.width, frame.height) if box is not None else None
        new_point = check_point(point, frame.width, frame.height) if point is not None else None
    except LabelError as exc:
        raise InvalidInputError(str(exc), field="box" if box is not None else "point") from None

    def work() -> Frame:
        label = frame.ball_label
        kind = BallKind.BOX if new_box is not None else BallKind.POINT if new_point is not None else None
        if label is None and kind is None:
            pass  # nothing to remove
        elif label is not None and kind is None and label.original_kind is None:
            frame.ball_label = None  # a label added by a reviewer, removed again: nothing to keep
        else:
            if label is None:
                label = BallLabel()
                frame.ball_label = label
            label.kind, label.box, label.point = kind, new_box, new_point
            label.edited_at = utcnow()
        _recompute(session, frame.system, settings)
        return frame

    return _in_transaction(session, work)


def _recompute(session: Session, system: System, settings: Settings) -> None:
    """The system-level recomputation of an edit; for an ISSIA system also the re-fit of the stretch
    of its sequence's trajectory the edit touches, and the systems whose place on it changed
    (``app.services.issia.refit_after_edit``), in the same transaction."""
    recompute_system(session, system, settings)
    refit_after_edit(session, system, settings)


def replace_field_lines(session: Session, frame_id: int, lines: Mapping[str, Any], *, settings: Settings) -> Frame:
    """Replace a frame's field lines, recalibrate the frame and recompute its system.

    Args:
        frame_id: the frame.
        lines: ``{class: [[[x, y], ...], ...]}`` in pixels of the frame (SoccerNet class names;
            repeated polylines of a class allowed). The imported original is kept.
        settings: admission and triangulation parameters.

    Returns:
        The frame with its new lines, calibration (source "computed") and derived rows, committed.

    Raises:
        NotFoundError: no such frame.
        InvalidInputError: unknown class, malformed polyline, NaN or infinity (field "lines", the
            message names the class and polyline).
    """
    frame = get_frame(session, frame_id)
    try:
        parsed = lines_to_json_lists(lines_from_json_lists(lines))
    except AnnotationError as exc:
        raise InvalidInputError(str(exc), field="lines") from None

    def work() -> Frame:
        fl = frame.field_lines
        if fl is None:
            frame.field_lines = FieldLineAnnotation(lines=parsed, original_lines={}, edited_at=utcnow())
        else:
            fl.lines = parsed
            fl.edited_at = utcnow()
        recompute_frame(session, frame, settings)
        refit_after_edit(session, frame.system, settings)
        return frame

    return _in_transaction(session, work)


def apply_mirrored_labels(session: Session, frame_id: int, *, settings: Settings) -> Frame:
    """Replace a frame's field lines by their mirrored labelling and recompute, in one transaction.

    The fix offered for a frame flagged ``probably_mirrored`` (``app.geometry.mirror``): every class
    is renamed by the pitch's 180-degree rotation (``app.geometry.annotations.mirror_lines``; the
    points stay where they are), then :func:`replace_field_lines` recalibrates the frame and
    recomputes its system. The imported original is kept, so the edit can be undone by applying
    it again. The reviewer decides; nothing mirrors labels without this call.

    Raises:
        NotFoundError: no such frame.
        InvalidInputError: the frame has no field lines (field "lines").
    """
    frame = get_frame(session, frame_id)
    if frame.field_lines is None or not frame.field_lines.lines:
        raise InvalidInputError(f"frame {frame_id} has no field lines to mirror", field="lines")
    mirrored = lines_to_json_lists(mirror_lines(lines_from_json_lists(frame.field_lines.lines)))
    return replace_field_lines(session, frame_id, mirrored, settings=settings)


def decide_review(session: Session, *, system_id: int | None = None, frame_id: int | None = None,
                  status: ReviewStatus | str, comment: str = "") -> ReviewDecision:
    """Record a review decision on a system or on a frame (exactly one of the two ids).

    Args:
        status: pending, accepted, rejected or needs_fix (enum or its value).
        comment: free text (kept as given).

    Returns:
        The committed :class:`ReviewDecision` (``decided_at`` is now, UTC).

    Raises:
        InvalidInputError: both or neither id, or an unknown status.
        NotFoundError: no such system or frame.
    """
    if (system_id is None) == (frame_id is None):
        raise InvalidInputError("give exactly one of system_id and frame_id", field="system_id")
    try:
        status = ReviewStatus(status)
    except ValueError:
        raise InvalidInputError(f"unknown review status {status!r}; choose one of "
                                f"{[s.value for s in ReviewStatus]}", field="status") from None
    if not isinstance(comment, str):
        raise InvalidInputError("comment must be text", field="comment")
    subject: System | Frame = get_system(session, system_id) if system_id is not None else get_frame(session, frame_id)  # type: ignore[arg-type]

    def work() -> ReviewDecision:
        review = subject.review
        if review is None:
            review = ReviewDecision()
            subject.review = review
        review.status = status  # type: ignore[assignment]
        review.comment = comment
        review.decided_at = utcnow()
        if isinstance(subject, System):
            subject.review_status = status  # type: ignore[assignment]  # the queue's copy
        session.flush()
        return review

    return _in_transaction(session, work)


def set_view_excluded(session: Session, frame_id: int, excluded: bool, *, settings: Settings) -> Frame:
    """Exclude a view from its system's triangulation, or restore it, then recompute the system, in
    one transaction.

    The decision is stored on the view's review (``ReviewDecision.excluded``, created pending when the
    view has none) and is reversible: the view keeps its labels and calibration, is drawn and judged,
    but takes no part in the 3D ball. Its review status and comment are left as they are.

    Raises:
        NotFoundError: no such frame.
        InvalidInputError: ``excluded`` is not a boolean (field "excluded").
    """
    if not isinstance(excluded, bool):
        raise InvalidInputError("excluded must be true or false", field="excluded")
    frame = get_frame(session, frame_id)

    def work() -> Frame:
        review = frame.review
        if review is None:
            review = ReviewDecision(status=ReviewStatus.PENDING, comment="")
            frame.review = review
        review.excluded = excluded
        _recompute(session, frame.system, settings)
        return frame

    return _in_transaction(session, work)
