"""Detections paired where the labelled views do not agree on a ball: one labelled ray and one detection
(``one_ray``), and detections that agree among themselves (``detections_agree``, weak labels joining them where a
third view confirms), each with the third views' word and a margin over the runner-up (docs/detectors.md, "The
check"). Where cameras take no part in the votes: :mod:`app.geometry.doubts.weak`."""
from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from itertools import combinations, product
from typing import Any, Hashable, Mapping, Sequence

import numpy as np

from app.geometry.doubts.contract import DoubtSettings, DoubtView, _inside, _plausible
from app.geometry.doubts.detected import (
    LONE_SIZE_TOLERANCE,
    MAX_CANDIDATES,
    PREFILTER,
    TIE_PX,
    CheckedDetection,
    Detection,
    _epipolar_distance,
    _near_ray,
    _observation,
    _on_ray_within_sigmas,
    _pinned,
    _refit,
    _scaled,
    explained,
    read_sigma,
    sigmas_px,
    size_ratio,
    under_grass,
)
from app.geometry.pitch import BALL_DIAMETER_M
from app.geometry.spread import position_covariance, position_sigma_m, projected_sigma_px
from app.geometry.triangulation import (
    BallObservation,
    angle_between_deg,
)
from app.geometry.weighting import label_centre, project_point, ray_at_height, rule_scale

#: A third calibrated view confirms a ball two views place when one of its detections (or its label) lies within its
#: tolerance of where that ball projects, at a ball's size; it contradicts it (a clear miss) when the ball projects
#: inside its image by that tolerance and nothing of it lies within :data:`MISS` tolerances.
MISS = 2.0
#: A candidate is chosen only when the runner-up (a candidate elsewhere, as well supported) is worse by at least this
#: fraction of the doubts' tau (px at 1920 width): two spots that meet the rays about as well cannot be told apart.
MARGIN = 0.5
#: Half a metre: twice it stays within the metre beyond which a 3D ball is wrong. How far a checked detection may
#: always move the ball the labelled views agree on (``app.geometry.doubts.detections._keeps_ball``), and the height
#: a ball "on the grass" may have (:data:`ON_GRASS_M`). Two rays from cameras sure to a few pixels can still fix the
#: depth badly (a small parallax, a far view): on a made set two right detections with cameras 3-4 px from the truth
#: put a ball 1.2 m off, their ball's sigma 9.6 m: the bound of a pairing's ball in the air (:func:`_placed`).
MAX_SPREAD_M = 0.5
#: A camera whose pixel sigma lets the ball's pixel wander over more than this share of its image tells no box from
#: another: the window where a second detection would make the choice ambiguous (:data:`MISS` tolerances around
#: the ball, the tolerance the view's sigma, at least tau) must cover at most a tenth of the image. The detector's
#: documented 1.2 false detections an image then put one in that window about one time in eight, and it misses the
#: ball about one time in seven (recall 0.85): a lone false box passes for the ball about 2 % of the time, the
#: issue's budget of wrong fills (at 1920 x 1080 a sigma of up to about 128 px).
MAX_WINDOW_SHARE = 0.1


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
    member's relative tolerance). None otherwise (:func:`meet_or_why` says which check refused)."""
    p = meet_or_why(members, tol, s)
    return p if isinstance(p, _Pairing) else None


def meet_or_why(members: Sequence[_Member], tol: Mapping[Hashable, float], s: DoubtSettings) -> _Pairing | str:
    """:func:`_meet`'s pairing, or the name of the check that refused it: ``"play_volume"`` (no ball, or one outside
    the play volume), ``"rays_meet"`` (a member's error at or beyond its tolerance), ``"size"`` (a box not a ball's
    size there), ``"baseline_parallax"`` (no pair of cameras far enough apart under enough parallax)."""
    ball = _refit([m.obs for m in members])
    if ball is None or not _plausible(ball, s):
        return "play_volume"
    errors: dict[Hashable, float] = {}
    ratios: dict[Hashable, float] = {}
    for m in members:
        e = _scaled(m.obs, ball)
        if e is None or e >= tol[m.view.view_id]:
            return "rays_meet"
        errors[m.view.view_id] = e
        if m.box is not None:
            r = size_ratio(m.view, m.box, ball, s.ball_diameter_m)
            if r is None or abs(r - 1.0) > m.size_tolerance:
                return "size"
            ratios[m.view.view_id] = r
    if not any(float(np.linalg.norm(a.obs.camera.C - b.obs.camera.C)) >= s.min_baseline_m
               and angle_between_deg(ball - a.obs.camera.C, ball - b.obs.camera.C) >= s.min_parallax_deg
               for a, b in combinations(members, 2)):
        return "baseline_parallax"
    return _Pairing(tuple(members), ball, errors, ratios, max(errors.values()))


def _band(a: DoubtView, b: DoubtView, sigma: Mapping[Hashable, float], s: DoubtSettings) -> float:
    """How far (px at 1920 width) a point may lie from ``a``'s ball ray seen in ``b``: tau, widened to both cameras'
    pixel sigmas (:func:`app.geometry.weighting.pixel_sigma`) added in quadrature where they exceed it."""
    return max(max(s.consensus_tau_px, s.triangulation_tau_px),
               math.hypot(sigma.get(a.view_id, 0.0), sigma.get(b.view_id, 0.0)))


def _on_epipolar(a: DoubtView, b: DoubtView, det_b: Detection, sigma: Mapping[Hashable, float],
                 s: DoubtSettings) -> bool:
    """Condition 1 for a pair: ``det_b``'s centre lies within :func:`_band` of ``a``'s ball ray seen in ``b``:
    measured in the detection's own image, not split between the two views as the refit's errors are (a view that
    sees the ball small would take most of the distance at a small cost in its pixels)."""
    return _epipolar_distance(a, det_b.centre, b, s) <= _band(a, b, sigma, s)


def _as_labelled(view: DoubtView, det: Detection) -> DoubtView:
    """``view`` with ``det``'s box as its ball label (so that its ray is the detection's)."""
    return dataclasses.replace(view, box=np.asarray(det.box, float), point=None)


def _third_views(p: _Pairing, thirds: Sequence[DoubtView], detections: Mapping[Hashable, Sequence[Detection]],
                 tol: Mapping[Hashable, float], s: DoubtSettings,
                 size_tolerance: float) -> tuple[dict[Hashable, Detection | None], tuple[Hashable, ...]]:
    """What the calibrated views outside the pairing say of its ball: view id -> the detection there (None: its
    label is there) for those that confirm it, and the ids of those that clearly miss it: a labelled view whose
    label lies more than :data:`MISS` tolerances from where the ball projects, wherever it projects (a person saw
    the one ball of the system at the label: a ball outside that view's image is elsewhere), and an unlabelled view
    the ball projects inside of by its tolerance where none of its detections lies within :data:`MISS` tolerances.
    An unlabelled view the ball projects outside of, or one without any detection (the detector may not have run
    on it), and a view the ball lies behind, say nothing."""
    inside = {m.view.view_id for m in p.members}
    confirmed: dict[Hashable, Detection | None] = {}
    missed: list[Hashable] = []
    for c in thirds:
        if c.view_id in inside or c.camera is None or c.view_id not in tol:
            continue
        uv = project_point(c, p.ball)
        k, t = rule_scale(c, s), tol[c.view_id]
        if uv is None:
            continue
        label = label_centre(c)
        # a label is read wherever the ball projects: on a made set two false boxes met at a ball 28 m off, above
        # the image of the one labelled view (a camera the players placed, its label at the true ball)
        if label is None and not _inside(c, uv, t / k):
            continue
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


def _placed(p: _Pairing, sigma: Mapping[Hashable, float], s: DoubtSettings) -> bool:
    """Whether the pairing's cameras place its ball within :data:`MAX_SPREAD_M` (:data:`GRASS_SPREAD_M` where the
    grass places it, :func:`_grass_placed`), one standard deviation along the worst direction at pixel sigmas ``sigma``
    (px at 1920 width, :func:`_spread`), and not under the grass (:func:`under_grass`). Asked of the chosen pairing
    only: a badly placed candidate is a rival still (dropping it first lets a false box placed better win alone)."""
    spread = _spread(p, sigma)
    return (spread is not None and spread <= (GRASS_SPREAD_M if _grass_placed(p) else MAX_SPREAD_M) and not under_grass(
        [(m.obs, m.view, m.view.box if m.box is None else m.box) for m in p.members], p.ball, sigma, s))


def _spread(p: _Pairing, sigma: Mapping[Hashable, float]) -> float | None:
    """The pairing's ball's spread (m, :func:`app.geometry.spread.position_sigma_m`) at its members' pixel sigmas."""
    return position_sigma_m([m.obs for m in p.members], p.ball,
                            {m.view.view_id: read_sigma(sigma, m.view.view_id) for m in p.members})


def _grass_placed(p: _Pairing) -> bool:
    """Whether every member's ray (its label's or detection's centre) meets the plane of a ball's centre on the grass
    (a radius up, :data:`app.geometry.pitch.BALL_DIAMETER_M`; SoccerNet world, z down) within :data:`MAX_SPREAD_M` of
    the pairing's ball: the grass then places it where each ray meets it, whatever the parallax fixes of its depth."""
    return all(_meets_grass_near(m, p.ball, MAX_SPREAD_M) for m in p.members)


def _meets_grass_near(m: _Member, ball: np.ndarray, within_m: float) -> bool:
    """Whether ``m``'s ray (its label's or detection's centre) meets the plane of a ball's centre on the grass (a radius
    up; SoccerNet world, z down) within ``within_m`` metres of ``ball`` ((3,) world metres)."""
    ray = m.obs.camera.rays(np.asarray(m.obs.point_px, float).reshape(1, 2))[0]
    grass = ray_at_height(m.obs.camera.C, ray, -BALL_DIAMETER_M / 2)
    return grass is not None and float(np.linalg.norm(grass - ball)) <= within_m


def _explained(p: _Pairing, sigma: Mapping[Hashable, float], s: DoubtSettings) -> bool:
    """Whether each detection lies from the ball within :data:`SIGMAS` standard deviations (:func:`explained`), a
    ball's size there within :data:`LONE_SIZE_TOLERANCE`. tau is the labels' wide tolerance: between cameras sure to
    a few pixels a box ten pixels off the ray (made set: 10 m off) or half the ball's size (29 m off) is not it."""
    return explained(p.errors, {m.view.view_id: (m.view, m.box) for m in p.members
                                if m.detection is not None and m.box is not None}, sigma, s) and all(
        abs(float(p.ratios[m.view.view_id]) - 1.0) <= LONE_SIZE_TOLERANCE for m in p.members if m.detection is not None)


#: The share of a person's box height, at its top and at its bottom, where a ball detector's false boxes sit: a head
#: (about an eighth of a standing person's height) and the feet. A detection whose centre lies there, within the box's
#: width (and a ball's radius beyond its top or bottom edge), is "on a person's head or feet".
HEAD_FEET = 0.15
#: The most (m) a ball's centre lies above the grass for it to be "on the grass": the allowance the play volume gives
#: below it (``app.geometry.pitch.PLAY_VOLUME``) and the spread a one-ray ball may have (:data:`MAX_SPREAD_M`).
ON_GRASS_M = 0.5
#: The most (m, one standard deviation along the worst direction) the ball of a chosen pairing may move with its
#: cameras' pixel sigmas where the grass places it (:func:`_grass_placed`), against :data:`MAX_SPREAD_M` elsewhere
#: (:func:`_placed`). Such a ball lies where each ray meets the grass, which the rays' parallax does not fix (a ball
#: in the air brought down to the grass by a badly fixed depth would leave the rays' grass points apart), and the
#: spread, from pixel sigmas that overstate the cameras' errors (about five times at the median,
#: ``app.geometry.weighting.pixel_sigma``), overstates the ball's. On 31 detector sets (``benchmarks/DETECTOR.md``,
#: 2026-11-27, sixth session) the true detections refused at one metre placed balls 0.02-0.39 m from the truth at
#: spreads of 1-2.2 m; two metres filled 36 views more, no bound at all 53, neither a wrong box nor a wrong 3D ball.
GRASS_SPREAD_M = 2.0
#: How far (m) from a one-ray ball on the grass the labelled ray must meet the grass (:func:`_told_from_players`):
#: for a box on a person's head or feet the metre beyond which a 3D ball is wrong; for any other box three metres
#: (a camera 1.1 m up saw a made set's ball along a ray meeting the grass 10 m beyond a false box at the other
#: image's edge: a 3D ball 11.3 m off; on 31 sets two metres cost 19 right fills, three metres 3).
GRASS_POINT_M, LOW_RAY_M = 1.0, 3.0


def _on_head_or_feet(view: DoubtView, det: Detection) -> bool:
    """Whether ``det``'s centre lies on a head or the feet of a person boxed in ``view`` (``view.players``, px): within
    the person's box across, and within :data:`HEAD_FEET` of its height below its top or above its bottom edge (or a
    ball's radius, half the detection's box, beyond that edge)."""
    (cx, cy), r = det.centre, max(det.box[2] - det.box[0], det.box[3] - det.box[1]) / 2
    for x1, y1, x2, y2 in view.players:
        h = y2 - y1
        if h > 0 and x1 <= cx <= x2 and (y1 - r <= cy <= y1 + HEAD_FEET * h or y2 - HEAD_FEET * h <= cy <= y2 + r):
            return True
    return False


def _told_from_players(p: _Pairing, view: DoubtView) -> bool:
    """Whether a lone labelled ray's pairing can be told from a false box: a third view confirms its ball, or its
    detection in ``view`` lies on a person's head or feet (:func:`_on_head_or_feet`) and the ball it makes lies on
    the grass (its centre at most :data:`ON_GRASS_M` above it; SoccerNet world, z down) where the labelled ray meets
    the grass (within :data:`GRASS_POINT_M` of it), or it lies elsewhere and its ball, if on the grass, is within
    :data:`LOW_RAY_M` of where the labelled ray meets the grass.

    With one labelled ray the detection alone fixes the depth along it, and nothing of the two views tells the ball
    from a false box that happens to lie on the ray's band at a ball's size. Such boxes are not spread evenly: a ball
    detector's false boxes sit mostly on players' heads and feet (60 % of them, the shared detector sets' README),
    and the players crowd where the ball is, which is where the ray's band crosses the view. A box there that puts the
    ball on the grass puts it where the labelled ray meets the grass, where a ball in play on the ground is, whatever
    the box shows (a ball at a player's feet; a near ball over a far player's head); one that puts it in the air rests
    its height on that box alone, which a head or feet on the band explain as well. On eleven detector sets
    (``benchmarks/DETECTOR.md``, 2026-11-27, branch safety) the one-ray pairings chosen on a head or feet with the
    ball in the air were four false boxes (balls 2-12 m off; three filled, each making a system's 3D ball wrong) to
    three balls; with the ball on the grass, about thirty balls and two false boxes (0.7 and 1.0 m off).
    A third view's label or detection at the ball (:func:`_third_views`) is the second witness such a box lacks.
    The height alone does not pin the ball on a ray that runs low over the grass: a camera low behind a goal sees the
    ball along a ray that stays within half a metre of the grass for metres, where any box on the grass along the
    band meets it (made sets: a box on a person's feet put the ball 0.44 m up where that ray was still 12.7 m from
    meeting the grass, a 3D ball made 12 m wrong; a false box elsewhere, 11.3 m wrong)."""
    (det,) = p.detections().values()
    if p.confirmed:
        return True
    on_grass = -float(p.ball[2]) <= ON_GRASS_M
    if _on_head_or_feet(view, det):
        return on_grass and _meets_grass_near(p.members[0], p.ball, GRASS_POINT_M)
    return not on_grass or _meets_grass_near(p.members[0], p.ball, LOW_RAY_M)


def _sure(view: DoubtView, sigma: Mapping[Hashable, float], s: DoubtSettings) -> bool:
    """A view whose camera may pair without its spread being asked: its pixel sigma (px at 1920 width) within tau (the
    judge lends one beyond half a vote; with a single other ray nothing outvotes its error: a shared set's labelled
    view of sigma 193 px and a right detection made a ball 2.9 m off). :func:`_one_ray` weighs it by its spread."""
    return float(sigma.get(view.view_id, 0.0)) <= max(s.consensus_tau_px, s.triangulation_tau_px)


def _ray_missed(lone: DoubtView, p: _Pairing, thirds: Sequence[DoubtView],
                detections: Mapping[Hashable, Sequence[Detection]], tol: Mapping[Hashable, float],
                s: DoubtSettings) -> bool:
    """Whether a third view clearly misses the ball a labelled ray and a detection place (:func:`_third_views`), read
    knowing that the system's ball lies on that ray: a labelled view's miss always counts (a person saw the ball
    at the label); an unlabelled view's miss counts only when one of its detections lies near the labelled ray
    (within :data:`MISS` tolerances of its epipolar segment across the play volume), i.e. where that view's detector
    shows a ball elsewhere on the ray. A view with no detection near the ray at all missed the ball wherever on the
    ray it lies (the detector misses about one ball in seven, the shared detector sets' README): its silence cannot
    tell this spot from any other, so it contradicts nothing (on the shared sets, ten right pairings 0.02-0.24 m
    from the true ball were dropped so, each by a view whose detector had missed a ball projecting within a few
    pixels of the pairing's)."""
    for vid in p.missed:
        c = _view(thirds, vid)
        if label_centre(c) is not None or _near_ray(lone, c, detections.get(vid) or (), MISS * tol[vid], s):
            return True
    return False


def _agrees(p: _Pairing, chosen: _Pairing, view: DoubtView, tol: Mapping[Hashable, float],
            sigma: Mapping[Hashable, float], s: DoubtSettings) -> bool:
    """Whether the detection of a labelled ray's pairing ``p`` in ``view`` and the ball of another view's ``chosen``
    pairing name one ball: the detection lies within :data:`MISS` tolerances (px at 1920 width) of where that ball
    projects, and within :data:`SIGMAS` standard deviations of it: the chosen ball's own uncertainty projected into
    ``view`` (its members' pixel sigmas, at least :data:`MIN_SIGMA_PX`, through
    :func:`app.geometry.spread.position_covariance` and :func:`app.geometry.spread.projected_sigma_px`), ``view``'s
    pixel sigma and :data:`CENTRE_NOISE` of the box's diameter, in quadrature. The tolerance alone is the doubts'
    wide one for labels; along a labelled ray two spots a metre apart may project within it in a far view (on a made
    set a false box on the ray in a view whose detector missed the ball made a 3D ball 1.38 m off, while the unsure
    view's detection of the ball, 31 px@1920 from where that ball projects, some four of its standard deviations,
    met the ray within half a pixel)."""
    ((vid, det),) = p.detections().items()
    obs = _observation(view, det, s)
    e = _scaled(obs, chosen.ball)
    if e is None or e > MISS * tol[view.view_id]:
        return False
    sig = {m.view.view_id: read_sigma(sigma, m.view.view_id) for m in chosen.members}
    cov = position_covariance([m.obs for m in chosen.members], chosen.ball, sig)
    spread = None if cov is None else projected_sigma_px(obs, chosen.ball, cov)
    if spread is None:  # the members fix no point: nothing sharper than the tolerance
        return True
    own = read_sigma(sigma, vid)
    return e <= sigmas_px(spread ** 2 + own ** 2, det.box, view, s)


def _lone_ray(vote: Any) -> DoubtView | None:
    """The one labelled view whose ray detections are checked against: the only labelled view that takes part, or,
    where none does, the only helper (a few-lined view lending half a vote) whose camera its players placed. A
    camera fitted to a few lines alone is never the only ray: as in the judge, such helpers alone say nothing (they
    fit their few lines yet may turn the ray by degrees; on the detector sets such a ray paired a false detection
    with a right-looking geometry twice, each time making a 3D ball metres off). A camera the players placed is
    over-determined by the foot points it shares with the well-lined views (at least 3 players, 70 % of them
    inliers, its pixel sigma where the play is within 10 px at 1920 width, ``app.geometry.calibration.players``)
    and its stored uncertainty says how far its ray may turn: it is checked within that uncertainty like a lined
    view's (on dev-large and the five doubts seeds 829 of 837 such cameras put the true ball within 20 px), and its
    half vote pairs only with a detection that is alone near its ray (:func:`_one_ray`)."""
    if len(vote.labelled) == 1:
        return vote.labelled[0]
    if not vote.labelled and len(vote.helpers) == 1 and vote.helpers[0].player_assisted:
        return vote.helpers[0]
    return None


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
             size_tolerance: float, half_vote: bool = False,
             ) -> dict[Hashable, tuple[CheckedDetection, str, tuple[Hashable, ...]]]:
    """One labelled ray and one detection: for each unlabelled view, its detections near the labelled view's ray
    across the play volume (its epipolar segment, tau widened by both cameras' pixel sigmas, :func:`_on_epipolar`) are
    paired with it (:func:`_meet`); a pairing a third view clearly misses is dropped (:func:`_ray_missed`), and the
    view's best-supported one is kept with its margin (:func:`_chosen`) where its cameras pin and place the ball
    (:func:`_pinned`, :func:`_placed`), explain the box (:func:`_explained`) and tell it from a false one
    (:func:`_told_from_players`). Views whose chosen balls disagree with each other are all left alone, and a chosen
    view is left alone where another view's every box on the ray lies elsewhere than its ball (:func:`_agrees`).

    A camera unsure beyond tau takes part weighted by its uncertainty (its sigma widens the band, its tolerance and
    the spread); one whose sigma no longer tells (:func:`_telling`) fills nothing (branch vote5, DETECTOR.md).

    ``half_vote``: the ray is a helper's (:func:`_lone_ray`, a camera the players placed). Its view is filled only
    when one detection at most of that view lies where the two cameras and the detector explain the ball on that ray
    (:func:`_on_ray_within_sigmas`): where the detector missed the ball, its false boxes cluster on the players around
    it, and two of them on the ray mean one may lie on it at a ball's size by chance (on a shared detector set such
    a box, with a second false box near the same segment, made a 3D ball 3.9 m off); a half vote has no margin of
    its own to tell them apart. A labelled view's full vote keeps the margin rule alone."""
    # the labelled ray's own box is not read for its size: annotated boxes are loose (on the shared detector sets
    # the true balls' labelled boxes measure 1.45 to 1.57 times the sphere's), and a player's head on that ray
    # lies at about nine tenths of the ball's depth, which no tolerance on a label's size tells apart
    ray = _Member(lone, by_id[lone.view_id], None, size_tolerance)
    chosen: dict[Hashable, tuple[_Pairing, int, float | None]] = {}
    met: dict[Hashable, list[_Pairing]] = {}
    if not _telling(lone, float(sigma.get(lone.view_id, 0.0)), s):
        return {}
    for v in unlabelled:
        near = _near_ray(lone, v, detections.get(v.view_id, ()), PREFILTER * tol[v.view_id], s)
        if half_vote and sum(_on_ray_within_sigmas(lone, v, d, sigma, s) for d in near) > 1:
            continue  # a half vote's ray arbitrates between no two candidates its cameras cannot tell apart
        pairings = [_judged(p, thirds, detections, tol, s, size_tolerance) for d in near
                    if _on_epipolar(lone, v, d, sigma, s)
                    and (p := _meet([ray, _member(v, d, s, size_tolerance)], tol, s)) is not None]
        met[v.view_id] = pairings
        # a view whose camera no longer tells fills nothing, yet its boxes on the ray still say where on it the ball
        # is (below); an unsure one that tells takes part weighted by its sigma (band, tolerance, spread)
        if not _telling(v, float(sigma.get(v.view_id, 0.0)), s):
            continue
        c = _chosen([p for p in pairings if not _ray_missed(lone, p, thirds, detections, tol, s)], s)
        if (c is not None and _pinned(lone, v, sigma, s) and _placed(c[0], sigma, s) and _explained(c[0], sigma, s)
                and _told_from_players(c[0], v)):
            chosen[v.view_id] = c
    # a view whose every box on the labelled ray (at a ball's size where the rays meet) lies elsewhere than a chosen
    # ball disputes it, whatever refused its own pairings: each is as much evidence of where on the ray the ball is
    # (on a made set a false box chosen so made a 3D ball 33 m off, while the other view's detection of the ball,
    # refused by that very box as a third view, could not answer back: the false ball projected outside its image)
    chosen = {b: cb for b, cb in chosen.items() if not any(
        a != b and ps and not any(_agrees(p, cb[0], _view(unlabelled, a), tol, sigma, s) for p in ps)
        for a, ps in met.items())}
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
                      sigma: Mapping[Hashable, float], s: DoubtSettings, size_tolerance: float,
                      rays: Sequence[DoubtView] = (), by_id: Mapping[Hashable, BallObservation] | None = None,
                      ) -> dict[Hashable, tuple[CheckedDetection, str, tuple[Hashable, ...]]]:
    """Detections that agree among themselves, where no labelled view takes part: every pair of detections in two
    calibrated views (``usable``: those that take part, and those with few lines whose calibration is sure) that
    meet at one ball (:func:`_meet`) collects the other views' word (:func:`_third_views`; a detection there joins
    the pairing when the rays of all still meet); a pairing of ``n`` views may have at most ``n - 2`` third views
    that clearly miss it (none for two: a detector misses about one ball in seven, so three or more views that
    meet outweigh one miss); the best supported is chosen with its margin over every other pairing
    (:func:`_chosen`), and fills its views.

    ``rays``: labelled views whose camera takes no full part in the votes (a helper's half vote, or an unsure camera
    that still tells where the ball lies, :func:`_telling`; ``by_id`` their label's observations): their labels pair
    like detections (a person saw the ball there; the box is not read for its size: labelled boxes are loose), but
    a pairing holding one must be confirmed by a third view (three views in all, at least one of them a detection):
    such a camera may turn its ray by degrees, and one detection on a turned ray is two views that cannot tell
    (:func:`_weak_ray` fills from one only where the box cannot make a 3D ball)."""
    thirds = witnesses
    items: dict[Hashable, list[Detection | None]] = {
        v.view_id: list((detections.get(v.view_id) or ())[:MAX_CANDIDATES]) if _sure(v, sigma, s) else []
        for v in usable}
    items.update({r.view_id: [None] for r in rays if by_id is not None and r.view_id in by_id})
    pool = [v for v in [*usable, *rays] if items.get(v.view_id)]

    def member(v: DoubtView, d: Detection | None) -> _Member:
        if d is None:
            assert by_id is not None  # a label's item exists only with its observation
            return _Member(v, by_id[v.view_id], None, size_tolerance)
        return _member(v, d, s, size_tolerance)

    def ray(v: DoubtView, d: Detection | None) -> tuple[DoubtView, np.ndarray]:
        if d is None:
            centre = label_centre(v)
            assert centre is not None  # a ray's view is labelled
            return v, centre
        return _as_labelled(v, d), d.centre

    def near(a: tuple[DoubtView, np.ndarray], b: tuple[DoubtView, np.ndarray], va: DoubtView, vb: DoubtView) -> bool:
        return _epipolar_distance(a[0], b[1], vb, s) <= _band(va, vb, sigma, s)

    seen: set[frozenset[tuple[Hashable, tuple[float, ...] | None]]] = set()
    pairings: list[_Pairing] = []
    for a, b in combinations(pool, 2):
        for da, db in product(items[a.view_id], items[b.view_id]):
            if da is None and db is None:
                continue  # two labels fill nothing; they may still be the third views of a pairing
            ra, rb = ray(a, da), ray(b, db)
            if not (near(ra, rb, a, b) and near(rb, ra, b, a)):
                continue
            p = _meet([member(a, da), member(b, db)], tol, s)
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
            key = frozenset((m.view.view_id, None if m.detection is None else m.detection.box) for m in p.members)
            if key in seen:
                continue
            seen.add(key)
            pairings.append(p)
    telling = {v.view_id for v in thirds if _telling(v, tol.get(v.view_id, math.inf), s)}
    kept = [p for p in pairings if len(p.missed) <= max(0, len(p.members) - 2)
            and (all(m.detection is not None for m in p.members)
                 or len(p.members) + sum(1 for c in p.confirmed if c in telling) >= 3)]
    c = _chosen(kept, s)
    return {} if c is None or not _placed(c[0], sigma, s) or _one_person(c[0]) else _found(*c, "detections_agree")


def _one_person(p: _Pairing) -> bool:
    """Whether detections that agree among themselves may be one person seen from each view: every detection of the
    pairing lies on a person's head or feet (:func:`_on_head_or_feet`), its ball is not on the grass where every ray
    meets it (:func:`_grass_placed`), and no third view confirms it. A person's head seen in two calibrated views
    meets at one point of the play volume at a ball's size as surely as the ball does, and a ball detector's false
    boxes sit there (60 % of them, the shared detector sets' README): on a made set two views' boxes on one player's
    head met 1.6 m up, 8.5 m from the ball, and made the system's 3D ball."""
    dets = [m for m in p.members if m.detection is not None]
    return (bool(dets) and not p.confirmed and not _grass_placed(p)
            and all(_on_head_or_feet(m.view, m.detection) for m in dets if m.detection is not None))


def _view(views: Sequence[DoubtView], view_id: Hashable) -> DoubtView:
    return next(v for v in views if v.view_id == view_id)


def _telling(view: DoubtView, sig: float, s: DoubtSettings) -> bool:
    """Whether a camera of pixel sigma ``sig`` (px at 1920 width) still tells where the ball lies in ``view``'s
    image (:data:`MAX_WINDOW_SHARE`): the disc of :data:`MISS` tolerances (its sigma, at least tau) around the ball's
    pixel covers at most that share of the image."""
    if not math.isfinite(sig):
        return False
    r = MISS * max(max(s.consensus_tau_px, s.triangulation_tau_px), sig) / rule_scale(view, s)
    return math.pi * r * r <= MAX_WINDOW_SHARE * view.width * view.height
