"""How far two views' cameras disagree on the players both see, in one compiled call: the arithmetic of
:func:`~app.geometry.calibration.players.pair_players_disagreement` (each direction: the other view's foot points
on the grass, :func:`~.grass.players_on_grass`; this view's foot points against them in their standard
deviations, :func:`~.players.players_disagreement`) for the few players two views share.

Why compiled: an import asks about a thousand pairs of cameras per 600 systems, each with a handful of players,
and numpy's per-call cost, some fifty calls on arrays of a few rows per direction, was the pair's time (about 1 ms a
pair, a sixth of the import's main process, ``benchmarks/SCALE.md`` 2026-11-29), not its arithmetic. The kernel
follows the numpy functions step by step, in the same order of operations; the small linear algebra (2 x 2
inverses and Cholesky factors, which numpy hands to LAPACK) is written out, so a figure may differ from the numpy
functions' in its last bits (``tests/geometry/test_pair_players.py`` checks every pair of the shared sets within
1e-9 relative).

World frame: SoccerNet (metres, origin at the centre spot, z down); image: continuous pixels of the view, origin at
the top-left corner.
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit

from app.geometry.calibration.grass import FOOT_OFFSET_M, FOOT_OFFSET_SIGMA_M, FOOT_SIGMA_PX
from app.geometry.calibration.residuals import JIT
from app.geometry.camera import Camera
from app.geometry.pair_error import REFERENCE_WIDTH_PX
from app.geometry.pitch import PITCH_LENGTH_M, PITCH_WIDTH_M

#: How far beyond the pitch's half length and half width (m) a player still counts (as ``grass._fused``).
_X_LIMIT_M = PITCH_LENGTH_M / 2 + 5.0
_Y_LIMIT_M = PITCH_WIDTH_M / 2 + 5.0


def camera_arrays(camera: Camera) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, bool]:
    """What the kernel reads of a camera: ``K`` (3, 3), ``K^-1`` (3, 3), ``R`` (3, 3), ``C`` (3,) m, the distortion
    coefficients (12,) (radial 6, tangential 2, thin prism 4, ``Camera.distort``'s model) and whether any is set."""
    dist = np.concatenate([np.asarray(camera.radial, float), np.asarray(camera.tangential, float),
                           np.asarray(camera.thin_prism, float)])
    # Copies, writable: a camera's arrays may be read-only, and numba compiles (and caches) a kernel per mix of them.
    return (np.array(camera.K, dtype=float), np.array(camera.K_inv, dtype=float), np.array(camera.R, dtype=float),
            np.array(camera.C, dtype=float), dist, bool(camera.has_distortion))


@njit(**JIT)
def _ground_point(Kinv: np.ndarray, R: np.ndarray, C: np.ndarray, dist: np.ndarray, distorted: bool, u: float,
                  v: float) -> tuple:
    """``grass.grass_points`` of one pixel ``(u, v)``: its ray (``Camera.rays``, undistorted by 20 fixed-point steps
    of ``Camera.undistort``) met with the ground ``z = 0`` and moved :data:`~.grass.FOOT_OFFSET_M` away from the
    camera; (x, y) m, NaN when the ray never meets the ground ahead of the camera."""
    dx = u * Kinv[0, 0] + v * Kinv[0, 1] + Kinv[0, 2]
    dy = u * Kinv[1, 0] + v * Kinv[1, 1] + Kinv[1, 2]
    x, y = dx, dy
    if distorted:
        k0, k1, k2, k3, k4, k5 = dist[0], dist[1], dist[2], dist[3], dist[4], dist[5]
        t0, t1, s0, s1, s2, s3 = dist[6], dist[7], dist[8], dist[9], dist[10], dist[11]
        for _ in range(20):
            r2 = x * x + y * y
            r4, r6 = r2 * r2, math.pow(r2, 3.0)
            factor = (1 + k0 * r2 + k1 * r4 + k2 * r6) / (1 + k3 * r2 + k4 * r4 + k5 * r6)
            xd = x * factor + 2 * t0 * x * y + t1 * (r2 + 2 * x * x) + s0 * r2 + s1 * r4
            yd = y * factor + 2 * t1 * x * y + t0 * (r2 + 2 * y * y) + s2 * r2 + s3 * r4
            x, y = x + (dx - xd), y + (dy - yd)
    d0 = x * R[0, 0] + y * R[1, 0] + R[2, 0]
    d1 = x * R[0, 1] + y * R[1, 1] + R[2, 1]
    d2 = x * R[0, 2] + y * R[1, 2] + R[2, 2]
    norm = math.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
    d0, d1, d2 = d0 / norm, d1 / norm, d2 / norm
    t = -C[2] / d2
    if not (abs(d2) >= 1e-9 and t > 0):
        return math.nan, math.nan
    px, py = C[0] + t * d0, C[1] + t * d1
    ax, ay = px - C[0], py - C[1]
    n = math.sqrt(ax * ax + ay * ay)
    if n > 1e-9:
        px, py = px + FOOT_OFFSET_M * ax / n, py + FOOT_OFFSET_M * ay / n
    return px, py


@njit(**JIT)
def _inverse(a: float, b: float, c: float, d: float) -> tuple:
    """The inverse of ``[[a, b], [c, d]]`` (row-major 4-tuple)."""
    det = a * d - b * c
    return d / det, -b / det, -c / det, a / det


@njit(**JIT)
def _on_grass(Kinv: np.ndarray, R: np.ndarray, C: np.ndarray, dist: np.ndarray, distorted: bool, sigma: float,
              uv: np.ndarray) -> tuple:
    """``grass.players_on_grass`` of one view's foot points ``uv`` (n, 2) px (``sigma``: their noise, px of the
    view): each player's ground point (n, 2) m, its covariance (n, 2, 2) m^2 and whether it is kept (on the ground
    ahead of the camera, inside the pitch and 5 m)."""
    n = uv.shape[0]
    points = np.empty((n, 2))
    covs = np.empty((n, 2, 2))
    kept = np.zeros(n, dtype=np.bool_)
    s2 = sigma * sigma
    off2 = FOOT_OFFSET_SIGMA_M * FOOT_OFFSET_SIGMA_M
    for i in range(n):
        u, v = uv[i, 0], uv[i, 1]
        g0x, g0y = _ground_point(Kinv, R, C, dist, distorted, u, v)
        g1x, g1y = _ground_point(Kinv, R, C, dist, distorted, u + 0.5, v)
        g2x, g2y = _ground_point(Kinv, R, C, dist, distorted, u, v + 0.5)
        if math.isnan(g0x) or math.isnan(g1x) or math.isnan(g2x):
            continue
        # The ground Jacobian (m per px) by half-pixel differences; the point's information, then its covariance.
        j00, j01 = (g1x - g0x) / 0.5, (g2x - g0x) / 0.5
        j10, j11 = (g1y - g0y) / 0.5, (g2y - g0y) / 0.5
        a00 = (s2 * j00) * j00 + (s2 * j01) * j01 + off2
        a01 = (s2 * j00) * j10 + (s2 * j01) * j11
        a10 = (s2 * j10) * j00 + (s2 * j11) * j01
        a11 = (s2 * j10) * j10 + (s2 * j11) * j11 + off2
        i00, i01, i10, i11 = _inverse(a00, a01, a10, a11)
        c00, c01, c10, c11 = _inverse(i00, i01, i10, i11)
        hx, hy = i00 * g0x + i01 * g0y, i10 * g0x + i11 * g0y
        cx, cy = c00 * hx + c01 * hy, c10 * hx + c11 * hy
        if abs(cx) <= _X_LIMIT_M and abs(cy) <= _Y_LIMIT_M:
            kept[i] = True
            points[i, 0], points[i, 1] = cx, cy
            covs[i, 0, 0], covs[i, 0, 1], covs[i, 1, 0], covs[i, 1, 1] = c00, c01, c10, c11
    return points, covs, kept


@njit(**JIT)
def _project(f: float, pp0: float, pp1: float, R: np.ndarray, C: np.ndarray, x: float, y: float) -> tuple:
    """``player_problem.project_points`` of one ground point ``(x, y, 0)`` (m): its pixel, 1e6 px behind the camera."""
    px, py, pz = x - C[0], y - C[1], 0.0 - C[2]
    xc = R[0, 0] * px + R[0, 1] * py + R[0, 2] * pz
    yc = R[1, 0] * px + R[1, 1] * py + R[1, 2] * pz
    zc = R[2, 0] * px + R[2, 1] * py + R[2, 2] * pz
    if zc <= 1e-6:
        return 1e6, 1e6
    return f * xc / zc + pp0, f * yc / zc + pp1


@njit(**JIT)
def _foot_world(C: np.ndarray, gx: float, gy: float) -> tuple:
    """``grass.foot_world`` of one grass point (m): moved :data:`~.grass.FOOT_OFFSET_M` towards the camera."""
    tx, ty = C[0] - gx, C[1] - gy
    norm = math.sqrt(tx * tx + ty * ty)
    if not norm > 1e-9:
        norm = 1.0
    return gx + FOOT_OFFSET_M * tx / norm, gy + FOOT_OFFSET_M * ty / norm


@njit(**JIT)
def _disagreement(K: np.ndarray, R: np.ndarray, C: np.ndarray, width: float, uv: np.ndarray, points: np.ndarray,
                  covs: np.ndarray, kept: np.ndarray, min_players: int) -> float:
    """``players.players_disagreement`` of one view (``K``, ``R``, ``C``; image ``width`` px; foot points ``uv``
    (n, 2) px) against the ground points ``points`` (n, 2) m and covariances ``covs`` (n, 2, 2) of the players
    ``kept``: the median whitened distance (standard deviations); -1 with fewer than ``min_players`` players."""
    idx = np.nonzero(kept)[0]
    m = idx.shape[0]
    if m < min_players:
        return -1.0
    f, pp0, pp1 = K[0, 0], K[0, 2], K[1, 2]
    sigma = FOOT_SIGMA_PX * (width / REFERENCE_WIDTH_PX)
    noise = sigma * sigma
    # Each foot point's whitening under the camera (``PlayerProblem.rewhiten``): the projection's Jacobian with
    # respect to the ground point by 0.01 m differences, ``J cov J^T + sigma^2 I``, the inverse of its Cholesky
    # factor; a covariance that is not positive definite anywhere whitens every point by the pixel noise alone.
    white = np.empty((m, 2, 2))
    definite = True
    for j in range(m):
        i = idx[j]
        gx, gy = points[i, 0], points[i, 1]
        q0 = _foot_world(C, gx, gy)
        q1 = _foot_world(C, gx + 0.01, gy)
        q2 = _foot_world(C, gx, gy + 0.01)
        u0, v0 = _project(f, pp0, pp1, R, C, q0[0], q0[1])
        u1, v1 = _project(f, pp0, pp1, R, C, q1[0], q1[1])
        u2, v2 = _project(f, pp0, pp1, R, C, q2[0], q2[1])
        J = ((u1 - u0) / 0.01, (u2 - u0) / 0.01, (v1 - v0) / 0.01, (v2 - v0) / 0.01)
        cv = covs[i]
        c = np.zeros(4)
        for a in range(2):
            for b in range(2):
                acc = 0.0
                for s in range(2):
                    for t in range(2):
                        acc += J[2 * a + s] * cv[s, t] * J[2 * b + t]
                c[2 * a + b] = acc
        c00, c10, c11 = c[0] + noise, c[2], c[3] + noise
        if not c00 > 0:
            definite = False
            break
        l00 = math.sqrt(c00)
        l10 = c10 / l00
        rest = c11 - l10 * l10
        if not rest > 0:
            definite = False
            break
        l11 = math.sqrt(rest)
        white[j, 0, 0], white[j, 0, 1] = 1.0 / l00, 0.0
        white[j, 1, 0], white[j, 1, 1] = -l10 / (l00 * l11), 1.0 / l11
    if not definite:
        for j in range(m):
            white[j, 0, 0], white[j, 0, 1], white[j, 1, 0], white[j, 1, 1] = 1.0 / sigma, 0.0, 0.0, 1.0 / sigma
    d = np.empty(m)
    for j in range(m):
        i = idx[j]
        qx, qy = _foot_world(C, points[i, 0], points[i, 1])
        u, v = _project(f, pp0, pp1, R, C, qx, qy)
        du, dv = u - uv[i, 0], v - uv[i, 1]
        wu = white[j, 0, 0] * du + white[j, 0, 1] * dv
        wv = white[j, 1, 0] * du + white[j, 1, 1] * dv
        d[j] = math.sqrt(wu * wu + wv * wv)
    for j in range(m):
        if math.isnan(d[j]):
            return math.nan
    d = np.sort(d)
    k = m // 2
    return d[k] if m % 2 else (d[k - 1] + d[k]) / 2


@njit(**JIT)
def pair_figures(K_a: np.ndarray, Kinv_a: np.ndarray, R_a: np.ndarray, C_a: np.ndarray, dist_a: np.ndarray,
                 distorted_a: bool, width_a: float, uv_a: np.ndarray, K_b: np.ndarray, Kinv_b: np.ndarray,
                 R_b: np.ndarray, C_b: np.ndarray, dist_b: np.ndarray, distorted_b: bool, width_b: float,
                 uv_b: np.ndarray, min_players: int) -> tuple:
    """Both directions of :func:`~.players.pair_players_disagreement` for the players two views share (their foot
    points ``uv_a``, ``uv_b`` (n, 2) px, row i the same player; the cameras as :func:`camera_arrays` gives them):
    view a's disagreement with where view b alone puts the players, and b's with a's (standard deviations), each -1
    when it has fewer than ``min_players`` players to compare."""
    sigma_b = FOOT_SIGMA_PX * (K_b[0, 2] * 2 + 1) / REFERENCE_WIDTH_PX
    points, covs, kept = _on_grass(Kinv_b, R_b, C_b, dist_b, distorted_b, sigma_b, uv_b)
    a_figure = _disagreement(K_a, R_a, C_a, width_a, uv_a, points, covs, kept, min_players)
    sigma_a = FOOT_SIGMA_PX * (K_a[0, 2] * 2 + 1) / REFERENCE_WIDTH_PX
    points, covs, kept = _on_grass(Kinv_a, R_a, C_a, dist_a, distorted_a, sigma_a, uv_a)
    b_figure = _disagreement(K_b, R_b, C_b, width_b, uv_b, points, covs, kept, min_players)
    return a_figure, b_figure
