"""Players place the cameras the lines cannot: a camera fitted to the foot points of the players its view shares
with the well-calibrated views of its system, at a position of the game's camera rig where one fits.

SoccerNet-v3 annotates the players of a multi-view system with a class and an ID across its views (one instant
seen by several cameras). A player stands on the grass: the bottom centre of its box (the foot point) back-projected
to the ground plane ``z = 0`` in a calibrated view is where it stands (:func:`grass_point`); fused over the
well-calibrated views that see it (:func:`players_on_grass`, the median, a player whose views disagree by more
than ``max_spread_m`` left out: a wrong ID). A view whose lines give no camera, or an unsure one, is then fitted to
its own foot points of those players (:func:`fit_camera_to_players`, robust least squares, soft-L1 loss): with its
centre at one of the game's rig positions (broadcast cameras stay put during a game) only rotation and focal length
are unknown, which two foot points fix and more over-determine; every position is tried and the best by residual
kept only with a margin over any other position elsewhere; without a position that fits, a full pose (7 unknowns)
when enough players are seen. The top of each whole box (the head point, :func:`~.grass.head_world`: a standing
player's height above where it stands) joins the fit too: players standing close together fix the camera's direction
but leave its zoom loose, which their boxes' heights in the image pin. Whatever field lines the view has join the same
least squares with their own residuals (:func:`app.geometry.calibration.residuals.residuals`). The ball is never an
input.

The camera carries its uncertainty from the fit (:func:`~.uncertainty.uncertainty_from_jacobian`: the
Gauss-Newton covariance of the parameters from the Jacobian of every residual, Hartley and Zisserman result 5.11),
the same :class:`~.uncertainty.CalibrationUncertainty` a line fit carries. The fit is refused (:class:`PlayerRefusal`)
when too few players are matched, their foot points lie on one image line, the residuals are large, a second rig
position fits nearly as well, or the propagated pixel uncertainty is large: a wrong camera is worse than none.

World frame: SoccerNet (metres, origin at the centre spot, z down); image: continuous pixels of the view, origin at
the top-left corner, principal point ``((W - 1) / 2, (H - 1) / 2)`` (:func:`~.result.principal_point`).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Mapping, Sequence

import cv2
import numpy as np
from numba import njit

from app.geometry.annotations import FieldLines, image_diagonal
from app.geometry.calibration.grass import (
    FOOT_OFFSET_M,
    FOOT_SIGMA_PX,
    HEAD_HEIGHT_M,
    HEAD_OFFSET_M,
    HEAD_SIGMA_M,
    GrassPlayer,
    PlayerKey,
    foot_world,
    head_world,
)
from app.geometry.calibration.initialisation import camera_from_homography, wahba_rotation
from app.geometry.calibration.observations import build_observations
from app.geometry.calibration.residuals import JIT, CameraParametrisation, _residual_rows, residuals, rotation_into
from app.geometry.calibration.result import principal_point
from app.geometry.calibration.uncertainty import (
    CalibrationUncertainty,
    line_noise,
    parameter_covariance,
    uncertainty_from_jacobian,
)
from app.geometry.camera import Camera
from app.geometry.pair_error import REFERENCE_WIDTH_PX
from app.geometry.pitch import MIN_LINE_CLASSES


@dataclass(frozen=True)
class PlayerFitSettings:
    """Thresholds of :func:`fit_camera_to_players`; pixels at a 1920-px-wide image (scaled to the view's width).

    Attributes:
        min_players_rig: fewest players matched for a fit at a rig position (4 unknowns; two players fix them).
        min_players_free: fewest players for a full pose (7 unknowns) without a rig position that fits.
        loss_scale: soft-L1 loss scale of a foot point's residual, in its standard deviations (each foot point's
            residual is whitened by what its own box and where the other views put the player allow,
            :func:`players_on_grass`).
        max_rms: largest RMS whitened residual of the inlying foot points of an accepted fit.
        inlier_sigma: a foot point farther than this many standard deviations from its player's projection is an
            outlier.
        min_inlier_share: smallest share of the matched players that must be inliers.
        rig_margin: a rig position is chosen only when every other position more than ``rig_same_m`` away fits
            with a robust cost at least this many times the best's.
        rig_same_m: positions closer than this (m) count as the same place.
        rig_refined: the rig positions whose starts come closest that are refined (the others cannot win).
        max_sigma_px: largest pixel uncertainty (px@1920) accepted of a point where the play is (the players'
            centre on the grass and 3 m up, :func:`projection_sigma_px`), the players' own uncertainty included.
        min_spread_px: the points the fit reads (foot and head points) must spread at least this far (px@1920, the
            smaller singular value of their centred pixels over sqrt(n)) off one image line: players standing in
            a row have their feet on one line, but their heads stand above it.
        line_limit_gamma: every fitted line class within this fraction of the image diagonal of its model
            element (as a line fit's ``refuse_gamma``).
        border_px: a box reaching within this many pixels of the image's bottom edge is cut: no foot point.
    """

    min_players_rig: int = 3
    min_players_free: int = 6
    loss_scale: float = 2.0
    max_rms: float = 2.5
    inlier_sigma: float = 4.0
    min_inlier_share: float = 0.7
    rig_margin: float = 3.0
    rig_refined: int = 3
    rig_same_m: float = 5.0
    max_sigma_px: float = 10.0
    min_spread_px: float = 4.0
    line_limit_gamma: float = 0.03
    border_px: float = 2.0


@dataclass(frozen=True)
class PlayerFit:
    """An accepted camera from players.

    Attributes:
        camera: the camera (pixels of the view, SoccerNet world).
        uncertainty: std of its parameters from the fit (a rig position's centre: position std 0).
        rig_index: the index of the rig position its centre is fixed at (``None``: a full pose).
        players: ``(key, foot pixel (2,), grass point (2,) m)`` of every player the fit used (inliers).
        rms_px: RMS residual of those foot points (px of the view).
        residuals_px: per fitted line class, its largest point distance (px of the view).
        line_rms_px: RMS of the line residuals (px), None without lines.
        sigma_px: the largest pixel uncertainty (px@1920) of a point where the players stand, on the grass or 3 m
            up (:func:`projection_sigma_px`).
    """

    camera: Camera
    uncertainty: CalibrationUncertainty
    rig_index: int | None
    players: tuple[tuple[PlayerKey, tuple[float, float], tuple[float, float]], ...]
    rms_px: float
    residuals_px: Mapping[str, float] = field(default_factory=dict)
    line_rms_px: float | None = None
    sigma_px: float = 0.0


#: Why :func:`fit_camera_to_players` refused: too few players matched, their foot points on one image line, no
#: fit within the residual limits, two rig positions fitting alike, a camera too unsure.
PLAYER_REFUSALS: tuple[str, ...] = ("few_players", "collinear_players", "players_misfit", "rig_ambiguous",
                                    "camera_unsure", "lines_admitted")


@dataclass(frozen=True)
class PlayerRefusal:
    """Why :func:`fit_camera_to_players` gave no camera: ``code`` (one of :data:`PLAYER_REFUSALS`), its numbers."""

    code: str
    numbers: Mapping[str, float] = field(default_factory=dict)


def projection_sigma_px(problem_rows: "_Problem", param: CameraParametrisation, x: np.ndarray, cov: np.ndarray,
                        world: np.ndarray) -> float:
    """The largest pixel uncertainty (px of the view) of the world points ``world`` (n, 3) under a fit's parameter
    covariance ``cov`` (k, k): ``sqrt(trace(J cov J^T))`` per point with ``J`` the (2, k) Jacobian of its projection
    (first-order propagation, Hartley and Zisserman result 5.6); ``inf`` when ``cov`` is not finite."""
    if not np.all(np.isfinite(cov)):
        return math.inf
    steps = _steps(x, param)
    f, R, C, _ = param.split(x)
    uv0 = _project(float(f), R, np.asarray(C, float), problem_rows.pp, world)
    cols = []
    for j in range(len(x)):
        fj, Rj, Cj, _ = param.split(x + np.eye(len(x))[j] * steps[j])
        cols.append((_project(float(fj), Rj, np.asarray(Cj, float), problem_rows.pp, world) - uv0) / steps[j])
    J = np.stack(cols, axis=-1)  # (n, 2, k)
    var = np.einsum("nik,kl,nil->n", J, cov, J)
    return float(np.sqrt(np.max(var))) if len(var) else math.inf


def _steps(x: np.ndarray, param: CameraParametrisation) -> np.ndarray:
    """Forward-difference steps of a parameter vector: focal (relative), rotation vector (rad), centre (m)."""
    steps = np.full(len(x), 1e-7)
    steps[0] = 1e-6 * x[0]
    if param.fixed_centre is None:
        steps[4:7] = 1e-5
    return steps


def _project(f: float, R: np.ndarray, C: np.ndarray, pp: np.ndarray, world: np.ndarray) -> np.ndarray:
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
class _Problem:
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

    def rewhiten(self, x: np.ndarray, param: CameraParametrisation) -> None:
        """Whiten each foot point's residual by its covariance under the camera ``x``: its own pixel noise and its
        grass point's covariance carried into this view (``J cov_g J^T + sigma^2 I``, ``J`` the projection's
        Jacobian with respect to the ground point, by forward differences of 0.01 m); the head points' likewise,
        with the box top's height (:data:`HEAD_SIGMA_M`) too. Every point the differences need is projected in one
        call (a fit's time was the calls)."""
        f_arr, R, C_arr, _ = param.split(x)
        f, C = float(f_arr), np.asarray(C_arr, float)
        g, gh = self.feet_m[:, :2], self.world[self.head_of, :2]
        n, h = len(g), len(gh)
        dx, dy = np.array([0.01, 0.0]), np.array([0.0, 0.01])
        heads = head_world(np.concatenate([gh, gh + dx, gh + dy]), C)
        up = heads[:h].copy()
        up[:, 2] = -(HEAD_HEIGHT_M + 0.01)
        uv = _project(f, R, C, self.pp, np.concatenate([foot_world(np.concatenate([g, g + dx, g + dy]), C), heads, up]))
        feet_uv, head_uv = uv[:3 * n].reshape(3, n, 2), uv[3 * n:].reshape(4, h, 2)
        J = np.stack([(feet_uv[1] - feet_uv[0]) / 0.01, (feet_uv[2] - feet_uv[0]) / 0.01], axis=-1)
        cov = np.einsum("nij,njk,nlk->nil", J, self.cov_g[self.foot_of], J) + self.sigma_px**2 * np.eye(2)
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
        cov_p = np.zeros((h, 3, 3))
        cov_p[:, :2, :2] = self.cov_g[self.head_of]
        cov_p[:, 2, 2] = HEAD_SIGMA_M**2
        cov = np.einsum("nij,njk,nlk->nil", J, cov_p, J) + self.sigma_px**2 * np.eye(2)
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
        """Every residual (px) of one vector ``x``: the foot points' (x, y) then the lines'."""
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
        """:meth:`rows` of the vectors ``X`` (b, k) at once -> (b, 2 n + m + 2 h): whitened (the foot and head points'
        by :meth:`rewhiten`, the lines' by their click noise), or in px. The players' rows in one compiled call
        (:func:`_player_rows`), the lines' in another: a fit's time was the calls, not their arithmetic."""
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
        steps = _steps(x, param)
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
    """The rows at ``x`` and their forward-difference Jacobian (:func:`_steps`' steps), as ``_Problem.jacobian``."""
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
    """``_Problem.fit``: robust Levenberg-Marquardt (iteratively reweighted, soft-L1 loss of scale ``loss``) of the
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


def _rig_starts(problem: _Problem, centre: np.ndarray
                ) -> tuple[float, list[tuple[CameraParametrisation, np.ndarray]]]:
    """Starting rotations and focal lengths at a fixed ``centre``: for a series of focal lengths, the Wahba rotation
    of the foot points' image rays onto their world directions; the two with the smallest median reprojection error
    (px), and that error."""
    alone = problem.head_alone()
    world = np.vstack([foot_world(problem.feet_m[:, :2], centre),
                       head_world(problem.world[problem.head_of[alone], :2], centre)])
    seen = np.vstack([problem.uv, problem.uv_head[alone]])
    world_dirs = world - centre
    world_dirs /= np.linalg.norm(world_dirs, axis=1, keepdims=True)
    focals = np.geomspace(0.4, 12.0, 20) * problem.width
    # Every focal length at once (the rays, the projections, the medians); only the small SVDs go one by one.
    cam = np.concatenate([(seen - problem.pp)[None] / focals[:, None, None],
                          np.ones((len(focals), len(seen), 1))], axis=2)
    cam /= np.linalg.norm(cam, axis=2, keepdims=True)
    Rs = np.array([wahba_rotation(c, world_dirs) for c in cam])
    Xc = np.einsum("fij,nj->fni", Rs, world - centre)
    z = Xc[..., 2]
    bad = z <= 1e-6
    uv = focals[:, None, None] * Xc[..., :2] / np.where(bad, 1.0, z)[..., None] + problem.pp
    uv[bad] = 1e6
    errors = np.median(np.linalg.norm(uv - seen, axis=2), axis=1)
    order = np.argsort(errors, kind="stable")
    out = []
    for j in order[:2]:
        param = CameraParametrisation(principal_point=problem.pp, R0=Rs[j], fixed_centre=np.asarray(centre, float))
        out.append((param, param.vector(float(focals[j]), centre)))
    return float(errors[order[0]]), out


def _free_start(problem: _Problem) -> tuple[CameraParametrisation, np.ndarray] | None:
    """A full pose from the ground homography of the foot points (Zhang's constraints,
    :func:`~.initialisation.camera_from_homography`), None when it gives none."""
    if len(problem.uv) < 4:
        return None
    H, _ = cv2.findHomography(problem.feet_m[:, :2], problem.uv, 0)
    if H is None or not np.all(np.isfinite(H)):
        return None
    got = camera_from_homography(np.asarray(H, float), problem.pp)
    if got is None:
        return None
    f, R, C = got
    param = CameraParametrisation(principal_point=problem.pp, R0=R)
    return param, param.vector(f, C)


@dataclass
class _Candidate:
    param: CameraParametrisation
    x: np.ndarray
    cost: float
    rig_index: int | None


def _best(problem: _Problem, starts: list[tuple[CameraParametrisation, np.ndarray]], loss: float,
          rig_index: int | None) -> _Candidate | None:
    """The best of the robust fits from ``starts``: each fitted with the foot points whitened at its start, then
    again whitened at its solution (the whitening depends on the camera)."""
    best = None
    for param, x0 in starts:
        try:
            problem.rewhiten(x0, param)
            x, cost = problem.fit(param, x0, loss)
            problem.rewhiten(x, param)
            x, cost = problem.fit(param, x, loss)
        except (ValueError, np.linalg.LinAlgError, FloatingPointError):
            continue
        if not np.all(np.isfinite(x)) or x[0] <= 0:
            continue
        if best is None or cost < best.cost:
            best = _Candidate(param, x, cost, rig_index)
    return best


def fit_camera_to_players(feet: Mapping[PlayerKey, np.ndarray], grass: Mapping[PlayerKey, GrassPlayer],
                          lines: FieldLines, width: int, height: int, rig_centres: Sequence[Sequence[float]] = (),
                          settings: PlayerFitSettings | None = None,
                          heads: Mapping[PlayerKey, np.ndarray] | None = None) -> PlayerFit | PlayerRefusal:
    """Fit a view's camera to its players' foot points (and its field lines), at a rig position where one fits.

    Args:
        feet: the view's players: key -> foot pixel (2,) px (:func:`foot_pixel`). Never the ball.
        grass: where the players stand (:func:`players_on_grass`, from the other, well-calibrated views).
        lines: the view's field lines (:data:`~app.geometry.annotations.FieldLines`, px; may be empty): their
            residuals join the fit's.
        width, height: the image size, px.
        rig_centres: the game's camera positions, (3,) metres each (world, z down), most supported first.
        settings: :class:`PlayerFitSettings`; defaults when None.
        heads: the view's players' head points (key -> the box's top centre (2,) px, :func:`~.grass.head_pixel`),
            None for none: each joins the fit as the point :data:`~.grass.HEAD_HEIGHT_M` above its player
            (:func:`~.grass.head_world`), whitened by the height's spread too; a box's height in the image is the
            player's distance, which the foot points of players standing close together leave loose.

    Returns:
        :class:`PlayerFit`, or :class:`PlayerRefusal` with its code and numbers.
    """
    s = settings or PlayerFitSettings()
    heads = heads or {}
    footed = [k for k in feet if k in grass]
    # A player whose feet the image's bottom edge cuts is still seen: its head point alone places it.
    keys = footed + [k for k in heads if k in grass and k not in feet]
    if len(keys) < s.min_players_rig:
        return PlayerRefusal("few_players", {"players": len(keys), "need": s.min_players_rig})
    scale = width / REFERENCE_WIDTH_PX
    uv = np.array([np.asarray(feet[k], float) for k in footed]).reshape(-1, 2)
    world = np.array([[grass[k].point_m[0], grass[k].point_m[1], 0.0] for k in keys])
    head_of = np.array([i for i, k in enumerate(keys) if k in heads], dtype=int)
    uv_head = np.array([np.asarray(heads[keys[i]], float) for i in head_of]).reshape(-1, 2)
    seen = np.vstack([uv, uv_head])  # every point the fit reads: the feet and the heads
    spread = float(np.linalg.svd(seen - seen.mean(axis=0), compute_uv=False)[-1]) / math.sqrt(len(seen))
    if spread < s.min_spread_px * scale:
        return PlayerRefusal("collinear_players", {"spread_px": spread, "limit_px": s.min_spread_px * scale})
    problem = _Problem(uv=uv, world=world, lines=dict(lines), pp=principal_point(width, height), width=width,
                       height=height, scale=scale, cov_g=np.array([grass[k].cov_m2 for k in keys], float),
                       uv_head=uv_head, head_of=head_of, foot_of=np.arange(len(footed)))
    loss_px = s.loss_scale
    fits = _rig_fits(problem, rig_centres, s)
    chosen: _Candidate | None = None
    refusal: PlayerRefusal | None = None
    if fits:
        best = fits[0]
        verdict = _judge(problem, best, s)
        if isinstance(verdict, PlayerRefusal):
            refusal = verdict
        else:
            centres = {c.rig_index: np.asarray(rig_centres[c.rig_index or 0], dtype=np.float64) for c in fits}
            here = centres[best.rig_index]
            rivals = [c for c in fits[1:] if float(np.linalg.norm(centres[c.rig_index] - here)) > s.rig_same_m]
            if rivals and rivals[0].cost < s.rig_margin * best.cost:
                refusal = PlayerRefusal("rig_ambiguous", {"cost": best.cost, "second_cost": rivals[0].cost})
            else:
                chosen = best
    if chosen is None and len(keys) >= s.min_players_free:
        # A full pose from the ground homography, and from the best rig fits with their centre freed (a camera
        # near, not at, a rig position).
        free_starts = [start] if (start := _free_start(problem)) is not None else []
        for fitted in fits[:2]:
            f, R, C, _ = fitted.param.split(fitted.x)
            free = CameraParametrisation(principal_point=problem.pp, R0=np.asarray(R))
            free_starts.append((free, free.vector(float(f), np.asarray(C, float))))
        cand = _best(problem, free_starts, loss_px, None) if free_starts else None
        if cand is not None:
            verdict = _judge(problem, cand, s)
            if isinstance(verdict, PlayerRefusal):
                refusal = refusal or verdict
            else:
                chosen, refusal = cand, None
    if chosen is None:
        refusal = refusal or PlayerRefusal("players_misfit" if fits else "few_players",
                                           {"players": len(keys), "need": s.min_players_free})
        if 0 < len(lines) < MIN_LINE_CLASSES and refusal.code == "players_misfit":
            # The view's few lines and its players cannot be fitted together: the lines may be wrong (a mirrored or
            # mislabelled class), which the players and the game's rig, two sources the view's labels do not touch,
            # can tell. Their camera without the lines is taken only at a rig position. A view with more classes
            # keeps its refusal: its lines alone say whether they are mirrored (the doubts' mirrored_labels).
            alone = fit_camera_to_players(feet, grass, {}, width, height, rig_centres, s, heads)
            if isinstance(alone, PlayerFit) and alone.rig_index is not None:
                return alone
        return refusal
    return _accepted(problem, chosen, keys, s)


#: Where the players tell a view's own lines wrong: the median, over the players it shares with the well-lined views,
#: of each foot point's distance from where those views put the player, in its standard deviations
#: (:func:`players_disagreement`). Chosen on ``soccernet-v3-dev-large`` and ``seed-202``: admitted lines cameras that
#: place the ball right disagree with their players by at most 10.2 sigma; the wrong ones (50-1,400 px@1920 off the
#: ball) by 15-120.
LINES_CONTRADICTED_SIGMA = 15.0


def players_disagreement(camera: Camera, feet: Mapping[PlayerKey, np.ndarray], grass: Mapping[PlayerKey, GrassPlayer],
                         width: int, height: int, min_players: int = 3) -> float | None:
    """How far a view's ``camera`` puts its players from where the well-calibrated views put them: the median, over
    the players with a foot point (``feet``, px) in ``grass`` (:func:`~.grass.players_on_grass`), of the foot point's
    distance from the projection of the player's :func:`~.grass.foot_world` point, in its standard deviations (its
    pixel noise and its grass point's covariance carried into the view, as the fit whitens it); the camera's lens
    distortion is left out. None with fewer than ``min_players`` such players."""
    keys = [k for k in feet if k in grass]
    if len(keys) < min_players:
        return None
    pp = np.array([camera.K[0, 2], camera.K[1, 2]])
    problem = _Problem(uv=np.array([np.asarray(feet[k], float) for k in keys]),
                       world=np.array([[grass[k].point_m[0], grass[k].point_m[1], 0.0] for k in keys]), lines={},
                       pp=pp, width=width, height=height, scale=width / REFERENCE_WIDTH_PX,
                       cov_g=np.array([grass[k].cov_m2 for k in keys], float))
    param = CameraParametrisation(principal_point=pp, R0=np.asarray(camera.R, float), fixed_centre=camera.C)
    x = param.vector(float(camera.K[0, 0]), np.asarray(camera.C, float))
    problem.rewhiten(x, param)
    return float(np.median(problem.pixel_errors(x, param)[1]))


def _rig_fits(problem: _Problem, rig_centres: Sequence[Sequence[float]], s: PlayerFitSettings) -> list[_Candidate]:
    """The view's camera fitted at the game's rig positions (m, world, z down), lowest cost first: every position's
    starts are cheap (a Wahba rotation per focal length); only the closest are refined (the best and its rivals)."""
    ranked = []
    for i, c in enumerate(rig_centres):
        centre = np.asarray(c, float)
        if centre.shape != (3,) or not np.all(np.isfinite(centre)) or centre[2] >= 0:
            continue
        error, starts = _rig_starts(problem, centre)
        ranked.append((error, i, starts))
    ranked.sort(key=lambda t: t[0])
    fits = []
    for k, (_, i, starts) in enumerate(ranked[:s.rig_refined]):
        cand = _best(problem, starts if k == 0 else starts[:1], s.loss_scale, i)
        if cand is not None:
            fits.append(cand)
    fits.sort(key=lambda c: c.cost)
    return fits

def _judge(problem: _Problem, cand: _Candidate, s: PlayerFitSettings) -> PlayerRefusal | None:
    """Refuse a fit whose foot points or lines are far from it."""
    n = len(problem.world)
    problem.rewhiten(cand.x, cand.param)
    _, d = problem.player_errors(cand.x, cand.param)
    inl = d <= s.inlier_sigma
    if inl.sum() < max(s.min_players_rig, math.ceil(s.min_inlier_share * n)):
        return PlayerRefusal("players_misfit", {"inliers": int(inl.sum()), "players": n})
    rms = float(np.sqrt(np.mean(d[inl] ** 2)))
    if rms > s.max_rms:
        return PlayerRefusal("players_misfit", {"rms_sigma": rms, "limit": s.max_rms})
    if problem.obs is not None:
        camera = cand.param.camera(cand.x)
        limit = s.line_limit_gamma * image_diagonal(problem.width, problem.height)
        worst = _class_worst(camera, problem)
        if worst and max(worst.values()) > limit:
            return PlayerRefusal("players_misfit", {"line_px": max(worst.values()), "limit_px": limit})
    return None


def _class_worst(camera: Camera, problem: _Problem) -> dict[str, float]:
    from app.geometry.calibration.starts import class_residuals  # the line fit's own per-class residuals

    assert problem.obs is not None
    per_class, _ = class_residuals(camera, problem.obs)
    return {c: float(v) for c, v in per_class.items()}


def _accepted(problem: _Problem, cand: _Candidate, keys: list[PlayerKey], s: PlayerFitSettings
              ) -> PlayerFit | PlayerRefusal:
    """The fit's camera, its uncertainty from the Jacobian of every residual at the solution, and its checks."""
    n = len(problem.world)
    param, x = cand.param, cand.x
    # Re-centre the rotation vector at the solution (the uncertainty's angles are taken at w = 0).
    f, R, C, _ = param.split(x)
    param = CameraParametrisation(principal_point=problem.pp, R0=np.asarray(R), fixed_centre=param.fixed_centre)
    x = param.vector(float(f), np.asarray(C, float))
    problem.rewhiten(x, param)
    r0 = problem.rows(x, param)
    d_px, d = problem.player_errors(x, param)
    inl = d <= s.inlier_sigma
    n_feet = len(problem.uv)
    n_lines = len(r0) - 2 * n_feet - 2 * len(problem.head_of)  # the rows: feet, lines, heads
    keep = np.concatenate([np.repeat(inl[problem.foot_of], 2), np.ones(n_lines, dtype=bool),
                           np.repeat(inl[problem.head_of], 2)])
    J = problem.jacobian(x, param)[1][keep]
    sigma = line_noise(r0[keep], len(x))
    uncertainty = uncertainty_from_jacobian(param, J, sigma, int(keep.sum()))
    camera = param.camera(x)
    # How far the camera may put a ball where the players are (on the grass and 3 m up), from the full covariance
    # of the fit (the centre's terms included: a full pose trades its centre against its angles).
    cov, undetermined = parameter_covariance(J, sigma)
    if np.any(undetermined):
        return PlayerRefusal("camera_unsure", {"sigma_px": math.inf, "limit_px": s.max_sigma_px})
    here = problem.world[inl].mean(axis=0, keepdims=True)  # where the play is: the players' centre
    probe = np.vstack([here, here + [0.0, 0.0, -3.0]])
    sigma_px = projection_sigma_px(problem, param, x, cov, probe) / problem.scale
    if not sigma_px <= s.max_sigma_px:
        return PlayerRefusal("camera_unsure", {"sigma_px": sigma_px, "limit_px": s.max_sigma_px})
    line_rms = None
    residuals_px: dict[str, float] = {}
    if problem.obs is not None:
        residuals_px = _class_worst(camera, problem)
        lr = r0[2 * n_feet:2 * n_feet + n_lines] * problem.line_sigma
        line_rms = float(np.sqrt(np.mean(lr ** 2))) if len(lr) else None
    pixel = {int(i): problem.uv[k] for k, i in enumerate(problem.foot_of)}
    for k, i in enumerate(problem.head_of):
        pixel.setdefault(int(i), problem.uv_head[k])  # a player seen without its feet: its head point
    used = tuple((keys[i], (float(pixel[i][0]), float(pixel[i][1])),
                  (float(problem.world[i, 0]), float(problem.world[i, 1]))) for i in range(n) if inl[i])
    return PlayerFit(camera=camera, uncertainty=uncertainty, rig_index=cand.rig_index, players=used,
                     rms_px=float(np.sqrt(np.mean(d_px[inl] ** 2))), residuals_px=residuals_px, line_rms_px=line_rms,
                     sigma_px=sigma_px)
