"""The states the audit log records for each edited part, and a revert or an undo restores and compares:
the ball label, the field lines, the exclusion, the review decisions, and what an import may change of a whole
system (plain JSON-ready dicts).
"""
from __future__ import annotations

import json
from typing import Any

from app.db.models import (
    Frame,
    ReviewStatus,
    System,
)
from app.geometry.calibration.result import MIRROR_FLAG


def same_json(a: Any, b: Any) -> bool:
    """Equal as JSON (tuples and lists alike, as stored)."""
    return json.dumps(a, sort_keys=True) == json.dumps(b, sort_keys=True)


# ----- the states the audit log records (and a revert restores) -------------------------------------
def ball_state(frame: Frame) -> dict[str, Any]:
    """``{"ball": {"box", "point"}}``: the frame's current ball label (both None: no ball), with its
    ``provenance`` when it was made from a suggestion and no person has placed it yet."""
    label = frame.ball_label
    state: dict[str, Any] = {"box": label.box if label else None, "point": label.point if label else None}
    if label is not None and label.suggested:
        state["provenance"] = label.provenance
    return {"ball": state}


def lines_state(frame: Frame) -> dict[str, Any]:
    """``{"lines": {class: [[[x, y], ...], ...]}}``: the frame's current field lines (px)."""
    return {"lines": frame.field_lines.lines if frame.field_lines is not None else {}}


def excluded_state(frame: Frame) -> dict[str, Any]:
    """``{"excluded": bool}``: the view is excluded from its system's triangulation."""
    return {"excluded": bool(frame.review is not None and frame.review.excluded)}


def review_state(subject: Frame | System) -> dict[str, Any]:
    """``{"review": {"status", "comment"}}`` of a frame or a system (pending without a decision), and ``batch_id``
    for a system a batch accepted after a sample (``app.services.curation.batches``; absent for a person's
    decision)."""
    review = subject.review
    state: dict[str, Any] = {"status": review.status.value if review else ReviewStatus.PENDING.value,
             "comment": review.comment if review else ""}
    if review is not None and review.batch_id is not None:
        state["batch_id"] = review.batch_id
    return {"review": state}


def system_review_state(system: System) -> dict[str, Any]:
    """:func:`review_state` of a system, plus, when it is accepted over open label doubts (the accept
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


def calibration_state(frame: Frame) -> dict[str, Any] | None:
    """The frame's stored calibration as its import or a recalibration left it (None without one): ``source``,
    ``status``, ``camera`` (SoccerNet JSON), ``jac`` (the three gammas), ``residuals_px``, ``flags``, ``reason``,
    ``uncertainty`` (and ``players`` for a camera the players placed); without what every recomputation derives
    again (admission, the mirror flag and its evidence)."""
    cal = frame.calibration
    if cal is None:
        return None
    return {"source": cal.source.value, "status": cal.status.value, "camera": cal.camera,
            "jac": [cal.jac_0005, cal.jac_001, cal.jac_002], "residuals_px": cal.residuals_px,
            "flags": [f for f in (cal.flags or []) if f != MIRROR_FLAG], "reason": cal.reason,
            "uncertainty": cal.uncertainty, **({"players": cal.players} if cal.players is not None else {})}


def system_import_state(system: System) -> dict[str, Any]:
    """``{"system": {"review", "views"}}``: what an import may change of a stored system (its entry of action
    ``system.import``): its decision (:func:`review_state`) and, per view in page order, ``frame_id``, ``ball``,
    ``lines``, ``calibration`` (:func:`calibration_state`), ``review`` and ``calibration_review``."""
    views = [{"frame_id": f.id, **ball_state(f), **lines_state(f), "calibration": calibration_state(f),
              **review_state(f), **calibration_review_state(f)} for f in system.frames]
    return {"system": {**review_state(system), "views": views}}
