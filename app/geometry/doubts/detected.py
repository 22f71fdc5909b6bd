"""A detector's box as the doubts read it: the detection, a checked one, and the measures on it (its size against
a ball at a depth, the ball a set of rays meets, a view's error against it, the detections near a point or along a
ray) that :mod:`~app.geometry.doubts.detections` and :mod:`~app.geometry.doubts.pairings` share."""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Hashable, Mapping, Sequence

import numpy as np

from app.geometry.ball import sphere_image_box
from app.geometry.doubts.contract import DoubtSettings, DoubtView, _plausible
from app.geometry.doubts.epipolar import _polyline_distance, _segment
from app.geometry.pair_error import REFERENCE_WIDTH_PX
from app.geometry.spread import position_covariance
from app.geometry.triangulation import (
    BallObservation,
    reprojection_error_px,
    triangulate_dlt,
    undistort_pixels,
)
from app.geometry.weighting import camera_of, project_point, rule_scale

#: A detection is refitted only when its centre lies within this many tolerances of where the others put the ball
#: (a cheap necessary test: the refit moves the ball by less than a tolerance in a view that agrees).
PREFILTER = 3.0
#: At most this many candidates of a view are refitted (the nearest): bounded time with hundreds of detections.
MAX_CANDIDATES = 16
#: Candidates whose errors differ by less than this (px at 1920 width) are tied: the detector's score orders them.
TIE_PX = 1.0
#: The least pixel sigma (px at 1920 width) a view is read with for a ball's spread: a fit's sigma below a pixel still
#: leaves the label's or the box's own pixel.
MIN_SIGMA_PX = 1.0
#: A chosen pairing's detection lies within this many standard deviations of where the labelled ray puts the ball:
#: both cameras' pixel sigmas and the detector's own centre error in quadrature (at 1920 width). Two standard
#: deviations: a box farther off is not explained by the cameras and the detector, however wide tau is.
SIGMAS = 2.0
#: The detector's centre error as a fraction of the box's diameter (0.12 d per axis, so 0.17 d across: the
#: detector's documented error, the shared detector sets' README).
CENTRE_NOISE = 0.17
#: A detection paired with one labelled ray alone has a ball's size where the two rays meet within this fraction
#: (|ratio - 1|): the detector's sides lie within 20 % of the ball's (the shared detector sets' README), twice that
#: for the cameras' scale at that depth. The doubts' size tolerance (0.5) serves checks with more views; with one ray
#: the box's size is the only witness of the depth besides the ray (right one-ray fills on nine made sets:
#: 0.67-1.19).
LONE_SIZE_TOLERANCE = 0.4


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
    """The three conditions (module docstring) for ``det`` in ``view`` against the agreeing ``voters``
    (:func:`check_or_why` says which refused)."""
    c = check_or_why(view, det, voters, tol, s, size_tolerance)
    return c if isinstance(c, CheckedDetection) else None


def check_or_why(view: DoubtView, det: Detection, voters: Sequence[BallObservation], tol: Mapping[Hashable, float],
                 s: DoubtSettings, size_tolerance: float) -> CheckedDetection | str:
    """:func:`_check`'s checked detection, or the name of the condition that refused it: ``"play_volume"``,
    ``"rays_meet"`` (a ray beyond its tolerance of the refitted ball) or ``"size"``."""
    cand = _observation(view, det, s)
    ball = _refit([*voters, cand])
    if ball is None or not _plausible(ball, s):
        return "play_volume"
    errors = {o.view_id: _scaled(o, ball) for o in [*voters, cand]}
    if any(e is None or e >= tol[i] for i, e in errors.items()):
        return "rays_meet"
    ratio = size_ratio(view, det.box, ball, s.ball_diameter_m)
    if ratio is None or abs(ratio - 1.0) > size_tolerance:
        return "size"
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


def read_sigma(sigma: Mapping[Hashable, float], view_id: Hashable) -> float:
    """A view's pixel sigma (px at 1920 width) as a ball's spread reads it: ``sigma``'s (0 where the view has none), at
    least :data:`MIN_SIGMA_PX`."""
    return max(MIN_SIGMA_PX, float(sigma.get(view_id, 0.0)))


#: A ball whose centre lies lower than a ball resting on the grass (a radius up) by more than this many of its own
#: standard deviations along the vertical is under the grass, where no ball is (:func:`under_grass`): one-sided,
#: about one chance in a thousand for a ball on the grass whose boxes and cameras err as their sigmas say. Set a
#: priori (the normal's 99.9 % point), not fitted.
UNDER_GRASS_SIGMAS = 3.0


def under_grass(members: Sequence[tuple[BallObservation, DoubtView, Sequence[float] | np.ndarray | None]],
                ball: np.ndarray, sigma: Mapping[Hashable, float], s: DoubtSettings) -> bool:
    """Whether the ball ``members``' rays meet at lies under the grass beyond its own uncertainty: its centre
    (``ball``, (3,) world metres, SoccerNet z down) lower than a ball resting on the grass (``s.ball_diameter_m`` / 2
    up) by more than :data:`UNDER_GRASS_SIGMAS` standard deviations of its height. The height's deviation is the
    least-squares ball's (:func:`app.geometry.spread.position_covariance`), each member's pixel sigma its camera's
    (``sigma``, px at 1920 width, at least :data:`MIN_SIGMA_PX`) and :data:`CENTRE_NOISE` of its box's diameter
    (``members``: (observation, view, box [x1, y1, x2, y2] px or None for a point)) in quadrature. False where the
    members fix no point.

    The play volume lets a ball's centre lie half a metre under the grass, the noise of a ball two unsure cameras
    place; two sure cameras that meet far under it meet at no ball. A false box on a labelled view's ray meets that
    ray at a ball's size somewhere along it, under the grass as readily as over it (made set seed-203-s2417: a box
    41 px off the ball in a camera 2.4 m high, on the ray of a view whose camera projects the true ball within 3 px,
    met it 0.23 m under a resting ball's centre, seven of its standard deviations: a 3D ball 1.13 m off)."""
    sig: dict[Hashable, float] = {}
    for obs, view, box in members:
        d = 0.0 if box is None else _diameter([float(x) for x in box], view) * REFERENCE_WIDTH_PX / view.width
        noise = CENTRE_NOISE * d
        sig[obs.view_id] = math.hypot(read_sigma(sigma, obs.view_id), noise)
    below = float(ball[2]) + s.ball_diameter_m / 2
    if below <= 0:
        return False
    cov = position_covariance([obs for obs, _, _ in members], ball, sig)
    return cov is not None and below > UNDER_GRASS_SIGMAS * math.sqrt(max(float(cov[2, 2]), 0.0))


def explained(errors: Mapping[Hashable, float], boxes: Mapping[Hashable, tuple[DoubtView, Sequence[float]]],
              sigma: Mapping[Hashable, float], s: DoubtSettings) -> bool:
    """Whether each detection's reprojection error from a ball (``errors``: view id -> px at 1920 width, for every
    view that placed the ball) lies within :data:`SIGMAS` standard deviations: every placing view's pixel sigma
    (``sigma``, px at 1920 width, at least :data:`MIN_SIGMA_PX`) and :data:`CENTRE_NOISE` of the detection's box
    diameter (``boxes``: view id -> (view, box (4,) px x1, y1, x2, y2), the detections only) in quadrature."""
    cams = sum(read_sigma(sigma, vid) ** 2 for vid in errors)
    return not any(errors[vid] > sigmas_px(cams, box, view, s) for vid, (view, box) in boxes.items())


def sigmas_px(cameras_var: float, box: Sequence[float], view: DoubtView, s: DoubtSettings) -> float:
    """:data:`SIGMAS` standard deviations (px at 1920 width) of a detection's centre in ``view``: the cameras'
    variance ``cameras_var`` (px^2 at 1920 width, their pixel sigmas squared and summed) and :data:`CENTRE_NOISE` of
    the ``box``'s diameter (px x1, y1, x2, y2) in quadrature."""
    d = _diameter(box, view) * rule_scale(view, s)
    return SIGMAS * math.sqrt(cameras_var + (CENTRE_NOISE * d) ** 2)


def _epipolar_distance(ray_view: DoubtView, centre: np.ndarray, view: DoubtView, s: DoubtSettings) -> float:
    """How far (px at 1920 width) ``centre`` (2,) px of ``view`` lies from the ball ray of ``ray_view``'s label (or
    detection, given as its box) across the play volume, seen in ``view`` (its epipolar segment,
    :func:`app.geometry.doubts.epipolar._segment`); ``inf`` when that ray misses the volume or is not seen."""
    seg = _segment(ray_view, view, s)
    if seg is None:
        return math.inf
    return _polyline_distance(seg[1], centre)[0] * rule_scale(view, s)


def _on_ray_within_sigmas(lone: DoubtView, view: DoubtView, det: Detection, sigma: Mapping[Hashable, float],
                          s: DoubtSettings) -> bool:
    """Whether ``det``'s centre lies within :data:`SIGMAS` standard deviations of ``lone``'s ball ray seen in
    ``view`` (its epipolar segment across the play volume, px at 1920 width): both cameras' pixel sigmas (each at
    least :data:`MIN_SIGMA_PX`) and the detector's centre error (:data:`CENTRE_NOISE` of the box's diameter) in
    quadrature, as :func:`_explained` asks of a chosen box. Where the ball lies on that ray a box farther off is not
    explained by the cameras and the detector, so it is no rival the ray cannot tell from another."""
    cams = sum(read_sigma(sigma, v.view_id) ** 2 for v in (lone, view))
    return _epipolar_distance(lone, det.centre, view, s) <= sigmas_px(cams, det.box, view, s)


def _pinned(a: DoubtView, b: DoubtView, sigma: Mapping[Hashable, float], s: DoubtSettings) -> bool:
    """Whether two cameras alone (a labelled ray and a detection) may place a ball: both sure (pixel sigma ``sigma``,
    px at 1920 width, within tau), or, where one is not, the other sure to half of tau. Two rays each of which may
    turn by about tau leave nothing to pin their ball where they meet (on a made set cameras of 26 and 18 px met a
    false box at the image's edge 15.8 m from the ball, every check of the spread and the box passed)."""
    tau = max(s.consensus_tau_px, s.triangulation_tau_px)
    low, high = sorted((float(sigma.get(a.view_id, 0.0)), float(sigma.get(b.view_id, 0.0))))
    return high <= tau or low <= tau / 2
