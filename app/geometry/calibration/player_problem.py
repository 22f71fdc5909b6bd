"""One view's players' least squares, as :mod:`~app.geometry.calibration.players` fits it: the residual rows of a
camera's parameter vectors (the foot points of the players whose feet are in the image, the field lines', the head
points'), each point whitened by its covariance under the camera, their forward-difference Jacobian and the robust
Levenberg-Marquardt over them (soft-L1 loss, iteratively reweighted).

A fit has 10-30 iterations over a few dozen rows, and a placement makes thousands of fits: numpy's per-call overhead
was their time, not the arithmetic. The players' rows of a batch of vectors are therefore one compiled call
(:func:`_player_rows`), the whole robust fit another (:func:`_robust_fit`, the lines' rows through the line fit's own
kernel, :func:`~app.geometry.calibration.residuals._residual_rows`), and the whitening's finite differences project
every point they need in one call. The compiled fit computes what numpy's did, to rounding (the same decisions and
cameras within 1e-7 relative on two tuning sets' placements, ``benchmarks/placement_cpu.py --against``).

World frame: SoccerNet (metres, origin at the centre spot, z down); image: continuous pixels of the view, origin at
the top-left corner. A player's foot point is :func:`~.grass.foot_world`'s point, its head point
:func:`~.grass.head_world`'s.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from numba import njit

from app.geometry.annotations import FieldLines
from app.geometry.calibration.grass import (
    FOOT_OFFSET_M,
    FOOT_SIGMA_PX,
    HEAD_HEIGHT_M,
    HEAD_OFFSET_M,
    HEAD_SIGMA_M,
    foot_world,
    head_world,
)
from app.geometry.calibration.observations import build_observations
from app.geometry.calibration.residuals import JIT, CameraParametrisation, _residual_rows, residuals, rotation_into


def projection_sigma_px(problem_rows: PlayerProblem, param: CameraParametrisation, x: np.ndarray, cov: np.ndarray,
                        world: np.ndarray) -> float:
    """The largest pixel uncertainty (px of the view) of the world points ``world`` (n, 3) under a fit's parameter
    covariance ``cov`` (k, k): ``sqrt(trace(J cov J^T))`` per point with ``J`` the (2, k) Jacobian of its projection
    (first-order propagation, Hartley and Zisserman result 5.6); ``inf`` when ``cov`` is not finite."""
    if not np.all(np.isfinite(cov)):
        return math.inf
    steps = forward_steps(x, param)
    f, R, C, _ = param.split(x)
    uv0 = project_points(float(f), R, np.asarray(C, float), problem_rows.pp, world)
    cols = []
    for j in range(len(x)):
        fj, Rj, Cj, _ = param.split(x + np.eye(len(x))[j] * steps[j])
        cols.append((project_points(float(fj), Rj, np.asarray(Cj, float), problem_rows.pp, world) - uv0) / steps[j])
    J = np.stack(cols, axis=-1)  # (n, 2, k)
    var = np.einsum("nik,kl,nil->n", J, cov, J)
    return float(np.sqrt(np.max(var))) if len(var) else math.inf


def forward_steps(x: np.ndarray, param: CameraParametrisation) -> np.ndarray:
    """Forward-difference steps of a parameter vector: focal (relative), rotation vector (rad), centre (m)."""
    steps = np.full(len(x), 1e-7)
    steps[0] = 1e-6 * x[0]
    if param.fixed_centre is None:
        steps[4:7] = 1e-5
    return steps


def project_points(f: float, R: np.ndarray, C: np.ndarray, pp: np.ndarray, world: np.ndarray) -> np.ndarray:
    """(n, 2) pixels of the ground points ``world`` (n, 3); a point behind the camera lands far away."""
    Xc = (world - C) @ R.T
    z = Xc[:, 2]
    bad = z <= 1e-6
    z = np.where(bad, 1.0, z)
    uv = f * Xc[:, :2] / z[:, None] + pp
    uv[bad] = 1e6
    return uv


@njit(**JIT)
def _player_rows(X: np.ndarray, R0: np.ndarray, fixed: bool, centre: np.ndarray, rel: np.ndarray, grass: np.ndarray,
                 up: np.ndarray, offset: np.ndarray, observed: np.ndarray, L: np.ndarray, pp: np.ndarray) -> np.ndarray:
    """The players' residual rows (b, 2 q) of the vectors ``X`` (b, k) (``[f, w (, C)]``, rotation ``exp([w]x) R0``):
    each point's projection less its ``observed`` pixel (q, 2), times its whitening ``L`` (q, 2, 2). A point is
    ``up`` (q,) m above its ``grass`` point (q, 2), moved ``offset`` (q,) m towards the camera along the ground
    (:func:`~.grass.foot_world`, :func:`~.grass.head_world` with a negative offset); with a ``fixed`` centre
    (3,) the points less it are given (``rel``, (q, 3)). A point behind the camera projects to 1e6 px."""
    q = grass.shape[0]
    out = np.empty((X.shape[0], 2 * q))
    R = np.empty((3, 3))
    for b in range(X.shape[0]):
        f = X[b, 0]
        rotation_into(X[b, 1], X[b, 2], X[b, 3], R0, R)
        if fixed:
            cx, cy, cz = centre[0], centre[1], centre[2]
        else:
            cx, cy, cz = X[b, 4], X[b, 5], X[b, 6]
        for i in range(q):
            if fixed:
                px, py, pz = rel[i, 0], rel[i, 1], rel[i, 2]
            else:
                tx, ty = cx - grass[i, 0], cy - grass[i, 1]
                norm = math.sqrt(tx * tx + ty * ty)
                if not norm > 1e-9:
                    norm = 1.0
                px = grass[i, 0] + offset[i] * tx / norm - cx
                py = grass[i, 1] + offset[i] * ty / norm - cy
                pz = -up[i] - cz
            xc = R[0, 0] * px + R[0, 1] * py + R[0, 2] * pz
            yc = R[1, 0] * px + R[1, 1] * py + R[1, 2] * pz
            zc = R[2, 0] * px + R[2, 1] * py + R[2, 2] * pz
            if zc <= 1e-6:
                u, v = 1e6, 1e6
            else:
                u, v = f * xc / zc + pp[0], f * yc / zc + pp[1]
            du, dv = u - observed[i, 0], v - observed[i, 1]
            out[b, 2 * i] = L[i, 0, 0] * du + L[i, 0, 1] * dv
            out[b, 2 * i + 1] = L[i, 1, 0] * du + L[i, 1, 1] * dv
    return out


@dataclass
class PlayerProblem:
    """One view's fit: its players' grass points, the foot pixels of those whose feet are in the image, its line
    observations, the scales, and the head pixels of the players whose box top is in the image (a player whose feet
    the image's bottom edge cuts is fitted by its head alone). Residual rows: the foot points' (x, y), the lines', the
    heads'."""

    uv: np.ndarray          # (f, 2) foot pixels, of the players ``foot_of``
    world: np.ndarray       # (n, 3) grass points, z = 0, of every player
    lines: FieldLines
    pp: np.ndarray
    width: int
    height: int
    scale: float            # px of the view per px@1920
    cov_g: np.ndarray       # (n, 2, 2) covariance of each grass point, m^2
    uv_head: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))  # (h, 2) head pixels
    head_of: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=int))  # (h,) their players' indices
    foot_of: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=int))  # (f,) the foot points' players

    def __post_init__(self) -> None:
        if len(self.foot_of) != len(self.uv):  # not given: every player has its foot point, in order
            self.foot_of = np.arange(len(self.uv))
        self.feet_m = self.world[self.foot_of]  # (f, 3) the grass points of the players with a foot point
        self.obs = build_observations(self.lines) if self.lines else None
        if self.obs is not None and self.obs.n_points == 0:
            self.obs = None
        self.sigma_px = FOOT_SIGMA_PX * self.scale
        self.line_sigma = max(1.0, self.scale)  # annotation clicks (:data:`.uncertainty.MIN_LINE_NOISE_PX` at 1920)
        self.L = np.repeat(np.eye(2)[None] / self.sigma_px, len(self.uv), axis=0)
        self.L_head = np.repeat(np.eye(2)[None] / self.sigma_px, len(self.uv_head), axis=0)
        self._feet_cache: dict[bytes, np.ndarray] = {}
        self._heads_cache: dict[bytes, np.ndarray] = {}
        self._points_cache: dict[bytes, np.ndarray] = {}
        # The foot then head points as :func:`_player_rows` reads them: grass point, height above it, offset
        # towards the camera along the ground (m), observed pixel. Only the players with a foot point have foot rows.
        f, head_g = len(self.uv), self.world[self.head_of, :2]
        self._grass = np.ascontiguousarray(np.concatenate([self.feet_m[:, :2], head_g]), dtype=float)
        self._up = np.concatenate([np.zeros(f), np.full(len(head_g), HEAD_HEIGHT_M)])
        self._offset = np.concatenate([np.full(f, FOOT_OFFSET_M), np.full(len(head_g), -HEAD_OFFSET_M)])
        self._observed = np.ascontiguousarray(np.concatenate([self.uv, self.uv_head]).reshape(-1, 2), dtype=float)
        self._whitening_of: tuple[np.ndarray, np.ndarray] | None = None
        self._whitening_cache = np.zeros((0, 2, 2))
        self._unit: np.ndarray | None = None
        # What :meth:`rewhiten` reads that no camera changes: the grass points and their 0.01 m neighbours (the
        # differences' points), the covariances, the pixel noise (made once: a placement rewhitens thousands of times).
        g, gh = self.feet_m[:, :2], self.world[self.head_of, :2]
        dx, dy = np.array([0.01, 0.0]), np.array([0.0, 0.01])
        self._feet_grid = np.concatenate([g, g + dx, g + dy])
        self._heads_grid = np.concatenate([gh, gh + dx, gh + dy])
        self._cov_feet = self.cov_g[self.foot_of]
        self._cov_heads = np.zeros((len(gh), 3, 3))
        self._cov_heads[:, :2, :2] = self.cov_g[self.head_of]
        self._cov_heads[:, 2, 2] = HEAD_SIGMA_M**2
        self._noise = self.sigma_px**2 * np.eye(2)

    def rewhiten(self, x: np.ndarray, param: CameraParametrisation) -> None:
        """Whiten each foot point's residual by its covariance under the camera ``x``: its own pixel noise and its
        grass point's covariance carried into this view (``J cov_g J^T + sigma^2 I``, ``J`` the projection's
        Jacobian with respect to the ground point, by forward differences of 0.01 m); the head points' likewise,
        with the box top's height (:data:`HEAD_SIGMA_M`) too. Every point the differences need is projected in one
        call (a fit's time was the calls)."""
        f_arr, R, C_arr, _ = param.split(x)
        f, C = float(f_arr), np.asarray(C_arr, float)
        n, h = len(self.feet_m), len(self.head_of)
        heads = head_world(self._heads_grid, C)
        up = heads[:h].copy()
        up[:, 2] = -(HEAD_HEIGHT_M + 0.01)
        feet = foot_world(self._feet_grid, C)
        uv = project_points(f, R, C, self.pp, np.concatenate([feet, heads, up]))
        feet_uv, head_uv = uv[:3 * n].reshape(3, n, 2), uv[3 * n:].reshape(4, h, 2)
        J = np.stack([(feet_uv[1] - feet_uv[0]) / 0.01, (feet_uv[2] - feet_uv[0]) / 0.01], axis=-1)
        cov = np.einsum("nij,njk,nlk->nil", J, self._cov_feet, J) + self._noise
        try:
            self.L = np.linalg.inv(np.linalg.cholesky(cov))
        except np.linalg.LinAlgError:
            self.L = np.repeat(np.eye(2)[None] / self.sigma_px, n, axis=0)
        if h:
            self.L_head = self._head_whitening(np.stack([(head_uv[k] - head_uv[0]) / 0.01 for k in (1, 2, 3)], axis=-1))

    def _head_whitening(self, J: np.ndarray) -> np.ndarray:
        """(h, 2, 2) whitening of the head points from ``J`` (h, 2, 3), their projections' Jacobian with respect to
        their grass point and height: their pixel noise, their grass point's covariance and the box top's height
        (:data:`HEAD_SIGMA_M`) carried into this view."""
        h = len(J)
        cov = np.einsum("nij,njk,nlk->nil", J, self._cov_heads, J) + self._noise
        try:
            return np.asarray(np.linalg.inv(np.linalg.cholesky(cov)))
        except np.linalg.LinAlgError:
            return np.repeat(np.eye(2)[None] / self.sigma_px, h, axis=0)

    def pixel_errors(self, x: np.ndarray, param: CameraParametrisation) -> tuple[np.ndarray, np.ndarray]:
        """Each foot point's distance (px) from its player's projection, and in its standard deviations."""
        r = self.rows_batch(np.asarray(x, float)[None], param, whiten=False)[0][:2 * len(self.uv)].reshape(-1, 2)
        return np.linalg.norm(r, axis=1), np.linalg.norm(np.einsum("nij,nj->ni", self.L, r), axis=1)

    def player_errors(self, x: np.ndarray, param: CameraParametrisation) -> tuple[np.ndarray, np.ndarray]:
        """Each player's distance (px) from its projection, and in its standard deviations (n,): its foot point's
        (:meth:`pixel_errors`), or its head point's for a player seen without its feet."""
        px, d = np.full(len(self.world), np.inf), np.full(len(self.world), np.inf)
        px[self.foot_of], d[self.foot_of] = self.pixel_errors(x, param)
        alone = self.head_alone()
        if alone.any():
            raw = self.rows_batch(np.asarray(x, float)[None], param, whiten=False)[0][-2 * len(self.uv_head):]
            raw = raw.reshape(-1, 2)[alone]
            px[self.head_of[alone]] = np.linalg.norm(raw, axis=1)
            d[self.head_of[alone]] = np.linalg.norm(np.einsum("nij,nj->ni", self.L_head[alone], raw), axis=1)
        return px, d

    def head_alone(self) -> np.ndarray:
        """(h,) whether each head point's player has no foot point (its feet cut by the image's bottom edge)."""
        return ~np.isin(self.head_of, self.foot_of)

    def rows(self, x: np.ndarray, param: CameraParametrisation) -> np.ndarray:
        """Every whitened residual of one vector ``x``: the foot points' (x, y), the lines', the head points'."""
        return self.rows_batch(np.asarray(x, float)[None], param)[0]

    def _feet_from(self, centre: np.ndarray) -> np.ndarray:
        """The foot points' world points (:func:`foot_world`) less a fixed ``centre`` (3,), (n, 3) m: at a rig
        position they do not move with the parameters, so each position's are made once."""
        key = np.asarray(centre, float).tobytes()
        got = self._feet_cache.get(key)
        if got is None:
            got = self._feet_cache[key] = foot_world(self.feet_m[:, :2], centre) - np.asarray(centre, float)
        return got

    def _heads_from(self, centre: np.ndarray) -> np.ndarray:
        """The head points' world points (:func:`head_world`) less a fixed ``centre`` (3,), (h, 3) m, made once per
        rig position as :meth:`_feet_from`."""
        key = np.asarray(centre, float).tobytes()
        got = self._heads_cache.get(key)
        if got is None:
            got = self._heads_cache[key] = (head_world(self.world[self.head_of, :2], centre)
                                            - np.asarray(centre, float))
        return got

    def rows_batch(self, X: np.ndarray, param: CameraParametrisation, whiten: bool = True) -> np.ndarray:
        """:meth:`rows` of the vectors ``X`` (b, k) at once -> (b, 2 f + m + 2 h) (f foot points, m line rows, h head
        points): whitened (the foot and head points' by :meth:`rewhiten`, the lines' by their click noise), or in px.
        The players' rows in one compiled call (:func:`_player_rows`), the lines' in another: a fit's time was the
        calls, not their arithmetic."""
        X = np.ascontiguousarray(X, dtype=float)
        n, h = len(self.uv), len(self.uv_head)
        fixed = param.fixed_centre is not None
        if fixed:
            centre = np.asarray(param.fixed_centre, float)
            rel = self._points_from(centre)
        else:
            centre, rel = np.zeros(3), np.zeros((n + h, 3))
        L = self._whitening() if whiten else self._unit_whitening()
        players = _player_rows(X, np.ascontiguousarray(param.R0, dtype=float), fixed, centre, rel, self._grass,
                               self._up, self._offset, self._observed, L, np.asarray(self.pp, float))
        if self.obs is None:
            return players
        lr = residuals(X, self.obs, param).reshape(len(X), -1)
        return np.concatenate([players[:, :2 * n], lr / self.line_sigma if whiten else lr, players[:, 2 * n:]], axis=1)

    def _points_from(self, centre: np.ndarray) -> np.ndarray:
        """The foot then head points' world points less a fixed ``centre`` (n + h, 3) m (:meth:`_feet_from`,
        :meth:`_heads_from`), made once per rig position."""
        key = np.asarray(centre, float).tobytes()
        got = self._points_cache.get(key)
        if got is None:
            got = self._points_cache[key] = np.ascontiguousarray(
                np.concatenate([self._feet_from(centre), self._heads_from(centre)]), dtype=float)
        return got

    def _whitening(self) -> np.ndarray:
        """The foot then head points' whitening (n + h, 2, 2), as :meth:`rewhiten` last set it."""
        made = self._whitening_of
        if made is None or made[0] is not self.L or made[1] is not self.L_head:
            self._whitening_cache = np.ascontiguousarray(np.concatenate([self.L, self.L_head]), dtype=float)
            self._whitening_of = (self.L, self.L_head)
        return self._whitening_cache

    def _unit_whitening(self) -> np.ndarray:
        """Identity whitening (n + h, 2, 2): the rows in px."""
        if self._unit is None:
            self._unit = np.ascontiguousarray(np.repeat(np.eye(2)[None], len(self.uv) + len(self.uv_head), axis=0))
        return self._unit

    def jacobian(self, x: np.ndarray, param: CameraParametrisation) -> tuple[np.ndarray, np.ndarray]:
        """The residuals (m,) at ``x`` and their forward-difference Jacobian (m, k), in one batched evaluation."""
        steps = forward_steps(x, param)
        X = np.vstack([x, x + np.diag(steps)])
        rr = self.rows_batch(X, param)
        return rr[0], ((rr[1:] - rr[0]) / steps[:, None]).T

    def fit(self, param: CameraParametrisation, x0: np.ndarray, loss_px: float,
            iterations: int = 30) -> tuple[np.ndarray, float]:
        """Robust Levenberg-Marquardt from ``x0`` (iteratively reweighted, soft-L1 loss of scale ``loss_px``, as
        ``scipy.optimize.least_squares(loss="soft_l1")`` defines it; :func:`_robust_fit`, one compiled call: a fit
        has 10-30 iterations of a few dozen rows, where numpy's per-call overhead was the time): the vector and its
        robust cost."""
        fixed = param.fixed_centre is not None
        centre = np.asarray(param.fixed_centre, float) if fixed else np.zeros(3)
        rel = self._points_from(centre) if fixed else np.zeros((len(self.uv) + len(self.uv_head), 3))
        obs = self.obs.kernel_arrays if self.obs is not None else _NO_LINES
        x, cost = _robust_fit(np.array(x0, dtype=float), float(loss_px), iterations,
                              np.ascontiguousarray(param.R0, dtype=float), fixed, centre, rel, self._grass, self._up,
                              self._offset, self._observed, self._whitening(), np.asarray(self.pp, float),
                              self.obs is not None, obs, float(self.line_sigma), 2 * len(self.uv))
        return x, float(cost)


#: The observations' kernel arrays of a view without lines (``Observations.kernel_arrays``' types, empty).
_NO_LINES = (np.zeros((0, 3)), np.zeros((0, 3)), np.zeros(0, dtype=np.int64), np.zeros((0, 2)), np.zeros(0),
             np.zeros(0), np.zeros(0), np.zeros(0), np.zeros((0, 2)), np.zeros(0))


@njit(**JIT)
def _fit_rows(X: np.ndarray, R0: np.ndarray, fixed: bool, centre: np.ndarray, rel: np.ndarray, grass: np.ndarray,
              up: np.ndarray, offset: np.ndarray, observed: np.ndarray, L: np.ndarray, pp: np.ndarray, lines: bool,
              obs: tuple, line_sigma: float, n2: int) -> np.ndarray:
    """Every whitened residual row of the vectors ``X`` (b, k): the feet's (the first ``n2`` of
    :func:`_player_rows`), the lines' (``residuals._residual_rows`` over ``line_sigma``), the heads'."""
    players = _player_rows(X, R0, fixed, centre, rel, grass, up, offset, observed, L, pp)
    if not lines:
        return players
    b = X.shape[0]
    R0s = np.empty((b, 3, 3))
    centres = np.empty((b, 3))
    for i in range(b):
        R0s[i] = R0
        centres[i] = centre
    lr = _residual_rows(X, R0s, centres, pp, fixed, False, obs)
    out = np.empty((b, players.shape[1] + lr.shape[1]))
    out[:, :n2] = players[:, :n2]
    out[:, n2:n2 + lr.shape[1]] = lr / line_sigma
    out[:, n2 + lr.shape[1]:] = players[:, n2:]
    return out


@njit(**JIT)
def _fit_jacobian(x: np.ndarray, R0: np.ndarray, fixed: bool, centre: np.ndarray, rel: np.ndarray,
                  grass: np.ndarray, up: np.ndarray, offset: np.ndarray, observed: np.ndarray, L: np.ndarray,
                  pp: np.ndarray, lines: bool, obs: tuple, line_sigma: float, n2: int) -> tuple:
    """The rows at ``x`` and their forward-difference Jacobian (:func:`forward_steps`' steps), as
    :meth:`PlayerProblem.jacobian`."""
    k = x.shape[0]
    steps = np.full(k, 1e-7)
    steps[0] = 1e-6 * x[0]
    if not fixed:
        steps[4:7] = 1e-5
    X = np.empty((k + 1, k))
    for i in range(k + 1):
        X[i] = x
    for j in range(k):
        X[j + 1, j] = x[j] + steps[j]
    rr = _fit_rows(X, R0, fixed, centre, rel, grass, up, offset, observed, L, pp, lines, obs, line_sigma, n2)
    J = np.empty((rr.shape[1], k))
    for j in range(k):
        J[:, j] = (rr[j + 1] - rr[0]) / steps[j]
    return rr[0].copy(), J


@njit(**JIT)
def _soft_l1_cost(r: np.ndarray, loss: float) -> float:
    z = (r / loss) ** 2
    return 0.5 * loss**2 * np.sum(2.0 * (np.sqrt(1.0 + z) - 1.0))


@njit(**JIT)
def _robust_fit(x0: np.ndarray, loss: float, iterations: int, R0: np.ndarray, fixed: bool, centre: np.ndarray,
                rel: np.ndarray, grass: np.ndarray, up: np.ndarray, offset: np.ndarray, observed: np.ndarray,
                L: np.ndarray, pp: np.ndarray, lines: bool, obs: tuple, line_sigma: float, n2: int) -> tuple:
    """``PlayerProblem.fit``: robust Levenberg-Marquardt (iteratively reweighted, soft-L1 loss of scale ``loss``) of the
    players' and lines' rows (:func:`_fit_rows`) from ``x0``; the trial step and its Jacobian in one evaluation
    (nearly every step is taken). Returns the vector and its robust cost."""
    x = x0.copy()
    r, J = _fit_jacobian(x, R0, fixed, centre, rel, grass, up, offset, observed, L, pp, lines, obs, line_sigma, n2)
    cost, lam = _soft_l1_cost(r, loss), 1e-3
    k = x.shape[0]
    for _ in range(iterations):
        w = 1.0 / np.sqrt(1.0 + (r / loss) ** 2)  # the soft-L1 loss's weights (IRLS)
        JW = np.ascontiguousarray((J * w.reshape(-1, 1)).T)
        A = JW @ J
        g = JW @ r
        M = A.copy()
        for j in range(k):
            M[j, j] = A[j, j] + lam * max(A[j, j], 1e-12)
        if not np.all(np.isfinite(M)) or not np.all(np.isfinite(g)):
            # numpy's solve gives NaN here, a step never taken: the fit stays where it is.
            break
        try:
            dx = -np.linalg.solve(M, g)
        except Exception:  # singular
            break
        x_new = x + dx
        r_new, J_new = _fit_jacobian(x_new, R0, fixed, centre, rel, grass, up, offset, observed, L, pp, lines, obs,
                                     line_sigma, n2)
        new = _soft_l1_cost(r_new, loss)
        if np.isfinite(new) and new < cost:
            small = cost - new < 1e-9 * max(cost, 1e-12) or np.linalg.norm(dx) < 1e-10 * (np.linalg.norm(x) + 1e-10)
            x, cost, lam = x_new, new, max(lam / 3.0, 1e-9)
            if small:
                break
            r, J = r_new, J_new
        else:
            lam *= 4.0
            if lam > 1e8:
                break
    return x, cost
