"""Pixel residuals of annotated field lines against a camera, vectorised for least squares.

Camera parameters (one vector ``x``, see :class:`CameraParametrisation`): focal length ``f`` (px,
square pixels), a rotation vector ``w`` applied on the left of a reference rotation ``R0``
(``R = exp([w]x) R0``, world to camera), the camera centre ``C`` (world, metres, z down) and,
optionally, SoccerNet's first radial coefficient ``k1``. The principal point is fixed.

Residuals, all in pixels of the frame:

* a point on a straight element (ground line, goal post, crossbar): signed distance to the image
  line through the projections of the element's two 3D end points, ``l = (P A) x (P B)``
  (Hartley and Zisserman, eq. 2.3 and 8.2; valid for elements off the ground plane too);
* a point on a circle: Sampson's first-order distance to the image conic ``H^-T Q H^-1`` of the
  ground circle ``Q`` through the ground homography ``H = P[:, (0, 1, 3)]`` (Hartley and Zisserman,
  section 4.2.6 and result 2.13);
* with ``k1``, the annotated (distorted) points are first undistorted with SoccerNet's radial model
  (method.md section 2), so the pinhole distances above apply; the distances stay in pixels.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import numpy as np

from app.geometry.calibration.observations import Observations
from app.geometry.camera import Camera
from app.geometry.pitch import GOAL_CLASSES


_SKEW_SLOTS = [1, 2, 3, 5, 6, 7]
_SKEW_FROM = [2, 1, 2, 0, 1, 0]
_SKEW_SIGN = np.array([-1.0, 1.0, 1.0, -1.0, -1.0, 1.0])


def rotation_from_vector(w: np.ndarray) -> np.ndarray:
    """Rodrigues' formula ``R = I + a [w]x + b [w]x^2``: rotation vector(s) (..., 3) radians ->
    rotation matrices (..., 3, 3).

    >>> np.allclose(rotation_from_vector(np.array([0.0, 0.0, np.pi / 2])) @ [1.0, 0.0, 0.0], [0.0, 1.0, 0.0])
    True
    """
    w = np.asarray(w, dtype=float)
    lead = w.shape[:-1]
    w = w.reshape(-1, 3)
    theta2 = np.einsum("ij,ij->i", w, w)
    theta = np.sqrt(theta2)
    small = theta < 1e-6
    safe = np.where(small, 1.0, theta)
    a = np.where(small, 1.0 - theta2 / 6.0, np.sin(safe) / safe)
    b = np.where(small, 0.5 - theta2 / 24.0, (1.0 - np.cos(safe)) / (safe * safe))
    kx = np.zeros((len(w), 9))
    kx[:, _SKEW_SLOTS] = w[:, _SKEW_FROM] * _SKEW_SIGN
    kx = kx.reshape(-1, 3, 3)
    out = np.eye(3) + a[:, None, None] * kx + b[:, None, None] * (kx @ kx)
    return out.reshape(lead + (3, 3))


def undistort_radial_k1(uv: np.ndarray, f: np.ndarray | float, pp: np.ndarray, k1: np.ndarray | float,
                        iterations: int = 4) -> np.ndarray:
    """Remove SoccerNet's one-coefficient radial distortion from pixels (method.md section 2).

    With ``d`` the distorted normalised point, the undistorted one is ``x = d / (1 + k1 rho)``
    where ``rho = |x|^2`` solves ``rho (1 + k1 rho)^2 = |d|^2``; ``rho`` is found by Newton's method
    from ``|d|^2`` (quadratic convergence; 4 steps reach 1e-12 for |k1| rho < 0.3).

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
    f = np.asarray(f, dtype=float)[..., None]
    k1 = np.asarray(k1, dtype=float)[..., None]
    if len(uv) == 0 or not np.any(k1):
        return np.broadcast_to(uv, f.shape[:-1] + uv.shape)
    d = (uv - pp)[None] / f[..., None] if f.ndim > 1 else (uv - pp) / f[..., None]
    d2 = np.sum(d * d, axis=-1)
    rho = d2
    for _ in range(iterations):
        q = 1.0 + k1 * rho
        rho = rho - (rho * q * q - d2) / (q * (q + 2.0 * k1 * rho))
    scale = f / (1.0 + k1 * rho)
    return d * scale[..., None] + pp


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
        f, R, C, k1 = self.split(x)
        f = float(f)
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


_ROLL1 = [1, 2, 0]
_ROLL2 = [2, 0, 1]


def _adjugate3(m: np.ndarray) -> np.ndarray:
    """Adjugate of (B, 3, 3) matrices: the inverse times the determinant, defined for singular ones
    too. Its columns are the cross products of the rows (r1 x r2, r2 x r0, r0 x r1)."""
    a, b = m[:, _ROLL1, :], m[:, _ROLL2, :]
    cof = a[:, :, _ROLL1] * b[:, :, _ROLL2] - a[:, :, _ROLL2] * b[:, :, _ROLL1]
    return np.swapaxes(cof, 1, 2)


def _distances(P: np.ndarray, obs: Observations, sp: np.ndarray, cp: np.ndarray
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(B, N) signed distances to the elements' image lines, (B, N) distances beyond the segments'
    projected ends (0 inside), (B, M) Sampson distances to the circles' image conics; pixels."""
    B = len(P)
    d_line = np.zeros((B, len(obs.seg_points)))
    d_ext = np.zeros((B, len(obs.seg_points)))
    d_cir = np.zeros((B, len(obs.circle_points)))
    with np.errstate(all="ignore"):
        if len(obs.seg_points):
            # Image lines of the elements, (B, 3, S): l = (P A) x (P B) (Hartley and Zisserman, 2.2).
            a = P @ obs.seg_ah_t
            b = P @ obs.seg_bh_t
            ln = a[:, _ROLL1] * b[:, _ROLL2] - a[:, _ROLL2] * b[:, _ROLL1]
            idx = obs.seg_index
            li = ln[:, :, idx]  # (B, 3, N)
            num = li[:, 0] * sp[..., 0] + li[:, 1] * sp[..., 1] + li[:, 2]
            d_line = num / np.hypot(li[:, 0], li[:, 1])
            # Beyond an end: the distance along the line past the projected end point (as the
            # official JaC measures to the end of the projected polyline). Only for elements whose
            # two ends are in front of the camera (the third row of P gives the depth).
            front = (a[:, 2] > 1e-3) & (b[:, 2] > 1e-3)
            ax, ay = a[:, 0] / a[:, 2], a[:, 1] / a[:, 2]
            dx, dy = b[:, 0] / b[:, 2] - ax, b[:, 1] / b[:, 2] - ay
            length = np.hypot(dx, dy)
            ux, uy = dx / length, dy / length
            s_along = (sp[..., 0] - ax[:, idx]) * ux[:, idx] + (sp[..., 1] - ay[:, idx]) * uy[:, idx]
            over = np.maximum(np.maximum(-s_along, s_along - length[:, idx]), 0.0)
            d_ext = np.where(front[:, idx] & np.isfinite(over), over, 0.0)
        if len(obs.circle_points):
            # Sampson distance to the image conic C = G^T Q G of the ground circle Q, with G the
            # adjugate of the ground homography: f = p^T C p = X^T Q X with X = G p the (scaled)
            # ground point, and grad_p f = 2 (G^T Q X)[:2].
            G = _adjugate3(P[:, :, (0, 1, 3)])
            if cp.ndim == 2:
                X = G[:, :, :2] @ cp.T + G[:, :, 2:]  # (B, 3, M)
            else:
                X = G[:, :, :2] @ np.swapaxes(cp, 1, 2) + G[:, :, 2:]
            x, y, w = X[:, 0], X[:, 1], X[:, 2]
            cx, cy, k = obs.circle_point_cx, obs.circle_point_cy, obs.circle_point_k
            u = x - cx * w
            v = y - cy * w
            t = k * w - cx * x - cy * y  # Q X third row, with k = cx^2 + cy^2 - r^2
            fval = x * u + y * v + w * t
            g0 = G[:, 0, 0, None] * u + G[:, 1, 0, None] * v + G[:, 2, 0, None] * t
            g1 = G[:, 0, 1, None] * u + G[:, 1, 1, None] * v + G[:, 2, 1, None] * t
            d_cir = fval / (2.0 * np.hypot(g0, g1))
    if not (np.isfinite(d_line).all() and np.isfinite(d_cir).all()):
        d_line = np.nan_to_num(d_line, nan=1e6, posinf=1e6, neginf=-1e6)
        d_cir = np.nan_to_num(d_cir, nan=1e6, posinf=1e6, neginf=-1e6)
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
    P = np.asarray(P, dtype=float)
    single = P.ndim == 2
    if single:
        P = P[None]
    sp = obs.seg_points if seg_points is None else seg_points
    cp = obs.circle_points if circle_points is None else circle_points
    d_line, d_ext, d_cir = _distances(P, obs, sp, cp)
    d_seg = np.copysign(np.hypot(d_line, d_ext), d_line)
    if single:
        return d_seg[0], d_cir[0]
    return d_seg, d_cir


def residuals(x: np.ndarray, obs: Observations, param: CameraParametrisation) -> np.ndarray:
    """Weighted residuals (pixels) of parameter vector(s) ``x`` (..., size) -> (..., 2 N + M):
    distances of the straight-element points to their lines, their distances beyond the segments'
    ends, then the circle points' distances, each times its class weight."""
    f, R, C, k1 = param.split(x)
    P = projection_matrix(f, param.principal_point, R, C)
    single = P.ndim == 2
    r = _weighted_distances(P[None] if single else P, np.reshape(f, (-1,)), np.reshape(k1, (-1,)), obs, param)
    return r[0] if single else r


def _weighted_distances(P: np.ndarray, f: np.ndarray, k1: np.ndarray, obs: Observations,
                        param: CameraParametrisation) -> np.ndarray:
    """:func:`residuals` from (B, 3, 4) projection matrices and their (B,) focal lengths and ``k1``."""
    pp = param.principal_point
    sp, cp = obs.seg_points, obs.circle_points
    if param.fit_k1:
        both = undistort_radial_k1(obs.all_points, f, pp, k1)
        sp, cp = both[..., : len(sp), :], both[..., len(sp):, :]
    d_line, d_ext, d_cir = _distances(P, obs, sp, cp)
    return np.concatenate([d_line * obs.seg_weight, d_ext * obs.seg_weight, d_cir * obs.circle_weight], axis=-1)


def ground_points_in_front(P: np.ndarray, obs: Observations) -> float:
    """Fraction of annotated ground points (not goal elements) whose ground back-projection lies in
    front of the camera.

    A valid camera sees its ground labels in front (1.0); a solution that explains the labels
    with the pitch behind the camera scores near 0. ``P`` is (3, 4).
    """
    goal_seg = np.array([c in GOAL_CLASSES for c in obs.seg_classes], dtype=bool)
    keep = ~goal_seg[obs.seg_index] if len(obs.seg_points) else np.zeros(0, bool)
    pts = np.concatenate([obs.seg_points[keep], obs.circle_points])
    if len(pts) == 0:
        return 1.0
    H = P[:, (0, 1, 3)]
    with np.errstate(all="ignore"):
        Hi = _adjugate3(H[None])[0]
        w = pts @ Hi[:, :2].T + Hi[:, 2]
        X = w[:, :2] / w[:, 2:3]
        # The third row of P = K R [I | -C] is r3 (X - C): the depth in metres.
        depth = X @ P[2, :2] + P[2, 3]
    return float(np.mean(np.isfinite(depth) & (depth > 0)))


def stacked_residuals(batches: Sequence[Sequence[tuple[np.ndarray, Observations, CameraParametrisation]]]
                      ) -> list[list[np.ndarray]]:
    """:func:`residuals` of many requests in few vectorised calls.

    Each request ``(x, obs, param)`` asks for ``residuals(x, obs, param)``, ``x`` one (k,) vector or
    a (B, k) batch. Requests on the same ``obs`` object whose parametrisations agree in shape
    (radial term or not, centre fixed or free, principal point) are stacked into one call with a
    per-row reference rotation and centre; every row is computed with exactly the arithmetic of its
    own call (element-wise operations and one small matrix product per row), so the answers equal
    the separate calls'. Used to fit one frame at every position of its game's rig at once
    (``app.geometry.calibration.frame.calibrate_frames_together``).

    Args:
        batches: lists of requests (one list per caller).

    Returns:
        Per list, per request, the residuals ``residuals(x, obs, param)`` would return, pixels.
    """
    groups: dict[tuple, list[tuple[int, int, np.ndarray, CameraParametrisation]]] = {}
    out: list[list[np.ndarray]] = [[None] * len(b) for b in batches]  # type: ignore[list-item]
    for i, batch in enumerate(batches):
        for j, (x, obs, param) in enumerate(batch):
            key = (id(obs), param.fit_k1, param.fixed_centre is None, tuple(np.asarray(param.principal_point).tolist()))
            groups.setdefault(key, []).append((i, j, np.asarray(x, dtype=float), param))
    for members in groups.values():
        obs = batches[members[0][0]][members[0][1]][1]
        first = members[0][3]
        X = np.concatenate([x.reshape(-1, x.shape[-1]) for _, _, x, _ in members])
        rows = [len(x) if x.ndim == 2 else 1 for _, _, x, _ in members]
        R0 = np.repeat(np.stack([p.R0 for _, _, _, p in members]), rows, axis=0)
        R_all = rotation_from_vector(X[:, 1:4]) @ R0  # row by row as CameraParametrisation.split
        # The projection matrices member by member, from the very arrays each separate call uses
        # (numpy's einsum rounds a row differently depending on its place in a batch).
        Ps, start = [], 0
        for (_, _, x, p), n in zip(members, rows):
            f = x[..., 0]
            C = x[..., 4:7] if p.fixed_centre is None else np.broadcast_to(p.fixed_centre, x.shape[:-1] + (3,))
            R = R_all[start:start + n] if x.ndim == 2 else R_all[start]
            P = projection_matrix(f, p.principal_point, R, C)
            Ps.append(P if x.ndim == 2 else P[None])
            start += n
        k1 = X[:, -1] if first.fit_k1 else np.zeros(len(X))
        r = _weighted_distances(np.concatenate(Ps), X[:, 0], k1, obs, first)
        start = 0
        for (i, j, x, _), n in zip(members, rows):
            out[i][j] = r[start] if x.ndim == 1 else r[start:start + n]
            start += n
    return out
