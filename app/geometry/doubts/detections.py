"""A ball detector's predictions checked against the other views: which detection, if any, is the ball a view
nobody labelled shows.

A detector finds the ball in most images it is run on, and other things too (players' heads and feet, anything
round); its score alone cannot tell them apart. The views of a multi-view system can: the ball is one sphere of
diameter phi = 0.22 m (``app.geometry.pitch.BALL_DIAMETER_M``), so a detection that is the ball in a view without a
label must satisfy three conditions at once (SoccerNet-v3D paper, Sec. 3, multi-view triangulation and
Eq. ball3Destimation; method.md sections 5-6):

1. **Rays meet.** Its centre's ray meets the rays of the labelled views that agree on the ball within the pair error
   of the triangulation's rule (``app.geometry.pair_error``; the same tolerance as the doubts' consensus,
   ``consensus_tau_px`` at 1920 px width, widened to the view's own calibration sigma,
   :func:`app.geometry.weighting.pixel_sigma`): refitting the ball with it (DLT over the agreeing views and the
   detection, ``app.geometry.triangulation.triangulate_dlt``) leaves every one of them within its tolerance.
2. **In the play volume.** The refitted ball lies where a game can hold a ball (``app.geometry.pitch.PLAY_VOLUME``).
3. **Its size is a ball's at that depth.** The detection's diameter ``d = (w + h) / 2`` (the larger side where the box
   was clipped at the image's edge) is within ``detection_size_tolerance`` (relative) of the diameter of the exact
   silhouette of a 0.22 m sphere at the refitted ball (:func:`app.geometry.ball.sphere_image_box`).

Where the labelled views agree on a ball (the doubt judge's consensus, :func:`app.geometry.doubts.judge.judge_system`
rule 3), each unlabelled view's detections are checked against it: in the views that take part in the judge's checks,
and in those with fewer line classes whose calibration is still sure (a vote above 0: the judge lends such a view's
label half a vote), each within its own calibration's pixel sigma; the chosen one must also leave that ball where the
labelled views place it (:func:`_keeps_ball`), else the judge's own ``ball_missing`` stays the view's fix. A view
with fewer line classes whose calibration is sure, none of whose detections lies near where that ball projects, gets
the judge's projected box when its uncertainty keeps it within the ball's radius (:func:`_sure_box_missing`). Where only
one view is labelled its ray leaves the depth open, so two unlabelled views' detections are needed: a pair of
detections (one per view) is checked when the three rays meet at one plausible ball
(:func:`app.geometry.consensus.ball_consensus` of the three, every one an inlier, no ambiguity) and both sizes agree;
the best such triple then stands as the consensus for the remaining views. Among a view's candidates the one whose ray
the others' ball meets best (the smallest reprojection error) is chosen, with its margin over the next candidate (px at
1920 width); the detector's score orders candidates whose errors are within :data:`TIE_PX` of each other (a tie) and
never makes a suggestion alone.

Doubts made here (:func:`check_detections`):

* ``ball_detected`` (accuses the missing label; code ``consensus`` or ``one_view``, and the pairings' codes of
  :mod:`app.geometry.doubts.pairings`: ``one_ray``, ``detections_agree``, ``weak_ray``, ``weak_view``): its fix
  snaps the view's label to the detection's box (image evidence, drawn by the detector), with the detector's
  ``source`` and ``score`` in its evidence; where the judge's own ``ball_missing`` names the same view, that doubt
  is replaced (one suggestion per view: the detection's box; ``evidence.ball_missing_px`` says how far the
  geometry's own box lay from it);
* ``detection_off_label`` (information, code ``agrees_with_others``): a labelled view the others outvote
  (``ball_off_consensus``) has a detection that satisfies the three conditions: the numbers (its distance from the
  label, its error to the others' ball) are evidence for that doubt, not a verdict.

Without detections the doubts are returned unchanged. Pure: numpy only, no database. World frame: SoccerNet (metres,
origin at the centre spot, z down); pixels of each view's own image, origin at its top-left corner.
"""
from __future__ import annotations

import math
from itertools import combinations, product
from typing import Any, Callable, Hashable, Mapping, Sequence

import numpy as np

from app.geometry.ball import sphere_image_box
from app.geometry.consensus import Consensus, ball_consensus
from app.geometry.doubts.contract import Doubt, DoubtSettings, DoubtView, _box_list, _inside, _plausible, _r
from app.geometry.doubts.detected import (
    CENTRE_NOISE,
    PREFILTER,
    SIGMAS,
    CheckedDetection,
    Detection,
    _best,
    _check,
    _diameter,
    _near_point,
    _near_ray,
    _observation,
    check_or_why,
    explained,
    read_sigma,
)
from app.geometry.doubts.judge import _missing_doubt, _voters_consensus, _votes
from app.geometry.doubts.pairings import (
    MAX_SPREAD_M,
    _among_detections,
    _lone_ray,
    _one_ray,
    _sure,
    _view,
)
from app.geometry.doubts.weak import _weak, _weak_on_lone_ray, _weak_ray, _weak_views
from app.geometry.pair_error import REFERENCE_WIDTH_PX
from app.geometry.spread import position_covariance, position_sigma_m, projected_sigma_px
from app.geometry.triangulation import (
    BallObservation,
    PairGeometry,
    pair_geometry,
)
from app.geometry.weighting import (
    calibration_weight,
    camera_of,
    centre_of,
    pixel_sigma,
    project_point,
    rule_scale,
)


def _few_lined(views: Sequence[DoubtView], vote: Any, s: DoubtSettings,
               weighed: Mapping[Any, tuple[float, float]] | None) -> list[tuple[DoubtView, float]]:
    """Unlabelled views with fewer line classes than the judge needs whose calibration is still sure (a vote above 0,
    :func:`app.geometry.weighting.calibration_weight`: the judge lends such a view's label half a vote), each with its
    pixel sigma (px at 1920 width): their detections are checked too, within that sigma."""
    out = []
    for v in views:
        if (v.camera is None or v.excluded or v.mirror_flagged or v.suggested or v.box is not None
                or v.point is not None or v.line_classes >= s.min_line_classes):
            continue
        known = weighed.get(v.view_id) if weighed is not None else None
        w, sig = known if known is not None else calibration_weight(v, s)
        if w > 0:
            out.append((v, float(sig)))
    return out


def _witnesses(views: Sequence[DoubtView], sigma: Mapping[Hashable, float], tol: Mapping[Hashable, float],
               s: DoubtSettings, weighed: Mapping[Any, tuple[float, float]] | None,
               ) -> tuple[list[DoubtView], dict[Hashable, float]]:
    """The third views a pairing of detections is asked about (:func:`_third_views`): every calibrated view not
    excluded, not flagged mirrored and without an unconfirmed label whose pixel sigma is finite, also those that
    take no part in the votes (a camera too unsure to make a ball can still show that the ball is not where a pairing
    puts it, within its own widened tolerance), with the tolerances: ``tol``'s, else tau widened to the view's sigma."""
    tau = max(s.consensus_tau_px, s.triangulation_tau_px)
    out: list[DoubtView] = []
    wtol = dict(tol)
    for v in views:
        if v.camera is None or v.excluded or v.mirror_flagged or v.suggested:
            continue
        known = weighed.get(v.view_id) if weighed is not None else None
        sig = sigma.get(v.view_id, (known if known is not None else calibration_weight(v, s))[1])
        if not math.isfinite(sig):
            continue
        wtol.setdefault(v.view_id, max(tau, float(sig)))
        out.append(v)
    return out, wtol


def _in_weak_views(views: Sequence[DoubtView], vote: Any, unlabelled: Sequence[DoubtView], cons: Consensus,
                   checked: Mapping[Hashable, tuple[CheckedDetection, str, tuple[Hashable, ...]]],
                   detections: Mapping[Any, Sequence[Detection]], sigma: Mapping[Hashable, float],
                   s: DoubtSettings, size_tolerance: float, weighed: Mapping[Any, tuple[float, float]] | None,
                   ) -> dict[Hashable, tuple[CheckedDetection, str, tuple[Hashable, ...]]]:
    """The views whose own camera takes no part in the checks, where the others place the ball: the labelled views'
    consensus, else the ball of a checked pairing with the most views (never a weak ray's or a weak view's: an unsure
    camera's word is not relayed to another), each within its own sigma
    (:func:`app.geometry.doubts.weak._weak_views`)."""
    _, weak = _weak(views, vote, unlabelled, s, weighed)
    targets = [v for v in views if v.view_id in weak and v.view_id not in checked]
    if not targets:
        return {}
    if cons.point is not None and not cons.ambiguous:
        ball, agreeing = cons.point, tuple(cons.inliers)
    else:
        placed = [(c, a) for c, code, a in checked.values() if code not in ("weak_ray", "weak_view")]
        if not placed:
            return {}
        c, agreeing = max(placed, key=lambda x: len(x[1]))
        ball = c.ball
    filled = {vid: c.detection for vid, (c, _, _) in checked.items()}
    return _weak_views(targets, ball, views, detections, {**sigma, **weak}, agreeing, filled, s, size_tolerance)


def _tolerances(views: Sequence[DoubtView], sigma: Mapping[Hashable, float], tau: float) -> dict[Hashable, float]:
    return {v.view_id: max(tau, float(sigma.get(v.view_id, 0.0))) for v in views}


def _without_labels(views: Sequence[DoubtView], vote: Any, unlabelled: Sequence[DoubtView],
                    witnesses: Sequence[DoubtView], detections: Mapping[Any, Sequence[Detection]],
                    wtol: Mapping[Hashable, float], sigma: Mapping[Hashable, float], s: DoubtSettings,
                    size_tolerance: float, weighed: Mapping[Any, tuple[float, float]] | None,
                    ) -> tuple[dict[Hashable, tuple[CheckedDetection, str, tuple[Hashable, ...]]],
                               dict[Hashable, float]]:
    """Where no labelled view takes part: the detections that agree among themselves, weak labels joining them where
    a third view confirms (:func:`app.geometry.doubts.pairings._among_detections`), else a weak label's ray and the
    one detection near it (:func:`app.geometry.doubts.weak._weak_ray`); with the pixel sigmas (px at 1920 width)
    widened by the weak cameras' own, which the weak views' check reads next."""
    rays, weak = _weak(views, vote, unlabelled, s, weighed)
    sigma = {**sigma, **rays, **weak}
    ray_views = [v for v in views if v.view_id in rays]
    obs = {v.view_id: BallObservation(v.view_id, camera_of(v), centre_of(v), REFERENCE_WIDTH_PX / rule_scale(v, s))
           for v in ray_views}
    checked = _among_detections(unlabelled, witnesses, detections, wtol, sigma, s, size_tolerance,
                                rays=ray_views, by_id=obs)
    if not checked:  # a weak label's ray and one detection, where the box cannot make a 3D ball
        targets = [*(v for v in unlabelled if _sure(v, sigma, s)), *(v for v in views if v.view_id in weak)]
        checked = _weak_ray(ray_views, targets, views, witnesses, detections, obs, wtol, sigma, s, size_tolerance)
    return checked, sigma


#: Where a detector ran, the judge's box for a view that misses its label (``ball_missing``, code ``consensus``) stays
#: that view's fix only when the ball the agreeing views place is tight enough there: the triangulation's covariance
#: projected into the view (:func:`_ball_sigma_px`) at most this many of the box's radii. The agreeing views' pixel
#: sigmas overstate their cameras' error (about five times at the median, ``app.geometry.weighting.pixel_sigma``),
#: hence more than one radius. Chosen on the shared detector sets and four made sets (seed-201/203/205 made with seed
#: 53, seed-205 with seed 97): two labelled views placed those boxes, right in 33 of 37 cases within it, 6 of 15 beyond.
LOOSE_BOX_RADII = 2.5
#: The pairing's projected box (``ball_missing``, code ``pairing``, :func:`_placed_missing`) is offered where its
#: uncertainty (the pairing ball's covariance projected into the view and the view's own pixel sigma, in quadrature)
#: is at most this many of the box's radii. Its pixel sigmas overstate too; on 31 detector sets
#: (``benchmarks/DETECTOR.md``, 2026-11-27, sixth session) such boxes were right 9 of 9 times at a sigma within half
#: a radius (the bound before: two sigmas within one), 81 of 87 within one and a half radii, 122 of 138 within 2.5.
PAIRING_BOX_RADII = 1.5


def check_detections(views: Sequence[DoubtView], doubts: Sequence[Doubt],
                     detections: Mapping[Any, Sequence[Detection]], settings: DoubtSettings,
                     size_tolerance: float,
                     geometry: Callable[[BallObservation, BallObservation], PairGeometry] = pair_geometry,
                     weighed: Mapping[Any, tuple[float, float]] | None = None) -> list[Doubt]:
    """The system's doubts (``doubts``, from :func:`app.geometry.doubts.judge.judge_system` on ``views``) with its
    detectors' predictions checked (module docstring): ``ball_detected`` added for each unlabelled view with a
    checked detection (replacing that view's ``ball_missing``), ``detection_off_label`` for each outvoted labelled
    view with one. Pure and deterministic.

    Args:
        views: the system's views, as given to the judge.
        doubts: the judge's doubts of them.
        detections: view id -> that view's detections (any detectors; a view absent has none).
        settings: the judge's thresholds (tau, play volume, ball diameter).
        size_tolerance: condition 3's relative tolerance on the diameter (e.g. 0.5: from half to one and a half
            times the sphere's).
        geometry, weighed: as for the judge (the recomputation's pair geometry and calibration weights).

    Returns:
        The doubts, in the judge's order, the new ones after them; ``doubts`` itself when no view has a detection.
    """
    if not any(detections.get(v.view_id) for v in views):
        return list(doubts)
    s = settings
    vote = _votes(views, s, weighed)
    cons, lone_contradicted = _voters_consensus(vote, s, geometry)
    lined = _few_lined(views, vote, s, weighed)
    sigma = {**vote.sigma, **{v.view_id: sig for v, sig in lined}}
    unlabelled = [*vote.unlabelled, *(v for v, _ in lined)]
    tol = _tolerances([*vote.judged, *vote.helpers, *(v for v, _ in lined)], sigma, vote.tau)
    witnesses, wtol = _witnesses(views, sigma, tol, s, weighed)
    by_id = {o.view_id: o for o in vote.obs}
    checked: dict[Hashable, tuple[CheckedDetection, str, tuple[Hashable, ...]]] = {}
    out_of_label: list[Doubt] = []
    few_missing: list[Doubt] = []
    contested: set[Hashable] = set()
    looseness: dict[Hashable, float] = {}
    if cons.point is not None and not cons.ambiguous:
        voters = [by_id[i] for i in cons.inliers]
        for v in unlabelled:
            near = _near_point(v, detections.get(v.view_id, ()), cons.point, PREFILTER * tol[v.view_id], s)
            best = _best([c for d in near if (c := _check(v, d, voters, tol, s, size_tolerance)) is not None])
            if best is not None and _keeps_ball(best, cons.point, voters, sigma):
                checked[v.view_id] = (best, "consensus", tuple(cons.inliers))
        out_of_label = _off_label(vote.labelled, cons, by_id, detections, tol, s, size_tolerance)
        contested = {v.view_id for v in vote.unlabelled if v.view_id not in checked and any(
            check_or_why(v, det, voters, tol, s, size_tolerance) == "size"
            for det in _near_point(v, detections.get(v.view_id, ()), cons.point, PREFILTER * tol[v.view_id], s))}
        few_missing = [d for v, _ in lined if v.view_id not in checked
                       and not _near_point(v, detections.get(v.view_id, ()), cons.point,
                                           PREFILTER * tol[v.view_id], s)
                       and (d := _sure_box_missing(v, cons, s)) is not None]
        looseness = {v.view_id: px for v in unlabelled if v.view_id not in checked
                     and (px := _ball_sigma_px(v, cons.point, voters, sigma)) is not None}
        few_missing = [d for d in few_missing if not _too_loose(d, looseness)]
    else:
        checked, sigma = _without_consensus(views, vote, lone_contradicted, unlabelled, witnesses, detections, by_id,
                                            tol, wtol, sigma, s, size_tolerance, weighed)
    checked.update(_in_weak_views(views, vote, unlabelled, cons, checked, detections, sigma, s, size_tolerance,
                                  weighed))
    few_missing = [d for d in few_missing if d.view_id not in checked]
    # where no labelled views agree on a ball (theirs has the judge's own boxes), the ball a pairing places
    placed = [] if cons.point is not None and not cons.ambiguous else _placed_missing(
        unlabelled, checked, detections, by_id, vote.tau, tol, sigma, s)
    loose = {d.view_id for d in doubts if d.kind == "ball_missing" and _too_loose(d, looseness)}
    if not checked and not out_of_label and not few_missing and not contested and not placed and not loose:
        return list(doubts)
    replaced = {*checked, *(d.view_id for d in placed)}
    kept = [_unsnapped(d) if d.kind == "ball_missing" and d.view_id in contested
            else _loose(d, looseness) if d.kind == "ball_missing" and d.view_id in loose else d
            for d in doubts if not (d.kind == "ball_missing" and d.view_id in replaced)]
    missing = {d.view_id: d for d in doubts if d.kind == "ball_missing" and d.view_id in checked}
    by_view = {v.view_id: v for v in views}
    new = [_detected_doubt(c, by_view[vid], code, agreeing, missing.get(vid), s)
           for vid, (c, code, agreeing) in checked.items()]
    return [*kept, *new, *few_missing, *placed, *out_of_label]


def _without_consensus(views: Sequence[DoubtView], vote: Any, lone_contradicted: bool,
                       unlabelled: Sequence[DoubtView], witnesses: Sequence[DoubtView],
                       detections: Mapping[Hashable, Sequence[Detection]], by_id: Mapping[Hashable, BallObservation],
                       tol: Mapping[Hashable, float], wtol: Mapping[Hashable, float], sigma: dict[Hashable, float],
                       s: DoubtSettings, size_tolerance: float, weighed: Mapping[Any, tuple[float, float]] | None
                       ) -> tuple[dict[Hashable, tuple[CheckedDetection, str, tuple[Hashable, ...]]],
                                  dict[Hashable, float]]:
    """The detections checked where the labelled views agree on no ball (:func:`check_detections`'s arguments): with
    one labelled ray, two detected views that meet it (:func:`_from_one_view`), else each detection against that ray
    alone (:func:`_one_ray`); with no labelled view taking part, the detections among themselves
    (:func:`_without_labels`). Returns the checked detections and the pixel sigmas (the last rule may add some)."""
    checked: dict[Hashable, tuple[CheckedDetection, str, tuple[Hashable, ...]]] = {}
    if (lone := _lone_ray(vote)) is not None and not lone_contradicted:
        checked = _from_one_view(lone, unlabelled, detections, by_id, tol, sigma, s, size_tolerance)
        if not checked:  # no second detected view: each detection is checked against the one labelled ray
            checked = _one_ray(lone, unlabelled, witnesses, detections, by_id, wtol, sigma, s, size_tolerance,
                               half_vote=lone not in vote.labelled)
    if not checked and not vote.labelled:  # no labelled view takes part: the detections may agree among themselves
        checked, sigma = _without_labels(views, vote, unlabelled, witnesses, detections, wtol, sigma, s,
                                         size_tolerance, weighed)
    if not checked and lone is not None and not lone_contradicted:
        checked, sigma = _weak_on_lone_ray(lone, views, vote, unlabelled, witnesses, detections, by_id, wtol, sigma,
                                           s, size_tolerance, weighed)
    return checked, sigma


def _unsnapped(d: Doubt) -> Doubt:
    """The judge's ``ball_missing`` without its box: a detection near where the labelled views' ball projects whose
    rays meet theirs in the play volume but whose size is not a ball's there (condition 3) says that the camera's
    scale there, or the box, is off; the sphere box the camera projects is then no label (the doubt stays, with
    ``evidence.detection_size_disagrees``)."""
    return Doubt(d.kind, d.view_id, d.code, {**d.evidence, "detection_size_disagrees": True}, None)


def _ball_sigma_px(v: DoubtView, ball: np.ndarray, voters: Sequence[BallObservation],
                   sigma: Mapping[Hashable, float]) -> float | None:
    """How far (px of ``v``, one standard deviation along the worst direction) the ball ``voters`` place (``ball``, (3,)
    world metres, z down) may project in ``v`` by their pixel sigmas alone (``sigma``, px at 1920 width, each read as
    at least :data:`MIN_SIGMA_PX`): the triangulation's covariance (:func:`app.geometry.spread.position_covariance`)
    carried through ``v``'s projection (:func:`app.geometry.spread.projected_sigma_px`). Two rays that meet at a
    small angle leave the ball's depth loose; a view looking across that depth sees it as pixels. None when the
    voters fix no point or the ball lies behind a camera."""
    cov = (position_covariance(voters, ball, {o.view_id: read_sigma(sigma, o.view_id) for o in voters})
           if len(voters) >= 2 else None)
    if cov is None or v.camera is None:
        return None
    px = projected_sigma_px(BallObservation(v.view_id, camera_of(v), np.zeros(2), v.width), ball, cov)
    return None if px is None else px * v.width / REFERENCE_WIDTH_PX


def _too_loose(d: Doubt, looseness: Mapping[Hashable, float]) -> bool:
    """Whether ``d`` (a ``ball_missing`` whose fix is a box) names a view where the agreeing views' ball is looser
    than :data:`LOOSE_BOX_RADII` of that box's radii (``looseness``: view id -> :func:`_ball_sigma_px`)."""
    box = (d.suggestion or {}).get("box")
    if box is None or d.view_id not in looseness:
        return False
    return looseness[d.view_id] > LOOSE_BOX_RADII * ((box[2] - box[0]) + (box[3] - box[1])) / 4


def _loose(d: Doubt, looseness: Mapping[Hashable, float]) -> Doubt:
    """``d`` without its box, saying how loose the ball is there (``evidence.ball_sigma_px``, px of the view, and
    ``evidence.ball_loose``): a person places the label (:data:`LOOSE_BOX_RADII`)."""
    return Doubt(d.kind, d.view_id, d.code, {**d.evidence, "ball_sigma_px": _r(looseness[d.view_id], 2),
                                             "ball_loose": True}, None)


def _sure_box_missing(v: DoubtView, cons: Consensus, s: DoubtSettings) -> Doubt | None:
    """The judge's ``ball_missing`` (code ``consensus``: the sphere box where the labelled views' ball projects,
    :func:`app.geometry.doubts.judge._missing_doubt`) for an unlabelled view with fewer line classes than the judge
    needs whose calibration is sure (:func:`_few_lined`) and none of whose detections is the ball: the judge leaves
    such views alone (their lines do not fix their camera), but its pixel sigma says how far the box may lie. It is
    offered only where that box's uncertainty (:func:`app.geometry.doubts.judge.consensus_box_sigma_px`: the agreeing
    views' spread and the view's pixel sigma in quadrature, px of the view) keeps the box's centre within the ball's
    own silhouette at :data:`SIGMAS` standard deviations (``SIGMAS * sigma`` at most the box's radius): a box that may
    lie farther than the ball's radius from it does not label that ball."""
    d = _missing_doubt(v, cons, s, "consensus", {"agreeing_views": list(cons.inliers)})
    if d is None or not d.suggestion:
        return None
    box, sigma = d.suggestion.get("box"), d.suggestion.get("box_sigma_px")
    if box is None or sigma is None:
        return None
    radius = ((box[2] - box[0]) + (box[3] - box[1])) / 4
    return d if SIGMAS * float(sigma) <= radius else None


def _placed_missing(unlabelled: Sequence[DoubtView],
                    checked: Mapping[Hashable, tuple[CheckedDetection, str, tuple[Hashable, ...]]],
                    detections: Mapping[Any, Sequence[Detection]], by_id: Mapping[Hashable, BallObservation],
                    tau: float, tol: Mapping[Hashable, float], sigma: Mapping[Hashable, float],
                    s: DoubtSettings) -> list[Doubt]:
    """``ball_missing`` (code ``pairing``) for the views whose detector shows nothing where a checked pairing places
    the ball, where no labelled views agree on one: the sphere box of that ball (the pairing with the most views:
    one labelled ray and detections, or detections among themselves; never a weak ray's or a weak view's, whose box
    makes no ball), for each view whose detections are checked (``unlabelled``) that is not filled, has none of its
    detections within :data:`PREFILTER` tolerances of where the ball projects (a box there that the checks refused
    says the camera or the ball is off there) and inside which it projects by ``inside_margin_px``, offered only
    where the box's uncertainty is at most :data:`PAIRING_BOX_RADII` of its radii: the ball's position covariance
    from the pairing's views (:func:`app.geometry.spread.position_covariance`: each view's pixel sigma, at least
    :data:`MIN_SIGMA_PX`, and for a detection :data:`CENTRE_NOISE` of its diameter, in quadrature) projected into the
    view (:func:`app.geometry.spread.projected_sigma_px`), and the view's own pixel sigma at the ball, in quadrature.

    The detector misses about one ball in seven (the shared detector sets' README); in one pass the views whose
    detector missed the ball would be left empty while the pairing's other views are filled, although the ball the
    pass places there projects into them as surely as a consensus ball does into the judge's views (a label and a
    detection from cameras sure to a few pixels place it within tens of centimetres, :func:`_placed`). The box
    agrees with that ball by construction: it adds no evidence of where the ball is, only the label a person would
    place there; the code says so. Unlike a view's own detection it cannot move the pass's 3D ball."""
    placed = [(c, a) for c, code, a in checked.values() if code not in ("weak_ray", "weak_view")]
    if not placed:
        return []
    best, agreeing = max(placed, key=lambda x: len(x[1]))
    ball = np.asarray(best.ball, float)
    views_by_id = {v.view_id: v for v in unlabelled}
    obs: list[BallObservation] = []
    obs_sigma: dict[Hashable, float] = {}
    for vid in agreeing:
        cam = read_sigma(sigma, vid)
        if vid in checked and vid in views_by_id:
            v, det = views_by_id[vid], checked[vid][0].detection
            obs.append(_observation(v, det, s))
            obs_sigma[vid] = math.hypot(cam, CENTRE_NOISE * _diameter(det.box, v) * rule_scale(v, s))
        elif vid in by_id:
            obs.append(by_id[vid])
            obs_sigma[vid] = cam
    cov = position_covariance(obs, ball, obs_sigma) if len(obs) >= 2 else None
    if cov is None:
        return []
    out: list[Doubt] = []
    for v in unlabelled:
        if v.view_id in checked or v.camera is None or _near_point(v, detections.get(v.view_id, ()), ball,
                                                                   PREFILTER * tol.get(v.view_id, tau), s):
            continue
        uv = project_point(v, ball)
        if uv is None or not _inside(v, uv, s.inside_margin_px / rule_scale(v, s)):
            continue
        box = sphere_image_box(camera_of(v), ball, s.ball_diameter_m / 2)
        own = pixel_sigma(v, ball, s)
        spread = projected_sigma_px(BallObservation(v.view_id, camera_of(v), uv, v.width), ball, cov)
        if box is None or spread is None or not math.isfinite(own):
            continue
        box_sigma = math.hypot(own, spread) / rule_scale(v, s)
        radius = ((box[2] - box[0]) + (box[3] - box[1])) / 4
        if box_sigma > PAIRING_BOX_RADII * radius:
            continue
        out.append(Doubt("ball_missing", v.view_id, "pairing", {
            "projected_px": [_r(uv[0]), _r(uv[1])], "ball3d": [_r(x, 3) for x in ball],
            "agreeing_views": list(agreeing), "filled_views": [a for a in agreeing if a in checked]},
            {"action": "snap_box", "box": _box_list(box), "box_sigma_px": _r(box_sigma, 2)}))
    return out


def _keeps_ball(best: CheckedDetection, ball: np.ndarray, voters: Sequence[BallObservation],
                sigma: Mapping[Hashable, float]) -> bool:
    """Whether filling the view with ``best`` leaves the ball the labelled views agree on (``ball``, (3,) world
    metres, z down) where their own evidence puts it: the refitted ball (``best.ball``) within :data:`SIGMAS`
    standard deviations of ``ball`` along the voters' worst direction (the triangulation's linearised covariance
    with each voter's pixel sigma ``sigma``, px at 1920 width, at least :data:`MIN_SIGMA_PX`;
    :func:`app.geometry.spread.position_sigma_m`, Hartley & Zisserman 5.2.3), or within :data:`MAX_SPREAD_M`,
    whichever is larger. Condition 1 asks each ray to stay within the doubts' wide tau (a label tolerance); between
    cameras sure to a few pixels a box that drags their ball farther than they can place it wrong is not the ball
    they see (on a made set such a box, 45 px off in a view whose detector missed the ball, moved a ball the labels
    placed 0.04 m from the truth by 1.3 m, and the pass left it 3.3 m off). Voters that fix no point say nothing."""
    spread = position_sigma_m(voters, ball, {o.view_id: read_sigma(sigma, o.view_id) for o in voters})
    if spread is None:
        return True
    return float(np.linalg.norm(np.asarray(best.ball, float) - np.asarray(ball, float))) <= max(SIGMAS * spread,
                                                                                                MAX_SPREAD_M)


def _from_one_view(lone: DoubtView, unlabelled: Sequence[DoubtView], detections: Mapping[Hashable, Sequence[Detection]],
                   by_id: Mapping[Hashable, BallObservation], tol: Mapping[Hashable, float],
                   sigma: Mapping[Hashable, float], s: DoubtSettings,
                   size_tolerance: float) -> dict[Hashable, tuple[CheckedDetection, str, tuple[Hashable, ...]]]:
    """With one labelled view: the best pair of detections in two unlabelled views whose rays meet the labelled
    view's at one plausible ball (all three inliers of their consensus, sizes agreeing, each detection within
    :data:`~app.geometry.doubts.detected.SIGMAS` standard deviations of the three cameras' pixel sigmas ``sigma``:
    :func:`~app.geometry.doubts.detected.explained`); it then stands as the consensus for the other unlabelled
    views."""
    lone_obs = by_id[lone.view_id]
    triples: list[tuple[float, float, CheckedDetection, CheckedDetection]] = []
    # only the detections near the labelled view's ray across the play volume can meet it (condition 1, necessary)
    near = {v.view_id: _near_ray(lone, v, detections.get(v.view_id, ()), PREFILTER * tol[v.view_id], s)
            for v in unlabelled}
    for a, b in combinations([v for v in unlabelled if near[v.view_id]], 2):
        for da, db in product(near[a.view_id], near[b.view_id]):
            oa, ob = _observation(a, da, s), _observation(b, db, s)
            # the plain pair geometry: a recomputation's memo would keep every candidate pair asked
            three = ball_consensus([lone_obs, oa, ob], tau_px=min(tol.values()), min_baseline_m=s.min_baseline_m,
                                   min_parallax_deg=s.min_parallax_deg, tolerances_px=tol,
                                   plausible=lambda p: _plausible(p, s))
            if three.point is None or three.ambiguous or len(three.inliers) != 3:
                continue
            # tau is the labels' wide tolerance: three cameras sure to a pixel or two that meet a box 20 px off
            # its ray meet no ball there (a false box on the labelled ray a metre or two from the ball, in a view
            # whose detector missed it, and the ball's detection in a view looking along that ray fit within tau)
            if not explained({k: float(e) for k, e in three.errors_1920.items() if e is not None},
                             {a.view_id: (a, da.box), b.view_id: (b, db.box)},
                             sigma, s):
                continue
            ca = _check(a, da, [lone_obs, ob], tol, s, size_tolerance)
            cb = _check(b, db, [lone_obs, oa], tol, s, size_tolerance)
            if ca is None or cb is None:
                continue
            worst = max(e for e in three.errors_1920.values() if e is not None)
            triples.append((worst, -(da.score + db.score), ca, cb))
    if not triples:
        return {}
    triples.sort(key=lambda t: (t[0], t[1]))
    worst, _, ca, cb = triples[0]
    rivals = [t[0] for t in triples[1:] if t[2].detection != ca.detection or t[3].detection != cb.detection]
    margin = (min(rivals) - worst) if rivals else None
    agreeing = (lone.view_id, ca.view_id, cb.view_id)
    found: dict[Hashable, tuple[CheckedDetection, str, tuple[Hashable, ...]]] = {
        c.view_id: (CheckedDetection(c.view_id, c.detection, c.error_1920, c.ball, c.size_ratio, len(triples), margin),
                    "one_view", agreeing) for c in (ca, cb)}
    voters = [lone_obs, _observation(_view(unlabelled, ca.view_id), ca.detection, s),
              _observation(_view(unlabelled, cb.view_id), cb.detection, s)]
    for v in unlabelled:
        if v.view_id in found:
            continue
        near_ball = _near_point(v, detections.get(v.view_id, ()), ca.ball, PREFILTER * tol[v.view_id], s)
        best = _best([c for d in near_ball if (c := _check(v, d, voters, tol, s, size_tolerance)) is not None])
        if best is not None:
            found[v.view_id] = (best, "one_view", agreeing)
    return found


def _off_label(labelled: Sequence[DoubtView], cons: Consensus, by_id: Mapping[Hashable, BallObservation],
               detections: Mapping[Hashable, Sequence[Detection]], tol: Mapping[Hashable, float], s: DoubtSettings,
               size_tolerance: float) -> list[Doubt]:
    """``detection_off_label`` for each labelled view the consensus outvotes whose detections include one that
    satisfies the three conditions against the agreeing views."""
    out: list[Doubt] = []
    voters = [by_id[i] for i in cons.inliers]
    for v in labelled:
        if v.view_id in cons.inliers or not detections.get(v.view_id) or v.box is None:
            continue
        best = _best([c for d in detections[v.view_id] if (c := _check(v, d, voters, tol, s, size_tolerance))
                      is not None])
        if best is None:
            continue
        label = np.array([(v.box[0] + v.box[2]) / 2, (v.box[1] + v.box[3]) / 2])
        far = float(np.linalg.norm(best.detection.centre - label)) * rule_scale(v, s)
        out.append(Doubt("detection_off_label", v.view_id, "agrees_with_others", {
            "detector": best.detection.source, "score": _r(best.detection.score, 3),
            "box": _box_list(np.asarray(best.detection.box)), "label_distance_px_1920": _r(far),
            "error_px_1920": _r(best.error_1920), "agreeing_views": list(cons.inliers),
            "size_ratio": _r(best.size_ratio, 2)}))
    return out


def _detected_doubt(c: CheckedDetection, view: DoubtView, code: str, agreeing: tuple[Hashable, ...],
                    missing: Doubt | None, s: DoubtSettings) -> Doubt:
    """``ball_detected`` for a checked detection: its evidence and its fix (snap to the detection's box)."""
    det = c.detection
    evidence: dict[str, Any] = {
        "detector": det.source, "score": _r(det.score, 3), "error_px_1920": _r(c.error_1920),
        "tau_px": _r(max(s.consensus_tau_px, s.triangulation_tau_px)), "agreeing_views": [a for a in agreeing
                                                                                         if a != c.view_id],
        "ball3d": [_r(x, 3) for x in c.ball], "size_ratio": _r(c.size_ratio, 2), "candidates_passed": c.passed,
        "margin_px_1920": None if c.margin_1920 is None else _r(c.margin_1920)}
    if missing is not None and missing.suggestion and missing.suggestion.get("box"):
        b = missing.suggestion["box"]
        centre = np.array([(b[0] + b[2]) / 2, (b[1] + b[3]) / 2])
        evidence["ball_missing_px"] = _r(float(np.linalg.norm(centre - det.centre)))
    box = _box_list(np.asarray(det.box, float))
    # its uncertainty: how far the others' ball lies from the detection's centre, in the view's own pixels
    return Doubt("ball_detected", c.view_id, code, evidence,
                 {"action": "snap_box", "box": box, "box_sigma_px": _r(c.error_1920 / rule_scale(view, s), 2)})
