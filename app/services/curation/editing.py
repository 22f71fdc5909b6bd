"""Reviewer edits: ball labels, field lines, a view's exclusion (the decisions are ``decisions``).

Every edit and the recomputation it implies (``app.services.derivation.recompute``) happen in one transaction:
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

Every system-level recomputation also replaces the system's doubts (``app.services.derivation.doubts``).

Each goes through the guarded, audited write of ``app.services.curation.writing`` (read, compute holding no
connection, compare the versions and write under the lock), carrying an
:class:`~app.services.curation.writing.EditContext` (``edit``: the route's, else one of its own), and resets
decisions by the one rule of ``app.services.curation.resets``; an undo or revert that brings the system's labels
back to those its decisions were made on gives those decisions back by the same module.

Bounded work: a field-line edit gives a view at most ``V3D_MAX_LINE_POINTS_PER_FRAME`` points (2,000; 422 naming
``lines`` before any geometry); lines stored before the cap still calibrate, mirror and edit.
"""
from __future__ import annotations

import dataclasses
from typing import Any, Mapping, Optional

import numpy as np
from sqlalchemy.orm import Session

from app.core.config import Settings
from app.core.errors import ConflictError, InvalidInputError
from app.datasets.labels import LabelError, check_box, check_line_point_count, check_line_points, check_point
from app.datasets.records import CalibrationFields
from app.db.models import (
    AuditEntry,
    BallKind,
    BallLabel,
    CalibrationSource,
    CalibrationStatus,
    FieldLineAnnotation,
    Frame,
    ReviewDecision,
    ReviewStatus,
    System,
)
from app.db.types import utcnow
from app.geometry.annotations import AnnotationError, lines_from_json_lists, lines_to_json_lists, mirror_lines
from app.geometry.calibration.result import PLAYERS_FLAG
from app.geometry.camera import Camera
from app.geometry.mirror import mirror_camera
from app.services.calibration.calibrating import apply_calibration
from app.services.calibration.players import players_mirror_evidence
from app.services.curation.resets import (
    calibration_words,
    jac_words,
    reset_after_change,
    reset_decisions_after_recalibration,
    reset_refitted_systems,
    restore_decisions,
)
from app.services.curation.states import (
    ball_state,
    excluded_state,
    lines_state,
    same_json,
    system_import_state,
)
from app.services.curation.writing import (
    EditContext,
    EditPlan,
    Expected,
    Revert,
    check_undo_state,
    frame_facts,
    guarded_frame_write,
    guarded_write,
)
from app.services.derivation.doubts import distance_to_others, doubt_settings, doubt_views
from app.services.derivation.recompute import (
    recompute_frame,
    recompute_system,
)
from app.services.derivation.rows import put_values
from app.services.kinds import kind_of


def check_provenance(provenance: Any) -> dict[str, Any] | None:
    """A suggested label's provenance as stored: ``{"source": "suggestion", "doubt": str, "code": str | None,
    "from_views": [int]}`` (with ``"detector": str, "score": float`` for a detector's box), or None. Raises
    :class:`InvalidInputError` (field ``provenance``) for another shape."""
    if provenance is None:
        return None
    if not isinstance(provenance, Mapping):
        raise InvalidInputError("provenance must be an object", field="provenance")
    doubt, code, views = provenance.get("doubt"), provenance.get("code"), provenance.get("from_views", [])
    if not isinstance(doubt, str) or not doubt or len(doubt) > 64:
        raise InvalidInputError("provenance.doubt must name the doubt kind the label was suggested by",
                                field="provenance")
    if code is not None and (not isinstance(code, str) or len(code) > 64):
        raise InvalidInputError("provenance.code must be a short string", field="provenance")
    if not isinstance(views, list) or len(views) > 64 or not all(isinstance(v, int) and not isinstance(v, bool)
                                                                   for v in views):
        raise InvalidInputError("provenance.from_views must be a list of frame ids", field="provenance")
    out: dict[str, Any] = {"source": "suggestion", "doubt": doubt, "code": code, "from_views": list(views)}
    detector, score = provenance.get("detector"), provenance.get("score")
    if detector is not None:  # a detector's box: which detector and its score stay with the placement
        if not isinstance(detector, str) or not detector or len(detector) > 100:
            raise InvalidInputError("provenance.detector must name the detector", field="provenance")
        if isinstance(score, bool) or not isinstance(score, (int, float)) or not 0.0 <= float(score) <= 1.0:
            raise InvalidInputError("provenance.score must be the detector's score in [0, 1]", field="provenance")
        out.update(detector=detector, score=float(score))
    return out


def update_ball_label(session: Session, frame_id: int, box: Any = None, point: Any = None, *,
                      settings: Settings, provenance: Any = None, actor: Optional[str] = None,
                      expected: Expected = None, revert: Optional[Revert] = None,
                      undo: Optional[Revert] = None, edit: Optional[EditContext] = None) -> Frame:
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
        edit: the edit's context (``writing.EditContext``), filled with its audit entry's id.

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
    edit = edit if edit is not None else EditContext()
    facts = frame_facts(session, frame_id)

    def validated(width: int, height: int) -> tuple[Any, Any]:
        try:
            return (check_box(box, width, height) if box is not None else None,
                    check_point(point, width, height) if point is not None else None)
        except LabelError as exc:
            raise InvalidInputError(str(exc), field="box" if box is not None else "point") from None

    new_box, new_point = validated(facts.width, facts.height)
    new_provenance = check_provenance(provenance) if (new_box is not None or new_point is not None) else None

    def apply(frame: Frame) -> Frame:
        nonlocal new_box, new_point
        if (frame.width, frame.height) != (facts.width, facts.height):  # re-imported since its facts were read
            new_box, new_point = validated(frame.width, frame.height)
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
            put_values(label, {"kind": kind, "box": new_box, "point": new_point, "provenance": new_provenance,
                               "edited_at": utcnow()})
            if (undo is None and revert is None and label.original_kind is not None and not label.edited
                    and before["ball"] != ball_state(frame)["ball"]):
                edit.facts["ball"] = "imported"  # back to the dataset's own label (the page's z), said as such
        _recompute(session, frame.system, settings, actor, edit)
        reset_after_change(session, frame, "ball.edit", before, ball_state(frame), actor, undo)
        restore_decisions(frame, undo or revert, actor, edit)
        return frame

    plan = EditPlan("ball.edit", ball_state, apply, actor, frame_id, expected, revert,
                    undo.entry_id if undo is not None else None, recompute=True, settings=settings)
    return guarded_frame_write(session, plan, system_id=facts.system_id, edit=edit)


def _recompute(session: Session, system: System, settings: Settings, actor: Optional[str],
               edit: EditContext) -> None:
    """The system-level recomputation of an edit by ``actor`` (from the rig rows it read, ``edit.rig``); for an
    ISSIA system also the re-fit of the stretch of its sequence's trajectory the edit touches, and the systems whose
    place on it changed (the kind's ``refit_after_edit``), whose decisions go back to pending
    (:func:`reset_refitted_systems`), in the same transaction."""
    refitted = kind_of(system).refit_after_edit(session, system, settings)
    if not refitted:  # an ISSIA system is recomputed after its re-fit
        recompute_system(session, system, settings, _rig_sources(edit))
    reset_refitted_systems(session, system, refitted, actor)


def _rig_sources(edit: EditContext) -> Optional[list[tuple[int, np.ndarray]]]:
    """``(frame id, camera centre)`` of the rig rows the edit read (``recompute_system``'s ``rig_sources``), None when
    its kind reads none."""
    return None if edit.rig is None else [(fid, c) for fid, c, _ in edit.rig]


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
                 actor: Optional[str], edit: EditContext, players: bool = False) -> Frame:
    """Store ``parsed`` as the frame's current lines, recalibrate the frame (``players``: and place it by its players
    where they place it, ``recompute_frame``) and recompute its system (an edit by ``actor``; the systems an ISSIA
    re-fit changed go back to pending: :func:`reset_refitted_systems`)."""
    fl = frame.field_lines
    if fl is None:
        frame.field_lines = FieldLineAnnotation(lines=parsed, original_lines={}, edited_at=utcnow())
    else:
        fl.lines = parsed
        fl.edited_at = utcnow()
    recompute_frame(session, frame, settings, edit.rig, players=players)
    refitted = kind_of(frame.system).refit_after_edit(session, frame.system, settings, recalibrated=frame)
    reset_refitted_systems(session, frame.system, refitted, actor)
    return frame


def replace_field_lines(session: Session, frame_id: int, lines: Mapping[str, Any], *, settings: Settings,
                        actor: Optional[str] = None, expected: Expected = None,
                        revert: Optional[Revert] = None, undo_of: Optional[int] = None,
                        undo: Optional[Revert] = None, edit: Optional[EditContext] = None) -> Frame:
    """Replace a frame's field lines, recalibrate the frame and recompute its system. A view the players placed is
    placed by them again where they place it with its new lines (``players.place_frame_by_players``, as the import
    did), so that an undo of the mirror fix, or of any line edit of such a view, gives its camera back.

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
            calibration is computed from the lines (and the players, above), so the camera and JaC come back as
            they were when nothing else in the game changed meanwhile.
        undo: the same as ``undo_of = undo.entry_id``, and refused (409) unless the lines under the lock are
            ``undo.expect`` (:func:`check_undo_state`; the undo of ``POST /api/audit/{id}/undo``).
        edit: the edit's context (``writing.EditContext``), filled with its audit entry's id.

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
    edit = edit if edit is not None else EditContext()
    facts = frame_facts(session, frame_id)
    parsed = parse_field_lines(lines, facts.width, facts.height, settings.max_line_points_per_frame)
    if undo is not None:
        undo_of = undo.entry_id

    def apply(frame: Frame) -> Frame:
        nonlocal parsed
        if (frame.width, frame.height) != (facts.width, facts.height):  # re-imported since its facts were read
            parsed = parse_field_lines(lines, frame.width, frame.height, settings.max_line_points_per_frame)
        before = lines_state(frame), calibration_words(frame, settings)
        check_undo_state(undo, before[0])
        jac_before = jac_words(frame, settings)
        placed = frame.calibration is not None and PLAYERS_FLAG in (frame.calibration.flags or [])
        _store_lines(session, frame, parsed, settings, actor, edit, players=placed)
        verb = "replaced" if undo_of is None else f"put back (undo of audit entry {undo_of})"
        reset_decisions_after_recalibration(session, frame, before, verb, actor, settings)
        restore_decisions(frame, undo or revert, actor, edit)
        edit.facts["calibration"] = (jac_before, jac_words(frame, settings))
        return frame

    if undo_of is not None:
        check_undo(session, undo_of, frame_id, parsed)
    plan = EditPlan("field_lines.replace", lines_state, apply, actor, frame_id, expected, revert, undo_of,
                    recompute=True, settings=settings, players=True)
    return guarded_frame_write(session, plan, system_id=facts.system_id, edit=edit)


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
    if not same_json(before, parsed):
        raise InvalidInputError(f"undo_of: the lines sent are not those before audit entry {entry_id}; an undo "
                                "writes back exactly the lines the entry replaced", field="undo_of")


def apply_mirrored_labels(session: Session, frame_id: int, *, settings: Settings, actor: Optional[str] = None,
                          expected: Expected = None, edit: Optional[EditContext] = None) -> Frame:
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

    A view the players placed is placed by them again after its lines are mirrored (as the import placed it,
    ``players.place_frame_by_players``): their camera does not depend on how its lines are named, so the fix keeps
    it where the players put it and the mirrored labels now meet it; the camera "as labelled" the guard compares is
    then the one the labels give (:func:`labels_camera`).

    Raises:
        NotFoundError: no such frame.
        InvalidInputError: the frame has no field lines (field "lines").
        ConflictError: the mirrored calibration brings the ball label no closer to the other views' ball.
        StaleVersionError: the frame's version is not in ``expected``; nothing changed.
    """
    context = edit if edit is not None else EditContext()

    def apply(frame: Frame) -> Frame:
        if frame.field_lines is None or not frame.field_lines.lines:
            raise InvalidInputError(f"frame {frame_id} has no field lines to mirror", field="lines")
        before = ball_error_to_others(frame, settings)
        lines_before = lines_state(frame), calibration_words(frame, settings)
        jac_before = jac_words(frame, settings)
        mirrored = lines_to_json_lists(mirror_lines(lines_from_json_lists(frame.field_lines.lines)))
        placed = frame.calibration is not None and PLAYERS_FLAG in (frame.calibration.flags or [])
        out = _store_lines(session, frame, mirrored, settings, actor, context, players=placed)
        after = ball_error_to_others(out, settings)
        if (before is not None and before[0] is not None
                and (after is None or after[0] is None or after[0] >= before[0])):
            mi = "an unknown number of" if after is None or after[0] is None else f"{after[0]:.0f}"
            raise ConflictError(
                f"mirroring {frame.name}'s field lines was not applied: with the mirrored calibration its ball label "
                f"would be {mi} px (at 1920 width) from the ball {before[1]} agree on, against {before[0]:.0f} px as "
                "labelled, so the mirrored calibration and the ball do not agree better")
        reset_decisions_after_recalibration(session, out, lines_before, "mirrored", actor, settings)
        context.facts["calibration"] = (jac_before, jac_words(out, settings))
        return out

    facts = frame_facts(session, frame_id)
    plan = EditPlan("field_lines.mirror", lines_state, apply, actor, frame_id, expected, recompute=True,
                    settings=settings, players=True)
    return guarded_frame_write(session, plan, system_id=facts.system_id, edit=context)


def ball_error_to_others(frame: Frame, settings: Settings) -> tuple[float | None, str] | None:
    """How far (px at 1920 width) ``frame``'s ball label lies from the ball the system's other views agree on, as the
    doubt judge finds it (``app.geometry.doubts.judge.consensus_without``: its voters, weights, pixel tolerances and
    play volume, with this view left out), with the camera its labels give now (:func:`labels_camera`), and those
    views' names; ``(None, names)`` when the frame has no camera or the ball projects behind it; None without a
    label or without an agreed ball."""
    views = doubt_views(frame.system)
    me = next((v for v in views if v.view_id == frame.id), None)
    if me is None:
        return None
    if me.camera is not None:
        me = dataclasses.replace(me, camera=labels_camera(frame, me.camera))
    cons, distance = distance_to_others(views, me, doubt_settings(settings))
    if cons is None:
        return None
    return distance, ", ".join(v.name for v in views if v.view_id in cons.inliers)


def labels_camera(frame: Frame, camera: Camera) -> Camera:
    """The camera ``frame``'s labels as they are give: its ``camera``, or that camera's mirror image
    (``app.geometry.mirror.mirror_camera``) when the players placed it and its lines fit it only mirrored
    (``players.players_mirror_evidence``)."""
    cal = frame.calibration
    if cal is not None and PLAYERS_FLAG in (cal.flags or []) and players_mirror_evidence(cal.players, cal.camera):
        return mirror_camera(camera)
    return camera


def set_view_excluded(session: Session, frame_id: int, excluded: bool, *, settings: Settings,
                      actor: Optional[str] = None, expected: Expected = None,
                      revert: Optional[Revert] = None, undo: Optional[Revert] = None,
                      edit: Optional[EditContext] = None) -> Frame:
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
    edit = edit if edit is not None else EditContext()
    facts = frame_facts(session, frame_id)

    def apply(frame: Frame) -> Frame:
        before = excluded_state(frame)
        check_undo_state(undo, before)
        review = frame.review
        if review is None:
            review = ReviewDecision(status=ReviewStatus.PENDING, comment="")
            frame.review = review
        review.excluded = excluded
        _recompute(session, frame.system, settings, actor, edit)
        reset_after_change(session, frame, "view.exclusion", before, excluded_state(frame), actor, undo)
        restore_decisions(frame, undo or revert, actor, edit)
        return frame

    plan = EditPlan("view.exclusion", excluded_state, apply, actor, frame_id, expected, revert,
                    undo.entry_id if undo is not None else None, recompute=True, settings=settings)
    return guarded_frame_write(session, plan, system_id=facts.system_id, edit=edit)


def restore_imported_system(session: Session, system_id: int, state: Mapping[str, Any], *, settings: Settings,
                            actor: Optional[str] = None, revert: Optional[Revert] = None,
                            undo: Optional[Revert] = None, edit: Optional[EditContext] = None) -> System:
    """Give system ``system_id`` back a state an import's merge recorded (``state``:
    :func:`~app.services.curation.states.system_import_state`, the ``before`` of a ``system.import`` entry): each
    view's ball label, current field lines, calibration (as stored, source included) and decisions, and the system's
    decision; then recompute the system (an ISSIA system re-fits its trajectory around it). Views the state does not
    name (added since) are left as they are. A guarded write of the system, audited as ``system.import`` (``revert``:
    as ``revert``; ``undo``: with ``reverts_id``, refused when the system is no longer the entry's ``after``).

    Raises:
        NotFoundError: no such system.
        ConflictError: a revert or undo of a system changed since (not forced).
    """
    edit = edit if edit is not None else EditContext()
    system_state = state["system"]

    def apply(system: System) -> System:
        check_undo_state(undo, system_import_state(system))
        now = utcnow()
        views = {f.id: f for f in system.frames}
        for view in system_state["views"]:
            frame = views.get(view["frame_id"])
            if frame is not None:
                _restore_view(frame, view, now)
        _restore_review(system, "review", system_state["review"], now)
        _recompute(session, system, settings, actor, edit)
        return system

    plan = EditPlan("system.import", system_import_state, apply, actor, revert=revert,
                    undo_of=undo.entry_id if undo is not None else None, recompute=True, settings=settings)
    return guarded_write(session, system_id, plan, edit=edit)


def _restore_view(frame: Frame, view: Mapping[str, Any], now: Any) -> None:
    """Put one view of a :func:`system_import_state` back: its ball label, lines, calibration and decisions."""
    ball = view["ball"]
    kind = BallKind.BOX if ball["box"] is not None else BallKind.POINT if ball["point"] is not None else None
    label = frame.ball_label
    if label is not None or kind is not None:
        label = label if label is not None else BallLabel()
        frame.ball_label = label
        put_values(label, {"kind": kind, "box": ball["box"], "point": ball["point"],
                           "provenance": ball.get("provenance")})
        label.edited_at = now if label.edited else None
    if frame.field_lines is not None and frame.field_lines.lines != view["lines"]:
        frame.field_lines.lines = view["lines"]
        frame.field_lines.edited_at = now if frame.field_lines.edited else None
    cal = view["calibration"]
    if cal is not None:
        apply_calibration(frame, CalibrationFields(
            CalibrationStatus(cal["status"]), cal["camera"], (cal["jac"][0], cal["jac"][1], cal["jac"][2]),
            residuals_px=cal["residuals_px"], flags=list(cal["flags"]), reason=cal["reason"],
            uncertainty=cal["uncertainty"], players=cal.get("players")), CalibrationSource(cal["source"]))
    _restore_review(frame, "review", view["review"], now)
    _restore_review(frame, "calibration_review", view["calibration_review"], now)


def _restore_review(subject: Frame | System, key: str, decision: Mapping[str, Any], now: Any) -> None:
    """Give ``subject`` back a recorded decision (``key`` "review" or "calibration_review" of its states), unless it
    is already that one."""
    review = subject.review
    status = ReviewStatus(decision["status"])
    if key == "calibration_review":
        if review is None or (review.calibration_status, review.calibration_comment) != (status, decision["comment"]):
            review = review if review is not None else ReviewDecision(status=ReviewStatus.PENDING, comment="")
            subject.review = review
            review.calibration_status, review.calibration_comment = status, decision["comment"]
            review.calibration_reset_reason, review.calibration_decided_at = None, now
    elif review is None or (review.status, review.comment) != (status, decision["comment"]):
        review = review if review is not None else ReviewDecision(status=ReviewStatus.PENDING, comment="")
        subject.review = review
        review.status, review.comment, review.reset_reason, review.decided_at = status, decision["comment"], None, now
