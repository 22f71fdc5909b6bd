"""Monocular 3D ball from a box, the optimised box, and the exact image of a sphere.

Paper references (SoccerNet-v3D, after Van Zandycke and De Vleeschouwer 2022):

* Eq. fromdiameter: ``p_c = K^-1 [px, py, 1]^T`` and ``p_c± = K^-1 [px, py ± d/2, 1]^T``;
* Eq. ball3Destimation: ``p = R^T (phi p_c / ||p_c+ - p_c-||) + C``. The paper writes ``+ t``, but
  with ``x_cam = R (X - C)`` the term is the camera centre ``C`` (method.md section 6);
* Eq. min_diametre: ``d_opt = argmin_d || p - R^T phi p_c / ||p_c+(d) - p_c-(d)|| - C ||``.

Because ``p_c`` has a camera z of 1, Eq. ball3Destimation puts the ball at camera **depth**
``z = phi / ||p_c+ - p_c-||`` on the ray through the box centre; without distortion and skew
``||p_c+ - p_c-|| = d / fy``, so ``z = phi fy / d``. Eq. min_diametre is then a one-dimensional
least-squares problem along that ray, solved here in closed form (:func:`optimise_box`).

The formula is a small-angle approximation (method.md section 7): the sphere subtends the angle
``2 asin(r / D)`` (``D`` the camera-to-centre distance), which images as ``2 fy tan(asin(r / D))``
on the optical axis only; off the axis the image is an ellipse stretched away from the principal
point, whose centre is not the projection of the ball's centre. The paper's model uses
``phi fy / z`` instead; on exact boxes it errs by 0.24 m median and up to 3.3 m on the dev set.
:func:`sphere_image_box` gives the exact axis-aligned box of the sphere's silhouette,
:func:`ball_from_box_exact` is its inverse (the exact monocular ball), and :func:`optimise_box`
offers exact variants built on it (:data:`OPTIMISED_BOX_METHODS`).

Which optimised box to use (synthetic dev set, ``benchmarks/synthetic_ball.py``, 79 views, IoU /
size error against the exact boxes): annotated 0.566 / 19.0 %, ``paper`` 0.618 / 1.4 %,
``exact_ray`` 0.623 / 0.08 % (0.623 / 0.32 % with a 0.1-degree calibration error), ``exact_fused``
0.694 / 0.08 % with true cameras but 0.518 with that calibration error. ``exact_ray`` is the
recommended exact variant: it keeps the annotated direction, so calibration errors do not move the
box, and it is consistent with :func:`ball_from_box_exact` as ``paper`` is with :func:`ball_from_box`.

Distortion: centres and box edges are undistorted before use (``p_c``, ``p_c±`` are undistorted
normalised coordinates); without distortion this is exactly the paper's ``K^-1``.

Frames: world = SoccerNet (metres, centre spot origin, z down); image = continuous pixels, origin
at the top-left corner; boxes are ``[x1, y1, x2, y2]`` in pixels.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import brentq, least_squares

from app.geometry.camera import MIN_DEPTH_M, Camera, as_points

#: Optimised-box variants (see :func:`optimise_box`).
OPTIMISED_BOX_METHODS = ("paper", "exact_ray", "exact_fused")

#: Points sampled on the silhouette circle when distortion forbids the closed form.
_SILHOUETTE_SAMPLES = 720


def box_centre_and_diameter(boxes: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Centre (px) and diameter (px) of ball boxes.

    The diameter is the **mean of width and height** (method.md section 6: boxes are rarely square).

    Args:
        boxes: (4,) or (N, 4) ``[x1, y1, x2, y2]`` pixels, with ``x2 > x1`` and ``y2 > y1``.

    Returns:
        ``(centres, diameters)``: (N, 2) pixels and (N,) pixels (N = 1 for a single box).

    Raises:
        ValueError: wrong shape, non-finite values, or a box with non-positive width or height.

    >>> c, d = box_centre_and_diameter([10.0, 20.0, 30.0, 44.0])
    >>> c.tolist(), d.tolist()
    ([[20.0, 32.0]], [22.0])
    """
    b = _as_boxes(boxes, "boxes")
    w, h = b[:, 2] - b[:, 0], b[:, 3] - b[:, 1]
    if np.any(w <= 0) or np.any(h <= 0):
        raise ValueError("boxes must have x2 > x1 and y2 > y1")
    return np.stack([(b[:, 0] + b[:, 2]) / 2, (b[:, 1] + b[:, 3]) / 2], axis=1), (w + h) / 2


def _centre_ray_camera(camera: Camera, centres_px: np.ndarray) -> np.ndarray:
    """(N, 2) pixels -> (N, 3) ``p_c``: undistorted normalised rays ``[x, y, 1]`` in the camera frame."""
    xy = camera.normalise_pixels(centres_px, undistort=True)
    return np.hstack([xy, np.ones((len(xy), 1))])


def _edge_span(camera: Camera, centres_px: np.ndarray, diameters_px: np.ndarray) -> np.ndarray:
    """``||p_c+ - p_c-||`` of Eq. fromdiameter for (N, 2) centres and (N,) diameters (px)."""
    off = np.stack([np.zeros_like(diameters_px), diameters_px / 2], axis=1)
    plus = camera.normalise_pixels(centres_px + off, undistort=True)
    minus = camera.normalise_pixels(centres_px - off, undistort=True)
    return np.linalg.norm(plus - minus, axis=1)


def ball_from_centre_diameter(camera: Camera, centres_px: np.ndarray, diameters_px: np.ndarray,
                              ball_diameter_m: float) -> np.ndarray:
    """Monocular 3D ball centre (paper Eq. fromdiameter and ball3Destimation).

    ``p = R^T (phi p_c / ||p_c+ - p_c-||) + C``; the point lies on the ray through the centre, at
    camera depth ``phi / ||p_c+ - p_c-||`` (``= phi fy / d`` without distortion).

    Args:
        camera: the view's camera.
        centres_px: (2,) or (N, 2) ball centres, pixels.
        diameters_px: scalar or (N,) apparent diameters, pixels, positive.
        ball_diameter_m: phi, metres (0.22 for a size-5 ball).

    Returns:
        (N, 3) world points, metres (SoccerNet frame, z down).

    Raises:
        ValueError: centres not (2,) or (N, 2), diameters neither a scalar nor (N,), non-finite
            centres, non-positive diameters or ball_diameter_m.

    >>> cam = Camera.from_parameters(focal_px=1000.0, principal_point=(960.0, 540.0), pan_deg=0.0,
    ...                              tilt_deg=90.0, roll_deg=0.0, position_m=[0.0, 50.0, -10.0])
    >>> np.round(ball_from_centre_diameter(cam, [960.0, 540.0], 4.4, 0.22), 9).tolist()
    [[0.0, 0.0, -10.0]]
    """
    c = as_points(centres_px, 2, "centres_px")
    d = np.asarray(diameters_px, dtype=float)
    if d.ndim > 1 or d.ndim == 1 and d.shape != (len(c),):
        raise ValueError(f"diameters_px must be a scalar or ({len(c)},), got {d.shape}")
    d = np.broadcast_to(d, (len(c),)).astype(float)
    if not np.all(np.isfinite(c)):
        raise ValueError("centres_px must be finite")
    if not (np.all(np.isfinite(d)) and np.all(d > 0)):
        raise ValueError("diameters_px must be positive")
    if not ball_diameter_m > 0:
        raise ValueError(f"ball_diameter_m must be positive, got {ball_diameter_m!r}")
    depth = ball_diameter_m / _edge_span(camera, c, d)
    return (_centre_ray_camera(camera, c) * depth[:, None]) @ camera.R + camera.C


def ball_from_box(camera: Camera, boxes: np.ndarray, ball_diameter_m: float) -> np.ndarray:
    """Monocular 3D ball from box(es): centre of the box and d = mean of width and height.

    Args:
        camera: the view's camera.
        boxes: (4,) or (N, 4) ``[x1, y1, x2, y2]`` pixels.
        ball_diameter_m: phi, metres.

    Returns:
        (N, 3) world points, metres (see :func:`ball_from_centre_diameter`).
    """
    centres, diameters = box_centre_and_diameter(boxes)
    return ball_from_centre_diameter(camera, centres, diameters, ball_diameter_m)


def ball_from_box_exact(camera: Camera, boxes: np.ndarray, ball_diameter_m: float) -> np.ndarray:
    """Monocular 3D ball from box(es) with the exact sphere silhouette (the inverse of :func:`sphere_image_box`).

    Each box edge back-projects to a plane through the camera centre that the ball touches: with
    ``l = (1, 0, -x1), (-1, 0, x2), (0, 1, -y1), (0, -1, y2)`` the plane ``pi = P^T l`` has the ball
    centre on its inner side at distance ``r = phi / 2``. The four conditions
    ``(n_k . X + pi_k[3]) / ||n_k|| = r`` are linear in X and solved by least squares (exact for a
    box that is the image of a sphere; for a loose box, the centre whose distances to the four
    tangent planes are closest to r). With distortion the edges are not images of planes: the
    solution is refined by least squares on :func:`sphere_image_box`, starting from the paper estimate.

    Unlike Eq. ball3Destimation this has no off-axis bias (on the synthetic dev set's precise boxes
    the paper formula errs by 0.24 m median and up to 3.3 m, 15 % of the distance).

    Args:
        camera: the view's camera.
        boxes: (4,) or (N, 4) ``[x1, y1, x2, y2]`` pixels.
        ball_diameter_m: phi, metres.

    Returns:
        (N, 3) world points, metres.

    Raises:
        ValueError: bad boxes or non-positive ball_diameter_m.

    >>> cam = Camera.from_parameters(focal_px=1000.0, principal_point=(960.0, 540.0), pan_deg=0.0,
    ...                              tilt_deg=90.0, roll_deg=0.0, position_m=[0.0, 50.0, -10.0])
    >>> box = sphere_image_box(cam, [12.0, 3.0, -1.0], 0.11)
    >>> np.round(ball_from_box_exact(cam, box, 0.22), 9).tolist()
    [[12.0, 3.0, -1.0]]
    """
    b = _as_boxes(boxes, "boxes")
    box_centre_and_diameter(b)  # validates the boxes
    if not ball_diameter_m > 0:
        raise ValueError(f"ball_diameter_m must be positive, got {ball_diameter_m!r}")
    r = ball_diameter_m / 2
    if camera.has_distortion:
        start = ball_from_box(camera, b, ball_diameter_m)
        return np.array([_refine_on_silhouette(camera, box, x0, r) for box, x0 in zip(b, start, strict=True)])
    P = camera.projection_matrix
    lines = np.zeros((len(b), 4, 3))
    lines[:, 0] = np.stack([np.ones(len(b)), np.zeros(len(b)), -b[:, 0]], axis=1)
    lines[:, 1] = np.stack([-np.ones(len(b)), np.zeros(len(b)), b[:, 2]], axis=1)
    lines[:, 2] = np.stack([np.zeros(len(b)), np.ones(len(b)), -b[:, 1]], axis=1)
    lines[:, 3] = np.stack([np.zeros(len(b)), -np.ones(len(b)), b[:, 3]], axis=1)
    planes = lines @ P  # (N, 4, 4): pi_k = P^T l_k, as rows
    norms = np.linalg.norm(planes[..., :3], axis=2, keepdims=True)
    A = planes[..., :3] / norms
    rhs = r - planes[..., 3] / norms[..., 0]
    return np.stack([np.linalg.lstsq(a, y, rcond=None)[0] for a, y in zip(A, rhs, strict=True)])


def _refine_on_silhouette(camera: Camera, box: np.ndarray, start: np.ndarray, r: float) -> np.ndarray:
    """Ball centre whose (distorted) silhouette box best matches ``box`` (least squares, px)."""
    scale = max(float(box[2] - box[0] + box[3] - box[1]), 1.0)

    def residual(x: np.ndarray) -> np.ndarray:
        pred = sphere_image_box(camera, x, r)
        return np.full(4, 1e3 * scale) if pred is None else pred - box

    return least_squares(residual, start, x_scale=np.full(3, 0.1), method="lm").x


def sphere_image_box(camera: Camera, centre_world: np.ndarray, radius_m: float) -> np.ndarray | None:
    """Exact axis-aligned box (px) of the image of a sphere (its silhouette, an ellipse without distortion).

    Without distortion the silhouette is the conic whose dual is ``C* = P Q* P^T`` with the sphere's
    dual quadric ``Q* = [[c c^T - r^2 I, c], [c^T, 1]]`` (Hartley and Zisserman 8.3); the box edges
    are its tangent lines ``x = u`` and ``y = v``, roots of ``C*00 - 2u C*02 + u^2 C*22 = 0`` (and
    likewise for v). With distortion, the silhouette circle on the sphere (the tangency points of
    the viewing cone) is sampled at 720 points and projected with distortion.

    Args:
        camera: the camera.
        centre_world: (3,) sphere centre, world metres.
        radius_m: sphere radius, metres (0.11 for a ball of 0.22 m).

    Returns:
        (4,) ``[x1, y1, x2, y2]`` pixels, or ``None`` when the sphere is not entirely in front of the
        camera (camera depth of its centre <= radius + :data:`MIN_DEPTH_M`: its image is unbounded
        or the camera is inside it).

    Raises:
        ValueError: bad shape or non-positive radius.

    >>> cam = Camera.from_parameters(focal_px=1000.0, principal_point=(960.0, 540.0), pan_deg=0.0,
    ...                              tilt_deg=90.0, roll_deg=0.0, position_m=[0.0, 50.0, -10.0])
    >>> box = sphere_image_box(cam, [0.0, 0.0, -10.0], 0.11)  # on the axis, 50 m away
    >>> round(float(box[2] - box[0]), 6), round(float(2000.0 * np.tan(np.arcsin(0.11 / 50.0))), 6)
    (4.400011, 4.400011)
    """
    c = np.asarray(centre_world, dtype=float).reshape(-1)
    if c.shape != (3,) or not np.all(np.isfinite(c)):
        raise ValueError(f"centre_world must be 3 finite numbers, got {centre_world!r}")
    if not radius_m > 0:
        raise ValueError(f"radius_m must be positive, got {radius_m!r}")
    depth = camera.points_in_camera(c)[0, 2]
    if depth <= radius_m + MIN_DEPTH_M:
        return None
    if camera.has_distortion:
        return _sampled_silhouette_box(camera, c, radius_m)
    Qs = np.empty((4, 4))
    Qs[:3, :3] = np.outer(c, c) - radius_m**2 * np.eye(3)
    Qs[:3, 3] = Qs[3, :3] = c
    Qs[3, 3] = 1.0
    P = camera.projection_matrix
    Cs = P @ Qs @ P.T
    x = _tangent_pair(Cs[0, 0], Cs[0, 2], Cs[2, 2])
    y = _tangent_pair(Cs[1, 1], Cs[1, 2], Cs[2, 2])
    return np.array([x[0], y[0], x[1], y[1]])


def _tangent_pair(a: float, b: float, c: float) -> tuple[float, float]:
    """Sorted roots of ``a - 2 b u + c u^2 = 0`` (c > 0, real for a sphere in front of the camera)."""
    disc = np.sqrt(max(b * b - a * c, 0.0))
    # Stable form: one root from the quadratic formula, the other from the product of roots a / c.
    q = b + np.copysign(disc, b)
    r1, r2 = q / c, (a / q if q != 0 else (b - disc) / c)
    return (min(r1, r2), max(r1, r2))


def _sampled_silhouette_box(camera: Camera, c: np.ndarray, r: float) -> np.ndarray:
    """Box of the projected (distorted) tangency circle of the viewing cone on the sphere."""
    v = c - camera.C
    dist = float(np.linalg.norm(v))
    u = v / dist
    centre = c - (r * r / dist) * u
    radius = r * np.sqrt(1.0 - (r / dist) ** 2)
    e1 = np.cross(u, [1.0, 0.0, 0.0] if abs(u[0]) < 0.9 else [0.0, 1.0, 0.0])
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(u, e1)
    t = np.linspace(0.0, 2 * np.pi, _SILHOUETTE_SAMPLES, endpoint=False)
    pts = centre + radius * (np.cos(t)[:, None] * e1 + np.sin(t)[:, None] * e2)
    uv, _ = camera.project(pts)
    return np.array([uv[:, 0].min(), uv[:, 1].min(), uv[:, 0].max(), uv[:, 1].max()])


@dataclass(frozen=True)
class OptimisedBox:
    """Result of :func:`optimise_box`.

    Attributes:
        status: ``"ok"``; ``"behind_camera"`` when the 3D ball projects behind the camera along the
            annotated ray (no positive diameter fits); ``"not_visible"`` when the ball placed by the
            method is not entirely in front of the camera (exact variants).
        method: one of :data:`OPTIMISED_BOX_METHODS`.
        box: (4,) ``[x1, y1, x2, y2]`` pixels, or ``None`` unless ok.
        d_px: ``d_opt`` in pixels (paper: width = height = d_opt; exact variants: the mean of the
            exact box's width and height), or ``None`` unless ok.
        error_m: SoccerNet-v3D's ``optimized_error``: distance (metres) between the 3D ball and the
            closest point of the annotated ray in front of the camera, i.e. the minimum of Eq.
            min_diametre (identical for all methods; the camera centre when behind).
        ray_point: (3,) the minimiser on the annotated ray (world metres): the monocular ball of the
            optimised paper box; ``None`` when behind the camera.
    """

    status: str
    method: str
    box: np.ndarray | None
    d_px: float | None
    error_m: float
    ray_point: np.ndarray | None


def optimise_box(camera: Camera, centre_px: np.ndarray, ball_world: np.ndarray, ball_diameter_m: float,
                 method: str = "paper") -> OptimisedBox:
    """Box consistent with the system's 3D ball (paper Eq. min_diametre), for a box or a point label.

    Along the ray ``C + lambda R^T p_c`` through the annotated centre, Eq. min_diametre minimises
    ``|| p - C - lambda R^T p_c ||`` over ``lambda = phi / ||p_c+(d) - p_c-(d)||``. The minimiser is
    the orthogonal projection ``lambda* = (R^T p_c) . (p - C) / ||p_c||^2`` (closed form, no local
    search); then ``d_opt`` solves ``||p_c+(d) - p_c-(d)|| = phi / lambda*``: ``d_opt = phi fy / lambda*``
    without distortion and skew, a bracketed root search otherwise. ``lambda* <= 0`` (the ball behind
    the camera along this ray) has no positive ``d``: status ``behind_camera``.

    Methods:
        * ``paper``: the box keeps the annotated centre; width = height = ``d_opt``.
        * ``exact_ray``: the exact silhouette box (:func:`sphere_image_box`) of the ball placed at the
          minimiser on the annotated ray (depth of the fused ball, direction of the annotation).
        * ``exact_fused``: the exact silhouette box of the ball at the fused point ``p`` itself (the
          annotated centre is not used for the box; it still defines ``error_m``).

    Args:
        camera: the view's camera.
        centre_px: (2,) annotated ball centre (box centre or point label), pixels.
        ball_world: (3,) the system's 3D ball ``p``, world metres.
        ball_diameter_m: phi, metres.
        method: one of :data:`OPTIMISED_BOX_METHODS`.

    Raises:
        ValueError: unknown method, bad shapes, non-positive ball_diameter_m.

    >>> cam = Camera.from_parameters(focal_px=1000.0, principal_point=(960.0, 540.0), pan_deg=0.0,
    ...                              tilt_deg=90.0, roll_deg=0.0, position_m=[0.0, 50.0, -10.0])
    >>> r = optimise_box(cam, [960.0, 540.0], [0.0, 0.0, -10.0], 0.22)
    >>> r.status, round(r.d_px, 9), np.round(r.box, 9).tolist(), round(r.error_m, 9)
    ('ok', 4.4, [957.8, 537.8, 962.2, 542.2], 0.0)
    """
    if method not in OPTIMISED_BOX_METHODS:
        raise ValueError(f"optimised box method {method!r} is unknown; choose one of {list(OPTIMISED_BOX_METHODS)}")
    c = np.asarray(centre_px, dtype=float).reshape(-1)
    p = np.asarray(ball_world, dtype=float).reshape(-1)
    if c.shape != (2,) or not np.all(np.isfinite(c)):
        raise ValueError(f"centre_px must be 2 finite numbers, got {centre_px!r}")
    if p.shape != (3,) or not np.all(np.isfinite(p)):
        raise ValueError(f"ball_world must be 3 finite numbers, got {ball_world!r}")
    if not ball_diameter_m > 0:
        raise ValueError(f"ball_diameter_m must be positive, got {ball_diameter_m!r}")

    p_c = _centre_ray_camera(camera, c[None, :])[0]
    v = p_c @ camera.R  # R^T p_c, world direction with camera-z component 1
    lam = float(v @ (p - camera.C) / (v @ v))
    if lam <= MIN_DEPTH_M:
        return OptimisedBox("behind_camera", method, None, None, float(np.linalg.norm(p - camera.C)), None)
    q = camera.C + lam * v
    error = float(np.linalg.norm(p - q))
    q.setflags(write=False)

    box: np.ndarray | None
    if method == "paper":
        d = _diameter_for_depth(camera, c, ball_diameter_m / lam)
        box = np.array([c[0] - d / 2, c[1] - d / 2, c[0] + d / 2, c[1] + d / 2])
    else:
        box = sphere_image_box(camera, q if method == "exact_ray" else p, ball_diameter_m / 2)
        if box is None:
            return OptimisedBox("not_visible", method, None, None, error, q)
        d = float((box[2] - box[0] + box[3] - box[1]) / 2)
    return OptimisedBox("ok", method, box, float(d), error, q)


def _diameter_for_depth(camera: Camera, centre_px: np.ndarray, span: float) -> float:
    """Pixel diameter d with ``||p_c+(d) - p_c-(d)|| = span`` (normalised units) at a centre."""
    unit = float(np.linalg.norm(np.linalg.inv(camera.K)[:, 1]))  # span per pixel without distortion
    d0 = span / unit
    if not camera.has_distortion:
        return d0
    c = centre_px[None, :]
    def f(d):
        return float(_edge_span(camera, c, np.array([d]))[0]) - span
    for k in (4.0, 32.0, 256.0):
        lo, hi = d0 / k, d0 * k
        if f(lo) <= 0 <= f(hi):
            return float(brentq(f, lo, hi, xtol=1e-9 * d0))
    raise ValueError(f"no box diameter reproduces the ball depth at centre {centre_px.tolist()}: "
                     "the camera's distortion is not monotonic there")


def _as_boxes(boxes: np.ndarray, name: str) -> np.ndarray:
    b = np.asarray(boxes, dtype=float)
    if b.ndim == 1:
        b = b[None, :]
    if b.ndim != 2 or b.shape[1] != 4:
        raise ValueError(f"{name} must have shape (4,) or (N, 4), got {np.shape(boxes)}")
    if not np.all(np.isfinite(b)):
        raise ValueError(f"{name} must be finite")
    return b
