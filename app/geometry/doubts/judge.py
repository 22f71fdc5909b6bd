"""The judge: the rules that find a system's doubts from its views (consensus, mirrored labels, missing balls,
near duplicates, disagreement), each doubt with its code, evidence and fix (package docstring: the kinds).
"""
from __future__ import annotations

import dataclasses
import math
from itertools import combinations
from typing import Any, Callable, Hashable, Iterable, Mapping, Sequence

import numpy as np

from app.geometry.ball import sphere_image_box
from app.geometry.consensus import Consensus, ball_consensus
from app.geometry.doubts.contract import Doubt, DoubtSettings, DoubtView, _box_list, _inside, _plausible, _r
from app.geometry.doubts.epipolar import _mono, _sees, _segment, _single_view_ball, epipolar_pair_error
from app.geometry.doubts.lone_pair import lone_pair_doubts
from app.geometry.mirror import mirror_camera
from app.geometry.pair_error import REFERENCE_WIDTH_PX
from app.geometry.triangulation import (
    BallObservation,
    PairGeometry,
    angle_between_deg,
    pair_geometry,
    reprojection_error_px,
)
from app.geometry.weighting import (
    axis_on_grass,
    calibration_weight,
    camera_of,
    centre_of,
    label_centre,
    pixel_sigma,
    project_point,
    rule_scale,
)


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
    camera to make worse. A camera the players placed whose lines fit it only mirrored (``refit`` of source
    ``players``) stays where it is with the fix, the labels mirrored to meet it: the camera as labelled is its mirror
    image, so the errors swap roles; without a ball the players' fit, with the game's rig, confirms the fix.
    """
    if v.camera is None:
        if ev.get("refit") or ev.get("verdict") == "probably_mirrored":
            return (True, "", {})
        return (False, "no_ray_confirms", {})
    by_players = (ev.get("refit") or {}).get("source") == "players"
    c = label_centre(v)
    if others is not None and others.point is not None and not others.ambiguous and c is not None:
        k = rule_scale(v, s)
        as_labelled, fixed = (mirror_camera(v.camera), v.camera) if by_players else (v.camera, mirror_camera(v.camera))
        e_as = reprojection_error_px(as_labelled, others.point, c)
        e_mi = reprojection_error_px(fixed, others.point, c)
        numbers = {"error_as_labelled_px_1920": None if e_as is None else _r(e_as * k),
                   "error_mirrored_px_1920": None if e_mi is None else _r(e_mi * k),
                   "agreeing_views": list(others.inliers)}
        tau = max(s.consensus_tau_px, s.triangulation_tau_px)
        if e_as is not None and (e_mi is None or e_as <= e_mi):
            return False, "as_labelled_fits", numbers
        if e_mi is None or e_mi * k > tau:
            return False, "mirrored_misses", numbers
        return True, "", numbers
    if by_players:
        return True, "", {"players_confirm": True}
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
            if ref is None and label_centre(v) is not None:
                ref = _single_view_ball(v, s)[0]
        if ref is None:
            ref = axis_on_grass(a, s)
        if ref is None:
            continue
        u, w = ref - camera_of(a).C, ref - camera_of(b).C
        angle = angle_between_deg(u, w)
        if angle >= s.near_duplicate_max_deg or not (_sees(a, ref) and _sees(b, ref)):
            continue
        # Name the view that adds nothing: an unlabelled one, else a replay, else the lower JaC.
        keep, drop = sorted((a, b), key=lambda v: (label_centre(v) is None, v.role != "action", -(v.jac or 0.0)))
        named.add(drop.view_id)
        out.append(Doubt(
            "near_duplicate_view", drop.view_id, "near_duplicate",
            {"other_view": keep.view_id, "angle_deg": _r(angle, 3), "baseline_m": _r(float(np.linalg.norm(u - w)), 2),
             "max_deg": s.near_duplicate_max_deg},
            {"action": "exclude_view"}))
    return out


def consensus_box_sigma_px(v: DoubtView, consensus: Consensus, s: DoubtSettings) -> float | None:
    """How far (px of ``v``'s own image, one standard deviation) the consensus ball's box in ``v`` may lie from
    where the ball is: the agreeing views' own spread (the RMS of their reprojection errors to the consensus
    ball, px at 1920 width: how well the rays that made it meet) and ``v``'s calibration's pixel sigma at that
    ball (:func:`~app.geometry.weighting.pixel_sigma`: how far its camera may put the ball's projection), added in
    quadrature and scaled to ``v``'s pixels. None when ``v``'s calibration leaves the pixel undetermined (``inf``)."""
    found = [consensus.errors_1920.get(i) for i in consensus.inliers]
    errs = [e for e in found if e is not None and math.isfinite(e)]
    spread = math.sqrt(sum(e * e for e in errs) / len(errs)) if errs else 0.0
    assert consensus.point is not None  # a consensus box is asked for only where there is a consensus ball
    own = pixel_sigma(v, consensus.point, s)
    if not math.isfinite(own):
        return None
    return _r(math.hypot(spread, own) / rule_scale(v, s), 2)


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
    assert ball is not None  # asked only where the views agree on a ball
    uv = project_point(v, ball)
    margin = s.inside_margin_px if margin_px is None else margin_px
    if uv is None or not _inside(v, uv, margin / rule_scale(v, s)):
        return None
    box = sphere_image_box(camera_of(v), ball, s.ball_diameter_m / 2)
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
    taken as a normal law (sigma ``ground_box_tolerance`` / 2) over the segment, is at least a half, or the box
    size agrees with the ball on the grass (placed ``grass``: most balls are on the ground, and the box does not say
    otherwise). A ball the box places in the air that only the grass guess puts inside is not claimed (an
    out-of-frame replay would be called missing). The segment is drawn (``evidence["epipolar_px"]``); a box is
    suggested only where the segment is short enough that any point on it lies within ``consensus_tau_px`` of its
    middle (code ``epipolar_box``; ``epipolar`` without a box). A suggested box lies on the other view's ray by
    construction, so it is a guess, not evidence (the service keeps its provenance)."""
    ball, how = _single_view_ball(only, s)
    if ball is None or not _plausible(ball, s):
        return None
    uv0 = project_point(v, ball)
    m = s.inside_margin_px / rule_scale(v, s)
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
        depth = np.linalg.norm(pts - camera_of(only).C, axis=1) / np.linalg.norm(mono - camera_of(only).C)
        w = np.exp(-0.5 * ((depth - 1.0) / (s.ground_box_tolerance / 2)) ** 2)
    else:
        w = np.ones(len(pts))
    chance = float(np.sum(w * inside) / np.sum(w))
    if chance < 0.5 and how != "grass":  # a box that agrees with the grass puts the ball where most balls are
        return None
    seen = uv[inside]
    length = float(np.sum(np.linalg.norm(np.diff(seen, axis=0), axis=1))) * rule_scale(v, s)
    evidence: dict[str, Any] = {"agreeing_views": [only.view_id], "epipolar_px": [[_r(x), _r(y)] for x, y in seen],
                                "segment_length_px_1920": _r(length), "inside_fraction": _r(inside.mean(), 2),
                                "inside_chance": _r(chance, 2),
                                "grass_px": [_r(uv0[0]), _r(uv0[1])], "placed": how, "depth_known": False}
    if length / 2 > s.consensus_tau_px or not inside.all():
        return Doubt("ball_missing", v.view_id, "epipolar", evidence, None)
    box = sphere_image_box(camera_of(v), ball, s.ball_diameter_m / 2)
    if box is None:
        return Doubt("ball_missing", v.view_id, "epipolar", evidence, None)
    evidence.update(projected_px=[_r(uv0[0]), _r(uv0[1])], ball3d=[_r(x, 3) for x in ball])
    # its uncertainty: the ball may lie anywhere on the stretch drawn, half its length either side of the box
    return Doubt("ball_missing", v.view_id, "epipolar_box", evidence,
                 {"action": "snap_box", "box": _box_list(box), "box_sigma_px": _r(length / 2 / rule_scale(v, s))})


@dataclasses.dataclass(frozen=True)
class _Votes:
    """Who votes on a system's ball and how much (the judge's rules 2 and 3, :func:`judge_system`)."""

    flagged: list[DoubtView]
    mirrored: list[DoubtView]
    helpers: list[DoubtView]
    judged: list[DoubtView]
    labelled: list[DoubtView]
    unlabelled: list[DoubtView]
    weight: dict[Hashable, float]
    sigma: dict[Hashable, float]
    tau: float
    obs: list[BallObservation]


def _votes(views: Sequence[DoubtView], s: DoubtSettings,
           weighed: Mapping[Hashable, tuple[float, float]] | None) -> _Votes:
    """The views that take part in the consensus and their votes (rules 2 and 3 of :func:`judge_system`)."""
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
               and not v.mirror_flagged and not v.suggested and label_centre(v) is not None]
    tau = max(s.consensus_tau_px, s.triangulation_tau_px)
    sigma: dict[Hashable, float] = {}
    weight: dict[Hashable, float] = {}
    for v in calibrated + helpers:
        known = weighed.get(v.view_id) if weighed is not None else None
        weight[v.view_id], sigma[v.view_id] = known if known is not None else calibration_weight(v, s)
    helpers = [v for v in helpers if weight[v.view_id] > 0]
    judged = [v for v in calibrated if v not in mirrored and weight[v.view_id] > 0 and not v.suggested]
    labelled = [v for v in judged if label_centre(v) is not None]
    unlabelled = [v for v in judged if label_centre(v) is None]
    obs = [BallObservation(v.view_id, camera_of(v), centre_of(v), REFERENCE_WIDTH_PX / rule_scale(v, s))
           for v in labelled + helpers]
    return _Votes(flagged, mirrored, helpers, judged, labelled, unlabelled, weight, sigma, tau, obs)


def _voters_consensus(vote: _Votes, s: DoubtSettings,
                      geometry: Callable[[BallObservation, BallObservation], PairGeometry]) -> tuple[Consensus, bool]:
    """The voters' robust consensus (rule 3 of :func:`judge_system`; helpers alone say nothing), and whether the lone
    labelled view is contradicted by a helper's label (then nothing is placed from it)."""
    cons = ball_consensus(vote.obs, tau_px=vote.tau, min_baseline_m=s.min_baseline_m,
                          min_parallax_deg=s.min_parallax_deg, weights=vote.weight, tolerances_px=vote.sigma,
                          plausible=lambda p: _plausible(p, s), geometry=geometry)
    lone_contradicted = bool(vote.helpers) and len(vote.labelled) == 1 and (
        vote.labelled[0].view_id not in cons.inliers
        and (cons.point is not None or cons.best_pair_error_1920 is not None))
    if not any(i in {v.view_id for v in vote.labelled} for i in cons.inliers):
        # helpers alone say nothing
        cons = ball_consensus([], tau_px=vote.tau, min_baseline_m=s.min_baseline_m,
                              min_parallax_deg=s.min_parallax_deg)
    return cons, lone_contradicted


def consensus_without(views: Sequence[DoubtView], view_id: Hashable, settings: DoubtSettings,
                      geometry: Callable[[BallObservation, BallObservation], PairGeometry] = pair_geometry,
                      weighed: Mapping[Any, tuple[float, float]] | None = None) -> Consensus:
    """The ball the views other than ``view_id`` agree on, exactly as :func:`judge_system` finds a system's
    consensus (rules 2 and 3: who votes, with what weight and pixel tolerance, within the play volume), with that
    view left out as if excluded: what a fix of that view's labels is measured against (the mirror guard,
    ``app.services.curation.editing.ball_error_to_others``). Pure. ``weighed`` as :func:`judge_system`'s.

    Returns:
        The :class:`~app.geometry.consensus.Consensus` (its ``point`` None when the others agree on no ball).
    """
    return consensuses_without(views, [view_id], settings, geometry, weighed)[view_id]


def consensuses_without(views: Sequence[DoubtView], view_ids: Iterable[Hashable], settings: DoubtSettings,
                        geometry: Callable[[BallObservation, BallObservation], PairGeometry] = pair_geometry,
                        weighed: Mapping[Any, tuple[float, float]] | None = None) -> dict[Hashable, Consensus]:
    """:func:`consensus_without` of each view of ``view_ids``: view id -> the ball the other views agree on. Who
    votes and how much is decided once for all the views (every rule of :func:`_votes` is a test of one view alone, so
    leaving a view out is taking it off every list: the same as marking it excluded and deciding again). Pure.
    ``weighed`` as :func:`judge_system`'s."""
    vote = _votes(views, settings, weighed)
    return {vid: _voters_consensus(_left_out(vote, vid), settings, geometry)[0] for vid in view_ids}


def _left_out(vote: _Votes, view_id: Hashable) -> _Votes:
    """``vote`` with view ``view_id`` taking no part (what :func:`_votes` gives with that view excluded)."""
    def keep(views: list[DoubtView]) -> list[DoubtView]:
        return [v for v in views if v.view_id != view_id]

    return dataclasses.replace(vote, flagged=keep(vote.flagged), mirrored=keep(vote.mirrored),
                               helpers=keep(vote.helpers), judged=keep(vote.judged), labelled=keep(vote.labelled),
                               unlabelled=keep(vote.unlabelled), obs=[o for o in vote.obs if o.view_id != view_id])


def judge_system(views: Sequence[DoubtView], settings: DoubtSettings,
                 geometry: Callable[[BallObservation, BallObservation], PairGeometry] = pair_geometry,
                 weighed: Mapping[Any, tuple[float, float]] | None = None) -> list[Doubt]:
    """Every doubt of one multi-view system (pure, deterministic; see the module docstring for the kinds).

    Rules, in order:

    1. info doubts per view (refused calibration, below admission, rig-assisted, few line classes);
    2. views that take part: calibrated, not excluded by the reviewer, with at least
       ``min_line_classes`` line classes, and a vote (:func:`app.geometry.weighting.calibration_weight`: what
       the calibration is worth, from admission and its pixel sigma). A view with at least
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
       volume by more than tau (:func:`epipolar_pair_error`), and when a ball rests on one pair of sure viewpoints
       meeting only at tau's edge (code ``lone_pair``, :func:`~app.geometry.doubts.lone_pair.lone_pair_doubts`);
    4. each unlabelled view in which the consensus ball projects inside the image (by
       ``inside_margin_px``) gets ``ball_missing`` with the exact sphere box there; with a single
       labelled view, only when the ball is more likely inside than not (:func:`_missing_from_one_view`:
       the segment drawn, a box only on a short segment);
    5. pairs of views from nearly the same viewpoint give ``near_duplicate_view`` naming the one that
       adds nothing (an unlabelled one, else a replay, else the lower JaC).

    Words are not written here: each doubt carries a ``code`` and its numbers, and
    ``app.services.wording.doubt_words`` composes the sentence.

    Args:
        views: the system's views (ids unique).
        settings: thresholds (:class:`DoubtSettings`).
        geometry: where the consensus's pairs' raw geometry comes from (``app.geometry.consensus.ball_consensus``).
        weighed: view id -> ``calibration_weight(view, settings)`` (weight, pixel sigma at 1920 px) where the caller
            computed it for these views and settings already (the triangulation's weights); computed here otherwise.

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
    vote = _votes(views, s, weighed)
    flagged, mirrored, helpers = vote.flagged, vote.mirrored, vote.helpers
    weight, sigma, tau = vote.weight, vote.sigma, vote.tau
    judged, labelled, unlabelled = vote.judged, vote.labelled, vote.unlabelled
    cons, lone_contradicted = _voters_consensus(vote, s, geometry)
    helper_ids = {v.view_id for v in helpers}
    doubts += [_mirror_doubt(v, "flagged" if v in flagged else "suspected", cons, s) for v in mirrored]
    by_id = {v.view_id: v for v in views}
    if cons.point is not None and not cons.ambiguous:
        accusing = sum(weight[i] for i in cons.inliers) >= 1.5  # a full vote and at least a half one
        off = [by_id[vid] for vid in cons.outliers if accusing and vid not in helper_ids]
        placed_off = _players_placed_off(views, cons, vote, s, {v.view_id for v in off}) if accusing else {}
        doubts += _off_consensus_doubts([*off, *(by_id[vid] for vid in placed_off)], cons, cons.point, sigma, tau, s,
                                        {**cons.errors_1920, **placed_off})
        missing = (_missing_doubt(v, cons, s, "consensus", {"agreeing_views": list(cons.inliers)}) for v in unlabelled)
        doubts += [d for d in missing if d is not None]
        doubts += lone_pair_doubts(cons, vote.obs, [v.view_id for v in labelled], weight, sigma, s, geometry)
    elif len(labelled) >= 2:
        doubts += _disagreement(vote, cons, s, geometry)
    elif len(labelled) == 1 and not lone_contradicted:
        # (a helper's label that misses the lone label contradicts it: nothing is placed from it)
        for v in unlabelled:
            d = _missing_from_one_view(labelled[0], v, s)
            if d is not None:
                doubts.append(d)
    doubts += _near_duplicates(judged, cons, s)
    return doubts


def _disagreement(vote: _Votes, cons: Consensus, s: DoubtSettings,
                  geometry: Callable[[BallObservation, BallObservation], PairGeometry]) -> list[Doubt]:
    """``views_disagree`` of two or more labelled views with no consensus or an ambiguous one (rule 3 of
    :func:`judge_system`), judged on the labelled views' own agreement (without the helpers, when there are any)."""
    labelled, weight, sigma, tau = vote.labelled, vote.weight, vote.sigma, vote.tau
    own = cons if not vote.helpers else ball_consensus(  # the labelled views' own agreement, without the helpers
        vote.obs[:len(labelled)], tau_px=tau, min_baseline_m=s.min_baseline_m, min_parallax_deg=s.min_parallax_deg,
        weights=weight, tolerances_px=sigma, plausible=lambda p: _plausible(p, s), geometry=geometry)
    d = _disagree_doubt(labelled, own, tau, s)
    return [] if d is None else [d]


#: A label of a view whose camera its players placed is accused (and snapped) only beyond this many times its
#: tolerance (tau widened to the camera's pixel sigma): such a view takes no part in the consensus, so the label is
#: accused on its own camera's word, which must then be far surer than the label. Measured with the guards of
#: :func:`_players_placed_off` on the dev set, dev-large and the five doubts seeds: 7 such labels accused, each on the
#: wrong spot (293-1575 px@1920 from the ball), every snap 1.6-18.7 px@1920 from the true ball; no right label
#: accused (without the guards, 3 right labels of systems with a replay out of time were, their snaps 197-265 px off).
#: 12 labels on the wrong spot stay unaccused (no ball agreed on, or a guard): a fix missed, never one made wrong.
PLAYERS_PLACED_MARGIN = 3.0


def _players_placed_off(views: Sequence[DoubtView], cons: Consensus, vote: _Votes, s: DoubtSettings,
                        accused: Iterable[Hashable]) -> dict[Hashable, float]:
    """View id -> error (px at 1920 width) of each labelled view whose camera its players placed (flag
    ``player_assisted``: the pose over-determined by the players it shares with the well-lined views,
    ``app.geometry.calibration.players``) and sure (pixel sigma within tau), off the consensus ball by more than
    :data:`PLAYERS_PLACED_MARGIN` tolerances, and not ``accused`` already (the consensus accuses its outliers but
    the helpers, and never a camera with no vote). Its few lines do not fix its camera, which is why it is no voter;
    its players do, so a label hundreds of px from where that camera sees the agreed ball is the label's error, and
    the consensus box is the fix (rule 3 of :func:`judge_system`). Only on a ball that at least two labelled full
    votes agree on, every voter within half of tau of it: a replay out of time among the voters (or a label of
    another moment in the view itself, agreed on by one full vote and a half one) leaves a ball its snap would make
    worse. (vote: the judge's votes, :func:`_votes`.)"""
    assert cons.point is not None  # asked only where the views agree on a ball
    sigma, tau = vote.sigma, vote.tau
    labelled = {v.view_id for v in vote.labelled}
    full = [i for i in cons.inliers if i in labelled and vote.weight.get(i, 0.0) >= 1.0]
    errors = [cons.errors_1920.get(i) for i in cons.inliers]
    if len(full) < 2 or any(e is None or e > tau / 2 for e in errors):
        return {}
    off: dict[Hashable, float] = {}
    skip = {*cons.inliers, *accused}
    for v in views:
        vid = v.view_id
        if (not v.player_assisted or v.excluded or v.camera is None or v.mirror_flagged or v.suggested
                or label_centre(v) is None or vid in skip):
            continue
        own = sigma.get(vid, math.inf)
        if own > tau:
            continue
        e = reprojection_error_px(camera_of(v), cons.point, centre_of(v))
        if e is not None and e * rule_scale(v, s) > PLAYERS_PLACED_MARGIN * max(tau, own):
            off[vid] = e * rule_scale(v, s)
    return off


def _off_consensus_doubts(outliers: Sequence[DoubtView], cons: Consensus, point: np.ndarray,
                         sigma: Mapping[Any, float], tau: float, s: DoubtSettings,
                         errors_1920: Mapping[Hashable, float | None] | None = None) -> list[Doubt]:
    """``ball_off_consensus`` of each of ``outliers``, labelled views off the non-ambiguous consensus ``cons`` of ball
    ``point`` (rule 3 of :func:`judge_system`): its error (``errors_1920``, px at 1920 width; the consensus's own
    when None) and tolerance, the agreeing views, and the fix (:func:`consensus_fix`) with the consensus ball's box
    where the ball projects inside the view."""
    errors = cons.errors_1920 if errors_1920 is None else errors_1920
    doubts = []
    for v in outliers:
        vid = v.view_id
        e = errors[vid]
        uv = project_point(v, point)
        box = sphere_image_box(camera_of(v), point, s.ball_diameter_m / 2) if uv is not None and _inside(
            v, uv, 0.0) else None
        suggestion = consensus_fix(v, cons, box, s)
        doubts.append(Doubt(
            "ball_off_consensus", vid, "off_consensus" if e is not None else "behind_camera",
            {"error_px_1920": None if e is None else _r(e), "tau_px": _r(max(tau, sigma.get(vid, 0.0))),
             "calibration_sigma_px_1920": _r(sigma.get(vid, 0.0)), "agreeing_views": list(cons.inliers),
             "ball3d": [_r(x, 3) for x in point],
             "projected_px": None if uv is None else [_r(uv[0]), _r(uv[1])]},
            suggestion))
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
        pair_errors = [epipolar_pair_error(a, b, s) for a, b in combinations(labelled, 2)]
        errs = [e for e in pair_errors if e is not None]
        if not errs or min(errs) <= tau:
            return None
        best, code = min(errs), "epipolar"
    return Doubt("views_disagree", None, code,
                 {"views": [v.view_id for v in labelled],
                  "best_pair_error_px_1920": None if math.isinf(best) else _r(best),
                  "tau_px": tau, "ambiguous": cons.ambiguous, "third_view": len(labelled) == 2})
