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

One rule for decisions after edits (issue 28): an edit that changes a system's labels or 3D result sets the
system's decision and the touched view's decision (its ball decision; its calibration decision for field lines)
back to pending with the reason, in the edit's transaction (:func:`reset_decisions_after_edit`); an edit that
changes nothing resets nothing. ``undo`` (:func:`check_undo_state`) marks a write as the undo of an audit entry
(``app.services.curation.reverting.undo_entry``): audited under the edit's own action with ``reverts_id``, refused
(409) when the edited part is not the entry's ``after`` under the lock; an undo resets decisions as any edit.

Every write is attributed and guarded, in its transaction: it first claims its resource
(``app.services.curation.versions``: compare-and-set of the frame's ``edit_version`` or the system's
``review_version`` against ``expected``, the versions of the client's ``If-Match``; None accepts any),
raising :class:`~app.core.errors.StaleVersionError` (with the resource's current rows and its
newest audit entry) when another write came first; then it applies the change, recomputes, and records
one audit entry (``app.services.accounts.audit``, by ``actor``, None meaning :func:`~app.services.accounts.audit.local_actor`)
with the edited part's state before and after. ``revert`` marks the write as the revert of an audit
entry (``app.services.curation.reverting``): it is recorded as action ``revert``, and refused with
:class:`~app.core.errors.ConflictError` when the state under the lock is not ``revert.expect``.

Concurrency (several server processes, issues 7 and 27): one locking design for every edit
(:func:`_write`). Nobody waits on another's geometry:

1. **Compute before the lock.** An edit that recomputes (``ball.edit``, ``field_lines.replace``,
   ``field_lines.mirror``, ``view.exclusion``) first runs its ``apply`` in a read snapshot
   (``app.db.session.begin_snapshot``: SQLite's deferred ``BEGIN`` under WAL, PostgreSQL ``REPEATABLE READ``; no
   lock, nothing flushed, :func:`_compute_before_lock`). Each recomputation it asks for (:func:`_recompute_planned`:
   the edited frame's calibration with its rig or prior retry, admission, mirror evidence, triangulation,
   reprojections, boxes, doubts, queue figures) is computed there, and the digest of every input it read
   (``recompute.recompute_inputs``: every view's ball label, field lines, exclusion and calibration of the
   system, its review status, the game's rig rows or learned camera prior) is kept with its results as plain
   values (``recompute.system_results``). The snapshot is rolled back; audit entries and decision resets made
   there are never written.
2. **Compare and write under the lock.** Then the write transaction begins (``begin_write``: SQLite's
   ``BEGIN IMMEDIATE``) and locks the edited system's row (:func:`lock_system`: ``SELECT ... FOR UPDATE`` on
   PostgreSQL, the game's row first for an ISSIA system) before it reads anything it changes; the objects loaded
   earlier are expired. Under the lock the edit claims its version (412), checks a revert (409), applies its
   change again and, at each recomputation, loads the system in a few queries and digests its inputs: equal to
   the digest computed from, the kept results are stored (``recompute.store_system_results``); different (another
   edit of the system, or of its game's rig, committed meanwhile), it is recomputed under the lock from what the
   other committed. The audit entry and the decision resets are written in the same transaction, as before.
   ``session.info[LAST_RECOMPUTATION]`` says which happened ("precomputed", "recomputed", "under_lock").

Two edits of one system's views therefore never lose each other's label: the later one finds the earlier one's
label under the lock and recomputes. Kinds whose edit re-fits beyond the system (ISSIA's trajectory:
``KindPolicy.computes_before_lock`` False) and writes that recompute nothing (review decisions) compute under the
lock as before. The lock is held only to compare and write, so waits are short: a served process waits at most
``V3D_WRITE_LOCK_TIMEOUT_S`` (SQLite busy timeout, PostgreSQL ``lock_timeout``) and the API answers 503 with
``Retry-After`` beyond it (``app.api.errors``).

Bounded work: a field-line edit gives a view at most ``V3D_MAX_LINE_POINTS_PER_FRAME`` points (2,000; 422 naming
``lines`` before any geometry); lines stored before the cap still calibrate, mirror and edit.
"""
from __future__ import annotations

import json
from collections.abc import Collection, Sequence
from dataclasses import dataclass, field
from typing import Any, Callable, Mapping, Optional, TypeVar

import numpy as np
from sqlalchemy import event, select
from sqlalchemy.orm import Session

from app.core.config import Settings
from app.db.models import (
    AuditEntry, BallKind, BallLabel, FieldLineAnnotation, Frame, Game, ReviewDecision, ReviewStatus, System,
)
from app.db.session import begin_snapshot, begin_write
from app.db.types import utcnow
from app.geometry.annotations import AnnotationError, lines_from_json_lists, lines_to_json_lists, mirror_lines
from app.datasets.labels import LabelError, check_box, check_line_point_count, check_line_points, check_point
from app.geometry.consensus import ball_consensus
from app.geometry.triangulation import REFERENCE_WIDTH_PX, BallObservation, reprojection_error_px
from app.services.accounts import audit
from app.services.accounts.summaries import summarize
from app.core.errors import ConflictError, InvalidInputError, NotFoundError, StaleVersionError, found
from app.services.kinds import kind_of, policy
from app.services.curation.recompute import (
    SystemResults, load_for_recompute, recompute_frame, recompute_inputs, recompute_system, store_system_results,
    system_results, system_rig_rows,
)
from app.services.calibration.calibrating import admission_jac, is_admitted
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


# ----- the one locking design of the edit path (module docstring, "Concurrency") ---------------------------
#: ``session.info`` key of the running edit's :class:`_Plan`.
_PLAN = "v3d.edit.plan"
#: ``session.info`` key: how the last edit's recomputation was stored: "precomputed" (computed before the lock,
#: its inputs unchanged under it), "recomputed" (an input changed meanwhile: computed again under the lock) or
#: "under_lock" (computed under the lock only: the kind re-fits beyond its system, or nothing was computed before).
LAST_RECOMPUTATION = "v3d.edit.recomputation"
#: The audited actions whose edits recompute their system, hence compute before the lock.
_RECOMPUTING = frozenset({"ball.edit", "field_lines.replace", "field_lines.mirror", "view.exclusion"})


@dataclass
class _Plan:
    """An edit's recomputations as computed before the write lock: per recomputation, in order, the digest of
    the inputs it read (``recompute.recompute_inputs``) and its results (``recompute.system_results``)."""

    capturing: bool = True
    entries: list[tuple[str, SystemResults]] = field(default_factory=list)
    used: int = 0
    recomputed: int = 0


class _NoWriteBeforeLock(Exception):
    """Raised by a flush while an edit computes before its lock: what follows the recomputation (audit entries,
    decision resets) is written under the lock only."""


@event.listens_for(Session, "before_flush")
def _no_flush_before_lock(session: Session, _context: Any, _instances: Any) -> None:
    plan = session.info.get(_PLAN)
    if plan is not None and plan.capturing:
        raise _NoWriteBeforeLock()


def computed_before_lock(system_id: int) -> None:
    """Called once an edit of system ``system_id`` has computed its recomputation, before it asks for the write
    lock (a hook: does nothing; the concurrency tests hold an edit here while another commits)."""


def _compute_before_lock(session: Session, system_id: int, subject: Callable[[], Any],
                         apply: Callable[[Any], Any]) -> Optional[_Plan]:
    """Run the edit's ``apply`` on ``subject()`` in a read snapshot (``begin_snapshot``: no lock, nothing
    flushed), keep what each of its recomputations read and found (:func:`_recompute_planned`), then roll the
    snapshot back. None when there is nothing to reuse: the system's kind re-fits beyond it
    (``KindPolicy.computes_before_lock``), the session holds unwritten changes of its caller, or nothing was
    computed. Whatever fails here is decided again under the lock (the same error, or none if the state changed)."""
    try:
        begin_snapshot(session)
    except RuntimeError:
        return None
    plan = _Plan()
    session.info[_PLAN] = plan
    try:
        with session.no_autoflush:
            if kind_of(get_system(session, system_id)).computes_before_lock:
                apply(subject())
    except Exception:  # noqa: BLE001  # _NoWriteBeforeLock once the recomputation is done; anything else: under the lock
        pass
    finally:
        session.info.pop(_PLAN, None)
        audit.recorded_entry_id(session)  # an entry apply added here is never written
        session.rollback()
    computed_before_lock(system_id)
    plan.capturing = False
    return plan if plan.entries else None


def _recompute_planned(session: Session, system: System, settings: Settings,
                       compute: Callable[[Optional[list[tuple[int, Any, bool]]]], Any]) -> None:
    """Run the recomputation ``compute`` of ``system`` within the running edit's plan: what it reads is loaded
    first (``load_for_recompute``, after a flush under the lock); before the lock it is computed and its inputs'
    digest and results kept; under the lock its results are stored when the inputs' digest is the one computed
    from (``store_system_results``), else it is computed again. Without a plan it is computed. ``compute(rig)`` takes
    the game's rig rows the digest read (``recompute.system_rig_rows``; None: not read), so it reads them once."""
    plan: Optional[_Plan] = session.info.get(_PLAN)
    if plan is None or not plan.capturing:
        session.flush()
    load_for_recompute(session, [system.id])  # what it reads, in a few queries (not one per relation and view)
    if plan is None or not kind_of(system).computes_before_lock:
        compute(None)
        return
    rig = system_rig_rows(session, system, settings)
    inputs = recompute_inputs(session, system, settings, rig)
    if plan.capturing:
        compute(rig)
        plan.entries.append((inputs, system_results(system)))
        return
    i, plan.used = plan.used, plan.used + 1
    if i < len(plan.entries) and plan.entries[i][0] == inputs:
        store_system_results(session, system, plan.entries[i][1])
    else:  # a view's label, lines, exclusion or calibration, or the game's rig, changed since: compute again
        plan.recomputed += 1
        compute(rig)


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
           actor: Optional[str], revert: Optional[Revert], undo_of: Optional[int] = None) -> T:
    """The guarded, audited write every edit goes through (module docstring), in one write transaction
    holding the lock of system ``system_id`` (:func:`_in_transaction`): ``claim`` (compare-and-set),
    ``state`` of ``subject()`` before, ``apply`` (change and recompute), ``state`` after, one audit entry
    (``undo_of``: the entry this edit undoes, recorded as its ``reverts_id`` under the edit's own action)."""

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
                     reverts_id=revert.entry_id if revert is not None else undo_of)
        return result

    plan = _compute_before_lock(session, system_id, subject, apply) if action in _RECOMPUTING else None
    if plan is not None:
        session.info[_PLAN] = plan
    try:
        result = _in_transaction(session, work, system_id=system_id)
    finally:
        session.info.pop(_PLAN, None)
    session.info[LAST_RECOMPUTATION] = ("under_lock" if plan is None or plan.used == 0
                                        else "recomputed" if plan.recomputed else "precomputed")
    return result


def _frame_write(session: Session, frame_id: int, expected: Expected, state: Callable[[Frame], dict[str, Any]],
                 apply: Callable[[Frame], T], action: str, actor: Optional[str], revert: Optional[Revert],
                 undo_of: Optional[int] = None) -> T:
    system_id = get_frame(session, frame_id).system_id
    return _write(session, system_id, lambda: claim_frame(session, frame_id, expected),
                  lambda: get_frame(session, frame_id), state, apply, action, actor, revert, undo_of)


# ----- the states the audit log records (and a revert restores) -------------------------------------
def ball_state(frame: Frame) -> dict[str, Any]:
    """``{"ball": {"box", "point"}}``: the frame's current ball label (both None: no ball), with its
    ``provenance`` when it was made from a suggestion and no person has placed it yet."""
    label = frame.ball_label
    state: dict[str, Any] = {"box": label.box if label else None, "point": label.point if label else None}
    if label is not None and label.suggested:
        state["provenance"] = label.provenance
    return {"ball": state}


def check_provenance(provenance: Any) -> dict[str, Any] | None:
    """A suggested label's provenance as stored: ``{"source": "suggestion", "doubt": str, "code": str | None,
    "from_views": [int]}``, or None. Raises :class:`InvalidInputError` (field ``provenance``) for another shape."""
    if provenance is None:
        return None
    if not isinstance(provenance, Mapping):
        raise InvalidInputError("provenance must be an object", field="provenance")
    doubt, code, views = provenance.get("doubt"), provenance.get("code"), provenance.get("from_views", [])
    if not isinstance(doubt, str) or not doubt or len(doubt) > 64:
        raise InvalidInputError("provenance.doubt must name the doubt kind the label was suggested by", field="provenance")
    if code is not None and (not isinstance(code, str) or len(code) > 64):
        raise InvalidInputError("provenance.code must be a short string", field="provenance")
    if not isinstance(views, list) or len(views) > 64 or not all(isinstance(v, int) and not isinstance(v, bool)
                                                                   for v in views):
        raise InvalidInputError("provenance.from_views must be a list of frame ids", field="provenance")
    return {"source": "suggestion", "doubt": doubt, "code": code, "from_views": list(views)}


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


def system_review_state(system: System) -> dict[str, Any]:
    """:func:`review_state` of a system, plus, when it is accepted over open label doubts (issue 28's accept
    guard), ``"overrode_doubts": [{"kind", "frame_id", "message"}]``: the doubts accusing a label that the
    accept stands over (whether the page's guard showed them or a script accepted), as the audit entry of
    the decision records them. A function of the stored state, so a revert's guard compares it as any other."""
    state = review_state(system)
    if state["review"]["status"] == ReviewStatus.ACCEPTED.value:
        open_doubts = [{"kind": d.kind, "frame_id": d.frame_id, "message": d.message}
                       for d in system.doubts if d.accuses_label]  # in id order
        if open_doubts:
            state["overrode_doubts"] = open_doubts
    return state


def calibration_review_state(frame: Frame) -> dict[str, Any]:
    """``{"calibration_review": {"status", "comment"}}``: the decision on a view's calibration (pending
    without one)."""
    review = frame.review
    return {"calibration_review": {
        "status": review.calibration_status.value if review else ReviewStatus.PENDING.value,
        "comment": review.calibration_comment if review else ""}}


def get_frame(session: Session, frame_id: int) -> Frame:
    """The frame with this id. Raises :class:`NotFoundError`."""
    return found(session.get(Frame, frame_id), "frame", frame_id)


def get_system(session: Session, system_id: int) -> System:
    """The system with this id. Raises :class:`NotFoundError`."""
    return found(session.get(System, system_id), "system", system_id)


def update_ball_label(session: Session, frame_id: int, box: Any = None, point: Any = None, *,
                      settings: Settings, provenance: Any = None, actor: Optional[str] = None,
                      expected: Expected = None, revert: Optional[Revert] = None,
                      undo: Optional[Revert] = None) -> Frame:
    """Set a frame's ball label to a box or a point, or remove it, then recompute its system.

    Args:
        frame_id: the frame.
        box: ``[x1, y1, x2, y2]`` pixels of the frame (may be partly outside the image).
        point: ``[x, y]`` pixels inside the image. Give at most one of ``box`` and ``point``; giving
            neither removes the label (the ball is not visible in this view).
        settings: admission and triangulation parameters.
        provenance: for a label made from a doubt's suggestion, where it came from
            (:func:`check_provenance`): stored on the label, which then joins no triangulation and no doubt
            vote until a person places it; None (a person placed it: drawn, moved or confirmed) clears it.
        actor, expected, revert: attribution and guard (module docstring); audited as ``ball.edit``.
        undo: this write undoes audit entry ``undo.entry_id`` (:func:`check_undo_state`; audited as
            ``ball.edit`` with ``reverts_id``).

    A label that changes sets the view's ball decision and the system's decision back to pending
    (:func:`reset_decisions_after_edit`).

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
    new_provenance = check_provenance(provenance) if (new_box is not None or new_point is not None) else None

    def apply(frame: Frame) -> Frame:
        before = ball_state(frame)
        check_undo_state(undo, before)
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
            label.provenance = new_provenance
            label.edited_at = utcnow()
        _recompute(session, frame.system, settings, actor)
        reset_after_change(session, frame, "ball.edit", before, ball_state(frame), actor, undo)
        return frame

    return _frame_write(session, frame_id, expected, ball_state, apply, "ball.edit", actor, revert,
                        undo.entry_id if undo is not None else None)


def _recompute(session: Session, system: System, settings: Settings, actor: Optional[str]) -> None:
    """The system-level recomputation of an edit by ``actor``; for an ISSIA system also the re-fit of the stretch
    of its sequence's trajectory the edit touches, and the systems whose place on it changed (the kind's
    ``refit_after_edit``), whose decisions go back to pending (:func:`reset_refitted_systems`), in the same
    transaction."""
    refitted = kind_of(system).refit_after_edit(session, system, settings)
    if not refitted:  # an ISSIA system is recomputed after its re-fit
        _recompute_planned(session, system, settings, lambda rig: recompute_system(
            session, system, settings, None if rig is None else [(fid, c) for fid, c, _ in rig]))
    reset_refitted_systems(session, system, refitted, actor)


def reset_refitted_systems(session: Session, edited: System, refitted: Sequence[System], actor: Optional[str]) -> int:
    """The one rule for decisions after edits (issue 28, item 3) for the systems an edit changed beside its own: an
    ISSIA edit re-fits its sequence's trajectory, which moves the 3D ball of neighbouring frames (``refitted``: the
    systems whose place on it changed); each of those, other than ``edited`` (whose decisions the edit itself
    resets), that was decided goes back to pending with the reason and its own ``system.review`` audit entry.

    Returns:
        How many systems were set back to pending.
    """
    who = actor or audit.local_actor()
    done = 0
    for other in refitted:
        decision = other.review
        if other.id == edited.id or decision is None or decision.status == ReviewStatus.PENDING:
            continue
        _system_back_to_pending(session, other, f"{other.name}: its 3D ball moved with the trajectory's re-fit after "
                                f"an edit of {edited.name} by {who}; decide it again", actor, utcnow())
        done += 1
    if done:
        session.flush()
    return done


def parse_field_lines(lines: Mapping[str, Any], width: int, height: int, max_points: int) -> dict[str, Any]:
    """Field lines as given -> validated JSON lists (px of a ``width`` x ``height`` frame, at most ``max_points``
    points in all: ``V3D_MAX_LINE_POINTS_PER_FRAME``); raises :class:`InvalidInputError` (field "lines") naming
    the class and polyline, or the count."""
    try:
        parsed = lines_to_json_lists(lines_from_json_lists(lines))
        check_line_point_count(parsed, max_points)
        check_line_points(parsed, width, height)
        return parsed
    except (AnnotationError, LabelError) as exc:
        raise InvalidInputError(str(exc), field="lines") from None


def _store_lines(session: Session, frame: Frame, parsed: dict[str, Any], settings: Settings,
                 actor: Optional[str]) -> Frame:
    """Store ``parsed`` as the frame's current lines, recalibrate the frame and recompute its system (an edit by
    ``actor``; the systems an ISSIA re-fit changed go back to pending: :func:`reset_refitted_systems`)."""
    fl = frame.field_lines
    if fl is None:
        frame.field_lines = FieldLineAnnotation(lines=parsed, original_lines={}, edited_at=utcnow())
    else:
        fl.lines = parsed
        fl.edited_at = utcnow()
    _recompute_planned(session, frame.system, settings, lambda rig: recompute_frame(session, frame, settings, rig))
    refitted = kind_of(frame.system).refit_after_edit(session, frame.system, settings, recalibrated=frame)
    reset_refitted_systems(session, frame.system, refitted, actor)
    return frame


def replace_field_lines(session: Session, frame_id: int, lines: Mapping[str, Any], *, settings: Settings,
                        actor: Optional[str] = None, expected: Expected = None,
                        revert: Optional[Revert] = None, undo_of: Optional[int] = None,
                        undo: Optional[Revert] = None) -> Frame:
    """Replace a frame's field lines, recalibrate the frame and recompute its system.

    Args:
        frame_id: the frame.
        lines: ``{class: [[[x, y], ...], ...]}`` in pixels of the frame (SoccerNet class names;
            repeated polylines of a class allowed). The imported original is kept.
        settings: admission and triangulation parameters.
        actor, expected, revert: attribution and guard (module docstring); audited as
            ``field_lines.replace``.
        undo_of: this write undoes audit entry ``undo_of`` (a page's undo, or the redo that undoes an
            undo): a field-line write of the same frame whose ``before`` lines are ``lines`` exactly
            (:func:`check_undo`). Audited as ``field_lines.replace`` with ``reverts_id = undo_of``. The
            calibration is computed from the lines alone, so the camera and JaC come back as they were
            when nothing else in the game changed meanwhile.
        undo: the same as ``undo_of = undo.entry_id``, and refused (409) unless the lines under the lock are
            ``undo.expect`` (:func:`check_undo_state`; the undo of ``POST /api/audit/{id}/undo``).

    Returns:
        The frame with its new lines, calibration (source "computed") and derived rows, committed.

    Raises:
        NotFoundError: no such frame.
        InvalidInputError: unknown class, malformed polyline, NaN or infinity, a point more than
            5 % of the image's size outside it (field "lines", the message names the class and polyline), more
            than ``settings.max_line_points_per_frame`` points in all (field "lines", before any geometry);
            an ``undo_of`` that is no field-line write of this frame with ``lines`` before it (field "undo_of").
        StaleVersionError: the frame's version is not in ``expected``; nothing changed.
    """
    frame = get_frame(session, frame_id)
    parsed = parse_field_lines(lines, frame.width, frame.height, settings.max_line_points_per_frame)
    if undo is not None:
        undo_of = undo.entry_id

    def apply(frame: Frame) -> Frame:
        before = lines_state(frame), calibration_words(frame, settings)
        check_undo_state(undo, before[0])
        jac_before = jac_words(frame, settings)
        _store_lines(session, frame, parsed, settings, actor)
        verb = "replaced" if undo_of is None else f"put back (undo of audit entry {undo_of})"
        reset_decisions_after_recalibration(session, frame, before, verb, actor, settings)
        audit.note_facts(session, calibration=(jac_before, jac_words(frame, settings)))
        return frame

    if undo_of is not None:
        check_undo(session, undo_of, frame_id, parsed)
    return _frame_write(session, frame_id, expected, lines_state, apply, "field_lines.replace", actor, revert,
                        undo_of)


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
    before the edit) and it was recalibrated, in the edit's transaction: a decided calibration decision of the view and a decided decision
    of its system go back to pending with the reason (``calibration_reset_reason``, ``reset_reason``), each
    with its own audit entry (``view.calibration_review``, ``system.review``: revertible) added before the
    edit's own, so the edit stays the frame's newest entry. The system's ``review_version`` is bumped (a page
    that drew the old decision gets 412 on deciding). Nothing changes when the lines did not.

    Returns:
        The reason (one sentence naming the view, the edit, who, and the calibration before and after), or
        None when nothing was reset.
    """
    lines_before, words_before = before
    if _same(lines_before, lines_state(frame)):
        return None
    who = actor or audit.local_actor()
    reason = (f"{frame.name}: field lines {verb} by {who}, the view was recalibrated "
              f"({words_before} -> {calibration_words(frame, settings)}); decide it again")
    return reason if reset_decisions_after_edit(session, frame, reason, actor, calibration=True) else None


def reset_after_change(session: Session, frame: Frame, action: str, before: dict[str, Any], after: dict[str, Any],
                       actor: Optional[str], undo: Optional[Revert] = None) -> Optional[str]:
    """After an edit of ``frame``'s ball label or exclusion (``action``, its state ``before`` and ``after``, as
    :func:`ball_state` / :func:`excluded_state` give them): when the state changed, the view's ball decision and
    the system's decision go back to pending (:func:`reset_decisions_after_edit`) with the reason, the edit in
    words (the audit log's, ``app.services.accounts.summaries.summarize``), who made it and, for an undo, which entry it undid.

    Returns:
        The reason, or None when the edit changed nothing or nothing was decided.
    """
    if _same(before, after):
        return None
    words = summarize(action, before, after, view=audit.view_name(frame))
    undone = f" (undo of audit entry {undo.entry_id})" if undo is not None else ""
    reason = f"{frame.name}: {words}{undone} by {actor or audit.local_actor()}; decide it again"
    return reason if reset_decisions_after_edit(session, frame, reason, actor, calibration=False) else None


def reset_decisions_after_edit(session: Session, frame: Frame, reason: str, actor: Optional[str], *,
                               calibration: bool) -> bool:
    """One rule for decisions after an edit that changed a system's labels or 3D result (issue 28, item 3), in
    the edit's transaction: the touched view's decision (its calibration decision when ``calibration``, i.e. a
    field-line edit; else its ball decision) and the system's decision, when decided, go back to pending with
    ``reason`` (``calibration_reset_reason`` / ``reset_reason``), each with its own audit entry
    (``view.calibration_review`` / ``view.review``, ``system.review``: revertible) added before the edit's own,
    so the edit stays the frame's newest entry. The system's ``review_version`` is bumped (a page that drew the
    old decision gets 412 on deciding).

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
        before = calibration_review_state(frame)
        review.calibration_status = ReviewStatus.PENDING  # type: ignore[assignment,union-attr]
        review.calibration_reset_reason = reason  # type: ignore[union-attr]
        review.calibration_decided_at = now  # type: ignore[union-attr]
        audit.record(session, actor=actor, action="view.calibration_review", frame=frame, before=before,
                     after=calibration_review_state(frame))
    elif view_decided:
        before = review_state(frame)
        review.status = ReviewStatus.PENDING  # type: ignore[assignment,union-attr]
        review.reset_reason = reason  # type: ignore[union-attr]
        review.decided_at = now  # type: ignore[union-attr]
        audit.record(session, actor=actor, action="view.review", frame=frame, before=before,
                     after=review_state(frame))
    if system_decided:
        _system_back_to_pending(session, system, reason, actor, now)
    session.flush()
    return True


def _system_back_to_pending(session: Session, system: System, reason: str, actor: Optional[str], now: Any) -> None:
    """Set ``system``'s decided decision back to pending with ``reason``, bump its ``review_version`` (a page that
    drew the old decision gets 412 on deciding) and record the change (``system.review``, revertible)."""
    before = review_state(system)
    decision = system.review
    decision.status = ReviewStatus.PENDING  # type: ignore[assignment,union-attr]
    decision.reset_reason = reason  # type: ignore[union-attr]
    decision.decided_at = now  # type: ignore[union-attr]
    system.review_status = ReviewStatus.PENDING  # type: ignore[assignment]  # the queue's copy
    system.review_version += 1
    audit.record(session, actor=actor, action="system.review", system=system, before=before,
                 after=review_state(system))


def check_undo_state(undo: Optional[Revert], state: dict[str, Any]) -> None:
    """An undo restores exactly only what nothing changed since: refuse it (:class:`ConflictError`, 409) when
    the edited part's state under the write's lock (``state``) is not the undone entry's ``after``
    (``undo.expect``). Nothing to check without an undo."""
    if undo is None or undo.expect is None or _same(state, undo.expect):
        return
    raise ConflictError(f"audit entry {undo.entry_id} cannot be undone: its resource changed since (it is now "
                        f"{json.dumps(state)[:300]}); undo the newer entries first", current=state)


def jac_words(frame: Frame, settings: Settings) -> str:
    """The frame's calibration for an entry's summary: "JaC 0.909" (at the admission's gamma,
    :func:`~app.services.calibration.calibrating.admission_jac`), or "refused" (no camera, or no JaC)."""
    cal = frame.calibration
    jac = admission_jac(cal, settings) if cal is not None and cal.camera is not None else None
    return f"JaC {jac:.3f}" if jac is not None else "refused"


def check_undo(session: Session, entry_id: int, frame_id: int, parsed: dict[str, Any]) -> None:
    """Check that writing the lines ``parsed`` (validated JSON lists, :func:`parse_field_lines`) to frame ``frame_id``
    undoes audit entry ``entry_id``: the entry is a write of that frame's field lines (a replacement, a
    mirroring, a revert or an undo of one) and its ``before`` lines are ``parsed`` (equal as JSON once read the
    same way: an imported ``100`` is ``100.0``). Entries never change, so this is read before the write's lock.

    Raises:
        InvalidInputError: field "undo_of", naming what does not match.
    """
    entry = session.get(AuditEntry, entry_id)
    if entry is None:
        raise InvalidInputError(f"undo_of: no audit entry {entry_id}", field="undo_of")
    if entry.frame_id != frame_id or not isinstance(entry.before, dict) or "lines" not in entry.before:
        raise InvalidInputError(f"undo_of: audit entry {entry_id} is no field-line write of frame {frame_id}",
                                field="undo_of")
    try:
        before = lines_to_json_lists(lines_from_json_lists(entry.before["lines"]))
    except AnnotationError:
        before = entry.before["lines"]
    if not _same(before, parsed):
        raise InvalidInputError(f"undo_of: the lines sent are not those before audit entry {entry_id}; an undo "
                                "writes back exactly the lines the entry replaced", field="undo_of")


def apply_mirrored_labels(session: Session, frame_id: int, *, settings: Settings, actor: Optional[str] = None,
                          expected: Expected = None) -> Frame:
    """Replace a frame's field lines by their mirrored labelling and recompute, in one transaction.

    The fix offered for a frame flagged ``probably_mirrored`` (``app.geometry.mirror``): every class
    is renamed by the pitch's 180-degree rotation (``app.geometry.annotations.mirror_lines``; the
    points stay where they are), then the frame is recalibrated and its system recomputed as by
    :func:`replace_field_lines`. The lines mirrored are those read under the write's lock. The imported
    original is kept, so the edit can be undone by applying it again. The reviewer decides; nothing
    mirrors labels without this call. Audited as ``field_lines.mirror``.

    The fix is applied only when the mirrored calibration and the ball agree better: when the frame has a
    ball label and the system's other views agree on a ball (:func:`ball_error_to_others`), the label must
    come closer to that ball with the mirrored camera than with the camera as labelled; otherwise nothing is
    stored and :class:`ConflictError` says by how much (a clean view's camera moved across the pitch, its 3D
    ball with it, was the harm this guards against).

    Raises:
        NotFoundError: no such frame.
        InvalidInputError: the frame has no field lines (field "lines").
        ConflictError: the mirrored calibration brings the ball label no closer to the other views' ball.
        StaleVersionError: the frame's version is not in ``expected``; nothing changed.
    """

    def apply(frame: Frame) -> Frame:
        if frame.field_lines is None or not frame.field_lines.lines:
            raise InvalidInputError(f"frame {frame_id} has no field lines to mirror", field="lines")
        before = ball_error_to_others(frame, settings)
        lines_before = lines_state(frame), calibration_words(frame, settings)
        jac_before = jac_words(frame, settings)
        mirrored = lines_to_json_lists(mirror_lines(lines_from_json_lists(frame.field_lines.lines)))
        out = _store_lines(session, frame, mirrored, settings, actor)
        after = ball_error_to_others(out, settings)
        if before is not None and before[0] is not None and (after is None or after[0] is None or after[0] >= before[0]):
            mi = "an unknown number of" if after is None or after[0] is None else f"{after[0]:.0f}"
            raise ConflictError(
                f"mirroring {frame.name}'s field lines was not applied: with the mirrored calibration its ball label "
                f"would be {mi} px (at 1920 width) from the ball {before[1]} agree on, against {before[0]:.0f} px as "
                "labelled, so the mirrored calibration and the ball do not agree better")
        reset_decisions_after_recalibration(session, out, lines_before, "mirrored", actor, settings)
        audit.note_facts(session, calibration=(jac_before, jac_words(out, settings)))
        return out

    get_frame(session, frame_id)
    return _frame_write(session, frame_id, expected, lines_state, apply, "field_lines.mirror", actor, None)


def ball_error_to_others(frame: Frame, settings: Settings) -> tuple[float | None, str] | None:
    """How far (px at 1920 width) ``frame``'s ball label lies from the ball the system's other views agree on
    (``app.geometry.consensus.ball_consensus`` of their admitted, included, person-placed labels, the doubt
    judge's tolerance), with the camera the frame has now, and those views' names; ``(None, names)`` when the
    frame has no camera or the ball projects behind it; None without a label or without an agreed ball."""
    from app.services.curation.doubts import doubt_settings, doubt_views  # the judge's adapter and tolerance
    s = doubt_settings(settings)
    views = doubt_views(frame.system)
    me = next((v for v in views if v.view_id == frame.id), None)
    if me is None or (me.box is None and me.point is None) or me.suggested:
        return None
    others = [v for v in views if v.view_id != frame.id and v.camera is not None and v.admitted and not v.excluded
              and not v.suggested and (v.box is not None or v.point is not None)]
    centre = lambda v: (np.asarray(v.box[:2]) + np.asarray(v.box[2:])) / 2 if v.box is not None else np.asarray(v.point)  # noqa: E731
    tau = max(s.consensus_tau_px, s.triangulation_tau_px)
    cons = ball_consensus([BallObservation(v.view_id, v.camera, centre(v), v.width) for v in others], tau_px=tau,
                          min_baseline_m=s.min_baseline_m, min_parallax_deg=s.min_parallax_deg)
    if cons.point is None or cons.ambiguous:
        return None
    names = ", ".join(v.name for v in others if v.view_id in cons.inliers)
    if me.camera is None:
        return None, names
    e = reprojection_error_px(me.camera, cons.point, centre(me))
    return (None if e is None else float(e) * REFERENCE_WIDTH_PX / me.width), names


def decide_review(session: Session, *, system_id: int | None = None, frame_id: int | None = None,
                  status: ReviewStatus | str, comment: str = "", actor: Optional[str] = None,
                  expected: Expected = None, revert: Optional[Revert] = None,
                  undo: Optional[Revert] = None) -> ReviewDecision:
    """Record a review decision on a system or on a frame (exactly one of the two ids).

    Args:
        status: pending, accepted, rejected or needs_fix (enum or its value).
        comment: free text (kept as given).
        actor, expected, revert: attribution and guard (module docstring; ``expected`` are versions of
            the system's review, or of the frame); audited as ``system.review`` or ``view.review``. An
            accept of a system records the label doubts open at that moment (:func:`system_review_state`).
        undo: this write undoes audit entry ``undo.entry_id`` (:func:`check_undo_state`).

    Returns:
        The committed :class:`ReviewDecision` (``decided_at`` is now, UTC).

    Raises:
        InvalidInputError: both or neither id, or an unknown status.
        NotFoundError: no such system or frame.
        StaleVersionError: the version is not in ``expected``; nothing changed.
    """
    if (system_id is None) == (frame_id is None):
        raise InvalidInputError("give exactly one of system_id and frame_id", field="system_id")
    status = _check_decision(status, comment)

    def apply(subject: System | Frame) -> ReviewDecision:
        check_undo_state(undo, review_state(subject))
        review = subject.review
        if review is None:
            review = ReviewDecision()
            subject.review = review
        review.status = status  # type: ignore[assignment]
        review.comment = comment
        review.decided_at = utcnow()
        review.reset_reason = None
        if isinstance(subject, System):
            subject.review_status = status  # type: ignore[assignment]  # the queue's copy
        return review

    if system_id is not None:
        get_system(session, system_id)
        return _write(session, system_id, lambda: claim_system_review(session, system_id, expected),
                      lambda: get_system(session, system_id), system_review_state, apply, "system.review", actor,
                      revert, undo.entry_id if undo is not None else None)
    get_frame(session, frame_id)  # type: ignore[arg-type]
    return _frame_write(session, frame_id, expected, review_state, apply, "view.review", actor, revert,  # type: ignore[arg-type]
                        undo.entry_id if undo is not None else None)


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
                       revert: Optional[Revert] = None, undo: Optional[Revert] = None) -> ReviewDecision:
    """Record the reviewer's decision on a view's calibration (its field lines and the camera fitted to
    them), beside the decision on its ball (:func:`decide_review`). Clears ``calibration_reset_reason``.
    Audited as ``view.calibration_review`` (``actor``, ``expected``: versions of the frame, ``revert``:
    module docstring; ``undo``: :func:`check_undo_state`). An edit of the view's field lines sets a decided calibration back to pending
    (:func:`reset_decisions_after_recalibration`).

    Returns:
        The committed :class:`ReviewDecision` of the frame (created with a pending ball decision when the
        view had none).

    Raises:
        InvalidInputError: an unknown status (field "status"), a comment that is not text.
        NotFoundError: no such frame.
        StaleVersionError: the frame's version is not in ``expected``; nothing changed.
    """
    status = _check_decision(status, comment)

    def apply(frame: Frame) -> ReviewDecision:
        check_undo_state(undo, calibration_review_state(frame))
        review = frame.review
        if review is None:
            review = ReviewDecision(status=ReviewStatus.PENDING, comment="")
            frame.review = review
        review.calibration_status = status  # type: ignore[assignment]
        review.calibration_comment = comment
        review.calibration_decided_at = utcnow()
        review.calibration_reset_reason = None
        return review

    get_frame(session, frame_id)
    return _frame_write(session, frame_id, expected, calibration_review_state, apply, "view.calibration_review",
                        actor, revert, undo.entry_id if undo is not None else None)


def set_view_excluded(session: Session, frame_id: int, excluded: bool, *, settings: Settings,
                      actor: Optional[str] = None, expected: Expected = None,
                      revert: Optional[Revert] = None, undo: Optional[Revert] = None) -> Frame:
    """Exclude a view from its system's triangulation, or restore it, then recompute the system, in
    one transaction.

    The decision is stored on the view's review (``ReviewDecision.excluded``, created pending when the
    view has none) and is reversible: the view keeps its labels and calibration, is drawn and judged,
    but takes no part in the 3D ball. Its review status and comment are left as they are. Audited as
    ``view.exclusion`` (``actor``, ``expected``, ``revert``: module docstring; ``undo``:
    :func:`check_undo_state`). A change sets the view's ball decision and the system's decision back to
    pending (:func:`reset_decisions_after_edit`).

    Raises:
        NotFoundError: no such frame.
        InvalidInputError: ``excluded`` is not a boolean (field "excluded").
        StaleVersionError: the frame's version is not in ``expected``; nothing changed.
    """
    if not isinstance(excluded, bool):
        raise InvalidInputError("excluded must be true or false", field="excluded")
    get_frame(session, frame_id)

    def apply(frame: Frame) -> Frame:
        before = excluded_state(frame)
        check_undo_state(undo, before)
        review = frame.review
        if review is None:
            review = ReviewDecision(status=ReviewStatus.PENDING, comment="")
            frame.review = review
        review.excluded = excluded
        _recompute(session, frame.system, settings, actor)
        reset_after_change(session, frame, "view.exclusion", before, excluded_state(frame), actor, undo)
        return frame

    return _frame_write(session, frame_id, expected, excluded_state, apply, "view.exclusion", actor, revert,
                        undo.entry_id if undo is not None else None)
