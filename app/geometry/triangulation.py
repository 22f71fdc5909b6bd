"""Pairwise triangulation of the ball centre and its fusion (paper Eq. triangulation, method.md section 5).

For every pair (i, j) of calibrated views with a ball label:

1. the ball centres are undistorted (pixels -> undistorted pixels of the same camera), then
   triangulated with the linear homogeneous DLT (Hartley and Zisserman, *Multiple View Geometry*,
   2nd ed., section 12.2) using ``P = K R [I | -C]``;
2. the point ``p_ij`` is reprojected (with distortion) into both views; the two pixel errors combine
   into ``e_ij`` by a named rule (:data:`app.geometry.pair_error.PAIR_ERROR_RULES`);
3. the parallax angle ``beta_ij`` between the two viewing rays (degrees) and the baseline
   ``|C_i - C_j|`` (metres) are recorded;
4. the pair is kept when ``e_ij < tau``, the baseline is at least ``min_baseline_m`` (paper: 1 m)
   and, beyond the paper, the parallax is at least ``min_parallax_deg``. The baseline rule alone
   misses near-duplicate viewpoints once cameras come from calibration: each calibrated centre errs
   by decimetres along the viewing direction, so two cameras 0.6 m apart can appear 1.5 m apart, while
   their rays still meet at well under a degree and the point's depth is unconstrained. The parallax
   angle is measured on the rays, so calibration error along the axis does not hide it.

The ball is the mean of the kept ``p_ij``; each labelled view then gets the reprojection error of
that fused ball in its own pixels (SoccerNet-v3D's ``rep_error``). Beyond the paper, views may be weighed
by what their calibration is worth (``view_weights`` of :func:`triangulate_ball`): a pair of weak
calibrations makes no ball and weaker pairs do not move the ball sure pairs make.

Points behind a camera: a pair whose ``p_ij`` has a camera depth below
:data:`app.geometry.camera.MIN_DEPTH_M` in either view is dropped with reason ``behind_camera``
(cheirality; its ``e_ij`` is undefined and reported as ``None``). This happens when the two rays
diverge, e.g. a wrongly placed ball label or a mirrored calibration: the algebraic DLT solution then
lies behind one of the cameras. For the fused ball, a view in which it lies behind the camera has
reprojection error ``None``.

World frame: SoccerNet (metres, origin at the centre spot, z down). Image: continuous pixels,
origin at the top-left corner.
"""
from __future__ import annotations

import dataclasses
import math
import numbers
import threading
from dataclasses import dataclass
from itertools import combinations, islice
from typing import Any, Callable, Hashable, Mapping, Sequence

import numpy as np

from app.geometry.camera import MIN_DEPTH_M, Camera, as_points
from app.geometry.pair_error import _rule, pair_error

#: Reasons a pair is dropped, in the order they are tested (a pair reports the first that applies).
DROP_REASONS = ("degenerate", "point_at_infinity", "behind_camera", "baseline_below_min", "parallax_below_min",
                "error_above_tau", "outside_play_volume", "weak_calibrations", "outweighed",
                "players_disagree", "beyond_joint_sigma", "sigma_above_bound", "lone_pair_at_tau_edge",
                "outside_consensus")


#: Least sum of the two views' calibration weights (``triangulate_ball`` ``view_weights``) of a pair that makes a
#: ball: a full vote and at least a half one (the doubt judge's rule for a consensus that accuses a view).
MIN_PAIR_WEIGHT = 1.5


#: Result statuses of :func:`triangulate_ball`.
STATUS_TRIANGULATED = "triangulated"


STATUS_INSUFFICIENT_VIEWS = "insufficient_views"


STATUS_NO_PAIR_KEPT = "no_pair_kept"


# Relative singular-value level below which the DLT system is rank deficient (identical rays).
_RANK_EPS = 1e-10


# |w| / ||X|| below which the homogeneous DLT solution is a point at infinity (parallel rays).
_INFINITY_EPS = 1e-12


@dataclass(frozen=True)
class BallObservation:
    """One view's ball label for triangulation.

    Attributes:
        view_id: any hashable identifier of the view (frame id, image name); kept as given.
        camera: the view's calibrated camera (its own resolution and principal point).
        point_px: (2,) ball centre in pixels of this image (distorted, as annotated).
        image_width: width of this image in pixels (for the scaled error rules).
    """

    view_id: Hashable
    camera: Camera
    point_px: np.ndarray
    image_width: float

    def __post_init__(self) -> None:
        p = np.array(self.point_px, dtype=float).reshape(-1)
        # both coordinates checked as Python floats: a recomputation makes a few dozen observations
        if p.shape != (2,) or not (math.isfinite(p[0]) and math.isfinite(p[1])):
            raise ValueError(f"BallObservation.point_px must be 2 finite numbers, got {self.point_px!r}")
        if not isinstance(self.camera, Camera):
            raise ValueError(f"BallObservation.camera must be a Camera, got {type(self.camera).__name__}")
        w = self.image_width
        if isinstance(w, bool) or not isinstance(w, numbers.Real) or not (math.isfinite(w) and w > 0):
            raise ValueError(f"BallObservation.image_width must be positive, got {self.image_width!r}")
        p.setflags(write=False)
        object.__setattr__(self, "point_px", p)
        object.__setattr__(self, "image_width", float(self.image_width))


@dataclass(frozen=True)
class PairResult:
    """Triangulation of one pair of views.

    Attributes:
        view_a, view_b: the two view ids (in input order).
        point: (3,) ``p_ij`` in world metres, or ``None`` when undefined (``degenerate``,
            ``point_at_infinity``).
        errors_px: reprojection errors of ``p_ij`` in view a and view b, each in its own pixels,
            or ``None`` when the point is undefined or behind a camera.
        error: ``e_ij`` by the chosen rule (px, see :data:`PAIR_ERROR_RULES`), or ``None``.
        parallax_deg: angle between the two viewing rays, degrees in [0, 180].
        baseline_m: distance between the two camera centres, metres.
        kept: whether ``p_ij`` enters the fused ball.
        reason: ``None`` when kept, else one of :data:`DROP_REASONS`.
    """

    view_a: Hashable
    view_b: Hashable
    point: np.ndarray | None
    errors_px: tuple[float, float] | None
    error: float | None
    parallax_deg: float
    baseline_m: float
    kept: bool
    reason: str | None

    def as_dict(self) -> dict:
        """JSON-ready form with the keys of the system view contract (docs/api.md)."""
        return {"view_a": self.view_a, "view_b": self.view_b,
                "point": None if self.point is None else [float(v) for v in self.point],
                "error_px": self.error, "parallax_deg": self.parallax_deg, "baseline_m": self.baseline_m,
                "kept": self.kept, "reason": self.reason}


@dataclass(frozen=True)
class TriangulationResult:
    """The fused 3D ball of a multi-view system.

    Attributes:
        status: :data:`STATUS_TRIANGULATED`, :data:`STATUS_INSUFFICIENT_VIEWS` (fewer than two
            labelled views) or :data:`STATUS_NO_PAIR_KEPT` (every pair dropped; see ``pairs``).
        point: (3,) fused ball centre, world metres (z down), or ``None`` unless triangulated.
        pairs: one :class:`PairResult` per pair of observations, in input order.
        view_errors_px: view id -> reprojection error (px, the view's own pixels) of the fused ball,
            ``None`` when it lies behind that camera; empty unless triangulated.
        tau_px, rule, min_baseline_m: the parameters used.
    """

    status: str
    point: np.ndarray | None
    pairs: tuple[PairResult, ...]
    view_errors_px: dict[Hashable, float | None]
    tau_px: float
    rule: str
    min_baseline_m: float

    @property
    def kept_pairs(self) -> tuple[PairResult, ...]:
        """The pairs whose points were averaged."""
        return tuple(p for p in self.pairs if p.kept)

    @property
    def contributing_views(self) -> frozenset[Hashable]:
        """Ids of the views that belong to at least one kept pair."""
        return frozenset(v for p in self.kept_pairs for v in (p.view_a, p.view_b))


def triangulate_dlt(projections: np.ndarray, points_px: np.ndarray) -> np.ndarray:
    """Linear homogeneous triangulation of one point seen in V views (Hartley and Zisserman 12.2).

    Each view contributes the rows ``x P3 - P1`` and ``y P3 - P2``; the point is the right singular
    vector of the smallest singular value. Rows are not reweighted, so with V = 2 the result equals
    ``cv2.triangulatePoints``. Pixels must be undistorted (see :func:`undistort_pixels`).

    Args:
        projections: (V, 3, 4) projection matrices ``P = K R [I | -C]``, V >= 2.
        points_px: (V, 2) undistorted pixel coordinates.

    Returns:
        (4,) homogeneous world point with unit norm (last coordinate may be ~0 for parallel rays).

    Raises:
        ValueError: bad shapes or fewer than two views.

    >>> from app.geometry.camera import Camera
    >>> a = Camera.from_parameters(focal_px=1000.0, principal_point=(960.0, 540.0), pan_deg=0.0,
    ...                            tilt_deg=90.0, roll_deg=0.0, position_m=[0.0, 50.0, -10.0])
    >>> b = Camera.from_parameters(focal_px=1000.0, principal_point=(960.0, 540.0), pan_deg=90.0,
    ...                            tilt_deg=90.0, roll_deg=0.0, position_m=[-50.0, 0.0, -10.0])
    >>> X = np.array([[1.0, 2.0, -3.0]])
    >>> uv = np.vstack([a.project(X)[0], b.project(X)[0]])
    >>> h = triangulate_dlt(np.stack([a.projection_matrix, b.projection_matrix]), uv)
    >>> np.round(h[:3] / h[3], 9).tolist()
    [1.0, 2.0, -3.0]
    """
    P = np.asarray(projections, dtype=float)
    x = np.asarray(points_px, dtype=float)
    if P.ndim != 3 or P.shape[1:] != (3, 4):
        raise ValueError(f"projections must have shape (V, 3, 4), got {P.shape}")
    if x.shape != (P.shape[0], 2):
        raise ValueError(f"points_px must have shape ({P.shape[0]}, 2), got {x.shape}")
    if P.shape[0] < 2:
        raise ValueError(f"triangulation needs at least two views, got {P.shape[0]}")
    if not (np.all(np.isfinite(P)) and np.all(np.isfinite(x))):
        raise ValueError("projections and points_px must be finite")
    return _dlt(P, x)[0]


def _dlt(P: np.ndarray, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(V, 3, 4), (V, 2) -> (unit homogeneous point (4,), singular values (4,)) of the DLT system."""
    A = np.concatenate([x[:, :1] * P[:, 2] - P[:, 0], x[:, 1:] * P[:, 2] - P[:, 1]], axis=0)
    _, s, vt = np.linalg.svd(A)
    return vt[-1], s


def undistort_pixels(camera: Camera, points_px: np.ndarray) -> np.ndarray:
    """Distorted pixels (N, 2) -> undistorted pixels (N, 2) of the same camera.

    The undistorted pixel is ``K [x_u, y_u, 1]`` with ``(x_u, y_u)`` the undistorted normalised
    coordinates (:meth:`Camera.normalise_pixels`); identity for a camera without distortion.

    Args:
        camera: the camera whose distortion is removed.
        points_px: (2,) or (N, 2) distorted pixels of that camera's image.

    Returns:
        (N, 2) undistorted pixels (N = 1 for a single point).

    Raises:
        ValueError: not (2,) or (N, 2).
    """
    pts = as_points(points_px, 2, "points_px")
    if not camera.has_distortion:
        return pts.copy()
    xy = camera.normalise_pixels(pts, undistort=True)
    return xy @ camera.K[:2, :2].T + camera.K[:2, 2]


def parallax_angle_deg(camera_a: Camera, point_a_px: np.ndarray, camera_b: Camera,
                       point_b_px: np.ndarray) -> float:
    """Angle (degrees, [0, 180]) between the viewing rays of two pixels in two cameras.

    Small angles mean large depth uncertainty even when the reprojection error is small (paper,
    section 3D ball localisation). Rays are undistorted, in the world frame.

    Args:
        camera_a, camera_b: the two cameras.
        point_a_px, point_b_px: (2,) pixel of each view, in its own image (distorted, as annotated).

    Returns:
        The angle between the two rays, degrees.
    """
    return angle_between_deg(view_ray(camera_a, point_a_px).ray, view_ray(camera_b, point_b_px).ray)


@dataclass(frozen=True)
class ViewRay:
    """One view's ball pixel made ready for triangulation (:func:`view_ray`).

    Attributes:
        ray: (3,) unit viewing ray in the world frame (SoccerNet, z down), from the camera centre.
        pixel: (2,) the pixel undistorted, in the same camera's pixels (the distorted pixel itself for a camera
            without distortion).
    """

    ray: np.ndarray
    pixel: np.ndarray


def view_ray(camera: Camera, point_px: np.ndarray) -> ViewRay:
    """The undistorted ray and pixel of one distorted pixel ``point_px`` ((2,), this camera's image): what
    :func:`parallax_angle_deg` (the ray, as :meth:`Camera.rays`) and the DLT (the pixel, as
    :func:`undistort_pixels`) take, from one undistortion."""
    p = np.asarray(point_px, dtype=float).reshape(1, 2)
    xy = camera.normalise_pixels(p, undistort=True)
    pixel = xy @ camera.K[:2, :2].T + camera.K[:2, 2] if camera.has_distortion else p
    d = np.array([xy[0, 0], xy[0, 1], 1.0]) @ camera.R  # R^T d_cam
    return ViewRay(d / math.sqrt(float(d @ d)), pixel[0])


def angle_between_deg(ra: np.ndarray, rb: np.ndarray) -> float:
    """Angle (degrees, [0, 180]) between two 3-vectors ``ra`` and ``rb`` (any length, e.g. unit rays or the
    directions from two camera centres to a point): atan2 of |cross| and dot, accurate at small angles where
    arccos(dot) is not; three-element arithmetic without numpy's array machinery."""
    ax, ay, az = float(ra[0]), float(ra[1]), float(ra[2])
    bx, by, bz = float(rb[0]), float(rb[1]), float(rb[2])
    cx, cy, cz = ay * bz - az * by, az * bx - ax * bz, ax * by - ay * bx
    return math.degrees(math.atan2(math.sqrt(cx * cx + cy * cy + cz * cz), ax * bx + ay * by + az * bz))


def reprojection_error_px(camera: Camera, point_world: np.ndarray, point_px: np.ndarray) -> float | None:
    """Distance (px) between a world point's projection (with distortion) and a pixel.

    Args:
        camera: the view's camera.
        point_world: (3,) world point, metres.
        point_px: (2,) observed pixel.

    Returns:
        The error in this image's pixels, or ``None`` when the point is behind the camera (camera
        depth below :data:`app.geometry.camera.MIN_DEPTH_M`).
    """
    # Camera.project for one point, without its array handling (a few per pair, many pairs per edit)
    Xc = camera.R @ (np.asarray(point_world, float).reshape(3) - camera.C)
    z = float(Xc[2])
    if not z > MIN_DEPTH_M:
        return None
    xy = Xc[:2] / z
    if camera.has_distortion:
        xy = camera.distort(xy.reshape(1, 2))[0]
    K = camera.K
    u = K[0, 0] * xy[0] + K[0, 1] * xy[1] + K[0, 2]
    v = K[1, 0] * xy[0] + K[1, 1] * xy[1] + K[1, 2]
    p = np.asarray(point_px, float).reshape(2)
    return math.hypot(float(u - p[0]), float(v - p[1]))


@dataclass(frozen=True)
class PairGeometry:
    """The raw geometry of two views' ball rays, before any rule (tau, pair-error rule, baseline, parallax) is
    applied: what the triangulation, the mirror evidence and the doubts' consensus each judge by their own rules.

    Attributes:
        baseline_m: distance between the two camera centres, metres.
        parallax_deg: angle between the two viewing rays, degrees in [0, 180].
        h: (4,) unit homogeneous DLT solution of the two undistorted pixels (:func:`triangulate_dlt`).
        full_rank: False when the DLT system's null space is two-dimensional (the rays coincide).
        at_infinity: ``h``'s last coordinate is ~0 (parallel rays).
        point: (3,) ``p_ij`` in world metres, None when not full rank or at infinity.
        errors_px: reprojection errors of ``point`` in view a and view b (own pixels), None without a point or
            when it lies behind either camera.
    """

    baseline_m: float
    parallax_deg: float
    h: np.ndarray
    full_rank: bool
    at_infinity: bool
    point: np.ndarray | None
    errors_px: tuple[float, float] | None


def pair_geometry(a: BallObservation, b: BallObservation) -> PairGeometry:
    """:class:`PairGeometry` of observations ``a`` and ``b`` (their cameras and distorted pixels): baseline,
    parallax (:func:`parallax_angle_deg`), the DLT of the undistorted pixels (Hartley and Zisserman 12.2) and,
    when its point is finite, its reprojection error in each view (:func:`reprojection_error_px`; None behind a
    camera). World frame: SoccerNet (metres, z down)."""
    return pair_geometry_of_rays(a, b, view_ray(a.camera, a.point_px), view_ray(b.camera, b.point_px))


def pair_geometry_of_rays(a: BallObservation, b: BallObservation, ray_a: ViewRay, ray_b: ViewRay) -> PairGeometry:
    """:func:`pair_geometry` from the two views' rays already computed (:func:`view_ray` of each observation's
    camera and pixel; :class:`PairGeometryMemo` computes each view's once for all its pairs)."""
    d = a.camera.C - b.camera.C
    baseline = math.sqrt(float(d @ d))
    beta = angle_between_deg(ray_a.ray, ray_b.ray)
    P = np.stack([a.camera.projection_matrix, b.camera.projection_matrix])
    uv = np.stack([ray_a.pixel, ray_b.pixel])
    h, s = _dlt(P, uv)
    h.setflags(write=False)
    full_rank = bool(s[2] > _RANK_EPS * s[0])
    at_infinity = bool(abs(h[3]) <= _INFINITY_EPS * np.linalg.norm(h[:3]))
    point, errors = None, None
    if full_rank and not at_infinity:
        point = h[:3] / h[3]
        point.setflags(write=False)
        e_a = reprojection_error_px(a.camera, point, a.point_px)
        e_b = reprojection_error_px(b.camera, point, b.point_px)
        errors = None if e_a is None or e_b is None else (e_a, e_b)
    return PairGeometry(baseline, beta, h, full_rank, at_infinity, point, errors)


class PairGeometryMemo:
    """:func:`pair_geometry` computed once per pair of rays: the triangulation, the mirror evidence
    and the doubts' consensus of one recomputation ask the same pairs of the same cameras and labels, and each
    applies its own rules to the one answer; one memo kept across recomputations (``max_entries``) also answers the
    pairs an edit did not touch (the views whose camera and label it left as they were). Keyed by the identity of
    both cameras and the bytes of both pixels (and the order of the two); the memo holds the cameras, so an id is
    never reused while it lives, and a camera object is never changed in place (its arrays are read-only).

    Args:
        max_entries: pairs (and, apart, rays) kept at most; beyond it the older half is dropped. None: unbounded
            (a memo for one recomputation).

    Safe to share between threads: a race computes a pair twice, never answers a wrong one.
    """

    def __init__(self, max_entries: int | None = None) -> None:
        if max_entries is not None and max_entries < 2:
            raise ValueError(f"PairGeometryMemo: max_entries must be at least 2, got {max_entries}")
        self.max_entries = max_entries
        self._pairs: dict[tuple, tuple[Camera, Camera, PairGeometry]] = {}
        self._rays: dict[tuple, tuple[Camera, ViewRay]] = {}
        self._lock = threading.Lock()
        self.asked = 0
        self.computed = 0

    def __call__(self, a: BallObservation, b: BallObservation) -> PairGeometry:
        """The geometry of ``a`` and ``b``, computed on the first ask of this pair."""
        pa, pb = np.asarray(a.point_px, float), np.asarray(b.point_px, float)
        key = (id(a.camera), pa.tobytes(), id(b.camera), pb.tobytes())
        self.asked += 1
        hit = self._pairs.get(key)
        if hit is not None and hit[0] is a.camera and hit[1] is b.camera:
            return hit[2]
        self.computed += 1
        g = pair_geometry_of_rays(a, b, self._ray(a.camera, pa, key[1]), self._ray(b.camera, pb, key[3]))
        self._keep(self._pairs, key, (a.camera, b.camera, g))
        return g

    def _ray(self, camera: Camera, pixel: np.ndarray, pixel_key: bytes) -> ViewRay:
        """:func:`view_ray` of ``camera`` and ``pixel``, computed once per camera and pixel (a view is in every
        pair of its system, and in the mirror evidence's pairs of its camera again)."""
        key = (id(camera), pixel_key)
        hit = self._rays.get(key)
        if hit is not None and hit[0] is camera:
            return hit[1]
        ray = view_ray(camera, pixel)
        self._keep(self._rays, key, (camera, ray))
        return ray

    def _keep(self, table: dict, key: tuple, value: tuple) -> None:
        """Store ``value``; past :attr:`max_entries`, drop the older half of ``table`` first (insertion order)."""
        with self._lock:
            if self.max_entries is not None and len(table) >= self.max_entries:
                for old in list(islice(table, len(table) // 2)):
                    del table[old]
            table[key] = value


def triangulate_pair(a: BallObservation, b: BallObservation, *, tau_px: float, rule: str,
                     min_baseline_m: float, min_parallax_deg: float,
                     geometry: Callable[[BallObservation, BallObservation], PairGeometry] = pair_geometry
                     ) -> PairResult:
    """Triangulate one pair of views and decide whether it is kept (see the module docstring).

    Args:
        a, b: the two observations.
        tau_px: keep when ``e_ij < tau_px`` (px, in the rule's units).
        rule: a key of :data:`PAIR_ERROR_RULES`.
        min_baseline_m: keep only when ``|C_a - C_b| >= min_baseline_m`` (metres).
        min_parallax_deg: keep only when the angle between the two rays is at least this (degrees;
            0 reproduces the paper).
        geometry: where the pair's raw geometry comes from (:func:`pair_geometry`, or a
            :class:`PairGeometryMemo` shared by one recomputation's judges).

    Raises:
        ValueError: unknown rule.
    """
    _rule(rule)
    g = geometry(a, b)
    beta, baseline = g.parallax_deg, g.baseline_m

    def dropped(reason: str, point=None, errors=None, error=None) -> PairResult:
        return PairResult(a.view_id, b.view_id, point, errors, error, beta, baseline, False, reason)

    if not g.full_rank:
        return dropped("degenerate")  # two-dimensional null space: the rays coincide
    if g.at_infinity:
        return dropped("point_at_infinity")
    point = g.point
    if g.errors_px is None:
        return dropped("behind_camera", point)
    e_a, e_b = g.errors_px
    e = pair_error((e_a, e_b), (a.image_width, b.image_width), rule)
    if baseline < min_baseline_m:
        return dropped("baseline_below_min", point, (e_a, e_b), e)
    if beta < min_parallax_deg:
        return dropped("parallax_below_min", point, (e_a, e_b), e)
    if not e < tau_px:
        return dropped("error_above_tau", point, (e_a, e_b), e)
    return PairResult(a.view_id, b.view_id, point, (e_a, e_b), e, beta, baseline, True, None)


def _weigh_pairs(pairs: Sequence[PairResult], weights: Mapping[Hashable, float]) -> list[PairResult]:
    """The pairs with ``weak_calibrations`` and ``outweighed`` drops applied (:func:`triangulate_ball`
    ``view_weights``)."""
    def total(p: PairResult) -> float:
        return float(weights.get(p.view_a, 1.0)) + float(weights.get(p.view_b, 1.0))

    out = [dataclasses.replace(p, kept=False, reason="weak_calibrations")
           if p.kept and total(p) < MIN_PAIR_WEIGHT else p for p in pairs]
    best = max((total(p) for p in out if p.kept), default=None)
    if best is None:  # no pair kept: none to outweigh
        return out
    return [dataclasses.replace(p, kept=False, reason="outweighed") if p.kept and total(p) < best else p
            for p in out]


#: Standard deviation (m) added to every pair's camera-position variance when weighting by uncertainty:
#: a floor, so that two views with tiny standard deviations do not take all the weight.
POSITION_STD_FLOOR_M = 0.1


def _pair_weights(kept: Sequence[PairResult], std_m: Mapping[Hashable, float] | None) -> np.ndarray:
    """Weights of the kept pairs' points: all 1 without ``std_m``, else ``1 / (s0^2 + s_a^2 + s_b^2)``;
    all 1 again when every weight is 0 (every pair has an undetermined camera)."""
    if std_m is None:
        return np.ones(len(kept))

    def var(view: Hashable) -> float:
        s = std_m.get(view)
        return 0.0 if s is None else float(s) ** 2

    w = np.array([1.0 / (POSITION_STD_FLOOR_M**2 + var(p.view_a) + var(p.view_b)) for p in kept])
    w = np.where(np.isfinite(w), w, 0.0)
    return w if w.sum() > 0 else np.ones(len(kept))


def triangulate_ball(observations: Sequence[BallObservation], *, tau_px: float, rule: str,
                     min_baseline_m: float, min_parallax_deg: float,
                     view_position_std_m: Mapping[Hashable, float] | None = None,
                     play_volume: Callable[[np.ndarray], bool] | None = None,
                     view_weights: Mapping[Any, float] | None = None,  # view id -> weight (Any: keys are invariant)
                     geometry: Callable[[BallObservation, BallObservation], PairGeometry] = pair_geometry
                     ) -> TriangulationResult:
    """The 3D ball of a multi-view system (paper Eq. triangulation, method.md section 5).

    Every pair of observations is triangulated (:func:`triangulate_pair`); the ball is the mean of
    the kept ``p_ij``; each view gets the reprojection error of the fused ball.

    Args:
        observations: the labelled, calibrated views (order is kept in ``pairs``); view ids must be unique.
        tau_px: pair error threshold ``tau`` in pixels (units of ``rule``); positive.
        rule: a key of :data:`PAIR_ERROR_RULES`.
        min_baseline_m: minimum camera-centre distance of a kept pair, metres (paper: 1 m).
        min_parallax_deg: minimum angle between the rays of a kept pair, degrees (0: the paper's rule).
        view_position_std_m: optional view id -> standard deviation of its camera position, metres
            (``app.geometry.calibration.CalibrationUncertainty.position_std_m``; ``inf`` for an undetermined one).
            Given, the kept ``p_ij`` are averaged with weights ``1 / (s0^2 + s_i^2 + s_j^2)`` (inverse-variance,
            :data:`POSITION_STD_FLOOR_M` = ``s0``; a view without a value counts as ``s0``) instead of the paper's
            plain mean, so that weakly calibrated views count less. ``None`` (default): the paper's mean.
        play_volume: optional test of a ball position (world metres -> bool, e.g.
            ``app.geometry.pitch.within_play_volume``): a pair kept by the paper's rules whose ``p_ij`` fails it
            (two rays that meet metres under the grass, or far outside the stadium, agree by coincidence) is
            dropped with reason ``outside_play_volume``. ``None`` (default): the paper's rules only.
        view_weights: optional view id -> what its calibration is worth as evidence (1 a full vote, 0.5 half,
            0 none; ``app.geometry.weighting.calibration_weight``, a view without a value counts 1). Given, a weak
            calibration neither makes nor moves a ball on its own: a pair kept by the rules above whose two
            weights sum below :data:`MIN_PAIR_WEIGHT` (two half votes, or a full vote and none) is dropped with
            reason ``weak_calibrations``, and of the pairs left only those of the highest weight sum are
            averaged, the others dropped with reason ``outweighed`` (two sure views fix the ball; a
            third view whose few lines may turn its ray by degrees would pull it metres off). ``None``
            (default): every view counts alike.
        geometry: where each pair's raw geometry comes from (:func:`pair_geometry`, or a
            :class:`PairGeometryMemo` the recomputation shares with the mirror evidence and the doubts).

    Returns:
        A :class:`TriangulationResult`. Fewer than two observations give status ``insufficient_views`` (no
        exception); all pairs dropped give ``no_pair_kept``.

    Raises:
        ValueError: unknown rule, non-positive ``tau_px``, negative ``min_baseline_m``,
            ``min_parallax_deg`` outside [0, 90) or duplicate view ids.
    """
    _rule(rule)
    if not tau_px > 0:
        raise ValueError(f"tau_px must be positive, got {tau_px!r}")
    if not min_baseline_m >= 0:
        raise ValueError(f"min_baseline_m must be >= 0, got {min_baseline_m!r}")
    if not 0 <= min_parallax_deg < 90:
        raise ValueError(f"min_parallax_deg must be in [0, 90), got {min_parallax_deg!r}")
    obs = list(observations)
    ids = [o.view_id for o in obs]
    if len(set(ids)) != len(ids):
        raise ValueError(f"observations: view ids must be unique, got {ids!r}")

    def result(status: str, point=None, pairs=(), errors=None) -> TriangulationResult:
        return TriangulationResult(status, point, tuple(pairs), errors or {}, float(tau_px), rule,
                                   float(min_baseline_m))

    if len(obs) < 2:
        return result(STATUS_INSUFFICIENT_VIEWS)
    pairs = [triangulate_pair(a, b, tau_px=tau_px, rule=rule, min_baseline_m=min_baseline_m,
                              min_parallax_deg=min_parallax_deg, geometry=geometry)
             for a, b in combinations(obs, 2)]
    if play_volume is not None:
        pairs = [dataclasses.replace(p, kept=False, reason="outside_play_volume")
                 if p.kept and p.point is not None and not play_volume(p.point) else p for p in pairs]
    if view_weights is not None:
        pairs = _weigh_pairs(pairs, view_weights)
    kept = [p.point for p in pairs if p.kept and p.point is not None]
    if not kept:
        return result(STATUS_NO_PAIR_KEPT, pairs=pairs)
    ball: np.ndarray = np.average(kept, axis=0, weights=_pair_weights([p for p in pairs if p.kept],
                                                                        view_position_std_m))
    ball.setflags(write=False)
    errors = {o.view_id: reprojection_error_px(o.camera, ball, o.point_px) for o in obs}
    return result(STATUS_TRIANGULATED, ball, pairs, errors)
