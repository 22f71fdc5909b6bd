"""Doubts: the label problems the geometry of one multi-view system can see, each with its evidence
and, where there is one, its fix.

A system's doubts are recomputed with every edit (``app.services.derivation.recompute``) and stored; this module
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

Each doubt carries a ``code`` (which reasoning found it, :data:`CODES`) and its numbers; the sentence a
person reads is composed above this module (``app.services.curation.doubt_words``).

Evidence is weighed by what each calibration is worth (:func:`pixel_sigma` from the stored calibration
uncertainty): a view below admission whose calibration is sure still votes (half a vote), an admitted
view whose calibration is unsure votes half and is accused only beyond its own pixel sigma. Agreement is
judged with each pair's conditioning: a pair whose rays meet only where no ball can be (under the grass,
far outside the stadium) does not agree, and a pair too poorly conditioned to triangulate (a near
duplicate) is judged by each label's distance to the other view's ray across the play volume
(:func:`epipolar_pair_error`). With one other labelled view the ball lies on that view's ray at an
unknown height: a view misses the ball only when that whole segment lies inside its image.

World frame: SoccerNet (metres, origin at the centre spot, z down). Pixels: continuous, origin at the
top-left corner of each view's own image.

Thresholds: :class:`DoubtSettings` (chosen with ``benchmarks/doubts.py`` and ``benchmarks/doubts_seeds.py``
on the sets that script names). The module is long because the contract, the settings and the judge's
rules belong together; the robust consensus lives in :mod:`app.geometry.consensus`.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from itertools import combinations
from typing import Any, Callable, Hashable, Sequence

import numpy as np

from app.geometry.ball import ball_from_box_exact, sphere_image_box
from app.geometry.camera import Camera
from app.geometry.consensus import Consensus, ball_consensus
from app.geometry.mirror import mirror_camera
from app.geometry.pitch import BALL_DIAMETER_M, MIN_LINE_CLASSES, PITCH_LENGTH_M, PITCH_WIDTH_M, within_play_volume
from app.geometry.triangulation import (REFERENCE_WIDTH_PX, BallObservation, PairGeometry, pair_geometry,
                                        reprojection_error_px)

#: Kinds that accuse a label (the review queue counts, filters and sorts by them).
LABEL_KINDS: tuple[str, ...] = (
    "mirrored_labels", "ball_off_consensus", "ball_missing", "views_disagree", "near_duplicate_view",
)
#: Kinds that inform without accusing a label.
INFO_KINDS: tuple[str, ...] = ("calibration_refused", "below_admission", "rig_assisted", "few_lines", "suggested_label")

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
    "ball_missing": ("consensus", "epipolar", "epipolar_box"),
    "views_disagree": ("no_agreement", "ambiguous", "epipolar"),
    "near_duplicate_view": ("near_duplicate",),
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
        uncertainty: the calibration's standard deviations as stored
            (``CalibrationUncertainty.to_json()``), or None (then the camera is taken as exact).
        suggested: the ball label was made from a doubt's suggestion and no person has placed it: it lies
            where the other views put the ball by construction, so it votes for nothing (info doubt
            ``suggested_label``) and the view is not called missing either.
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
    uncertainty: dict[str, Any] | None = None
    suggested: bool = False


@dataclass(frozen=True)
class Doubt:
    """One doubt of a system.

    Attributes:
        kind: one of :data:`LABEL_KINDS` or :data:`INFO_KINDS`.
        view_id: the view it names (None: the system as a whole).
        code: which reasoning found it (one of :data:`CODES` of its kind); the words are composed from
            ``kind``, ``code`` and ``evidence`` by ``app.services.curation.doubt_words``.
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

    The first five fields carry the names of the service's triangulation settings
    (``app.core.config.Settings``); every other field ``f`` is read from ``Settings.doubt_f``. The
    defaults are the operating point chosen with ``benchmarks/doubts.py`` (precision against recall on
    the synthetic SoccerNet-v3 dev sets, v3d's own calibration); see that script's docstring.

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
        single_view_margin_px: unused since the judge reasons on the whole epipolar segment (kept so that
            a deployment's ``V3D_DOUBT_SINGLE_VIEW_MARGIN_PX`` stays valid).
        ground_box_tolerance: a labelled view places the ball on the grass when the monocular depth from
            its box is within this relative difference of the grass depth on its ray (fraction; SoccerNet-v3
            boxes err by about 19 % in size): the reference point of its calibration's pixel sigma and of the
            near-duplicate angle.
        mirror_rig_near_m, mirror_rig_gap_m: an unflagged view is suspected mirrored when its ray meets
            another view's only mirrored and its mirrored camera stands within ``mirror_rig_near_m`` of a
            known camera position of the game while as labelled it stands ``mirror_rig_gap_m`` farther
            (metres; calibrated centres of one camera scatter by about a metre).
        max_ball_height_m: highest plausible ball (metres above the grass).
        max_below_m: lowest plausible ball centre below the grass (metres: triangulation noise).
        play_margin_m: a ball more than this beyond the touch or goal lines is not a ball position
            (metres; the mirror evidence's margin).
        min_line_classes: a view with fewer distinct line classes gets the info doubt ``few_lines`` and
            takes no part in the checks: with the game's rig, two or three classes give a camera that
            fits its own lines perfectly (JaC 1.0) yet may turn its ball ray by degrees, so its ball
            would be accused for its camera's fault (on dev-large, every false alarm of that kind).
    """

    triangulation_tau_px: float = 20.0
    pair_error_rule: str = "max_scaled_1920"
    min_baseline_m: float = 1.0
    min_parallax_deg: float = 2.0
    ball_diameter_m: float = BALL_DIAMETER_M
    consensus_tau_px: float = 25.0
    near_duplicate_max_deg: float = 3.0
    inside_margin_px: float = 0.0
    single_view_margin_px: float = 40.0
    ground_box_tolerance: float = 0.35
    max_ball_height_m: float = 30.0
    max_below_m: float = 0.5
    play_margin_m: float = 15.0
    mirror_rig_near_m: float = 1.0
    mirror_rig_gap_m: float = 2.0
    min_line_classes: int = MIN_LINE_CLASSES


def _scale(view: DoubtView, s: DoubtSettings) -> float:
    """Factor from the view's pixels to the units of the settings (1920-px width, or raw px)."""
    return 1.0 if s.pair_error_rule == "max_px" else REFERENCE_WIDTH_PX / view.width


def _centre(view: DoubtView) -> np.ndarray | None:
    if view.box is not None:
        b = np.asarray(view.box, float)
        return np.array([(b[0] + b[2]) / 2, (b[1] + b[3]) / 2])
    return None if view.point is None else np.asarray(view.point, float).reshape(2)


def _r(x: float, nd: int = 1) -> float:
    return round(float(x), nd)


def _box_list(box: np.ndarray | None) -> list[float] | None:
    return None if box is None else [_r(v, 2) for v in box]


def _inside(view: DoubtView, uv: np.ndarray, margin_px: float) -> bool:
    """The pixel lies inside the view's image shrunk by ``margin_px`` (view pixels)."""
    return bool(margin_px <= uv[0] <= view.width - margin_px and margin_px <= uv[1] <= view.height - margin_px)


def _project(view: DoubtView, point: np.ndarray) -> np.ndarray | None:
    uv, ok = view.camera.project(np.asarray(point, float).reshape(1, 3))
    return uv[0] if ok[0] else None


def _plausible(point: np.ndarray, s: DoubtSettings) -> bool:
    """A ball position a game could hold (:func:`app.geometry.pitch.within_play_volume` with the judge's margins)."""
    return bool(within_play_volume(np.asarray(point, float).reshape(1, 3), margin_m=s.play_margin_m,
                                   max_height_m=s.max_ball_height_m, max_below_m=s.max_below_m)[0])


def pixel_sigma(view: DoubtView, point: np.ndarray, s: DoubtSettings) -> float:
    """How far (px at 1920 width) the view's calibration may put ``point``'s projection: the first-order
    propagation of its stored uncertainty (``calibrations.uncertainty``,
    :class:`app.geometry.calibration.uncertainty.CalibrationUncertainty`) to the pixel of ``point``, with
    the rotation and focal terms independent: ``sqrt((f s_pan)^2 + (f s_tilt)^2 + (r s_roll)^2 + (r s_f / f)^2)``
    (angles in radians, ``r`` the pixel's distance to the principal point). The centre's terms are left
    out: the fit trades the centre along the viewing direction against the focal length, which moves
    the ball's pixel little (with them the figure overstates the error of the synthetic sets' views
    about 25 times at the median; without them about 5 times, and it still ranks the views whose
    calibration failed: of the admitted views above ``consensus_tau_px`` 11 % project the true ball more
    than that far off, of those below it 0.3 %). 0 without a stored uncertainty; ``inf`` for a parameter the
    lines leave undetermined.
    """
    u = view.uncertainty
    if not u or view.camera is None:
        return 0.0
    uv = _project(view, point)
    if uv is None:
        return math.inf
    f = float(view.camera.K[0, 0])
    r = float(np.linalg.norm(uv - view.camera.K[:2, 2]))
    def num(key: str) -> float:
        v = u.get(key)
        return math.inf if v is None else float(v)
    terms = (f * math.radians(num("pan_deg")), f * math.radians(num("tilt_deg")), r * math.radians(num("roll_deg")),
             r * num("focal_px") / f)
    if any(math.isinf(t) or math.isnan(t) for t in terms):
        return math.inf
    return float(math.sqrt(sum(t * t for t in terms))) * _scale(view, s)


def calibration_weight(view: DoubtView, s: DoubtSettings) -> tuple[float, float]:
    """What the view's calibration is worth as evidence of a ball, and its pixel sigma: ``(weight, sigma)``.

    ``sigma`` (px at 1920 width) is :func:`pixel_sigma` where the view's ball label's ray meets the grass
    (the pixel sigma hardly depends on the point's depth), else where its optical axis does, else 50 m
    along the axis. ``weight``: for a view with at least ``min_line_classes`` line classes the vote of
    :func:`_vote_weight` (1 admitted and sure, 0.5 unsure or below admission but sure, else 0); for a view
    with fewer classes (its camera is not fixed by its own lines: with the game's rig two or three classes
    fit exactly yet may turn the ball ray by degrees) half a vote when its stored uncertainty is sure (sigma
    within ``consensus_tau_px``) and it fits at least half of its lines (JaC@0.5 % >= 0.5), else 0.
    The doubt judge weighs its votes with it; the triangulation (``app.geometry.triangulation.triangulate_ball``
    ``view_weights``) lets no pair without a full vote make a ball, and no weaker pair move one that
    full votes make. A view without a camera: ``(0.0, inf)``."""
    if view.camera is None:
        return 0.0, math.inf
    c = _centre(view)
    ref = None if c is None else _ray_at_height(view.camera.C, view.camera.rays(c.reshape(1, 2))[0],
                                                  -s.ball_diameter_m / 2)
    if ref is None:
        ref = _axis_on_grass(view, s)
    if ref is None:  # a camera looking above the horizon: a point 50 m along its axis
        ref = view.camera.C + 50.0 * view.camera.R[2]
    sigma = pixel_sigma(view, ref, s)
    if view.line_classes >= s.min_line_classes:
        return _vote_weight(view, sigma, s), sigma
    sure = bool(view.uncertainty) and sigma <= s.consensus_tau_px and (view.jac or 0.0) >= 0.5
    return (0.5 if sure else 0.0), sigma


def _vote_weight(view: DoubtView, sigma_1920: float, s: DoubtSettings) -> float:
    """What the view's calibration is worth in the consensus: 1 for an admitted view whose pixel sigma
    (:func:`pixel_sigma`) is within ``consensus_tau_px``; half a vote for an admitted view above it or
    for a view below admission within it (each projects the true ball more than tau off about one time in
    ten on the synthetic sets, against 0.3 % for full votes), the latter only when it fits at least half of
    its own lines (JaC@0.5 % >= 0.5); 0 otherwise."""
    sure = sigma_1920 <= s.consensus_tau_px
    if view.admitted:
        return 1.0 if sure else 0.5
    # below admission: its uncertainty speaks for it only if the camera fits most of its own lines
    # (JaC@0.5 % of at least a half; a camera that fits none, JaC 0, is a failed fit whatever its sigma)
    return 0.5 if sure and (view.jac or 0.0) >= 0.5 else 0.0


def _info_doubts(views: Sequence[DoubtView], s: DoubtSettings) -> list[Doubt]:
    out: list[Doubt] = []
    for v in views:
        if v.camera is None:
            reason = v.calibration_reason or "no calibration"
            out.append(Doubt("calibration_refused", v.view_id, "refused", {"reason": reason}))
        elif not v.admitted:
            out.append(Doubt("below_admission", v.view_id, "below_admission",
                             {"jac": None if v.jac is None else _r(v.jac, 4)}))
        if v.rig_assisted:
            out.append(Doubt("rig_assisted", v.view_id, "rig_assisted", {}))
        if v.suggested:
            out.append(Doubt("suggested_label", v.view_id, "unconfirmed", {}))
        if v.line_classes < s.min_line_classes:
            out.append(Doubt("few_lines", v.view_id, "few_lines",
                             {"line_classes": int(v.line_classes), "min_line_classes": int(s.min_line_classes)}))
    return out


def _mirror_doubt(v: DoubtView, code: str, others: Consensus | None, s: DoubtSettings) -> Doubt:
    """``mirrored_labels`` for ``v`` (``code``: ``flagged``, ``suspected`` or ``refit``), with the fix when the
    mirrored calibration and the ball agree better (:func:`_mirror_fix_check`)."""
    ev = dict(v.mirror_evidence or {})
    evidence: dict[str, Any] = {k: ev[k] for k in ("verdict", "margin", "camera_y_m", "mirrored_camera_y_m",
                                                    "side_vote", "rig_distance_m", "rig_distance_mirrored_m",
                                                    "rig_vote", "refit") if k in ev}
    evidence["flagged"] = bool(v.mirror_flagged)
    fix_ok, why_not, numbers = _mirror_fix_check(v, ev, others, s)
    evidence.update(numbers)
    evidence["fix_agrees"] = fix_ok
    if not fix_ok:
        evidence["no_fix"] = why_not
    return Doubt("mirrored_labels", v.view_id, code, evidence, {"action": "mirror_labels"} if fix_ok else None)


def _mirror_fix_check(v: DoubtView, ev: dict[str, Any], others: Consensus | None,
                      s: DoubtSettings) -> tuple[bool, str, dict[str, Any]]:
    """Whether mirroring the view's labels is a fix the other views' ball confirms: (offered, code of why
    not, numbers).

    The mirror fix replaces the view's camera by its mirror image (``app.geometry.mirror.mirror_camera``:
    the camera its mirrored labels calibrate to, exactly). With a ball the other views agree on and a ball
    label in this view, the fix is offered only when the mirrored camera brings the label closer to that
    ball than the camera as labelled does, and within tolerance (``as_labelled_fits`` / ``mirrored_misses``
    otherwise; the numbers ``error_as_labelled_px_1920``, ``error_mirrored_px_1920``). Without such a ball no
    fix is offered unless the game's rig says which view is mirrored: a single other view's ray meeting this one
    only mirrored (``app.geometry.mirror.pair_relation`` "different") cannot tell which of the two is mirrored,
    the rig can (the mirrored camera within ``mirror_rig_near_m`` of a known camera position, the camera as
    labelled ``mirror_rig_gap_m`` farther; else ``one_view_cannot_tell``; ``as_labelled_meets`` when a ray meets
    it as labelled, ``no_ray_confirms`` without any). A view
    without a camera (refused as labelled) whose mirrored labels fit (``refit``) gets the fix: it has no
    camera to make worse.
    """
    if v.camera is None:
        return (True, "", {}) if ev.get("refit") or ev.get("verdict") == "probably_mirrored" else (False, "no_ray_confirms", {})
    c = _centre(v)
    if others is not None and others.point is not None and not others.ambiguous and c is not None:
        k = _scale(v, s)
        e_as = reprojection_error_px(v.camera, others.point, c)
        e_mi = reprojection_error_px(mirror_camera(v.camera), others.point, c)
        numbers = {"error_as_labelled_px_1920": None if e_as is None else _r(e_as * k),
                   "error_mirrored_px_1920": None if e_mi is None else _r(e_mi * k),
                   "agreeing_views": list(others.inliers)}
        tau = max(s.consensus_tau_px, s.triangulation_tau_px)
        if e_as is not None and (e_mi is None or e_as <= e_mi):
            return False, "as_labelled_fits", numbers
        if e_mi is None or e_mi * k > tau:
            return False, "mirrored_misses", numbers
        return True, "", numbers
    pairs = [p for p in ev.get("pairs") or [] if isinstance(p, dict)]
    if any(p.get("relation") == "same" for p in pairs):
        return False, "as_labelled_meets", {}
    if not any(p.get("relation") == "different" for p in pairs):
        return False, "no_ray_confirms", {}
    # one other view's ray cannot tell which of the two is mirrored (mirroring either meets it): the game's rig
    # can, when the mirrored camera stands at a known camera position (within mirror_rig_near_m) and the camera
    # as labelled at least mirror_rig_gap_m farther from every one; without it, on a clean view such a fix
    # moved a right camera, and its 3D ball, across the pitch
    d, dm = ev.get("rig_distance_m"), ev.get("rig_distance_mirrored_m")
    if isinstance(d, (int, float)) and isinstance(dm, (int, float)) and dm <= s.mirror_rig_near_m \
            and d >= dm + s.mirror_rig_gap_m:
        return True, "", {"rig_confirms": True}
    return False, "one_view_cannot_tell", {}


def _mirror_suspected(v: DoubtView, s: DoubtSettings) -> bool:
    """Not flagged, but the mirror evidence points at this view: no other view's ball ray meets its ray
    only as labelled, and its mirrored camera stands at a known camera position of the game (within
    ``mirror_rig_near_m``) while as labelled it stands at least ``mirror_rig_gap_m`` farther from every one.
    The flag itself weighs that rig vote low so that it never flags alone (a replay camera seen once whose
    mirror image happens to stand near a known position); a doubt asks a person to look, and a mirror
    image within a metre of a known camera, with the camera itself far from any, is rare by chance. The
    fix is still offered only when the ball confirms it (:func:`_mirror_fix_check`)."""
    ev = v.mirror_evidence or {}
    d, dm = ev.get("rig_distance_m"), ev.get("rig_distance_mirrored_m")
    if v.mirror_flagged or not isinstance(d, (int, float)) or not isinstance(dm, (int, float)):
        return False
    same = any(p.get("relation") == "same" for p in ev.get("pairs") or [])
    return bool(not same and dm <= s.mirror_rig_near_m and d >= dm + s.mirror_rig_gap_m)


def _near_duplicates(views: Sequence[DoubtView], consensus: Consensus, s: DoubtSettings) -> list[Doubt]:
    """Pairs of views that both show the ball and whose camera centres subtend less than
    ``near_duplicate_max_deg`` at it.

    The angle is measured at the consensus ball, else at the ball a labelled view of the pair places
    on the grass or by its box, else where the first view's optical axis meets the grass: calibrated
    centres err mostly along the viewing direction, which barely changes that angle."""
    out: list[Doubt] = []
    named: set[Hashable] = set()
    for a, b in combinations(views, 2):
        if a.view_id in named or b.view_id in named:
            continue
        ref = consensus.point
        for v in (a, b):
            if ref is None and _centre(v) is not None:
                ref = _single_view_ball(v, s)[0]
        if ref is None:
            ref = _axis_on_grass(a, s)
        if ref is None:
            continue
        u, w = ref - a.camera.C, ref - b.camera.C
        angle = math.degrees(math.atan2(np.linalg.norm(np.cross(u, w)), float(u @ w)))
        if angle >= s.near_duplicate_max_deg or not (_sees(a, ref) and _sees(b, ref)):
            continue
        # Name the view that adds nothing: an unlabelled one, else a replay, else the lower JaC.
        keep, drop = sorted((a, b), key=lambda v: (_centre(v) is None, v.role != "action", -(v.jac or 0.0)))
        named.add(drop.view_id)
        out.append(Doubt(
            "near_duplicate_view", drop.view_id, "near_duplicate",
            {"other_view": keep.view_id, "angle_deg": _r(angle, 3), "baseline_m": _r(np.linalg.norm(u - w), 2),
             "max_deg": s.near_duplicate_max_deg},
            {"action": "exclude_view"}))
    return out


def _sees(v: DoubtView, ball: np.ndarray) -> bool:
    """The view shows the ball: it has a ball label, or the ball projects inside its image (a camera at
    the same place that looks elsewhere is another shot, not a duplicate)."""
    if _centre(v) is not None:
        return True
    uv = _project(v, ball)
    return uv is not None and _inside(v, uv, 0.0)


def _axis_on_grass(v: DoubtView, s: DoubtSettings) -> np.ndarray | None:
    """Where the view's optical axis meets the plane of ball centres on the grass, or None."""
    d = v.camera.R[2]  # optical axis in the world frame
    return _ray_at_height(v.camera.C, d, -s.ball_diameter_m / 2)


def _ray_at_height(origin: np.ndarray, direction: np.ndarray, z: float) -> np.ndarray | None:
    if abs(direction[2]) < 1e-9:
        return None
    t = (z - origin[2]) / direction[2]
    return None if t <= 0 else origin + t * direction


def _single_view_ball(v: DoubtView, s: DoubtSettings) -> tuple[np.ndarray | None, str]:
    """The ball one labelled view places: on the grass along its ray when the box size agrees (most
    balls are on the ground), else at the monocular estimate (method.md section 6, exact silhouette);
    a point label goes on the grass. Returns (point or None, how it was placed)."""
    c = _centre(v)
    ray = v.camera.rays(c.reshape(1, 2))[0]
    grass = _ray_at_height(v.camera.C, ray, -s.ball_diameter_m / 2)
    mono = _mono(v, s)
    if mono is None:
        return grass, "grass"
    if grass is not None:
        ratio = np.linalg.norm(mono - v.camera.C) / np.linalg.norm(grass - v.camera.C)
        if abs(ratio - 1.0) <= s.ground_box_tolerance:
            return grass, "grass"
    return mono, "box"


def _mono(v: DoubtView, s: DoubtSettings) -> np.ndarray | None:
    """The monocular ball of the view's box (method.md section 6, exact silhouette), world metres, or None
    without a box or where the camera cannot place it (a badly distorted camera far outside its valid field)."""
    if v.box is None:
        return None
    try:
        with np.errstate(all="ignore"):
            mono = ball_from_box_exact(v.camera, np.asarray(v.box, float), s.ball_diameter_m)[0]
    except (ValueError, np.linalg.LinAlgError):
        return None
    return mono if np.all(np.isfinite(mono)) else None


def ray_in_play_volume(camera: Camera, pixel: np.ndarray, s: DoubtSettings) -> tuple[float, float] | None:
    """The depths ``t`` (metres along the unit ray from the camera centre) at which the ball seen at
    ``pixel`` would lie in the play volume (:func:`_plausible`: the pitch plus ``play_margin_m``, from
    ``max_ball_height_m`` above the grass to ``max_below_m`` below it), at least 1 m in front of the
    camera: ``(t_near, t_far)``, or None when the ray never enters it (slab intersection of the ray with
    the volume's box)."""
    ray = camera.rays(np.asarray(pixel, float).reshape(1, 2))[0]
    C = camera.C
    lo = np.array([-(PITCH_LENGTH_M / 2 + s.play_margin_m), -(PITCH_WIDTH_M / 2 + s.play_margin_m), -s.max_ball_height_m])
    hi = np.array([PITCH_LENGTH_M / 2 + s.play_margin_m, PITCH_WIDTH_M / 2 + s.play_margin_m, s.max_below_m])
    t0, t1 = 1.0, math.inf
    for k in range(3):
        if abs(ray[k]) < 1e-12:
            if not lo[k] <= C[k] <= hi[k]:
                return None
            continue
        a, b = (lo[k] - C[k]) / ray[k], (hi[k] - C[k]) / ray[k]
        t0, t1 = max(t0, min(a, b)), min(t1, max(a, b))
    return (float(t0), float(t1)) if t0 < t1 else None


def _segment(labelled: DoubtView, other: DoubtView, s: DoubtSettings, samples: int = 64,
             by_box: bool = False) -> tuple[np.ndarray, np.ndarray] | None:
    """The labelled view's ball ray across the play volume (:func:`ray_in_play_volume`), seen in
    ``other``: ``(world points (N, 3), pixels (N, 2) of other, NaN where behind its camera)``, ``samples``
    points evenly spread in depth; None when the ray misses the volume. ``by_box``: only the depths
    the view's box size allows (the monocular depth, method.md section 6, within ``ground_box_tolerance``
    of it), for a box label."""
    span = ray_in_play_volume(labelled.camera, _centre(labelled), s)
    if span is None:
        return None
    ray = labelled.camera.rays(_centre(labelled).reshape(1, 2))[0]
    mono = _mono(labelled, s) if by_box else None
    if mono is not None:  # the box's size bounds the depth (boxes err by ~20 % in size)
        d = float(np.linalg.norm(mono - labelled.camera.C))
        span = (max(span[0], d * (1 - s.ground_box_tolerance)), min(span[1], d * (1 + s.ground_box_tolerance)))
        if span[0] >= span[1]:
            return None
    t = np.linspace(span[0], span[1], samples)
    pts = labelled.camera.C + t[:, None] * ray
    uv, ok = other.camera.project(pts)
    uv = np.where(ok[:, None], uv, np.nan)
    return pts, uv


def _polyline_distance(uv: np.ndarray, p: np.ndarray) -> tuple[float, int]:
    """Distance (px) from ``p`` to the polyline ``uv`` (N, 2; NaN rows break it) and the index of the
    nearest vertex; ``(inf, -1)`` without a finite segment."""
    a, b = uv[:-1], uv[1:]
    ok = np.isfinite(a).all(1) & np.isfinite(b).all(1)
    if not ok.any():
        return math.inf, -1
    a, b = a[ok], b[ok]
    ab = b - a
    L = np.maximum(np.sum(ab * ab, axis=1), 1e-12)
    t = np.clip(np.sum((p - a) * ab, axis=1) / L, 0.0, 1.0)
    d = np.linalg.norm(a + t[:, None] * ab - p, axis=1)
    k = int(np.argmin(d))
    idx = np.flatnonzero(ok)[k] + (1 if t[k] > 0.5 else 0)
    return float(d[k]), int(idx)


def epipolar_pair_error(a: DoubtView, b: DoubtView, s: DoubtSettings) -> float | None:
    """How far (px at 1920 width) two labelled views are from seeing one ball the game could hold: the
    smaller of the two distances from a view's label to the other view's ball ray across the play
    volume, seen in it (its epipolar segment). It needs no triangulation, so it judges pairs of any
    conditioning: a near-duplicate pair (the rays nearly parallel, no depth) and a pair whose rays meet
    only under the grass are tested as well as a wide one. ``inf`` when a ray misses the play volume;
    None when neither segment is seen by the other camera."""
    best: float | None = None
    for x, y in ((a, b), (b, a)):
        seg = _segment(x, y, s)
        if seg is None:
            return math.inf
        d, _ = _polyline_distance(seg[1], _centre(y))
        if math.isfinite(d):
            d *= _scale(y, s)
            best = d if best is None else min(best, d)
    return best


def consensus_box_sigma_px(v: DoubtView, consensus: Consensus, s: DoubtSettings) -> float | None:
    """How far (px of ``v``'s own image, one standard deviation) the consensus ball's box in ``v`` may lie from
    where the ball is: the agreeing views' own spread (the RMS of their reprojection errors to the consensus
    ball, px at 1920 width: how well the rays that made it meet) and ``v``'s calibration's pixel sigma at that
    ball (:func:`pixel_sigma`: how far its camera may put the ball's projection), added in quadrature and
    scaled to ``v``'s pixels. None when ``v``'s calibration leaves the pixel undetermined (``inf``)."""
    errs = [consensus.errors_1920.get(i) for i in consensus.inliers]
    errs = [e for e in errs if e is not None and math.isfinite(e)]
    spread = math.sqrt(sum(e * e for e in errs) / len(errs)) if errs else 0.0
    own = pixel_sigma(v, consensus.point, s)
    if not math.isfinite(own):
        return None
    return _r(math.hypot(spread, own) / _scale(v, s), 2)


def consensus_fix(v: DoubtView, consensus: Consensus, box: np.ndarray | None, s: DoubtSettings,
                  alternatives: Sequence[str] = ("exclude_view",)) -> dict[str, Any]:
    """The fix of a doubt that accuses ``v``'s ball label (``ball_off_consensus``) or its absence
    (``ball_missing``): snap the label to the box the other views agree on, ``box`` (the exact sphere box of
    the consensus ball in ``v``, ``[x1, y1, x2, y2]`` px of ``v``), with its uncertainty ``box_sigma_px``
    (:func:`consensus_box_sigma_px`) and the other fixes that apply (``alternatives``: actions of
    :data:`SUGGESTION_ACTIONS`, e.g. excluding the view when its label is right and its timing or camera is
    not). Without a box (the ball projects outside ``v`` or behind its camera) the first alternative is the
    fix, ``{"action": "exclude_view"}``."""
    if box is None:
        return {"action": alternatives[0]} if alternatives else {"action": "exclude_view"}
    out: dict[str, Any] = {"action": "snap_box", "box": _box_list(box),
                           "box_sigma_px": consensus_box_sigma_px(v, consensus, s)}
    if alternatives:
        out["alternatives"] = list(alternatives)
    return out


def _missing_doubt(v: DoubtView, consensus: Consensus, s: DoubtSettings, code: str,
                   extra: dict[str, Any], margin_px: float | None = None) -> Doubt | None:
    """``ball_missing`` for an unlabelled view when the consensus ball projects inside its image by
    ``margin_px`` (px at 1920 width; default ``inside_margin_px``), else None; its fix is
    :func:`consensus_fix` (the sphere box with its uncertainty)."""
    ball = consensus.point
    uv = _project(v, ball)
    margin = s.inside_margin_px if margin_px is None else margin_px
    if uv is None or not _inside(v, uv, margin / _scale(v, s)):
        return None
    box = sphere_image_box(v.camera, ball, s.ball_diameter_m / 2)
    if box is None:
        return None
    evidence = {"projected_px": [_r(uv[0]), _r(uv[1])], "ball3d": [_r(x, 3) for x in ball], **extra}
    return Doubt("ball_missing", v.view_id, code, evidence, consensus_fix(v, consensus, box, s, alternatives=()))


def _missing_from_one_view(only: DoubtView, v: DoubtView, s: DoubtSettings) -> Doubt | None:
    """``ball_missing`` for ``v`` when one other view is labelled. One ray does not fix the ball's depth: the
    ball lies on that view's ray, within the depths its box size allows (:func:`_segment` ``by_box``), at an
    unknown height. ``v`` is said to miss it when the ball is more likely inside ``v``'s image than not: it
    projects inside (by ``inside_margin_px``) where :func:`_single_view_ball` places it (on the grass when
    the box size agrees, else at the box's depth), and the chance that it lies inside, the box-size depth
    taken as a normal law (sigma ``ground_box_tolerance`` / 2) over the segment, is at least a half. A ball
    in the air that only the grass guess puts inside is not claimed (an out-of-frame replay would be called
    missing). The segment is drawn (``evidence["epipolar_px"]``); a box is suggested only where the
    segment is short enough that any point on it lies within ``consensus_tau_px`` of its middle (code
    ``epipolar_box``; ``epipolar`` without a box). A suggested box lies on the other view's ray by
    construction, so it is a guess, not evidence (the service keeps its provenance)."""
    ball, how = _single_view_ball(only, s)
    if ball is None or not _plausible(ball, s):
        return None
    uv0 = _project(v, ball)
    m = s.inside_margin_px / _scale(v, s)
    if uv0 is None or not _inside(v, uv0, m):
        return None
    seg = _segment(only, v, s, by_box=True)
    if seg is None:
        return None
    pts, uv = seg
    with np.errstate(invalid="ignore"):
        inside = np.isfinite(uv).all(1) & (uv[:, 0] >= m) & (uv[:, 0] <= v.width - m) & (uv[:, 1] >= m) & (
            uv[:, 1] <= v.height - m)
    # the chance that the ball is inside: the box-size depth as a normal law (sigma half the tolerance,
    # so the segment spans two sigmas each side), weighed over the segment's samples
    mono = _mono(only, s)
    if mono is not None:
        depth = np.linalg.norm(pts - only.camera.C, axis=1) / np.linalg.norm(mono - only.camera.C)
        w = np.exp(-0.5 * ((depth - 1.0) / (s.ground_box_tolerance / 2)) ** 2)
    else:
        w = np.ones(len(pts))
    chance = float(np.sum(w * inside) / np.sum(w))
    if chance < 0.5:
        return None
    seen = uv[inside]
    length = float(np.sum(np.linalg.norm(np.diff(seen, axis=0), axis=1))) * _scale(v, s)
    evidence: dict[str, Any] = {"agreeing_views": [only.view_id], "epipolar_px": [[_r(x), _r(y)] for x, y in seen],
                                "segment_length_px_1920": _r(length), "inside_fraction": _r(inside.mean(), 2), "inside_chance": _r(chance, 2),
                                "grass_px": [_r(uv0[0]), _r(uv0[1])], "placed": how, "depth_known": False}
    if length / 2 > s.consensus_tau_px or not inside.all():
        return Doubt("ball_missing", v.view_id, "epipolar", evidence, None)
    box = sphere_image_box(v.camera, ball, s.ball_diameter_m / 2)
    if box is None:
        return Doubt("ball_missing", v.view_id, "epipolar", evidence, None)
    evidence.update(projected_px=[_r(uv0[0]), _r(uv0[1])], ball3d=[_r(x, 3) for x in ball])
    # its uncertainty: the ball may lie anywhere on the stretch drawn, half its length either side of the box
    return Doubt("ball_missing", v.view_id, "epipolar_box", evidence,
                 {"action": "snap_box", "box": _box_list(box), "box_sigma_px": _r(length / 2 / _scale(v, s))})


def judge_system(views: Sequence[DoubtView], settings: DoubtSettings = DoubtSettings(),
                 geometry: Callable[[BallObservation, BallObservation], PairGeometry] = pair_geometry) -> list[Doubt]:
    """Every doubt of one multi-view system (pure, deterministic; see the module docstring for the kinds).

    Rules, in order:

    1. info doubts per view (refused calibration, below admission, rig-assisted, few line classes);
    2. views that take part: calibrated, not excluded by the reviewer, with at least
       ``min_line_classes`` line classes, and a vote (:func:`_vote_weight`: what the calibration is worth,
       from admission and the calibration's pixel sigma, :func:`pixel_sigma`). A view with at least
       ``min_line_classes`` classes flagged mirrored (refused, calibrated or below admission: JaC is the
       same for labels and their mirror), or a view that takes part and is suspected mirrored
       (:func:`_mirror_suspected`), gets ``mirrored_labels`` and takes no further part (its camera is
       the mirrored one, so its ray says nothing about its ball label, and it is not accused twice);
    3. the labelled views' robust consensus (:func:`app.geometry.consensus.ball_consensus` with
       ``consensus_tau_px``, votes weighted, each view's tolerance widened to its pixel sigma, a proposal
       outside the play volume refused): each labelled view off a non-ambiguous consensus gets
       ``ball_off_consensus`` (fix: snap to the consensus ball's box with its uncertainty, :func:`consensus_fix`,
       or exclude it; exclude only when that ball does not project inside it); labelled views with no
       consensus or an ambiguous one give one ``views_disagree`` for the system, also when the only pairs
       are too poorly conditioned to triangulate but their labels miss each other's ray across the play
       volume by more than tau (:func:`epipolar_pair_error`);
    4. each unlabelled view in which the consensus ball projects inside the image (by
       ``inside_margin_px``) gets ``ball_missing`` with the exact sphere box there; with a single
       labelled view, only when the ball is more likely inside than not (:func:`_missing_from_one_view`:
       the segment drawn, a box only on a short segment);
    5. pairs of views from nearly the same viewpoint give ``near_duplicate_view`` naming the one that
       adds nothing (an unlabelled one, else a replay, else the lower JaC).

    Words are not written here: each doubt carries a ``code`` and its numbers, and
    ``app.services.curation.doubt_words`` composes the sentence.

    Args:
        views: the system's views (ids unique).
        settings: thresholds (:class:`DoubtSettings`).
        geometry: where the consensus's pairs' raw geometry comes from (``app.geometry.consensus.ball_consensus``).

    Returns:
        The doubts: info kinds first, then ``mirrored_labels``, ``ball_off_consensus``, ``ball_missing``,
        ``views_disagree`` and ``near_duplicate_view``.

    Raises:
        ValueError: duplicate view ids.
    """
    s = settings
    ids = [v.view_id for v in views]
    if len(set(ids)) != len(ids):
        raise ValueError(f"views: view ids must be unique, got {ids!r}")
    doubts = _info_doubts(views, s)
    lined = [v for v in views if not v.excluded and v.line_classes >= s.min_line_classes]
    calibrated = [v for v in lined if v.camera is not None]
    # the mirror flag is today's verdict whatever the view's admission (JaC is the same for labels and
    # their mirror), also for a view refused as labelled; the ray-based suspicion needs a view that takes part
    flagged = [v for v in lined if v.mirror_flagged]
    suspected = [v for v in calibrated if v not in flagged and v.admitted and _mirror_suspected(v, s)]
    mirrored = flagged + suspected
    # views with few line classes are not judged (their camera is not fixed by their lines), but one whose
    # calibration is sure (pixel sigma within tau, e.g. a rig camera whose few lines fix its rotation)
    # lends its label half a vote to the consensus
    helpers = [v for v in views if not v.excluded and v.camera is not None and v.line_classes < s.min_line_classes
               and not v.mirror_flagged and not v.suggested and _centre(v) is not None]
    tau = max(s.consensus_tau_px, s.triangulation_tau_px)
    sigma: dict[Hashable, float] = {}
    weight: dict[Hashable, float] = {}
    for v in calibrated + helpers:
        weight[v.view_id], sigma[v.view_id] = calibration_weight(v, s)
    helpers = [v for v in helpers if weight[v.view_id] > 0]
    judged = [v for v in calibrated if v not in mirrored and weight[v.view_id] > 0 and not v.suggested]
    labelled = [v for v in judged if _centre(v) is not None]
    unlabelled = [v for v in judged if _centre(v) is None]
    voters = labelled + helpers
    obs = [BallObservation(v.view_id, v.camera, _centre(v), REFERENCE_WIDTH_PX / _scale(v, s)) for v in voters]
    cons = ball_consensus(obs, tau_px=tau, min_baseline_m=s.min_baseline_m, min_parallax_deg=s.min_parallax_deg,
                          weights=weight, tolerances_px=sigma, plausible=lambda p: _plausible(p, s), geometry=geometry)
    lone_contradicted = bool(helpers) and len(labelled) == 1 and (
        labelled[0].view_id not in cons.inliers and (cons.point is not None or cons.best_pair_error_1920 is not None))
    if not any(i in {v.view_id for v in labelled} for i in cons.inliers):
        cons = ball_consensus([], tau_px=tau)  # helpers alone say nothing
    helper_ids = {v.view_id for v in helpers}
    doubts += [_mirror_doubt(v, "flagged" if v in flagged else "suspected", cons, s) for v in mirrored]
    by_id = {v.view_id: v for v in views}
    if cons.point is not None and not cons.ambiguous:
        accusing = sum(weight[i] for i in cons.inliers) >= 1.5  # a full vote and at least a half one
        for vid in cons.outliers if accusing else ():
            if vid in helper_ids:
                continue
            v = by_id[vid]
            e = cons.errors_1920[vid]
            uv = _project(v, cons.point)
            box = sphere_image_box(v.camera, cons.point, s.ball_diameter_m / 2) if uv is not None and _inside(
                v, uv, 0.0) else None
            suggestion = consensus_fix(v, cons, box, s)
            doubts.append(Doubt(
                "ball_off_consensus", vid, "off_consensus" if e is not None else "behind_camera",
                {"error_px_1920": None if e is None else _r(e), "tau_px": _r(max(tau, sigma.get(vid, 0.0))),
                 "calibration_sigma_px_1920": _r(sigma.get(vid, 0.0)), "agreeing_views": list(cons.inliers),
                 "ball3d": [_r(x, 3) for x in cons.point],
                 "projected_px": None if uv is None else [_r(uv[0]), _r(uv[1])]},
                suggestion))
        for v in unlabelled:
            d = _missing_doubt(v, cons, s, "consensus", {"agreeing_views": list(cons.inliers)})
            if d is not None:
                doubts.append(d)
    elif len(labelled) >= 2:
        own = cons if not helpers else ball_consensus(  # the labelled views' own agreement, without the helpers
            obs[:len(labelled)], tau_px=tau, min_baseline_m=s.min_baseline_m, min_parallax_deg=s.min_parallax_deg,
            weights=weight, tolerances_px=sigma, plausible=lambda p: _plausible(p, s), geometry=geometry)
        d = _disagree_doubt(labelled, own, tau, s)
        if d is not None:
            doubts.append(d)
    elif len(labelled) == 1 and not lone_contradicted:
        # (a helper's label that misses the lone label contradicts it: nothing is placed from it)
        for v in unlabelled:
            d = _missing_from_one_view(labelled[0], v, s)
            if d is not None:
                doubts.append(d)
    doubts += _near_duplicates(judged, cons, s)
    return doubts


def _disagree_doubt(labelled: Sequence[DoubtView], cons: Consensus, tau: float, s: DoubtSettings) -> Doubt | None:
    """``views_disagree`` when no ball is agreed on: with a pair error from the consensus (``no_agreement``,
    or ``ambiguous`` for two camps), or, when no pair had the geometry to triangulate, from the labels'
    distances to each other's ray across the play volume (``epipolar``: above tau for every pair). None
    when the views agree within tau but no pair could triangulate (a near-duplicate pair that agrees)."""
    best = cons.best_pair_error_1920
    code = "ambiguous" if cons.ambiguous else "no_agreement"
    if cons.point is not None and not cons.ambiguous:
        return None  # they agree, but no ball is agreed on by the helpers' votes: nothing to say
    if best is None:
        errs = [epipolar_pair_error(a, b, s) for a, b in combinations(labelled, 2)]
        errs = [e for e in errs if e is not None]
        if not errs or min(errs) <= tau:
            return None
        best, code = min(errs), "epipolar"
    return Doubt("views_disagree", None, code,
                 {"views": [v.view_id for v in labelled],
                  "best_pair_error_px_1920": None if math.isinf(best) else _r(best),
                  "tau_px": tau, "ambiguous": cons.ambiguous, "third_view": len(labelled) == 2})
