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
rule 3), each unlabelled view's detections are checked against it: in the views that take part in the judge's
checks, and in those with fewer line classes whose calibration is still sure (a vote above 0: the judge lends such a
view's label half a vote), each within its own calibration's pixel sigma. Where only one view is labelled its ray
leaves the depth open, so two unlabelled views' detections are needed: a pair of detections (one per view) is checked
when the three rays meet at one plausible ball (:func:`app.geometry.consensus.ball_consensus` of the three, every one an
inlier, no ambiguity) and both sizes agree; the best such triple then stands as the consensus for the remaining
views. Among a view's candidates the one whose ray the others' ball meets best (the smallest reprojection error) is
chosen, with its margin over the next candidate (px at 1920 width); the detector's score orders candidates whose
errors are within :data:`TIE_PX` of each other (a tie) and never makes a suggestion alone.

Doubts made here (:func:`check_detections`):

* ``ball_detected`` (accuses the missing label; code ``consensus`` or ``one_view``): its fix snaps the view's label
  to the detection's box (image evidence, drawn by the detector), with the detector's ``source`` and ``score`` in
  its evidence; where the judge's own ``ball_missing`` names the same view, that doubt is replaced (one suggestion
  per view: the detection's box; ``evidence.ball_missing_px`` says how far the geometry's own box lay from it);
* ``detection_off_label`` (information, code ``agrees_with_others``): a labelled view the others outvote
  (``ball_off_consensus``) has a detection that satisfies the three conditions: the numbers (its distance from the
  label, its error to the others' ball) are evidence for that doubt, not a verdict.

Without detections the doubts are returned unchanged. Pure: numpy only, no database. World frame: SoccerNet (metres,
origin at the centre spot, z down); pixels of each view's own image, origin at its top-left corner.
"""
from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from itertools import combinations, product
from typing import Any, Callable, Hashable, Mapping, Sequence

import numpy as np

from app.geometry.ball import sphere_image_box
from app.geometry.consensus import Consensus, ball_consensus
from app.geometry.doubts.contract import Doubt, DoubtSettings, DoubtView, _box_list, _inside, _plausible, _r
from app.geometry.doubts.epipolar import _polyline_distance, _segment
from app.geometry.doubts.judge import _voters_consensus, _votes
from app.geometry.pair_error import REFERENCE_WIDTH_PX
from app.geometry.triangulation import (
    BallObservation,
    PairGeometry,
    angle_between_deg,
    pair_geometry,
    reprojection_error_px,
    triangulate_dlt,
    undistort_pixels,
)
from app.geometry.weighting import calibration_weight, camera_of, label_centre, project_point, rule_scale

#: A detection is refitted only when its centre lies within this many tolerances of where the others put the ball
#: (a cheap necessary test: the refit moves the ball by less than a tolerance in a view that agrees).
PREFILTER = 3.0
#: At most this many candidates of a view are refitted (the nearest): bounded time with hundreds of detections.
MAX_CANDIDATES = 16
#: Candidates whose errors differ by less than this (px at 1920 width) are tied: the detector's score orders them.
TIE_PX = 1.0


@dataclass(frozen=True)
class Detection:
    """One prediction of a detector on one view: ``source`` (the detector's name), ``score`` in [0, 1] and ``box``
    (4,) ``[x1, y1, x2, y2]`` px of the view's image (clipped to it)."""

    source: str
    score: float
    box: tuple[float, float, float, float]

    @property
    def centre(self) -> np.ndarray:
        """(2,) the box's centre, px."""
        return np.array([(self.box[0] + self.box[2]) / 2, (self.box[1] + self.box[3]) / 2])


@dataclass(frozen=True)
class CheckedDetection:
    """A detection that passed the three conditions in its view: ``error_1920`` (px at 1920 width) of its centre
    to the refitted ball, ``ball`` (3,) that ball (world metres), ``size_ratio`` (its diameter over the sphere's
    there), and how many candidates of the view passed (``passed``) with the ``margin_1920`` of the chosen one over
    the next (None with one)."""

    view_id: Hashable
    detection: Detection
    error_1920: float
    ball: np.ndarray
    size_ratio: float
    passed: int = 1
    margin_1920: float | None = None


def _diameter(box: Sequence[float], view: DoubtView) -> float:
    """A box's ball diameter (px): the mean side, the larger side where the box touches the image's edge."""
    w, h = box[2] - box[0], box[3] - box[1]
    clipped = box[0] <= 0.5 or box[1] <= 0.5 or box[2] >= view.width - 0.5 or box[3] >= view.height - 0.5
    return float(max(w, h) if clipped else (w + h) / 2)


def size_ratio(view: DoubtView, box: Sequence[float], ball: np.ndarray, ball_diameter_m: float) -> float | None:
    """The box's diameter over that of the exact silhouette of a ball of ``ball_diameter_m`` (m) centred at
    ``ball`` (3,) world metres in ``view`` (None where the sphere is not wholly in front of the camera)."""
    expected = sphere_image_box(camera_of(view), ball, ball_diameter_m / 2)
    if expected is None:
        return None
    d = ((expected[2] - expected[0]) + (expected[3] - expected[1])) / 2
    return _diameter(box, view) / float(d) if d > 0 else None


def _refit(obs: Sequence[BallObservation]) -> np.ndarray | None:
    """The DLT ball (3,) world metres of the observations' undistorted pixels, None at infinity."""
    h = triangulate_dlt(np.stack([o.camera.projection_matrix for o in obs]),
                        np.stack([undistort_pixels(o.camera, o.point_px)[0] for o in obs]))
    return None if abs(h[3]) < 1e-12 else h[:3] / h[3]


def _scaled(o: BallObservation, point: np.ndarray) -> float | None:
    e = reprojection_error_px(o.camera, point, o.point_px)
    return None if e is None else e * REFERENCE_WIDTH_PX / o.image_width


def _observation(view: DoubtView, det: Detection, s: DoubtSettings) -> BallObservation:
    return BallObservation(view.view_id, camera_of(view), det.centre, REFERENCE_WIDTH_PX / rule_scale(view, s))


def _check(view: DoubtView, det: Detection, voters: Sequence[BallObservation], tol: Mapping[Hashable, float],
           s: DoubtSettings, size_tolerance: float) -> CheckedDetection | None:
    """The three conditions (module docstring) for ``det`` in ``view`` against the agreeing ``voters``."""
    cand = _observation(view, det, s)
    ball = _refit([*voters, cand])
    if ball is None or not _plausible(ball, s):
        return None
    errors = {o.view_id: _scaled(o, ball) for o in [*voters, cand]}
    if any(e is None or e >= tol[i] for i, e in errors.items()):
        return None
    ratio = size_ratio(view, det.box, ball, s.ball_diameter_m)
    if ratio is None or abs(ratio - 1.0) > size_tolerance:
        return None
    e = errors[view.view_id]
    assert e is not None  # checked above
    return CheckedDetection(view.view_id, det, float(e), ball, float(ratio))


def _best(checked: list[CheckedDetection]) -> CheckedDetection | None:
    """The best-supported candidate (smallest error; within :data:`TIE_PX` the higher score), with the count and
    its margin over the next."""
    if not checked:
        return None
    low = min(c.error_1920 for c in checked)
    ranked = sorted(checked, key=lambda c: (c.error_1920 - low >= TIE_PX, -c.detection.score, c.error_1920))
    best, rest = ranked[0], ranked[1:]
    margin = min(c.error_1920 for c in rest) - best.error_1920 if rest else None
    return CheckedDetection(best.view_id, best.detection, best.error_1920, best.ball, best.size_ratio, len(checked),
                            margin)


def _near_point(view: DoubtView, detections: Sequence[Detection], ball: np.ndarray, within_1920: float,
                s: DoubtSettings) -> list[Detection]:
    """The detections whose centre lies within ``within_1920`` (px at 1920 width) of ``ball``'s projection in
    ``view``, nearest first, at most :data:`MAX_CANDIDATES` (a cheap necessary test before the refit)."""
    uv = project_point(view, ball)
    if uv is None or not detections:
        return []
    d = np.array([np.linalg.norm(det.centre - uv) for det in detections]) * rule_scale(view, s)
    order = [int(i) for i in np.argsort(d, kind="stable") if d[i] < within_1920]
    return [detections[i] for i in order[:MAX_CANDIDATES]]


def _near_ray(lone: DoubtView, view: DoubtView, detections: Sequence[Detection], within_1920: float,
              s: DoubtSettings) -> list[Detection]:
    """The detections whose centre lies within ``within_1920`` (px at 1920 width) of ``lone``'s ball ray across
    the play volume seen in ``view`` (its epipolar segment), nearest first, at most :data:`MAX_CANDIDATES`."""
    seg = _segment(lone, view, s) if detections else None
    if seg is None:
        return []
    d = np.array([_polyline_distance(seg[1], det.centre)[0] for det in detections]) * rule_scale(view, s)
    order = [int(i) for i in np.argsort(d, kind="stable") if d[i] < within_1920]
    return [detections[i] for i in order[:MAX_CANDIDATES]]


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


def _tolerances(views: Sequence[DoubtView], sigma: Mapping[Hashable, float], tau: float) -> dict[Hashable, float]:
    return {v.view_id: max(tau, float(sigma.get(v.view_id, 0.0))) for v in views}


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
    if cons.point is not None and not cons.ambiguous:
        voters = [by_id[i] for i in cons.inliers]
        for v in unlabelled:
            near = _near_point(v, detections.get(v.view_id, ()), cons.point, PREFILTER * tol[v.view_id], s)
            best = _best([c for d in near if (c := _check(v, d, voters, tol, s, size_tolerance)) is not None])
            if best is not None:
                checked[v.view_id] = (best, "consensus", tuple(cons.inliers))
        out_of_label = _off_label(vote.labelled, cons, by_id, detections, tol, s, size_tolerance)
    elif (lone := _lone_ray(vote)) is not None and not lone_contradicted:
        checked = _from_one_view(lone, unlabelled, detections, by_id, tol, s, size_tolerance)
        if not checked:  # no second detected view: each detection is checked against the one labelled ray
            checked = _one_ray(lone, unlabelled, witnesses, detections, by_id, wtol, sigma, s, size_tolerance)
    elif not vote.labelled:  # no labelled view takes part: the detections may agree among themselves
        checked = _among_detections(unlabelled, witnesses, detections, wtol, sigma, s, size_tolerance)
    if not checked and not out_of_label:
        return list(doubts)
    kept = [d for d in doubts if not (d.kind == "ball_missing" and d.view_id in checked)]
    missing = {d.view_id: d for d in doubts if d.kind == "ball_missing" and d.view_id in checked}
    by_view = {v.view_id: v for v in views}
    new = [_detected_doubt(c, by_view[vid], code, agreeing, missing.get(vid), s)
           for vid, (c, code, agreeing) in checked.items()]
    return [*kept, *new, *out_of_label]


def _from_one_view(lone: DoubtView, unlabelled: Sequence[DoubtView], detections: Mapping[Hashable, Sequence[Detection]],
                   by_id: Mapping[Hashable, BallObservation], tol: Mapping[Hashable, float], s: DoubtSettings,
                   size_tolerance: float) -> dict[Hashable, tuple[CheckedDetection, str, tuple[Hashable, ...]]]:
    """With one labelled view: the best pair of detections in two unlabelled views whose rays meet the labelled
    view's at one plausible ball (all three inliers of their consensus, sizes agreeing); it then stands as the
    consensus for the other unlabelled views."""
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


#: A third calibrated view confirms a ball two views place when one of its detections (or its label) lies within its
#: tolerance of where that ball projects, at a ball's size; it contradicts it (a clear miss) when the ball projects
#: inside its image by that tolerance and nothing of it lies within :data:`MISS` tolerances.
MISS = 2.0
#: A candidate is chosen only when the runner-up (a candidate elsewhere, as well supported) is worse by at least this
#: fraction of the doubts' tau (px at 1920 width): two spots that meet the rays about as well cannot be told apart.
MARGIN = 0.5


@dataclass(frozen=True)
class _Member:
    """One view of a pairing: its camera's observation, its box (a detection's, or the labelled view's own label;
    None for a point label) with the relative size tolerance that box is read with, and the detection (None for
    the labelled ray)."""

    view: DoubtView
    obs: BallObservation
    box: tuple[float, float, float, float] | None
    size_tolerance: float
    detection: Detection | None = None


@dataclass(frozen=True)
class _Pairing:
    """Views whose rays meet at one ball (:func:`_meet`): the members, the ball (3,) world metres, each member's
    error (px at 1920 width) and size ratio, the worst error, and the third views that confirm it or miss it."""

    members: tuple[_Member, ...]
    ball: np.ndarray
    errors: dict[Hashable, float]
    ratios: dict[Hashable, float]
    error_1920: float
    confirmed: tuple[Hashable, ...] = ()
    missed: tuple[Hashable, ...] = ()

    def detections(self) -> dict[Hashable, Detection]:
        return {m.view.view_id: m.detection for m in self.members if m.detection is not None}


def _member(view: DoubtView, det: Detection, s: DoubtSettings, size_tolerance: float) -> _Member:
    return _Member(view, _observation(view, det, s), det.box, size_tolerance, det)


def _meet(members: Sequence[_Member], tol: Mapping[Hashable, float], s: DoubtSettings) -> _Pairing | None:
    """Whether the members' rays meet at one ball of ``s.ball_diameter_m`` (the checks of one labelled ray and one
    detection, and of detections among themselves): the DLT ball of their centres lies in the play volume, every
    member's reprojection error is within its tolerance (``tol``: tau widened to its calibration's pixel sigma, so
    the distance between a detection and the other view's epipolar line may reach both views' tolerances), some
    pair of them sees it from cameras at least ``min_baseline_m`` apart under at least ``min_parallax_deg`` (else
    the rays meet anywhere along their common direction), and each box is a ball's size at that depth (within its
    member's relative tolerance). None otherwise."""
    ball = _refit([m.obs for m in members])
    if ball is None or not _plausible(ball, s):
        return None
    errors: dict[Hashable, float] = {}
    ratios: dict[Hashable, float] = {}
    for m in members:
        e = _scaled(m.obs, ball)
        if e is None or e >= tol[m.view.view_id]:
            return None
        errors[m.view.view_id] = e
        if m.box is not None:
            r = size_ratio(m.view, m.box, ball, s.ball_diameter_m)
            if r is None or abs(r - 1.0) > m.size_tolerance:
                return None
            ratios[m.view.view_id] = r
    if not any(float(np.linalg.norm(a.obs.camera.C - b.obs.camera.C)) >= s.min_baseline_m
               and angle_between_deg(ball - a.obs.camera.C, ball - b.obs.camera.C) >= s.min_parallax_deg
               for a, b in combinations(members, 2)):
        return None
    return _Pairing(tuple(members), ball, errors, ratios, max(errors.values()))


def _epipolar_distance(ray_view: DoubtView, centre: np.ndarray, view: DoubtView, s: DoubtSettings) -> float:
    """How far (px at 1920 width) ``centre`` (2,) px of ``view`` lies from the ball ray of ``ray_view``'s label (or
    detection, given as its box) across the play volume, seen in ``view`` (its epipolar segment,
    :func:`app.geometry.doubts.epipolar._segment`); ``inf`` when that ray misses the volume or is not seen."""
    seg = _segment(ray_view, view, s)
    if seg is None:
        return math.inf
    return _polyline_distance(seg[1], centre)[0] * rule_scale(view, s)


def _on_epipolar(a: DoubtView, b: DoubtView, det_b: Detection, sigma: Mapping[Hashable, float],
                 s: DoubtSettings) -> bool:
    """Condition 1 for a pair: ``det_b``'s centre lies within tau of ``a``'s ball ray seen in ``b`` (px at 1920 width),
    tau widened by both cameras' pixel sigmas (:func:`app.geometry.weighting.pixel_sigma`, added in quadrature):
    measured in the detection's own image, not split between the two views as the refit's errors are (a view that
    sees the ball small would take most of the distance at a small cost in its pixels)."""
    tau = max(s.consensus_tau_px, s.triangulation_tau_px)
    return _epipolar_distance(a, det_b.centre, b, s) <= max(tau, math.hypot(sigma.get(a.view_id, 0.0),
                                                                             sigma.get(b.view_id, 0.0)))


def _as_labelled(view: DoubtView, det: Detection) -> DoubtView:
    """``view`` with ``det``'s box as its ball label (so that its ray is the detection's)."""
    return dataclasses.replace(view, box=np.asarray(det.box, float), point=None)


def _third_views(p: _Pairing, thirds: Sequence[DoubtView], detections: Mapping[Hashable, Sequence[Detection]],
                 tol: Mapping[Hashable, float], s: DoubtSettings,
                 size_tolerance: float) -> tuple[dict[Hashable, Detection | None], tuple[Hashable, ...]]:
    """What the calibrated views outside the pairing say of its ball: view id -> the detection there (None: its
    label is there) for those that confirm it, and the ids of those that clearly miss it (the ball projects inside
    the image by the view's tolerance, and neither its label nor any of its detections lies within :data:`MISS`
    tolerances). A view the ball projects outside of, or without a label and without any detection (the detector
    may not have run on it), says nothing."""
    inside = {m.view.view_id for m in p.members}
    confirmed: dict[Hashable, Detection | None] = {}
    missed: list[Hashable] = []
    for c in thirds:
        if c.view_id in inside or c.camera is None or c.view_id not in tol:
            continue
        uv = project_point(c, p.ball)
        k, t = rule_scale(c, s), tol[c.view_id]
        if uv is None or not _inside(c, uv, t / k):
            continue
        label = label_centre(c)
        if label is not None:
            d = float(np.linalg.norm(label - uv)) * k
            if d < t:
                confirmed[c.view_id] = None
            elif d > MISS * t:
                missed.append(c.view_id)
            continue
        dets = detections.get(c.view_id) or ()
        if not dets:
            continue
        dist = [float(np.linalg.norm(det.centre - uv)) * k for det in dets]
        near = [(dd, det) for dd, det in zip(dist, dets, strict=True) if dd < t
                and (r := size_ratio(c, det.box, p.ball, s.ball_diameter_m)) is not None
                and abs(r - 1.0) <= size_tolerance]
        if near:
            confirmed[c.view_id] = min(near, key=lambda x: x[0])[1]
        elif min(dist) > MISS * t:
            missed.append(c.view_id)
    return confirmed, tuple(missed)


def _judged(p: _Pairing, thirds: Sequence[DoubtView], detections: Mapping[Hashable, Sequence[Detection]],
            tol: Mapping[Hashable, float], s: DoubtSettings, size_tolerance: float) -> _Pairing:
    """The pairing with its third views' word (:func:`_third_views`)."""
    confirmed, missed = _third_views(p, thirds, detections, tol, s, size_tolerance)
    return _Pairing(p.members, p.ball, p.errors, p.ratios, p.error_1920, tuple(confirmed), missed)


def _same_spot(a: _Pairing, b: _Pairing) -> bool:
    """Two pairings name the same ball: in every view where both have a detection, the two detections' centres lie
    within half a ball's box of each other (a detector's duplicate boxes of one ball are no rivals)."""
    da, db = a.detections(), b.detections()
    for vid in set(da) & set(db):
        x, y = da[vid], db[vid]
        half = max(x.box[2] - x.box[0], x.box[3] - x.box[1], y.box[2] - y.box[0], y.box[3] - y.box[1]) / 2
        if float(np.linalg.norm(x.centre - y.centre)) > half:
            return False
    return True


def _chosen(pairings: Sequence[_Pairing], s: DoubtSettings) -> tuple[_Pairing, int, float | None] | None:
    """The best-supported pairing (most views: members and third views that confirm it; then the smallest worst
    error; the detectors' summed score only orders pairings whose errors are within :data:`TIE_PX`), with how many
    passed and its margin over the runner-up (px at 1920 width; None without one). None when the runner-up, a
    pairing elsewhere as well supported, is not worse by :data:`MARGIN` of tau: the rays cannot tell them apart."""
    if not pairings:
        return None

    def support(p: _Pairing) -> int:
        return len(p.members) + len(p.confirmed)

    top = max(support(p) for p in pairings)
    low = min(p.error_1920 for p in pairings if support(p) == top)
    ranked = sorted(pairings, key=lambda p: (-support(p), p.error_1920 - low >= TIE_PX,
                                             -sum(d.score for d in p.detections().values()), p.error_1920))
    best = ranked[0]
    rivals = [p for p in ranked[1:] if not _same_spot(p, best)]
    level = [p for p in rivals if support(p) >= support(best)]
    if level and min(p.error_1920 for p in level) - best.error_1920 < MARGIN * max(s.consensus_tau_px,
                                                                                     s.triangulation_tau_px):
        return None
    margin = min(p.error_1920 for p in rivals) - best.error_1920 if rivals else None
    return best, len(pairings), margin


def _sure(view: DoubtView, sigma: Mapping[Hashable, float], s: DoubtSettings) -> bool:
    """A view whose camera may make a ball with one other ray: its pixel sigma (px at 1920 width) within tau. A camera
    that may put the ball's pixel farther off than the doubts' tolerance cannot place a ball within it (the judge
    lends such a view half a vote; with a single other ray nothing outvotes its error: on a shared detector set a
    labelled view of sigma 193 px and a right detection made a ball 2.9 m off)."""
    return float(sigma.get(view.view_id, 0.0)) <= max(s.consensus_tau_px, s.triangulation_tau_px)


def _lone_ray(vote: Any) -> DoubtView | None:
    """The one labelled view whose ray detections are checked against: the only labelled view that takes part. A
    few-lined view's label (a helper's half vote) is never the only ray: as in the judge, helpers alone say nothing
    (their cameras fit their few lines yet may turn the ray by degrees; on the detector sets such a ray paired a false
    detection with a right-looking geometry twice, each time making a 3D ball metres off)."""
    return vote.labelled[0] if len(vote.labelled) == 1 else None


def _found(p: _Pairing, passed: int, margin: float | None, code: str,
           ) -> dict[Hashable, tuple[CheckedDetection, str, tuple[Hashable, ...]]]:
    """The pairing's detections as checked ones, each naming the other views that agree (members and confirming
    third views)."""
    ids = [m.view.view_id for m in p.members] + list(p.confirmed)
    out: dict[Hashable, tuple[CheckedDetection, str, tuple[Hashable, ...]]] = {}
    for vid, det in p.detections().items():
        out[vid] = (CheckedDetection(vid, det, float(p.errors[vid]), p.ball, float(p.ratios[vid]), passed, margin),
                    code, tuple(ids))
    return out


def _one_ray(lone: DoubtView, unlabelled: Sequence[DoubtView], thirds: Sequence[DoubtView],
             detections: Mapping[Hashable, Sequence[Detection]], by_id: Mapping[Hashable, BallObservation],
             tol: Mapping[Hashable, float], sigma: Mapping[Hashable, float], s: DoubtSettings,
             size_tolerance: float) -> dict[Hashable, tuple[CheckedDetection, str, tuple[Hashable, ...]]]:
    """One labelled ray and one detection: for each unlabelled view, its detections near the labelled view's ray
    across the play volume (its epipolar segment), within tau widened by both cameras' pixel sigmas
    (:func:`_on_epipolar`), are paired with it (:func:`_meet`: the rays meet within both views' tolerances in the
    play volume, the detection's box is a ball's size at that depth); a pairing a third view
    clearly misses is dropped (:func:`_third_views`), and the view's best-supported one is kept with its margin
    (:func:`_chosen`). Views whose chosen balls disagree with each other (one's ball misses the other's detection
    by more than its tolerance) are all left alone."""
    # the labelled ray's own box is not read for its size: annotated boxes are loose (on the shared detector sets
    # the true balls' labelled boxes measure 1.45 to 1.57 times the sphere's), and a player's head on that ray
    # lies at about nine tenths of the ball's depth, which no tolerance on a label's size tells apart
    ray = _Member(lone, by_id[lone.view_id], None, size_tolerance)
    chosen: dict[Hashable, tuple[_Pairing, int, float | None]] = {}
    if not _sure(lone, sigma, s):
        return {}
    for v in unlabelled:
        if not _sure(v, sigma, s):
            continue
        near = _near_ray(lone, v, detections.get(v.view_id, ()), PREFILTER * tol[v.view_id], s)
        pairings = [_judged(p, thirds, detections, tol, s, size_tolerance) for d in near
                    if _on_epipolar(lone, v, d, sigma, s)
                    and (p := _meet([ray, _member(v, d, s, size_tolerance)], tol, s)) is not None]
        c = _chosen([p for p in pairings if not p.missed], s)
        if c is not None:
            chosen[v.view_id] = c
    # the views filled must name one ball: each chosen ball meets every other chosen detection within MISS tolerances
    for (a, ca), (b, cb) in product(chosen.items(), chosen.items()):
        if a != b:
            (det,) = cb[0].detections().values()
            e = _scaled(_observation(_view(unlabelled, b), det, s), ca[0].ball)
            if e is None or e > MISS * tol[b]:
                return {}
    found: dict[Hashable, tuple[CheckedDetection, str, tuple[Hashable, ...]]] = {}
    for p, passed, margin in chosen.values():
        found.update(_found(p, passed, margin, "one_ray"))
    return found


def _among_detections(usable: Sequence[DoubtView], witnesses: Sequence[DoubtView],
                      detections: Mapping[Hashable, Sequence[Detection]], tol: Mapping[Hashable, float],
                      sigma: Mapping[Hashable, float], s: DoubtSettings,
                      size_tolerance: float) -> dict[Hashable, tuple[CheckedDetection, str, tuple[Hashable, ...]]]:
    """Detections that agree among themselves, where no labelled view takes part: every pair of detections in two
    calibrated views (``usable``: those that take part, and those with few lines whose calibration is sure) that
    meet at one ball (:func:`_meet`) collects the other views' word (:func:`_third_views`; a detection there joins
    the pairing when the rays of all still meet); a pairing of ``n`` views may have at most ``n - 2`` third views
    that clearly miss it (none for two: a detector misses about one ball in seven, so three or more views that
    meet outweigh one miss); the best supported is chosen with its margin over every other pairing
    (:func:`_chosen`), and fills its views."""
    thirds = witnesses
    cands = {v.view_id: list((detections.get(v.view_id) or ())[:MAX_CANDIDATES]) if _sure(v, sigma, s) else []
             for v in usable}
    seen: set[frozenset[tuple[Hashable, tuple[float, ...]]]] = set()
    pairings: list[_Pairing] = []
    for a, b in combinations([v for v in usable if cands[v.view_id]], 2):
        for da, db in product(cands[a.view_id], cands[b.view_id]):
            if not (_on_epipolar(_as_labelled(a, da), b, db, sigma, s)
                    and _on_epipolar(_as_labelled(b, db), a, da, sigma, s)):
                continue
            p = _meet([_member(a, da, s, size_tolerance), _member(b, db, s, size_tolerance)], tol, s)
            if p is None:
                continue
            p = _judged(p, thirds, detections, tol, s, size_tolerance)
            extra = {vid: det for vid, det in _third_views(p, usable, detections, tol, s, size_tolerance)[0].items()
                     if det is not None}
            if extra:  # the third views' detections join when every ray still meets the refitted ball
                grown = _meet([*p.members, *(_member(_view(usable, vid), det, s, size_tolerance)
                                             for vid, det in extra.items())], tol, s)
                if grown is not None:
                    p = _judged(grown, thirds, detections, tol, s, size_tolerance)
            key = frozenset((vid, det.box) for vid, det in p.detections().items())
            if key in seen:
                continue
            seen.add(key)
            pairings.append(p)
    kept = [p for p in pairings if len(p.missed) <= max(0, len(p.members) - 2)]
    c = _chosen(kept, s)
    return {} if c is None else _found(*c, "detections_agree")


def _view(views: Sequence[DoubtView], view_id: Hashable) -> DoubtView:
    return next(v for v in views if v.view_id == view_id)


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
