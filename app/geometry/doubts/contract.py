"""The doubts' contract: the kinds that accuse a label and those that inform, the codes of each reasoning, the
suggested fixes, a view as the judge sees it (:class:`DoubtView`), a doubt (:class:`Doubt`) and the
thresholds (:class:`DoubtSettings`); with the small view helpers the rules share (inside the image, the play
volume; a label's centre, a point's pixel and the rule's units are :mod:`app.geometry.weighting`'s).

World frame: SoccerNet (metres, origin at the centre spot, z down); pixels of each view's own image.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Hashable, Iterable

import numpy as np

from app.geometry.camera import Camera
from app.geometry.pitch import PlayVolume, within_play_volume

#: Kinds that accuse a label (the review queue counts, filters and sorts by them).
LABEL_KINDS: tuple[str, ...] = (
    "mirrored_labels", "ball_off_consensus", "ball_missing", "views_disagree", "near_duplicate_view", "ball_detected",
)


#: How much of a system each label-accusing kind says is wrong, the review queue's severity (larger is worse;
#: ``app.services.curation.queue``): 3, a view's field lines are mirrored (its camera, and so every figure of that
#: view, is wrong); 2, a ball label contradicts the other views by more than tau (an error measured in px); 1, a
#: label may be missing or redundant, or a detector saw a ball that no label holds (nothing measured against it).
#: Within one severity the queue puts the largest reprojection error first: the size of the error.
LABEL_KIND_SEVERITY: dict[str, int] = {
    "mirrored_labels": 3, "ball_off_consensus": 2, "views_disagree": 2, "ball_missing": 1, "near_duplicate_view": 1,
    "ball_detected": 1,
}


def label_severity(kinds: Iterable[str]) -> int:
    """The largest :data:`LABEL_KIND_SEVERITY` among doubt ``kinds`` (0 when none accuses a label): a system's
    severity, stored with its doubts (``System.label_severity``) for the review queue's default order."""
    return max((LABEL_KIND_SEVERITY.get(k, 0) for k in kinds), default=0)


#: Kinds whose suggested box is a detector's (their ``evidence`` names the ``detector`` and its ``score``): the page
#: draws that box in the detections' own colour with its detector and score, and the fix's button says whose box it
#: places (``static/js/words.js`` ``DETECTOR_KINDS``, written from this).
DETECTOR_KINDS: tuple[str, ...] = ("ball_detected",)


#: Kinds that inform without accusing a label.
INFO_KINDS: tuple[str, ...] = ("calibration_refused", "below_admission", "rig_assisted", "few_lines", "suggested_label",
                               "detection_off_label")


#: ``suggestion["action"]`` values: what the fix of a doubt does (one key on the system page).
#: ``snap_box``: set the view's ball label to ``suggestion["box"]``; ``exclude_view``: exclude the
#: view from the triangulation (a stored, reversible per-view decision); ``mirror_labels``: replace
#: the view's field lines by their mirrored labelling.
#: ``snap_point``: set the view's point label to ``suggestion["point"]`` (ISSIA, where the sequence's
#: trajectory projects). A doubt that accuses a ball label (``ball_off_consensus``, ``ball_missing``) and has
#: a box the other views agree on offers it (``snap_box``) with its uncertainty ``box_sigma_px`` (px of the
#: view, one standard deviation; :func:`consensus_fix`) and lists the other fixes that apply in
#: ``suggestion["alternatives"]`` (e.g. ``["exclude_view"]``).
SUGGESTION_ACTIONS: tuple[str, ...] = ("snap_box", "exclude_view", "mirror_labels", "snap_point")


#: ``Doubt.code`` per kind: which reasoning found the doubt (the words layer writes one sentence per code).
CODES: dict[str, tuple[str, ...]] = {
    "calibration_refused": ("refused",), "below_admission": ("below_admission",),
    "rig_assisted": ("rig_assisted",), "few_lines": ("few_lines",), "suggested_label": ("unconfirmed",),
    "mirrored_labels": ("flagged", "suspected"),
    "ball_off_consensus": ("off_consensus", "behind_camera", "trajectory"),
    "ball_missing": ("consensus", "epipolar", "epipolar_box", "pairing"),
    "views_disagree": ("no_agreement", "ambiguous", "epipolar", "lone_pair"),
    "near_duplicate_view": ("near_duplicate",),
    # a detector's prediction checked against the other views (app.geometry.doubts.detections)
    # (consensus: the labelled views agree; one_view: one labelled view and two detected views; one_ray: one
    # labelled view and one detection; detections_agree: no labelled view takes part, detections meet; weak_ray: a
    # label whose camera takes no part and the one detection near its ray, a box that cannot make a 3D ball;
    # weak_view: a view whose own camera takes no part, the one detection where the others' ball projects)
    "ball_detected": ("consensus", "one_view", "one_ray", "detections_agree", "weak_ray", "weak_view"),
    "detection_off_label": ("agrees_with_others",),
}


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
        player_assisted: the camera was fitted to its players' foot points (``app.geometry.calibration.players``):
            its pose is over-determined by the players it shares with the well-lined views, not by its few lines.
        uncertainty: the calibration's standard deviations as stored
            (``CalibrationUncertainty.to_json()``), or None (then the camera is taken as exact).
        suggested: the ball label was made from a doubt's suggestion and no person has placed it: it lies
            where the other views put the ball by construction, so it votes for nothing (info doubt
            ``suggested_label``) and the view is not called missing either.
        players: the people the dataset boxed in the view (players, goalkeepers, referees), each ``(x1, y1, x2, y2)``
            px of its image; given where a detector's predictions are checked (empty otherwise).
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
    player_assisted: bool = False
    uncertainty: dict[str, Any] | None = None
    suggested: bool = False
    players: tuple[tuple[float, float, float, float], ...] = ()


@dataclass(frozen=True)
class Doubt:
    """One doubt of a system.

    Attributes:
        kind: one of :data:`LABEL_KINDS` or :data:`INFO_KINDS`.
        view_id: the view it names (None: the system as a whole).
        code: which reasoning found it (one of :data:`CODES` of its kind); the words are composed from
            ``kind``, ``code`` and ``evidence`` by ``app.services.wording.doubt_words``.
        evidence: the numbers behind it (JSON-ready: floats, ints, strings, lists, dicts).
        suggestion: the fix, ``{"action": one of SUGGESTION_ACTIONS, ...}`` (``"box"``:
            ``[x1, y1, x2, y2]`` in the named view's own pixels for ``snap_box``), or None.
    """

    kind: str
    view_id: Hashable | None
    code: str
    evidence: dict[str, Any] = field(default_factory=dict)
    suggestion: dict[str, Any] | None = None

    @property
    def accuses_label(self) -> bool:
        """True for the kinds of :data:`LABEL_KINDS`."""
        return self.kind in LABEL_KINDS


@dataclass(frozen=True)
class DoubtSettings:
    """Thresholds of :func:`judge_system`.

    No defaults of its own: the service builds it from ``app.core.config.Settings``
    (``app.services.derivation.doubts.doubt_settings``: the triangulation's settings for the first five fields,
    ``Settings.doubt_*`` for the others), whose defaults are the operating point chosen with
    ``benchmarks/doubts.py`` (precision against recall on the synthetic SoccerNet-v3 dev sets, v3d's own
    calibration); see that script's docstring.

    Attributes:
        triangulation_tau_px: tau of the triangulation (px at 1920 width); unused by the judge except
            as the floor of ``consensus_tau_px`` (a view the triangulation keeps is never accused).
        pair_error_rule: the triangulation's pair-error rule; ``max_px`` makes every error below raw
            pixels, the other rules pixels of a 1920-px-wide image.
        min_baseline_m: pairs of cameras closer than this propose no ball (metres).
        min_parallax_deg: pairs whose ball rays meet at a smaller angle propose no ball (degrees).
        ball_diameter_m: phi (metres).
        consensus_tau_px: a labelled view is off the consensus ball, and two views disagree, when the
            reprojection error exceeds this (px at 1920 width). Swept: good views of v3d's own
            calibrations reach about 20 px, corrupted ones mostly exceed 60 px.
        near_duplicate_max_deg: two views are near duplicates when their camera centres subtend less
            than this angle at the ball (degrees). Swept: true near duplicates are within 0.6 deg,
            distinct broadcast viewpoints at least 10 deg apart.
        inside_margin_px: the ball of the other views must project at least this far inside the image
            for ``ball_missing`` (px at 1920 width; negative lets it lie that far outside).
        ground_box_tolerance: a labelled view places the ball on the grass when the monocular depth from
            its box is within this relative difference of the grass depth on its ray (fraction; SoccerNet-v3
            boxes err by about 19 % in size): the reference point of its calibration's pixel sigma and of the
            near-duplicate angle.
        mirror_rig_near_m, mirror_rig_gap_m: an unflagged view is suspected mirrored when its ray meets
            another view's only mirrored and its mirrored camera stands within ``mirror_rig_near_m`` of a
            known camera position of the game while as labelled it stands ``mirror_rig_gap_m`` farther
            (metres; calibrated centres of one camera scatter by about a metre).
        play_volume: where a ball can be (:data:`app.geometry.pitch.PLAY_VOLUME`; its height from
            ``V3D_DOUBT_MAX_BALL_HEIGHT_M``): a proposal outside it is no agreement.
        min_line_classes: a view with fewer distinct line classes gets the info doubt ``few_lines`` and
            takes no part in the checks: with the game's rig, two or three classes give a camera that
            fits its own lines perfectly (JaC 1.0) yet may turn its ball ray by degrees, so its ball
            would be accused for its camera's fault (on dev-large, every false alarm of that kind).
        below_admission_takes_part: the system's 3D ball is judged by evidence
            (``app.services.derivation.ball.takes_part``): a labelled view below admission joins its ball while its
            camera fits most of its own lines (``app.geometry.weighting.fits_own_lines``). What the checks that may
            place a box only where it cannot make a 3D ball ask (``app.geometry.doubts.weak._uncounted``).
    """

    triangulation_tau_px: float
    pair_error_rule: str
    min_baseline_m: float
    min_parallax_deg: float
    ball_diameter_m: float
    consensus_tau_px: float
    near_duplicate_max_deg: float
    inside_margin_px: float
    ground_box_tolerance: float
    play_volume: PlayVolume
    mirror_rig_near_m: float
    mirror_rig_gap_m: float
    min_line_classes: int
    below_admission_takes_part: bool


def _r(x: float, nd: int = 1) -> float:
    return round(float(x), nd)


def _box_list(box: np.ndarray | None) -> list[float] | None:
    return None if box is None else [_r(v, 2) for v in box]


def _inside(view: DoubtView, uv: np.ndarray, margin_px: float) -> bool:
    """The pixel lies inside the view's image shrunk by ``margin_px`` (view pixels)."""
    return bool(margin_px <= uv[0] <= view.width - margin_px and margin_px <= uv[1] <= view.height - margin_px)


def _plausible(point: np.ndarray, s: DoubtSettings) -> bool:
    """A ball position a game could hold (:func:`app.geometry.pitch.within_play_volume` with the judge's margins)."""
    return bool(within_play_volume(point, s.play_volume)[0])
