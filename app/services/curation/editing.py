"""Reviewer edits: ball labels, field lines and review decisions.

Every edit and the recomputation it implies (``app.services.curation.recompute``) happen in one transaction:
the function commits when everything succeeded and rolls back otherwise, so a failing
recomputation leaves the edit unstored too. Invalid input raises
:class:`~app.core.errors.InvalidInputError` before anything changes; an unknown id raises
:class:`~app.core.errors.NotFoundError`.

* ball label -> the system's triangulation, reprojections and optimised boxes; for an ISSIA system
  also the re-fit of the sequence's trajectory around its frame and the systems it changes;
* field lines -> the frame's calibration -> the same system-level recomputation (also the
  one-click fix of mirrored labels, :func:`apply_mirrored_labels`);
* a view's exclusion from the triangulation (:func:`set_view_excluded`, the fix of a doubt that
  names a view that adds nothing or disagrees) -> the system-level recomputation.

Every system-level recomputation also replaces the system's doubts (``app.services.curation.doubts``).

Every write is attributed and guarded, in its transaction: it first claims its resource
(``app.services.curation.versions``: compare-and-set of the frame's ``edit_version`` or the system's
``review_version`` against ``expected``, the versions of the client's ``If-Match``; None accepts any),
raising :class:`~app.core.errors.StaleVersionError` (with the resource's current rows and its
newest audit entry) when another write came first; then it applies the change, recomputes, and records
one audit entry (``app.services.accounts.audit``, by ``actor``, None meaning :func:`~app.services.accounts.audit.local_actor`)
with the edited part's state before and after. ``revert`` marks the write as the revert of an audit
entry (``app.services.curation.reverting``): it is recorded as action ``revert``, and refused with
:class:`~app.core.errors.ConflictError` when the state under the lock is not ``revert.expect``.

Concurrency (several server processes, issue 7): every edit is one write unit of work
(:func:`_in_transaction`, which :func:`_write` runs in): it begins a write transaction (``app.db.session.begin_write``: SQLite's
``BEGIN IMMEDIATE``, waiting its turn for the write lock) and locks the edited system's row
(:func:`lock_system`: ``SELECT ... FOR UPDATE`` on PostgreSQL, also the game's row for an ISSIA system,
whose edits re-fit its whole sequence) before it reads anything it changes, so two edits of one
system's views run one after the other and the second recomputes from the first's labels. Nothing is
read before the lock and written after it: the objects loaded earlier are expired and read again.
"""
from __future__ import annotations

import json
from collections.abc import Collection
from dataclasses import dataclass
from typing import Any, Callable, Mapping, Optional, TypeVar

from sqlalchemy import select
from sqlalchemy.orm import Session

from app.core.config import Settings
from app.db.models import (
    BallKind, BallLabel, FieldLineAnnotation, Frame, Game, ReviewDecision, ReviewStatus, System,
)
from app.db.session import begin_write
from app.db.types import utcnow
from app.geometry.annotations import AnnotationError, lines_from_json_lists, lines_to_json_lists, mirror_lines
from app.datasets.labels import LabelError, check_box, check_line_points, check_point
from app.services.accounts import audit
from app.core.errors import ConflictError, InvalidInputError, NotFoundError, StaleVersionError, found
from app.services.kinds import kind_of, policy
from app.services.curation.recompute import load_for_recompute, recompute_frame, recompute_system
from app.services.curation.system_page import load_frame
from app.services.curation.versions import claim_frame, claim_system_review

T = TypeVar("T")
Expected = Optional[Collection[int]]


@dataclass(frozen=True)
class Revert:
    """An edit that reverts audit entry ``entry_id``: recorded as action ``revert``; refused (409) when
    the edited part's state under the lock is not ``expect`` (the entry's ``after``; None: forced)."""

    entry_id: int
    expect: Optional[dict[str, Any]] = None


def lock_system(session: Session, system_id: int) -> None:
    """Lock the system's row (and, for an ISSIA system, its game's row first) until the transaction
    ends, then expire every loaded object so that what the caller reads next is read under the lock.

    PostgreSQL: ``SELECT ... FOR UPDATE`` makes concurrent edits of one system (one sequence for ISSIA,
    whose edits re-fit the trajectory of the whole game) wait for each other, so no recomputation is
    computed from labels another transaction is changing and then overwrites that transaction's result.
    Rows are always locked game first, then system: no two edits wait for each other in a cycle. Systems
    of other games, and other systems of a SoccerNet game, are edited in parallel. SQLite ignores
    ``FOR UPDATE``; its ``BEGIN IMMEDIATE`` already serialises every write transaction.

    Raises:
        NotFoundError: no system has this id.
    """
    row = session.execute(select(System.game_id, System.kind).where(System.id == system_id)).one_or_none()
    if row is None:
        raise NotFoundError("system", system_id)
    if policy(row.kind).edit_locks_game:
        session.execute(select(Game.id).where(Game.id == row.game_id).with_for_update())
    session.execute(select(System.id).where(System.id == system_id).with_for_update())
    session.expire_all()


def _in_transaction(session: Session, work: Callable[[], T], *, system_id: int) -> T:
    """Run ``work`` as one write unit of work on the system ``system_id`` and commit; roll back and
    re-raise on any error. The write transaction begins (``begin_write``) and the system is locked
    (:func:`lock_system`) before ``work`` reads anything, so ``work`` reads fresh rows under the lock.
    A stale version (:class:`StaleVersionError`) gets the resource's current JSON and newest audit
    entry, read after the rollback."""
    try:
        begin_write(session)
        lock_system(session, system_id)
        result = work()
        session.commit()
        return result
    except BaseException as exc:
        session.rollback()
        if isinstance(exc, StaleVersionError):
            _describe_current(session, exc)
        raise


def _describe_current(session: Session, exc: StaleVersionError) -> None:
    """Fill a stale write's current state: the frame loaded for its view, or the system and its review."""
    if exc.kind == "frame":
        exc.current = load_frame(session, exc.ident)
        exc.last_change = audit.latest_entry(session, frame_id=exc.ident)
    else:
        system = get_system(session, exc.ident)
        system.review  # loaded now: the answer is shaped after the session is gone
        exc.current = system
        exc.last_change = audit.latest_entry(session, system_id=exc.ident)


def _same(a: Any, b: Any) -> bool:
    """Equal as JSON (tuples and lists alike, as stored)."""
    return json.dumps(a, sort_keys=True) == json.dumps(b, sort_keys=True)


def _write(session: Session, system_id: int, claim: Callable[[], None], subject: Callable[[], Frame | System],
           state: Callable[[Any], dict[str, Any]], apply: Callable[[Any], T], action: str,
           actor: Optional[str], revert: Optional[Revert]) -> T:
    """The guarded, audited write every edit goes through (module docstring), in one write transaction
    holding the lock of system ``system_id`` (:func:`_in_transaction`): ``claim`` (compare-and-set),
    ``state`` of ``subject()`` before, ``apply`` (change and recompute), ``state`` after, one audit entry."""

    def work() -> T:
        claim()
        target = subject()
        before = state(target)
        if revert is not None and revert.expect is not None and not _same(before, revert.expect):
            raise ConflictError(f"audit entry {revert.entry_id} cannot be reverted: its resource changed since "
                                f"(it is now {json.dumps(before)[:300]}); revert the newer entries first, or force it",
                                current=before)
        result = apply(target)
        session.flush()
        frame = target if isinstance(target, Frame) else None
        audit.record(session, actor=actor, action="revert" if revert is not None else action, frame=frame,
                     system=target if frame is None else None, before=before, after=state(target),
                     reverts_id=revert.entry_id if revert is not None else None)
        return result

    return _in_transaction(session, work, system_id=system_id)


def _frame_write(session: Session, frame_id: int, expected: Expected, state: Callable[[Frame], dict[str, Any]],
                 apply: Callable[[Frame], T], action: str, actor: Optional[str], revert: Optional[Revert]) -> T:
    system_id = get_frame(session, frame_id).system_id
    return _write(session, system_id, lambda: claim_frame(session, frame_id, expected),
                  lambda: get_frame(session, frame_id), state, apply, action, actor, revert)


# ----- the states the audit log records (and a revert restores) -------------------------------------
def ball_state(frame: Frame) -> dict[str, Any]:
    """``{"ball": {"box", "point"}}``: the frame's current ball label (both None: no ball)."""
    label = frame.ball_label
    return {"ball": {"box": label.box if label else None, "point": label.point if label else None}}


def lines_state(frame: Frame) -> dict[str, Any]:
    """``{"lines": {class: [[[x, y], ...], ...]}}``: the frame's current field lines (px)."""
    return {"lines": frame.field_lines.lines if frame.field_lines is not None else {}}


def excluded_state(frame: Frame) -> dict[str, Any]:
    """``{"excluded": bool}``: the view is excluded from its system's triangulation."""
    return {"excluded": bool(frame.review is not None and frame.review.excluded)}


def review_state(subject: Frame | System) -> dict[str, Any]:
    """``{"review": {"status", "comment"}}`` of a frame or a system (pending without a decision)."""
    review = subject.review
    return {"review": {"status": review.status.value if review else ReviewStatus.PENDING.value,
                       "comment": review.comment if review else ""}}


def get_frame(session: Session, frame_id: int) -> Frame:
    """The frame with this id. Raises :class:`NotFoundError`."""
    return found(session.get(Frame, frame_id), "frame", frame_id)


def get_system(session: Session, system_id: int) -> System:
    """The system with this id. Raises :class:`NotFoundError`."""
    return found(session.get(System, system_id), "system", system_id)


def update_ball_label(session: Session, frame_id: int, box: Any = None, point: Any = None, *,
                      settings: Settings, actor: Optional[str] = None, expected: Expected = None,
                      revert: Optional[Revert] = None) -> Frame:
    """Set a frame's ball label to a box or a point, or remove it, then recompute its system.

    Args:
        frame_id: the frame.
        box: ``[x1, y1, x2, y2]`` pixels of the frame (may be partly outside the image).
        point: ``[x, y]`` pixels inside the image. Give at most one of ``box`` and ``point``; giving
            neither removes the label (the ball is not visible in this view).
        settings: admission and triangulation parameters.
        actor, expected, revert: attribution and guard (module docstring); audited as ``ball.edit``.

    Returns:
        The frame, with its ``ball_label`` and its system's derived rows updated and committed.

    Raises:
        NotFoundError: no such frame.
        InvalidInputError: both box and point, non-finite numbers, a degenerate box, a box entirely
            outside the image, a point outside it (field "box" or "point").
        StaleVersionError: the frame's version is not in ``expected``; nothing changed.
    """
    if box is not None and point is not None:
        raise InvalidInputError("give a box or a point, not both", field="box")
    frame = get_frame(session, frame_id)
    try:
        new_box = check_box(box, frame.width, frame.height) if box is not None else None
        new_point = check_point(point, frame.width, frame.height) if point is not None else None
    except LabelError as exc:
        raise InvalidInputError(str(exc), field="box" if box is not None else "point") from None

    def apply(frame: Frame) -> Frame:
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

    return _frame_write(session, frame_id, expected, ball_state, apply, "ball.edit", actor, revert)


def _recompute(session: Session, system: System, settings: Settings) -> None:
    """The system-level recomputation of an edit; for an ISSIA system also the re-fit of the stretch
    of its sequence's trajectory the edit touches, and the systems whose place on it changed
    (the kind's ``refit_after_edit``), in the same transaction."""
    if not kind_of(system).refit_after_edit(session, system, settings):  # an ISSIA system is recomputed after its re-fit
        session.flush()
        load_for_recompute(session, [system.id])  # what it reads, in a few queries (not one per relation and view)
        recompute_system(session, system, settings)


def _parse_lines(lines: Mapping[str, Any], width: int, height: int) -> dict[str, Any]:
    """Field lines as given -> validated JSON lists (px of a ``width`` x ``height`` frame); raises
    :class:`InvalidInputError` (field "lines") naming the class and polyline."""
    try:
        parsed = lines_to_json_lists(lines_from_json_lists(lines))
        check_line_points(parsed, width, height)
        return parsed
    except (AnnotationError, LabelError) as exc:
        raise InvalidInputError(str(exc), field="lines") from None


def _store_lines(session: Session, frame: Frame, parsed: dict[str, Any], settings: Settings) -> Frame:
    """Store ``parsed`` as the frame's current lines, recalibrate the frame and recompute its system."""
    fl = frame.field_lines
    if fl is None:
        frame.field_lines = FieldLineAnnotation(lines=parsed, original_lines={}, edited_at=utcnow())
    else:
        fl.lines = parsed
        fl.edited_at = utcnow()
    recompute_frame(session, frame, settings)
    kind_of(frame.system).refit_after_edit(session, frame.system, settings, recalibrated=frame)
    return frame


def replace_field_lines(session: Session, frame_id: int, lines: Mapping[str, Any], *, settings: Settings,
                        actor: Optional[str] = None, expected: Expected = None,
                        revert: Optional[Revert] = None) -> Frame:
    """Replace a frame's field lines, recalibrate the frame and recompute its system.

    Args:
        frame_id: the frame.
        lines: ``{class: [[[x, y], ...], ...]}`` in pixels of the frame (SoccerNet class names;
            repeated polylines of a class allowed). The imported original is kept.
        settings: admission and triangulation parameters.
        actor, expected, revert: attribution and guard (module docstring); audited as
            ``field_lines.replace``.

    Returns:
        The frame with its new lines, calibration (source "computed") and derived rows, committed.

    Raises:
        NotFoundError: no such frame.
        InvalidInputError: unknown class, malformed polyline, NaN or infinity, a point more than
            5 % of the image's size outside it (field "lines", the message names the class and polyline).
        StaleVersionError: the frame's version is not in ``expected``; nothing changed.
    """
    frame = get_frame(session, frame_id)
    parsed = _parse_lines(lines, frame.width, frame.height)
    return _frame_write(session, frame_id, expected, lines_state,
                        lambda frame: _store_lines(session, frame, parsed, settings),
                        "field_lines.replace", actor, revert)


def apply_mirrored_labels(session: Session, frame_id: int, *, settings: Settings, actor: Optional[str] = None,
                          expected: Expected = None) -> Frame:
    """Replace a frame's field lines by their mirrored labelling and recompute, in one transaction.

    The fix offered for a frame flagged ``probably_mirrored`` (``app.geometry.mirror``): every class
    is renamed by the pitch's 180-degree rotation (``app.geometry.annotations.mirror_lines``; the
    points stay where they are), then the frame is recalibrated and its system recomputed as by
    :func:`replace_field_lines`. The lines mirrored are those read under the write's lock. The imported
    original is kept, so the edit can be undone by applying it again. The reviewer decides; nothing
    mirrors labels without this call. Audited as ``field_lines.mirror``.

    Raises:
        NotFoundError: no such frame.
        InvalidInputError: the frame has no field lines (field "lines").
        StaleVersionError: the frame's version is not in ``expected``; nothing changed.
    """

    def apply(frame: Frame) -> Frame:
        if frame.field_lines is None or not frame.field_lines.lines:
            raise InvalidInputError(f"frame {frame_id} has no field lines to mirror", field="lines")
        mirrored = lines_to_json_lists(mirror_lines(lines_from_json_lists(frame.field_lines.lines)))
        return _store_lines(session, frame, mirrored, settings)

    get_frame(session, frame_id)
    return _frame_write(session, frame_id, expected, lines_state, apply, "field_lines.mirror", actor, None)


def decide_review(session: Session, *, system_id: int | None = None, frame_id: int | None = None,
                  status: ReviewStatus | str, comment: str = "", actor: Optional[str] = None,
                  expected: Expected = None, revert: Optional[Revert] = None) -> ReviewDecision:
    """Record a review decision on a system or on a frame (exactly one of the two ids).

    Args:
        status: pending, accepted, rejected or needs_fix (enum or its value).
        comment: free text (kept as given).
        actor, expected, revert: attribution and guard (module docstring; ``expected`` are versions of
            the system's review, or of the frame); audited as ``system.review`` or ``view.review``.

    Returns:
        The committed :class:`ReviewDecision` (``decided_at`` is now, UTC).

    Raises:
        InvalidInputError: both or neither id, or an unknown status.
        NotFoundError: no such system or frame.
        StaleVersionError: the version is not in ``expected``; nothing changed.
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

    def apply(subject: System | Frame) -> ReviewDecision:
        review = subject.review
        if review is None:
            review = ReviewDecision()
            subject.review = review
        review.status = status  # type: ignore[assignment]
        review.comment = comment
        review.decided_at = utcnow()
        if isinstance(subject, System):
            subject.review_status = status  # type: ignore[assignment]  # the queue's copy
        return review

    if system_id is not None:
        get_system(session, system_id)
        return _write(session, system_id, lambda: claim_system_review(session, system_id, expected),
                      lambda: get_system(session, system_id), review_state, apply, "system.review", actor, revert)
    get_frame(session, frame_id)  # type: ignore[arg-type]
    return _frame_write(session, frame_id, expected, review_state, apply, "view.review", actor, revert)  # type: ignore[arg-type]


def set_view_excluded(session: Session, frame_id: int, excluded: bool, *, settings: Settings,
                      actor: Optional[str] = None, expected: Expected = None,
                      revert: Optional[Revert] = None) -> Frame:
    """Exclude a view from its system's triangulation, or restore it, then recompute the system, in
    one transaction.

    The decision is stored on the view's review (``ReviewDecision.excluded``, created pending when the
    view has none) and is reversible: the view keeps its labels and calibration, is drawn and judged,
    but takes no part in the 3D ball. Its review status and comment are left as they are. Audited as
    ``view.exclusion`` (``actor``, ``expected``, ``revert``: module docstring).

    Raises:
        NotFoundError: no such frame.
        InvalidInputError: ``excluded`` is not a boolean (field "excluded").
        StaleVersionError: the frame's version is not in ``expected``; nothing changed.
    """
    if not isinstance(excluded, bool):
        raise InvalidInputError("excluded must be true or false", field="excluded")
    get_frame(session, frame_id)

    def apply(frame: Frame) -> Frame:
        review = frame.review
        if review is None:
            review = ReviewDecision(status=ReviewStatus.PENDING, comment="")
            frame.review = review
        review.excluded = excluded
        _recompute(session, frame.system, settings)
        return frame

    return _frame_write(session, frame_id, expected, excluded_state, apply, "view.exclusion", actor, revert)
