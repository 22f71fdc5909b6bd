"""Doubts: the label problems the geometry of one multi-view system can see, each with its evidence
and, where there is one, its fix.

A system's doubts are recomputed with every edit (``app.services.recompute``) and stored; this module
is pure (numpy / OpenCV, no database, no settings object). Kinds that accuse labels
(:data:`LABEL_KINDS`):

* ``mirrored_labels``: the view's field lines are labelled left for right (the verdict of
  ``app.geometry.mirror.mirror_evidence``, passed in through :class:`DoubtView`);
* ``ball_off_consensus``: the view's ball label disagrees with the ball the other views agree on;
* ``ball_missing``: a calibrated view without a ball label in which the ball of the other views
  reprojects inside the image;
* ``views_disagree``: the labelled views cannot all be right and the culprit cannot be told;
* ``near_duplicate_view``: two views from nearly the same viewpoint; names the one that adds nothing.

Information kinds (:data:`INFO_KINDS`) say why a view does not take part, without accusing a label.

World frame: SoccerNet (metres, origin at the centre spot, z down). Pixels: continuous, origin at the
top-left corner of each view's own image.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Hashable

import numpy as np

from app.geometry.camera import Camera

#: Kinds that accuse a label (the review queue counts, filters and sorts by them).
LABEL_KINDS: tuple[str, ...] = (
    "mirrored_labels", "ball_off_consensus", "ball_missing", "views_disagree", "near_duplicate_view",
)
#: Kinds that inform without accusing a label.
INFO_KINDS: tuple[str, ...] = ("calibration_refused", "below_admission", "rig_assisted", "few_lines")

#: ``suggestion["action"]`` values: what the fix of a doubt does (one key on the system page).
#: ``snap_box``: set the view's ball label to ``suggestion["box"]``; ``exclude_view``: exclude the
#: view from the triangulation (a stored, reversible per-view decision); ``mirror_labels``: replace
#: the view's field lines by their mirrored labelling.
SUGGESTION_ACTIONS: tuple[str, ...] = ("snap_box", "exclude_view", "mirror_labels")


@dataclass(frozen=True)
class DoubtView:
    """One view of a system as the doubt judge sees it.

    Attributes:
        view_id: the view's identifier (the service passes the frame id).
        name: the image name (``"12_1.png"``).
        role: ``"action"``, ``"replay"`` or ``"camera"`` (single-view systems).
        width, height: image size, pixels.
        camera: the calibrated camera at this resolution, or None (refused, never calibrated).
        admitted: the calibration clears admission (JaC@0.5 % above the threshold).
        jac: JaC@0.5 % of the calibration (fraction), None without one.
        line_classes: number of distinct annotated field-line classes.
        box: (4,) ``[x1, y1, x2, y2]`` ball box in pixels, or None.
        point: (2,) ball point in pixels for point-only labels (ISSIA), or None.
        excluded: a reviewer excluded this view from the triangulation.
        mirror_flagged: the view's labels are flagged probably mirrored.
        mirror_evidence: ``MirrorVerdict.as_dict()`` of the view, or None.
        calibration_reason: why calibration was refused, None otherwise.
        rig_assisted: the camera was fitted at a position of the game's camera rig.
    """

    view_id: Hashable
    name: str
    role: str
    width: int
    height: int
    camera: Camera | None
    admitted: bool
    jac: float | None = None
    line_classes: int = 0
    box: np.ndarray | None = None
    point: np.ndarray | None = None
    excluded: bool = False
    mirror_flagged: bool = False
    mirror_evidence: dict[str, Any] | None = None
    calibration_reason: str | None = None
    rig_assisted: bool = False


@dataclass(frozen=True)
class Doubt:
    """One doubt of a system.

    Attributes:
        kind: one of :data:`LABEL_KINDS` or :data:`INFO_KINDS`.
        view_id: the view it names (None: the system as a whole).
        message: one sentence with its numbers.
        evidence: the numbers behind it (JSON-ready: floats, ints, strings, lists, dicts).
        suggestion: the fix, ``{"action": one of SUGGESTION_ACTIONS, ...}`` (``"box"``:
            ``[x1, y1, x2, y2]`` in the named view's own pixels for ``snap_box``), or None.
    """

    kind: str
    view_id: Hashable | None
    message: str
    evidence: dict[str, Any] = field(default_factory=dict)
    suggestion: dict[str, Any] | None = None

    @property
    def accuses_label(self) -> bool:
        """True for the kinds of :data:`LABEL_KINDS`."""
        return self.kind in LABEL_KINDS


@dataclass(frozen=True)
class DoubtSettings:
    """TEMPORARY (integration scaffold, replaced by the judge's branch)."""

    triangulation_tau_px: float = 20.0


def judge_system(views, settings):  # TEMPORARY scaffold
    out = []
    for v in views:
        if v.mirror_flagged and not v.excluded:
            out.append(Doubt("mirrored_labels", v.view_id, "mirrored", dict(v.mirror_evidence or {}),
                             {"action": "mirror_labels"}))
        if v.camera is not None and v.box is None and v.point is None:
            w, h = v.width, v.height
            out.append(Doubt("ball_missing", v.view_id, "missing", {"epipolar_px": [[10, 10], [w / 2, h / 2]]},
                             {"action": "snap_box", "box": [w / 2 - 5, h / 2 - 5, w / 2 + 5, h / 2 + 5]}))
    return out
