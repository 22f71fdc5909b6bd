"""Doubts: the label problems the geometry of one multi-view system can see, each with its evidence
and, where there is one, its fix.

A system's doubts are recomputed with every edit (``app.services.curation.recompute``) and stored; this module
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

Thresholds: :class:`DoubtSettings` (chosen with ``benchmarks/doubts.py``). The module has about 480
lines because the contract, the settings and the judge's rules belong together; the robust
consensus lives in :mod:`app.geometry.consensus`.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from itertools import combinations
from typing import Any, Hashable, Sequence

import numpy as np

from app.geometry.ball import ball_from_box_exact, sphere_image_box
from app.geometry.camera import Camera
from app.geometry.consensus import Consensus, ball_consensus
from app.geometry.triangulation import REFERENCE_WIDTH_PX, BallObservation

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
#: ``snap_point``: set the view's point label to ``suggestion["point"]`` (ISSIA, where the sequence's
#: trajectory projects).
SUGGESTION_ACTIONS: tuple[str, ...] = ("snap_box", "exclude_view", "mirror_labels", "snap_point")


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
        single_view_margin_px: with a single other labelled view the ball's depth along its ray is
            uncertain (a ball in the air put on the grass moves along the epipolar line): it must
            project at least this far inside the image for ``ball_missing`` (px at 1920 width).
        ground_box_tolerance: with a single other labelled view, the ball is put on the grass when the
            monocular depth from the box is within this relative difference of the grass depth on its
            ray (fraction; SoccerNet-v3 boxes err by about 19 % in size).
        mirror_rig_near_m, mirror_rig_gap_m: an unflagged view is suspected mirrored when its ray meets
            another view's only mirrored and its mirrored camera stands within ``mirror_rig_near_m`` of a
            known camera position of the game while as labelled it stands ``mirror_rig_gap_m`` farther
            (metres; calibrated centres of one camera scatter by about a metre).
        max_ball_height_m: highest plausible ball (metres above the grass) for a placed ball.
        min_line_classes: a view with fewer distinct line classes gets the info doubt ``few_lines`` and
            takes no part in the checks: with the game's rig, two or three classes give a camera that
            fits its own lines perfectly (JaC 1.0) yet may turn its ball ray by degrees, so its ball
            would be accused for its camera's fault (on dev-large, every false alarm of that kind).
    """

    triangulation_tau_px: float = 20.0
    pair_error_rule: str = "max_scaled_1920"
    min_baseline_m: float = 1.0
    min_parallax_deg: float = 2.0
    ball_diameter_m: float = 0.22
    consensus_tau_px: float = 25.0
    near_duplicate_max_deg: float = 3.0
    inside_margin_px: float = 0.0
    single_view_margin_px: float = 40.0
    ground_box_tolerance: float = 0.35
    max_ball_height_m: float = 30.0
    mirror_rig_near_m: float = 1.0
    mirror_rig_gap_m: float = 2.0
    min_line_classes: int = 4


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
    """A ball in or near the stadium: within 30 m of the pitch, below ``max_ball_height_m``, not underground."""
    return bool(abs(point[0]) < 82.5 and abs(point[1]) < 64.0 and -s.max_ball_height_m <= point[2] <= 0.5)


def _info_doubts(views: Sequence[DoubtView], s: DoubtSettings) -> list[Doubt]:
    out: list[Doubt] = []
    for v in views:
        if v.camera is None:
            reason = v.calibration_reason or "no calibration"
            out.append(Doubt("calibration_refused", v.view_id, f"{v.name} has no camera ({reason}), so its labels "
                             "cannot be checked against the other views.", {"reason": reason}))
        elif not v.admitted:
            out.append(Doubt("below_admission", v.view_id, f"{v.name} is calibrated with JaC@0.5 % "
                             f"{_fmt(v.jac)}, below admission, so it takes no part in the checks.",
                             {"jac": None if v.jac is None else _r(v.jac, 4)}))
        if v.rig_assisted:
            out.append(Doubt("rig_assisted", v.view_id, f"{v.name} was calibrated at a camera position of the "
                             "game's rig (its lines alone did not fix the camera).", {}))
        if v.line_classes < s.min_line_classes:
            out.append(Doubt("few_lines", v.view_id, f"{v.name} has {v.line_classes} field-line classes "
                             f"(fewer than {s.min_line_classes}), too few to fix its camera reliably.",
                             {"line_classes": int(v.line_classes), "min_line_classes": int(s.min_line_classes)}))
    return out


def _fmt(x: float | None, nd: int = 3) -> str:
    return "unknown" if x is None else f"{x:.{nd}f}"


def _mirror_doubt(v: DoubtView) -> Doubt:
    ev = dict(v.mirror_evidence or {})
    evidence = {k: ev[k] for k in ("verdict", "margin", "camera_y_m", "mirrored_camera_y_m", "side_vote",
                                   "rig_distance_m", "rig_distance_mirrored_m", "rig_vote", "sentence") if k in ev}
    evidence["flagged"] = bool(v.mirror_flagged)
    if v.mirror_flagged:
        margin = ev.get("margin")
        why = "the mirror evidence flags it" + (f" (margin {margin:.1f})" if isinstance(margin, (int, float)) else "")
    else:
        why = (f"its ball ray meets another view's only mirrored, and mirrored its camera stands "
               f"{ev['rig_distance_mirrored_m']:.2f} m from a known camera of the game against "
               f"{ev['rig_distance_m']:.1f} m as labelled")
    return Doubt("mirrored_labels", v.view_id, f"{v.name}'s field lines look labelled left for right: {why}.",
                 evidence, {"action": "mirror_labels"})


def _mirror_suspected(v: DoubtView, s: DoubtSettings) -> bool:
    """Not flagged, but the mirror evidence points at this view: its ball ray meets another view's only
    when one of the two is mirrored (relation "different"), and its mirrored camera stands at a known
    camera position of the game (within ``mirror_rig_near_m``) while as labelled it stands at least
    ``mirror_rig_gap_m`` farther from every one. The flag itself weighs that rig vote low so that it
    never flags alone; a doubt asks a person to look, so the pair's disagreement plus the rig suffice."""
    ev = v.mirror_evidence or {}
    d, dm = ev.get("rig_distance_m"), ev.get("rig_distance_mirrored_m")
    if v.mirror_flagged or not isinstance(d, (int, float)) or not isinstance(dm, (int, float)):
        return False
    different = any(p.get("relation") == "different" for p in ev.get("pairs") or [])
    return bool(different and dm <= s.mirror_rig_near_m and d >= dm + s.mirror_rig_gap_m)


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
            "near_duplicate_view", drop.view_id,
            f"{drop.name} sees the ball from nearly the same place as {keep.name} (their cameras are "
            f"{angle:.2f} deg apart seen from the ball, {np.linalg.norm(u - w):.1f} m apart), so it adds no depth.",
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
    if v.box is None:
        return grass, "grass"
    mono = ball_from_box_exact(v.camera, np.asarray(v.box, float), s.ball_diameter_m)[0]
    if grass is not None:
        ratio = np.linalg.norm(mono - v.camera.C) / np.linalg.norm(grass - v.camera.C)
        if abs(ratio - 1.0) <= s.ground_box_tolerance:
            return grass, "grass"
    return mono, "box"


def _epipolar_px(labelled: DoubtView, missing: DoubtView, s: DoubtSettings, samples: int = 64) -> list[list[float]]:
    """The labelled view's ball ray seen in the missing view: pixels of the missing view inside its image,
    from 1 m in front of the labelled camera to where the ray meets the ball-on-grass height (or 300 m),
    at most ``samples`` points evenly spread in depth over the stretch of the ray the view sees."""
    c = _centre(labelled)
    ray = labelled.camera.rays(c.reshape(1, 2))[0]
    grass = _ray_at_height(labelled.camera.C, ray, -s.ball_diameter_m / 2)
    far = 300.0 if grass is None else min(300.0, float(np.linalg.norm(grass - labelled.camera.C)))
    if far <= 1.0:
        return []
    def inside(t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        uv, ok = missing.camera.project(labelled.camera.C + t[:, None] * ray)
        with np.errstate(invalid="ignore"):
            keep = ok & (uv[:, 0] >= 0) & (uv[:, 0] <= missing.width) & (uv[:, 1] >= 0) & (uv[:, 1] <= missing.height)
        return uv, keep

    coarse = np.geomspace(1.0, far, 4 * samples)  # find the stretch of the ray that the view sees ...
    _, keep = inside(coarse)
    if not keep.any():
        return []
    idx = np.flatnonzero(keep)
    lo, hi = coarse[max(idx[0] - 1, 0)], coarse[min(idx[-1] + 1, len(coarse) - 1)]
    uv, keep = inside(np.linspace(lo, hi, samples))  # ... then sample it evenly
    return [[_r(x, 1), _r(y, 1)] for x, y in uv[keep]]


def _missing_doubt(v: DoubtView, ball: np.ndarray, s: DoubtSettings, source: str,
                   extra: dict[str, Any], margin_px: float | None = None) -> Doubt | None:
    """``ball_missing`` for an unlabelled view when ``ball`` projects inside its image by ``margin_px``
    (px at 1920 width; default ``inside_margin_px``), else None."""
    uv = _project(v, ball)
    margin = s.inside_margin_px if margin_px is None else margin_px
    if uv is None or not _inside(v, uv, margin / _scale(v, s)):
        return None
    box = sphere_image_box(v.camera, ball, s.ball_diameter_m / 2)
    if box is None:
        return None
    evidence = {"projected_px": [_r(uv[0]), _r(uv[1])], "ball3d": [_r(x, 3) for x in ball], "source": source,
                **extra}
    return Doubt("ball_missing", v.view_id,
                 f"{v.name} has no ball label, but the ball {source} projects inside it at "
                 f"({uv[0]:.0f}, {uv[1]:.0f}) px.", evidence, {"action": "snap_box", "box": _box_list(box)})


def judge_system(views: Sequence[DoubtView], settings: DoubtSettings = DoubtSettings()) -> list[Doubt]:
    """Every doubt of one multi-view system (pure, deterministic; see the module docstring for the kinds).

    Rules, in order:

    1. info doubts per view (refused calibration, below admission, rig-assisted, few line classes);
    2. views that take part: calibrated, admitted, not excluded by the reviewer, with at least
       ``min_line_classes`` line classes. A calibrated view flagged mirrored (admitted or not: JaC is
       the same for labels and their mirror), or a view that takes part and is suspected mirrored
       (:func:`_mirror_suspected`), gets ``mirrored_labels`` and takes no further part (its camera is
       the mirrored one, so its ray says nothing about its ball label, and it is not accused twice);
    3. the labelled views' robust consensus (:func:`app.geometry.consensus.ball_consensus` with
       ``consensus_tau_px``): each labelled view off a non-ambiguous consensus gets
       ``ball_off_consensus`` (fix: exclude it, or snap to the consensus ball's box); labelled views
       with no consensus or an ambiguous one give one ``views_disagree`` for the system;
    4. each unlabelled view in which the consensus ball projects inside the image (by
       ``inside_margin_px``) gets ``ball_missing`` with the exact sphere box there; with a single
       labelled view the ball is placed on its ray (:func:`_single_view_ball`) and the ray's epipolar
       segment goes in the evidence (``epipolar_px``);
    5. pairs of views from nearly the same viewpoint give ``near_duplicate_view`` naming the one that
       adds nothing (an unlabelled one, else a replay, else the lower JaC).

    Args:
        views: the system's views (ids unique).
        settings: thresholds (:class:`DoubtSettings`).

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
    usable = [v for v in views if v.camera is not None and v.admitted and not v.excluded
              and v.line_classes >= s.min_line_classes]
    # the mirror flag is today's verdict whatever the view's admission (JaC is the same for labels and
    # their mirror); the ray-based suspicion needs a view that takes part
    flagged = [v for v in views if v.mirror_flagged and v.camera is not None and not v.excluded]
    mirrored = flagged + [v for v in usable if v not in flagged and _mirror_suspected(v, s)]
    doubts += [_mirror_doubt(v) for v in mirrored]
    judged = [v for v in usable if v not in mirrored]
    labelled = [v for v in judged if _centre(v) is not None]
    unlabelled = [v for v in judged if _centre(v) is None]
    tau = max(s.consensus_tau_px, s.triangulation_tau_px)
    obs = [BallObservation(v.view_id, v.camera, _centre(v), REFERENCE_WIDTH_PX / _scale(v, s))
           for v in labelled]
    cons = ball_consensus(obs, tau_px=tau, min_baseline_m=s.min_baseline_m, min_parallax_deg=s.min_parallax_deg)
    by_id = {v.view_id: v for v in views}
    if cons.point is not None and not cons.ambiguous:
        support = [by_id[i].name for i in cons.inliers]
        for vid in cons.outliers:
            v = by_id[vid]
            e = cons.errors_1920[vid]
            uv = _project(v, cons.point)
            box = sphere_image_box(v.camera, cons.point, s.ball_diameter_m / 2) if uv is not None and _inside(
                v, uv, 0.0) else None
            suggestion: dict[str, Any] = {"action": "exclude_view"}
            if box is not None:
                suggestion["box"] = _box_list(box)
            far = "behind the camera" if e is None else f"{e:.0f} px (at 1920 width) away"
            doubts.append(Doubt(
                "ball_off_consensus", vid,
                f"{v.name}'s ball label is {far} from the ball that {', '.join(support)} agree on "
                f"(tolerance {tau:.0f} px).",
                {"error_px_1920": None if e is None else _r(e), "tau_px": tau, "agreeing_views": list(cons.inliers),
                 "ball3d": [_r(x, 3) for x in cons.point],
                 "projected_px": None if uv is None else [_r(uv[0]), _r(uv[1])]},
                suggestion))
        for v in unlabelled:
            d = _missing_doubt(v, cons.point, s, f"that {', '.join(support)} agree on",
                               {"agreeing_views": list(cons.inliers)})
            if d is not None:
                doubts.append(d)
    elif len(labelled) >= 2 and cons.best_pair_error_1920 is not None:
        doubts.append(_disagree_doubt(labelled, cons, tau))
    elif len(labelled) == 1:
        only = labelled[0]
        ball, how = _single_view_ball(only, s)
        if ball is not None and _plausible(ball, s):
            for v in unlabelled:
                src = f"of {only.name} ({'on the grass along its ray' if how == 'grass' else 'from its box size'})"
                d = _missing_doubt(v, ball, s, src, {"agreeing_views": [only.view_id], "placed": how,
                                                     "epipolar_px": _epipolar_px(only, v, s)},
                                   margin_px=s.single_view_margin_px)
                if d is not None:
                    doubts.append(d)
    doubts += _near_duplicates(judged, cons, s)
    return doubts


def _disagree_doubt(labelled: Sequence[DoubtView], cons: Consensus, tau: float) -> Doubt:
    names = ", ".join(v.name for v in labelled)
    best = cons.best_pair_error_1920
    miss = "their rays diverge" if math.isinf(best) else f"best pair misses by {best:.0f} px at 1920 width"
    decide = ("a third view of the ball" if len(labelled) == 2 else "another view of the ball") + \
        " or a check of the replays' timing would tell which label is wrong"
    return Doubt("views_disagree", None,
                 f"The ball labels of {names} cannot all be right ({miss}, tolerance "
                 f"{tau:.0f} px); {decide}.",
                 {"views": [v.view_id for v in labelled], "best_pair_error_px_1920": None if math.isinf(best) else _r(best),
                  "tau_px": tau, "ambiguous": cons.ambiguous, "decide_by": decide})
