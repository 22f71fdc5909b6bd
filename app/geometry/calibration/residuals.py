"""Pixel residuals of annotated field lines against a camera, compiled for the least squares.

Camera parameters (one vector ``x``, see :class:`CameraParametrisation`): focal length ``f`` (px,
square pixels), a rotation vector ``w`` applied on the left of a reference rotation ``R0``
(``R = exp([w]x) R0``, world to camera), the camera centre ``C`` (world, metres, z down) and,
optionally, SoccerNet's first radial coefficient ``k1``. The principal point is fixed.

Residuals, all in pixels of the frame:

* a point on a straight element (ground line, goal post, crossbar): signed distance to the image
  line through the projections of the element's two 3D end points, ``l = (P A) x (P B)``
  (Hartley and Zisserman, eq. 2.3 and 8.2; valid for elements off the ground plane too), and its
  distance beyond the projected ends of the segment (0 inside);
* a point on a circle: Sampson's first-order distance to the image conic ``H^-T Q H^-1`` of the
  ground circle ``Q`` through the ground homography ``H = P[:, (0, 1, 3)]`` (Hartley and Zisserman,
  section 4.2.6 and result 2.13);
* with ``k1``, the annotated (distorted) points are first undistorted with SoccerNet's radial model
  (method.md section 2), so the pinhole distances above apply; the distances stay in pixels.

The arithmetic is compiled with numba (``cache=True``: compiled once per installation, loaded by each
process in well under a second), point by point in scalar loops: a frame has 10 to 150 points, where
numpy's per-call overhead, not the arithmetic, dominated. Each formula has one implementation here,
shared by the fits (:mod:`.solver`), the ranking of starts and the final per-class residuals.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Sequence

import numpy as np
from numba import njit

from app.geometry.calibration.observations import Observations
from app.geometry.camera import Camera

#: numba options of every kernel: cached on disk; float errors give inf/nan as numpy does (no
#: ZeroDivisionError); the GIL released.
JIT: dict[str, Any] = {"cache": True, "error_model": "numpy", "nogil": True}

#: Replacement of a non-finite distance (degenerate camera), px.
_HUGE_PX = 1e6


@njit(**JIT)
def rotation_into(w0: float, w1: float, w2: float, R0: np.ndarray, out: np.ndarray) -> None:
    """``out = exp([w]x) R0`` (3, 3) by Rodrigues' formula ``I + a [w]x + b [w]x^2`` (a series below
    1e-6 rad)."""
    theta2 = w0 * w0 + w1 * w1 + w2 * w2
    theta = math.sqrt(theta2)
    if theta < 1e-6:
        a = 1.0 - theta2 / 6.0
        b = 0.5 - theta2 / 24.0
    else:
        a = math.sin(theta) / theta
        b = (1.0 - math.cos(theta)) / (theta * theta)
    # [w]x = [[0, -w2, w1], [w2, 0, -w0], [-w1, w0, 0]]; [w]x^2 = w w^T - |w|^2 I.
    e00 = 1.0 - b * (w1 * w1 + w2 * w2)
    e11 = 1.0 - b * (w0 * w0 + w2 * w2)
    e22 = 1.0 - b * (w0 * w0 + w1 * w1)
    e01, e10 = -a * w2 + b * w0 * w1, a * w2 + b * w0 * w1
    e02, e20 = a * w1 + b * w0 * w2, -a * w1 + b * w0 * w2
    e12, e21 = -a * w0 + b * w1 * w2, a * w0 + b * w1 * w2
    for j in range(3):
        r0, r1, r2 = R0[0, j], R0[1, j], R0[2, j]
        out[0, j] = e00 * r0 + e01 * r1 + e02 * r2
        out[1, j] = e10 * r0 + e11 * r1 + e12 * r2
        out[2, j] = e20 * r0 + e21 * r1 + e22 * r2


@njit(**JIT)
def projection_into(f: float, pp: np.ndarray, R: np.ndarray, C: np.ndarray, out: np.ndarray) -> None:
    """``out = K R [I | -C]`` (3, 4) with ``K = [[f, 0, pp0], [0, f, pp1], [0, 0, 1]]``."""
    for j in range(3):
        out[0, j] = f * R[0, j] + pp[0] * R[2, j]
        out[1, j] = f * R[1, j] + pp[1] * R[2, j]
        out[2, j] = R[2, j]
    for i in range(3):
        out[i, 3] = -(out[i, 0] * C[0] + out[i, 1] * C[1] + out[i, 2] * C[2])


@njit(**JIT)
def undistort_into(uv: np.ndarray, f: float, pp: np.ndarray, k1: float, out: np.ndarray, iterations: int = 4) -> None:
    """Undistorted pixels (N, 2) of distorted ones ``uv`` (:func:`undistort_radial_k1`) into ``out``."""
    for n in range(uv.shape[0]):
        dx = (uv[n, 0] - pp[0]) / f
        dy = (uv[n, 1] - pp[1]) / f
        d2 = dx * dx + dy * dy
        rho = d2
        for _ in range(iterations):
            q = 1.0 + k1 * rho
            rho = rho - (rho * q * q - d2) / (q * (q + 2.0 * k1 * rho))
        s = f / (1.0 + k1 * rho)
        out[n, 0] = dx * s + pp[0]
        out[n, 1] = dy * s + pp[1]


@njit(**JIT)
def _finite_or_huge(v: float) -> float:
    if math.isnan(v):
        return _HUGE_PX
    if math.isinf(v):
        return _HUGE_PX if v > 0 else -_HUGE_PX
    return v


@njit(**JIT)
def _ground_adjugate(P: np.ndarray) -> tuple:
    """The adjugate ``G`` (row-major 9-tuple) of the ground homography ``H = P[:, (0, 1, 3)]`` of a
    (3, 4) projection: its inverse up to scale, defined for a singular one too; column ``r`` of ``G``
    is the cross product of rows ``r + 1`` and ``r + 2`` of ``H``."""
    h00, h01, h02 = P[0, 0], P[0, 1], P[0, 3]
    h10, h11, h12 = P[1, 0], P[1, 1], P[1, 3]
    h20, h21, h22 = P[2, 0], P[2, 1], P[2, 3]
    g00, g10, g20 = h11 * h22 - h12 * h21, h12 * h20 - h10 * h22, h10 * h21 - h11 * h20
    g01, g11, g21 = h21 * h02 - h22 * h01, h22 * h00 - h20 * h02, h20 * h01 - h21 * h00
    g02, g12, g22 = h01 * h12 - h02 * h11, h02 * h10 - h00 * h12, h00 * h11 - h01 * h10
    return g00, g01, g02, g10, g11, g12, g20, g21, g22


#: Columns of the per-element scratch of :func:`distances_into`.
_SCRATCH = 10


@njit(**JIT)
def distances_into(P: np.ndarray, sp: np.ndarray, cp: np.ndarray, o: tuple, d_line: np.ndarray, d_ext: np.ndarray,
                   d_cir: np.ndarray, scratch: np.ndarray) -> None:
    """The distances of the points ``sp`` (N, 2) of straight elements and ``cp`` (M, 2) of circles
    under ``P`` (3, 4), px: signed to the element's image line (``d_line``, N), beyond the
    projected segment's ends (``d_ext``, N; 0 inside, and 0 for an element with an end behind the
    camera), Sampson's to the circle's image conic (``d_cir``, M); non-finite values (a degenerate
    camera) become +-1e6 (``d_ext`` 0). ``o``: :attr:`Observations.kernel_arrays`; ``scratch``:
    (S, 10) work space."""
    seg_a, seg_b, seg_index, ccx, ccy, ck = o[0], o[1], o[2], o[5], o[6], o[7]
    for s in range(seg_a.shape[0]):
        # Image line of the element: l = (P A) x (P B) (Hartley and Zisserman, 2.2).
        a0 = P[0, 0] * seg_a[s, 0] + P[0, 1] * seg_a[s, 1] + P[0, 2] * seg_a[s, 2] + P[0, 3]
        a1 = P[1, 0] * seg_a[s, 0] + P[1, 1] * seg_a[s, 1] + P[1, 2] * seg_a[s, 2] + P[1, 3]
        a2 = P[2, 0] * seg_a[s, 0] + P[2, 1] * seg_a[s, 1] + P[2, 2] * seg_a[s, 2] + P[2, 3]
        b0 = P[0, 0] * seg_b[s, 0] + P[0, 1] * seg_b[s, 1] + P[0, 2] * seg_b[s, 2] + P[0, 3]
        b1 = P[1, 0] * seg_b[s, 0] + P[1, 1] * seg_b[s, 1] + P[1, 2] * seg_b[s, 2] + P[1, 3]
        b2 = P[2, 0] * seg_b[s, 0] + P[2, 1] * seg_b[s, 1] + P[2, 2] * seg_b[s, 2] + P[2, 3]
        l0, l1 = a1 * b2 - a2 * b1, a2 * b0 - a0 * b2
        scratch[s, 0], scratch[s, 1], scratch[s, 2] = l0, l1, a0 * b1 - a1 * b0
        scratch[s, 3] = math.hypot(l0, l1)
        # Beyond an end: the distance along the line past the projected end point (as the official
        # JaC measures to the end of the projected polyline), only for elements whose two ends are
        # in front of the camera (the third row of P gives the depth).
        ax, ay = a0 / a2, a1 / a2
        dx, dy = b0 / b2 - ax, b1 / b2 - ay
        length = math.hypot(dx, dy)
        scratch[s, 4], scratch[s, 5] = ax, ay
        scratch[s, 6], scratch[s, 7] = dx / length, dy / length
        scratch[s, 8] = length
        scratch[s, 9] = 1.0 if a2 > 1e-3 and b2 > 1e-3 else 0.0
    for n in range(sp.shape[0]):
        s = seg_index[n]
        x, y = sp[n, 0], sp[n, 1]
        d_line[n] = _finite_or_huge((scratch[s, 0] * x + scratch[s, 1] * y + scratch[s, 2]) / scratch[s, 3])
        d_ext[n] = 0.0
        if scratch[s, 9] > 0.0:
            along = (x - scratch[s, 4]) * scratch[s, 6] + (y - scratch[s, 5]) * scratch[s, 7]
            past = along - scratch[s, 8]
            if not (math.isnan(along) or math.isnan(past)):
                over = max(-along, past, 0.0)
                if not math.isinf(over):
                    d_ext[n] = over
    if cp.shape[0] == 0:
        return
    # Sampson distance to the image conic C = G^T Q G of the ground circle Q, with G the adjugate
    # of the ground homography H = P[:, (0, 1, 3)]: f = p^T C p = X^T Q X with X = G p the (scaled) ground point, and
    # grad_p f = 2 (G^T Q X)[:2].
    g00, g01, g02, g10, g11, g12, g20, g21, g22 = _ground_adjugate(P)
    for m in range(cp.shape[0]):
        px, py = cp[m, 0], cp[m, 1]
        x = g00 * px + g01 * py + g02
        y = g10 * px + g11 * py + g12
        w = g20 * px + g21 * py + g22
        cx, cy, k = ccx[m], ccy[m], ck[m]
        u = x - cx * w
        v = y - cy * w
        t = k * w - cx * x - cy * y  # Q X third row, with k = cx^2 + cy^2 - r^2
        fval = x * u + y * v + w * t
        grad0 = g00 * u + g10 * v + g20 * t
        grad1 = g01 * u + g11 * v + g21 * t
        d_cir[m] = _finite_or_huge(fval / (2.0 * math.hypot(grad0, grad1)))


@njit(**JIT)
def residuals_into(x: np.ndarray, pp: np.ndarray, R0: np.ndarray, centre: np.ndarray, fixed: bool, fit_k1: bool,
                   o: tuple, out: np.ndarray, R: np.ndarray, P: np.ndarray, sp: np.ndarray, cp: np.ndarray,
                   d_line: np.ndarray, d_ext: np.ndarray, d_cir: np.ndarray, scratch: np.ndarray) -> None:
    """Weighted residuals (px) of one parameter vector ``x`` into ``out`` (2 N + M,): the
    straight-element points' distances to their lines, their distances beyond the segments' ends,
    then the circle points' distances, each times its class weight (:func:`residuals`). ``pp``
    (2,) px, ``R0`` (3, 3), ``centre`` (3,) metres used when ``fixed``; the rest is scratch
    (:func:`workspace`)."""
    seg_points, seg_weight, circle_points, circle_weight = o[3], o[4], o[8], o[9]
    f = x[0]
    rotation_into(x[1], x[2], x[3], R0, R)
    projection_into(f, pp, R, centre if fixed else x[4:7], P)
    points_s, points_c = seg_points, circle_points
    if fit_k1 and x[x.shape[0] - 1] != 0.0:
        k1 = x[x.shape[0] - 1]
        undistort_into(seg_points, f, pp, k1, sp)
        undistort_into(circle_points, f, pp, k1, cp)
        points_s, points_c = sp, cp
    distances_into(P, points_s, points_c, o, d_line, d_ext, d_cir, scratch)
    n, m = d_line.shape[0], d_cir.shape[0]
    for i in range(n):
        out[i] = d_line[i] * seg_weight[i]
        out[n + i] = d_ext[i] * seg_weight[i]
    for i in range(m):
        out[2 * n + i] = d_cir[i] * circle_weight[i]


@njit(**JIT)
def workspace(o: tuple) -> tuple:
    """Scratch arrays of :func:`residuals_into` for the observations ``o``."""
    n, m, s = o[3].shape[0], o[8].shape[0], o[0].shape[0]
    return (np.empty((3, 3)), np.empty((3, 4)), np.empty((n, 2)), np.empty((m, 2)), np.empty(n), np.empty(n),
            np.empty(m), np.empty((s, _SCRATCH)))


@njit(**JIT)
def _residual_rows(X: np.ndarray, R0s: np.ndarray, centres: np.ndarray, pp: np.ndarray, fixed: bool, fit_k1: bool,
                   o: tuple) -> np.ndarray:
    """Residuals (B, 2 N + M) of the rows of ``X`` (B, k), row ``b`` with reference rotation
    ``R0s[b]`` and, when ``fixed``, centre ``centres[b]``."""
    R, P, sp, cp, d_line, d_ext, d_cir, scratch = workspace(o)
    out = np.empty((X.shape[0], 2 * d_line.shape[0] + d_cir.shape[0]))
    for b in range(X.shape[0]):
        residuals_into(X[b], pp, R0s[b], centres[b], fixed, fit_k1, o, out[b], R, P, sp, cp, d_line, d_ext, d_cir,
                       scratch)
    return out


def rotation_from_vector(w: np.ndarray) -> np.ndarray:
    """Rodrigues' formula ``R = I + a [w]x + b [w]x^2``: rotation vector(s) (..., 3) radians ->
    rotation matrices (..., 3, 3).

    >>> np.allclose(rotation_from_vector(np.array([0.0, 0.0, np.pi / 2])) @ [1.0, 0.0, 0.0], [0.0, 1.0, 0.0])
    True
    """
    w = np.asarray(w, dtype=float)
    flat = w.reshape(-1, 3)
    out = np.empty((len(flat), 3, 3))
    eye = np.eye(3)
    for i, (w0, w1, w2) in enumerate(flat.tolist()):
        rotation_into(w0, w1, w2, eye, out[i])
    return out.reshape(w.shape[:-1] + (3, 3))


def undistort_radial_k1(uv: np.ndarray, f: np.ndarray | float, pp: np.ndarray, k1: np.ndarray | float,
                        iterations: int = 4) -> np.ndarray:
    """Remove SoccerNet's one-coefficient radial distortion from pixels (method.md section 2).

    With ``d`` the distorted normalised point, the undistorted one is ``x = d / (1 + k1 rho)``
    where ``rho = |x|^2`` solves ``rho (1 + k1 rho)^2 = |d|^2``; ``rho`` is found by Newton's method
    from ``|d|^2`` (quadratic convergence; 4 steps reach 1e-12 for |k1| rho < 0.3). A ``k1`` of 0
    returns the points as they are.

    Args:
        uv: (N, 2) distorted pixels. f: focal length(s) px, shape (...). pp: (2,) principal point px.
        k1: coefficient(s), shape (...) like ``f``.

    Returns:
        (..., N, 2) undistorted pixels (same focal length and principal point).

    >>> uv = np.array([[900.0, 500.0]])
    >>> xd = (uv - 480.0) / 1000.0; xd = xd * (1 + 0.1 * np.sum(xd**2))  # distort by hand
    >>> np.round(undistort_radial_k1(xd * 1000.0 + 480.0, 1000.0, np.array([480.0, 480.0]), 0.1), 6).tolist()
    [[900.0, 500.0]]
    """
    uv = np.ascontiguousarray(uv, dtype=float).reshape(-1, 2)
    f, k1 = np.broadcast_arrays(np.asarray(f, dtype=float), np.asarray(k1, dtype=float))
    out = np.empty(f.shape + uv.shape)
    flat_out = out.reshape((f.size,) + uv.shape)
    pp = np.asarray(pp, dtype=float)
    for i, (fi, ki) in enumerate(zip(f.ravel().tolist(), k1.ravel().tolist(), strict=True)):
        if ki == 0.0:
            flat_out[i] = uv
        else:
            undistort_into(uv, fi, pp, ki, flat_out[i], iterations)
    return out


@dataclass(frozen=True)
class CameraParametrisation:
    """Maps parameter vectors to cameras for one frame.

    Vector layout: ``[f, w0, w1, w2, Cx, Cy, Cz (, k1)]``; with ``fixed_centre`` the centre entries
    are absent: ``[f, w0, w1, w2 (, k1)]``.

    Attributes:
        principal_point: (2,) fixed principal point, px.
        R0: (3, 3) reference rotation (world to camera) the rotation vector is applied to.
        fit_k1: the vector carries ``k1`` as its last entry.
        fixed_centre: if given, (3,) camera centre held fixed (rig prior), metres.
    """

    principal_point: np.ndarray
    R0: np.ndarray
    fit_k1: bool = False
    fixed_centre: np.ndarray | None = None

    @property
    def size(self) -> int:
        """Length of a parameter vector."""
        return 4 + (3 if self.fixed_centre is None else 0) + (1 if self.fit_k1 else 0)

    def split(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Vectors (..., size) -> focal px (...), R (..., 3, 3), C (..., 3) metres, k1 (...)."""
        x = np.asarray(x, dtype=float)
        f = x[..., 0]
        R = rotation_from_vector(x[..., 1:4]) @ self.R0
        if self.fixed_centre is None:
            C = x[..., 4:7]
        else:
            C = np.broadcast_to(self.fixed_centre, x.shape[:-1] + (3,))
        k1 = x[..., -1] if self.fit_k1 else np.zeros(x.shape[:-1])
        return f, R, C, k1

    def vector(self, f: float, C: np.ndarray, k1: float = 0.0) -> np.ndarray:
        """Parameter vector at the reference rotation."""
        parts = [[f, 0.0, 0.0, 0.0]]
        if self.fixed_centre is None:
            parts.append(list(C))
        if self.fit_k1:
            parts.append([k1])
        return np.concatenate(parts).astype(float)

    def camera(self, x: np.ndarray) -> Camera:
        """The :class:`~app.geometry.camera.Camera` of one vector ``x``."""
        f_arr, R, C, k1 = self.split(x)
        f = float(f_arr)
        K = np.array([[f, 0.0, self.principal_point[0]], [0.0, f, self.principal_point[1]], [0.0, 0.0, 1.0]])
        radial = np.zeros(6)
        radial[0] = float(k1)
        return Camera(K=K, R=R, C=np.array(C, dtype=float), radial=radial)


def projection_matrix(f: np.ndarray | float, pp: np.ndarray, R: np.ndarray, C: np.ndarray) -> np.ndarray:
    """``P = K R [I | -C]`` with square pixels (paper Eq. projection), batched.

    Args:
        f: focal length(s) px, shape (...). pp: (2,) px. R: (..., 3, 3). C: (..., 3) metres.

    Returns:
        (..., 3, 4) projection matrices.
    """
    f = np.asarray(f, dtype=float)
    R = np.asarray(R, dtype=float)
    KR = R.copy()
    KR[..., 0, :] = f[..., None] * R[..., 0, :] + pp[0] * R[..., 2, :]
    KR[..., 1, :] = f[..., None] * R[..., 1, :] + pp[1] * R[..., 2, :]
    t = -np.einsum("...ij,...j->...i", KR, C)
    return np.concatenate([KR, t[..., None]], axis=-1)


@njit(**JIT)
def _point_distances(P: np.ndarray, sp: np.ndarray, cp: np.ndarray, o: tuple) -> tuple:
    B, n, m = P.shape[0], o[3].shape[0], o[8].shape[0]
    d_line, d_ext, d_cir = np.empty((B, n)), np.empty((B, n)), np.empty((B, m))
    scratch = np.empty((o[0].shape[0], _SCRATCH))
    for b in range(B):
        distances_into(P[b], sp[b], cp[b], o, d_line[b], d_ext[b], d_cir[b], scratch)
    return d_line, d_ext, d_cir


def point_distances(P: np.ndarray, obs: Observations, seg_points: np.ndarray | None = None,
                    circle_points: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Pixel distance of every annotated point to its projected model element.

    Args:
        P: (3, 4) or (B, 3, 4) projection matrices (pinhole, pixels).
        obs: the frame's :class:`Observations`.
        seg_points, circle_points: replacement points, (N, 2) / (M, 2) or per camera (B, N, 2) /
            (B, M, 2) (e.g. undistorted); default the annotated ones.

    Returns:
        ``(d_seg, d_circle)`` with the leading shape of ``P``: (..., N) distances to the straight
        elements' projected segments (signed by the side of the line), and (..., M) Sampson
        distances to the circles' image conics (first order in the distance), pixels. Non-finite
        values (degenerate camera) are replaced by +-1e6 px.
    """
    P = np.ascontiguousarray(P, dtype=float)
    single = P.ndim == 2
    P = P.reshape(-1, 3, 4)
    B = len(P)
    sp = obs.seg_points if seg_points is None else seg_points
    cp = obs.circle_points if circle_points is None else circle_points
    sp = np.ascontiguousarray(np.broadcast_to(sp, (B,) + np.shape(sp)[-2:]), dtype=float)
    cp = np.ascontiguousarray(np.broadcast_to(cp, (B,) + np.shape(cp)[-2:]), dtype=float)
    d_line, d_ext, d_cir = _point_distances(P, sp, cp, obs.kernel_arrays)
    d_seg = np.copysign(np.hypot(d_line, d_ext), d_line)
    if single:
        return d_seg[0], d_cir[0]
    return d_seg, d_cir


def residuals(x: np.ndarray, obs: Observations, param: CameraParametrisation) -> np.ndarray:
    """Weighted residuals (pixels) of parameter vector(s) ``x`` (..., size) -> (..., 2 N + M):
    distances of the straight-element points to their lines, their distances beyond the segments'
    ends, then the circle points' distances, each times its class weight."""
    return residual_rows(x, obs, [param])


def residual_rows(x: np.ndarray, obs: Observations, params: Sequence[CameraParametrisation]) -> np.ndarray:
    """:func:`residuals` of the vectors ``x`` (..., size), each with its own parametrisation
    (``params``: one per vector, or one for all; they must agree in shape: radial term or not, centre
    fixed or free, principal point) -> (..., 2 N + M) pixels."""
    x = np.asarray(x, dtype=float)
    X = np.ascontiguousarray(x.reshape(-1, x.shape[-1]))
    if len(params) == 1:
        params = list(params) * len(X)
    first = params[0]
    if len(params) != len(X) or any(p.fit_k1 != first.fit_k1 or (p.fixed_centre is None) != (first.fixed_centre is None)
                                    for p in params):
        raise ValueError("residual_rows: one parametrisation per vector, all of one shape")
    R0s = np.ascontiguousarray([p.R0 for p in params], dtype=float).reshape(-1, 3, 3)
    fixed = first.fixed_centre is not None
    centres = (np.ascontiguousarray([p.fixed_centre for p in params], dtype=float) if fixed
               else np.zeros((len(X), 3)))
    pp = np.ascontiguousarray(first.principal_point, dtype=float)
    r = _residual_rows(X, R0s, centres, pp, fixed, first.fit_k1, obs.kernel_arrays)
    return r.reshape(x.shape[:-1] + (r.shape[-1],))


@njit(**JIT)
def _in_front(P: np.ndarray, pts: np.ndarray) -> float:
    """Fraction of the ground points ``pts`` (G, 2) px whose back-projection through the ground
    homography ``H = P[:, (0, 1, 3)]`` lies in front of the camera (depth > 0)."""
    g00, g01, g02, g10, g11, g12, g20, g21, g22 = _ground_adjugate(P)
    ahead = 0
    for i in range(pts.shape[0]):
        u, v = pts[i, 0], pts[i, 1]
        w = g20 * u + g21 * v + g22
        x = (g00 * u + g01 * v + g02) / w
        y = (g10 * u + g11 * v + g12) / w
        # The third row of P = K R [I | -C] is r3 (X - C): the depth in metres.
        depth = x * P[2, 0] + y * P[2, 1] + P[2, 3]
        if math.isfinite(depth) and depth > 0:
            ahead += 1
    return ahead / pts.shape[0]


def ground_points_in_front(P: np.ndarray, obs: Observations) -> float:
    """Fraction of annotated ground points (not goal elements) whose ground back-projection lies in
    front of the camera.

    A valid camera sees its ground labels in front (1.0); a solution that explains the labels
    with the pitch behind the camera scores near 0. ``P`` is (3, 4).
    """
    pts = obs.ground_points
    if len(pts) == 0:
        return 1.0
    return float(_in_front(np.ascontiguousarray(P, dtype=float), pts))
