"""The ball's motion models between kicks and bounces, and their robust fits to the labels of static
cameras: the numerical core of :mod:`app.geometry.trajectory` (ISSIA-3D).

Models (6 parameters ``q``, ``t`` seconds after the piece's first frame; world: SoccerNet metres, z down):

* ``flight``: ``p(t) = p0 + v0 t + (0, 0, g t^2 / 2)``, ``q = (p0, v0)``, ``g`` = :data:`GRAVITY_M_S2`;
* ``roll``: on the grass, centre at ``z = -r`` (:data:`BALL_RADIUS_M`), horizontal
  ``p(t') = p0 + v0 t' + a t'^2 / 2`` with ``t' = min(t, t_stop)``, ``q = (x0, y0, vx, vy, ax, ay)``;
  a decelerating roll stops at ``t_stop = -(v0 . a) / |a|^2`` (:func:`stop_time`) and stays there.

A label is the undistorted normalised point ``(x, y)`` of a camera ``(R, C)``; its residual is the pixel
distance, on a 1920-px-wide image (:data:`app.geometry.pair_error.REFERENCE_WIDTH_PX`), between it
and the projection of ``p(t)``. Two fits, each of a *set* of labels (a stretch of frames) and one model:

* :func:`linear_fits`: iteratively reweighted linear least squares on the algebraic residual
  ``(r_1 - x r_3) . (p - C)``, ``(r_2 - y r_3) . (p - C)`` (``r_i`` rows of R), reweighted by the
  depth so that it equals the pixel error, with Cauchy weights (scale :data:`CAUCHY_PX`), 6 rounds
  from zero. The segmentation fits many stretches (a break's candidate cuts), so this fits many sets
  at once: their rows are stacked and every round is a handful of array operations over all of
  them, then each set's weighted normal equations (equilibrated, solved together; a set whose
  equations are rank-deficient or ill-conditioned, condition above :data:`_NORMAL_COND_MAX`, is solved
  by ``numpy.linalg.lstsq``: the minimum-norm solution). A set's result does not depend on the
  other sets it is fitted with.
* :func:`refine`: the robust least squares of the pixel residuals, ``min sum_j c^2 log(1 + f_j^2 /
  c^2)`` over the 2n scalar residuals ``f_j`` (``scipy.optimize.least_squares`` with ``loss="cauchy"``,
  ``f_scale=c`` minimises the same function): Levenberg-Marquardt with the analytic Jacobian
  (:func:`residuals_and_jacobian`) and the loss's Gauss-Newton curvature ``rho' + 2 z rho''``
  (Triggs et al., "Bundle adjustment - a modern synthesis", 2000, section 4.3; scipy's scaling),
  from a start (the linear solution, or the parameters before an edit), until the cost stops
  decreasing (relative change below 1e-12) or the step is below 1e-10 of the parameters.

Pure: numpy only.
"""
from __future__ import annotations

from typing import Any, Sequence

import numpy as np

from app.geometry.camera import Camera
from app.geometry.pair_error import REFERENCE_WIDTH_PX
from app.geometry.pitch import BALL_DIAMETER_M, within_play_volume

GRAVITY_M_S2 = 9.81
BALL_RADIUS_M = BALL_DIAMETER_M / 2.0
KINDS = ("flight", "roll")
#: Scale of the Cauchy loss on pixel residuals (px at 1920 width): label noise is about 1 px.
CAUCHY_PX = 3.0
#: Rounds of the reweighted linear fit.
LINEAR_ROUNDS = 6
#: Largest condition number of a set's equilibrated normal equations solved as such (they square the
#: condition of the least squares: below this the solution is within about 1e-8 of ``lstsq``'s); above
#: it ``lstsq`` solves the set (and gives the minimum-norm solution of a rank-deficient one).
_NORMAL_COND_MAX = 1e8


class LabelTable:
    """Flattened labels: per label its sequence frame index, camera index, undistorted normalised point
    and its camera's geometry.

    Attributes (N labels): ``frame`` (N,) sequence frame indices; ``cam`` (N,) camera indices; ``xy`` (N, 2)
    undistorted normalised points; ``R`` (N, 3, 3) world-to-camera rotations; ``C`` (N, 3) camera centres
    (m); ``scale`` (N,) normalised units -> px at 1920 width; ``rows`` (N, 2, 3) the rows ``r_1 - x r_3``,
    ``r_2 - y r_3`` of the algebraic residual.
    """

    def __init__(self, points: np.ndarray, cameras: Sequence[Camera | None], widths: Sequence[float],
                 use: np.ndarray, first_frame: int = 0):
        """``points`` (F, K, 2) pixels, ``use`` (F, K) the labels to take (their camera not None); row 0
        of ``points`` is sequence frame ``first_frame``."""
        frames, cams = np.nonzero(use)
        self.frame, self.cam = frames + first_frame, cams
        xy = np.zeros((len(frames), 2))
        for k, cam in enumerate(cameras):
            sel = cams == k
            if sel.any():
                xy[sel] = cam.normalise_pixels(points[frames[sel], k], undistort=True)  # type: ignore[union-attr]  # a camera with a used label is set
        self.xy = xy
        # cams: the cameras of the used labels, each set (a label counts only with its camera)
        self.R = np.stack([cameras[int(k)].R for k in cams]) if len(cams) else np.zeros((0, 3, 3))  # type: ignore[union-attr]  # see the comment above
        self.C = np.stack([cameras[int(k)].C for k in cams]) if len(cams) else np.zeros((0, 3))  # type: ignore[union-attr]  # see the comment above
        scale = np.array([0.5 * (cam.K[0, 0] + cam.K[1, 1]) * REFERENCE_WIDTH_PX / w if cam is not None else 1.0
                          for cam, w in zip(cameras, widths, strict=False)])
        self.scale = scale[cams]
        self.rows = self.R[:, :2, :] - self.xy[:, :, None] * self.R[:, 2:3, :]

    def take(self, idx: np.ndarray) -> "LabelTable":
        """The labels ``idx`` alone (row i of the result is label ``idx[i]``)."""
        sub = object.__new__(LabelTable)
        for name in ("frame", "cam", "xy", "R", "C", "scale", "rows"):
            setattr(sub, name, getattr(self, name)[idx])
        return sub

    def residuals(self, idx: np.ndarray | slice, pos: np.ndarray) -> np.ndarray:
        """(n, 2) pixel residuals (1920 width) of labels ``idx`` at world positions ``pos`` (n, 3)."""
        return _pixel_residuals(self.R[idx], self.C[idx], self.xy[idx], self.scale[idx], pos)


def _pixel_residuals(R: np.ndarray, C: np.ndarray, xy: np.ndarray, scale: np.ndarray, pos: np.ndarray) -> np.ndarray:
    xc = np.einsum("nij,nj->ni", R, pos - C)
    z = np.where(xc[:, 2] > 1e-6, xc[:, 2], 1e-6)
    return (xc[:, :2] / z[:, None] - xy) * scale[:, None]


def stop_time(kind: str, q: np.ndarray) -> float:
    """Seconds after the piece's start at which a decelerating roll stops, ``-(v0 . a) / |a|^2``
    (``inf`` for a flight or a roll that does not decelerate)."""
    if kind != "roll":
        return np.inf
    va = float(q[2] * q[4] + q[3] * q[5])
    return -va / float(q[4] * q[4] + q[5] * q[5]) if va < 0 else np.inf


def positions(kind: str, q: np.ndarray, t: np.ndarray) -> np.ndarray:
    """(N,) seconds -> (N, 3) world positions (m) of the model ``kind`` with parameters ``q`` (6,)."""
    t = np.atleast_1d(np.asarray(t, float))
    out = np.empty((len(t), 3))
    if kind == "flight":
        out[:] = q[None, 0:3] + q[None, 3:6] * t[:, None]
        out[:, 2] += 0.5 * GRAVITY_M_S2 * t ** 2
    else:
        tt = np.minimum(t, stop_time(kind, q))[:, None]
        out[:, :2] = q[None, 0:2] + q[None, 2:4] * tt + 0.5 * q[None, 4:6] * tt ** 2
        out[:, 2] = -BALL_RADIUS_M
    return out


def shifted(kind: str, q: np.ndarray, dt: float) -> np.ndarray:
    """The parameters of model ``kind`` with ``t = 0`` moved ``dt`` seconds later (the same motion for a
    flight; for a roll the same until its stop): position and velocity at ``dt`` (a roll's at its stop
    when ``dt`` is past it), the acceleration unchanged."""
    q = np.asarray(q, float)
    if kind == "flight":
        return np.concatenate([positions(kind, q, np.array([dt]))[0], q[3:6] + np.array([0.0, 0.0, GRAVITY_M_S2 * dt])])
    te = min(dt, stop_time(kind, q))
    return np.concatenate([positions(kind, q, np.array([te]))[0, :2], q[2:4] + q[4:6] * te, q[4:6]])


#: The fastest ball a fitted piece may have, m/s (the hardest shots on record are about 35 m/s): a piece
#: faster than this fitted a wrong label, not a ball.
MAX_BALL_SPEED_M_S = 45.0
#: A roll decelerating harder than this (m/s^2; grass slows a ball by about 0.5-3 m/s^2) is a stop a
#: break should explain, not a roll.
MAX_ROLL_DECELERATION_M_S2 = 20.0


def plausible(kind: str, q: np.ndarray, duration_s: float) -> bool:
    """A ball could move as model ``kind`` with parameters ``q`` (6,) does for ``duration_s`` seconds:
    never faster than :data:`MAX_BALL_SPEED_M_S`, inside the play volume (:data:`app.geometry.pitch.PLAY_VOLUME`) at its
    ends and its highest point, a roll decelerating by at most :data:`MAX_ROLL_DECELERATION_M_S2`. A fit of a few labels
    that one wrong label pulls, or of one camera whose depth the labels barely fix, breaks these long before it looks
    wrong in the image.
    World: SoccerNet metres (pitch 105 x 68 m centred on the centre spot, z down)."""
    q = np.asarray(q, float)
    if not np.all(np.isfinite(q)) or duration_s < 0:
        return False
    T = float(duration_s)
    if kind == "flight":
        speeds: list[Any] = [np.linalg.norm(q[3:6] + np.array([0.0, 0.0, GRAVITY_M_S2 * t])) for t in (0.0, T)]
        apex = min(max(-q[5] / GRAVITY_M_S2, 0.0), T)  # the highest point (z smallest) inside the piece
        ends = positions(kind, q, np.array([0.0, T, apex]))
    else:
        if float(np.hypot(q[4], q[5])) > MAX_ROLL_DECELERATION_M_S2:
            return False
        te = min(T, stop_time(kind, q))
        speeds = [float(np.hypot(*(q[2:4] + q[4:6] * t))) for t in (0.0, te)]
        ends = positions(kind, q, np.array([0.0, te]))
    if max(speeds) > MAX_BALL_SPEED_M_S:
        return False
    return bool(within_play_volume(ends).all())


def robust_cost(residuals_px: np.ndarray) -> float:
    """Cauchy cost of labels, ``sum_i c^2 log(1 + |r_i|^2 / c^2)`` (px^2), ``residuals_px`` (n, 2)."""
    e2 = np.einsum("ij,ij->i", residuals_px, residuals_px)
    return float(np.sum(CAUCHY_PX ** 2 * np.log1p(e2 / CAUCHY_PX ** 2)))


def linear_fits(L: LabelTable,
                jobs: Sequence[tuple[np.ndarray, str, int]], fps: float) -> list[tuple[np.ndarray, float]]:
    """The reweighted linear fit (module docstring) of several label sets at once.

    Args:
        L: the labels.
        jobs: per set ``(idx, kind, first_frame)``: label indices into ``L`` (non-empty), the model, and the
            frame at ``t = 0``.
        fps: frames per second.

    Returns:
        Per set ``(q (6,), cost)``: the parameters after :data:`LINEAR_ROUNDS` rounds and the Cauchy cost
        of its labels there (:func:`robust_cost`, px^2), the same whichever sets it is fitted with.
    """
    m = len(jobs)
    if m == 0:
        return []
    # flights first, then rolls: each model's rows are one slice
    order = sorted(range(m), key=lambda j: jobs[j][1] == "roll")
    jobs = [jobs[j] for j in order]
    sizes = np.array([len(j[0]) for j in jobs])
    ends = np.cumsum(sizes)
    starts = ends - sizes
    idx = np.concatenate([np.asarray(j[0], int) for j in jobs])
    n_sets_flight = sum(j[1] != "roll" for j in jobs)
    nf = int(ends[n_sets_flight - 1]) if n_sets_flight else 0  # rows [0, nf) flights, [nf, n) rolls
    t = (L.frame[idx] - np.repeat(np.array([j[2] for j in jobs], float), sizes)) / fps
    rows, R, C, xy, scale = L.rows[idx], L.R[idx], L.C[idx], L.xy[idx], L.scale[idx]
    n = len(idx)
    # p = B(t) q + c(t): c is gravity's drop for a flight, the radius for a roll; b = rows . (C - c)
    cz = np.empty(n)
    cz[:nf] = 0.5 * GRAVITY_M_S2 * t[:nf] ** 2
    cz[nf:] = -BALL_RADIUS_M
    Cc = C.copy()
    Cc[:, 2] -= cz
    b = np.einsum("nrj,nj->nr", rows, Cc)
    rows_xy, t_roll = rows[nf:, :, 0:2], t[nf:]
    roll_sizes = sizes[n_sets_flight:]
    W = np.empty((n, 2, 7))  # the weighted equations [A | b] * s
    depth = np.linalg.norm(C, axis=1)
    w = np.ones(n)
    q = np.zeros((m, 6))
    tr = t_roll
    for _ in range(LINEAR_ROUNDS):
        s = (np.sqrt(w) * scale / depth)[:, None]
        W[:, :, 6] = b * s
        s = s[:, :, None]
        W[:nf, :, 0:3] = rows[:nf] * s[:nf]
        W[:nf, :, 3:6] = rows[:nf] * (s[:nf] * t[:nf, None, None])
        if nf < n:
            # a roll that stops inside the set: its times after the stop are held at the stop (linear given it)
            sr, trr = s[nf:], tr[:, None, None]
            W[nf:, :, 0:2] = rows_xy * sr
            W[nf:, :, 2:4] = rows_xy * (sr * trr)
            W[nf:, :, 4:6] = rows_xy * (sr * (0.5 * trr ** 2))
        q = _solve_sets(W, starts, ends)
        qs = np.repeat(q, sizes, axis=0)
        pos = np.empty((n, 3))
        pos[:nf] = qs[:nf, 0:3] + qs[:nf, 3:6] * t[:nf, None]
        pos[:nf, 2] += cz[:nf]
        if nf < n:
            stops = np.repeat([stop_time("roll", qq) for qq in q[n_sets_flight:]], roll_sizes)
            tr = np.minimum(t_roll, stops)
            trr = tr[:, None]
            pos[nf:, 0:2] = qs[nf:, 0:2] + qs[nf:, 2:4] * trr + 0.5 * qs[nf:, 4:6] * trr ** 2
            pos[nf:, 2] = -BALL_RADIUS_M
        xc = np.einsum("nij,nj->ni", R, pos - C)
        depth = np.maximum(xc[:, 2], 0.5)
        z = np.where(xc[:, 2] > 1e-6, xc[:, 2], 1e-6)
        res = (xc[:, :2] / z[:, None] - xy) * scale[:, None]
        e2 = np.einsum("ij,ij->i", res, res)
        w = 1.0 / (1.0 + e2 / CAUCHY_PX ** 2)
    cost = CAUCHY_PX ** 2 * np.log1p(e2 / CAUCHY_PX ** 2)
    out: list[tuple[np.ndarray, float]] = [(np.zeros(6), 0.0)] * m
    for i, j in enumerate(order):
        out[j] = (q[i].copy(), float(np.sum(cost[starts[i]:ends[i]])))
    return out


def _solve_sets(W: np.ndarray, starts: np.ndarray, ends: np.ndarray) -> np.ndarray:
    """Least squares of each set's equations ``W[starts[i]:ends[i]]`` = ``[M | y]`` ((rows, 2, 7)):
    (m, 6) solutions from the equilibrated normal equations (each set's own product, so a set's
    solution does not depend on the others); ``lstsq`` for an ill-conditioned or rank-deficient set."""
    G7 = np.stack([W[a:b].reshape(-1, 7).T @ W[a:b].reshape(-1, 7) for a, b in zip(starts, ends, strict=False)])
    G, h = G7[:, :6, :6], G7[:, :6, 6]
    d = np.sqrt(np.einsum("mii->mi", G))
    d = np.where(d > 0, d, 1.0)
    Gs = G / d[:, :, None] / d[:, None, :]
    ev = np.linalg.eigvalsh(Gs)
    good = ev[:, 0] > ev[:, -1] / _NORMAL_COND_MAX
    q = np.zeros((len(G), 6))
    if good.all():
        return np.linalg.solve(Gs, (h / d)[:, :, None])[:, :, 0] / d
    if good.any():
        q[good] = np.linalg.solve(Gs[good], (h[good] / d[good])[:, :, None])[:, :, 0] / d[good]
    for i in np.nonzero(~good)[0]:
        Wi = W[starts[i]:ends[i]].reshape(-1, 7)
        q[i] = np.linalg.lstsq(Wi[:, :6], Wi[:, 6], rcond=None)[0]
    return q


def residuals_and_jacobian(L: LabelTable, kind: str, q: np.ndarray, t: np.ndarray,
                           jacobian: bool = True) -> tuple[np.ndarray, np.ndarray | None]:
    """Pixel residuals of all labels of ``L`` (times ``t`` (n,) s) under model ``kind`` with params ``q``,
    flattened (2n,), and their derivative (2n, 6) with respect to ``q`` (None without ``jacobian``).

    A residual is ``s (x_c[:2] / z - xy)`` with ``x_c = R (p - C)``, ``z = x_c[2]``, so its derivative in
    ``p`` is ``s / z (R_{0,1} - (x_c[:2] / z) R_2)``; ``p = B(t') q + c(t')`` with ``t' = min(t, t_stop(q))``:
    ``B(t')``, plus, for a roll's times after its stop, ``v(t_stop) (d t_stop / d q)`` with
    ``t_stop = -(v0 . a) / |a|^2`` (:func:`stop_time`).
    """
    ts = stop_time(kind, q)
    tt = np.minimum(t, ts)
    pos = positions(kind, q, t)
    R, C = L.R, L.C
    xc = np.einsum("nij,nj->ni", R, pos - C)
    z = np.where(xc[:, 2] > 1e-6, xc[:, 2], 1e-6)
    uv = xc[:, :2] / z[:, None]
    f = ((uv - L.xy) * L.scale[:, None]).reshape(-1)
    if not jacobian:
        return f, None
    D = (R[:, :2, :] - uv[:, :, None] * R[:, 2:3, :]) * (L.scale / z)[:, None, None]  # (n, 2, 3) d residual / d p
    J = np.empty((len(t), 2, 6))
    if kind == "flight":
        J[:, :, 0:3] = D
        J[:, :, 3:6] = D * tt[:, None, None]
    else:
        Dxy = D[:, :, 0:2]
        J[:, :, 0:2] = Dxy
        J[:, :, 2:4] = Dxy * tt[:, None, None]
        J[:, :, 4:6] = Dxy * (0.5 * tt ** 2)[:, None, None]
        if np.isfinite(ts):
            stopped = t >= ts
            if stopped.any():
                aa, va = float(q[4:6] @ q[4:6]), float(q[2:4] @ q[4:6])
                v = np.array([q[2] + q[4] * ts, q[3] + q[5] * ts, 0.0])
                g = np.array([0.0, 0.0, -q[4] / aa, -q[5] / aa, -q[2] / aa + 2 * va * q[4] / aa ** 2,
                              -q[3] / aa + 2 * va * q[5] / aa ** 2])
                J[stopped] += (D[stopped] @ v)[:, :, None] * g[None, None, :]
    return f, J.reshape(-1, 6)


def position_prior(times_s: Sequence[float], targets: np.ndarray, sigma_m: float) -> tuple[np.ndarray, np.ndarray]:
    """A flight's position at ``times_s`` (m,) s (after the piece's first frame) pulled towards ``targets``
    (m, 3) world metres with standard deviation ``sigma_m``: the ``prior`` of :func:`refine`, scaled so
    that ``sigma_m`` weighs as much as :data:`CAUCHY_PX` of a label's residual. Linear in ``q`` because
    ``p(t) = p0 + v0 t + (0, 0, g t^2 / 2)``."""
    rows, rhs = [], []
    w = CAUCHY_PX / sigma_m
    for tau, target in zip(times_s, np.asarray(targets, float), strict=False):
        rows.append(np.hstack([np.eye(3), tau * np.eye(3)]) * w)
        rhs.append((target - np.array([0.0, 0.0, 0.5 * GRAVITY_M_S2 * tau ** 2])) * w)
    return np.vstack(rows), np.concatenate(rhs)


def determined(L: LabelTable, kind: str, q: np.ndarray, t: np.ndarray, *, max_condition: float = 1e12) -> bool:
    """The labels of ``L`` (times ``t``) determine model ``kind`` near ``q``: the Cauchy-weighted normal
    matrix ``J^T diag(rho') J`` of the pixel residuals, equilibrated, has a condition number below
    ``max_condition`` (a fit of too few labels, e.g. two frames of one camera, leaves directions free,
    and its minimum then depends on where the fit started)."""
    f, J = residuals_and_jacobian(L, kind, q, t)
    assert J is not None  # asked for: jacobian defaults to True
    H = (J / (1.0 + (f / CAUCHY_PX) ** 2)[:, None]).T @ J
    d = np.sqrt(np.diag(H))
    if not np.all(d > 0):
        return False
    ev = np.linalg.eigvalsh(H / d[:, None] / d[None, :])
    return bool(ev[0] > ev[-1] / max_condition)


def _loss(f: np.ndarray) -> float:
    return float(np.sum(np.log1p((f / CAUCHY_PX) ** 2))) * CAUCHY_PX ** 2


def refine(L: LabelTable, kind: str, q: np.ndarray, t: np.ndarray, *, max_iterations: int = 100,
           prior: tuple[np.ndarray, np.ndarray] | None = None) -> np.ndarray:
    """The robust least-squares fit (module docstring) of model ``kind`` to all labels of ``L`` at times
    ``t`` (n,) s, from ``q`` (6,); returns the parameters (6,).

    ``prior``: ``(A, b)``, (m, 6) and (m,): linear residuals ``A q - b``, in the units of a pixel
    residual, added to the cost as plain squares (a prior is not an outlier to discount): e.g.
    :func:`position_prior`.

    Levenberg-Marquardt on ``sum_j c^2 log(1 + f_j^2 / c^2)`` (:data:`CAUCHY_PX`): gradient ``J^T (rho' f)``,
    curvature ``H = J^T diag(max(rho' + 2 z rho'', eps)) J`` (``z = f^2 / c^2``), step
    ``-(H + lambda diag H)^-1 grad`` taken when it lowers the cost. Converged when the Gauss-Newton
    step's predicted decrease ``grad^T H^-1 grad / 2`` is below 1e-12 of the cost (or the cost stops
    decreasing, or ``max_iterations``).
    """
    q = np.asarray(q, float).copy()

    m = 0 if prior is None else len(prior[1])

    def rows(q, jacobian=True):  # the labels' residuals, then the prior's
        f, J = residuals_and_jacobian(L, kind, q, t, jacobian)
        if prior is None:
            return f, J
        A, b = prior
        return np.concatenate([f, A @ q - b]), (np.vstack([J, A]) if J is not None else None)

    def loss(f):  # Cauchy on the labels' rows, squares on the prior's
        return _loss(f[:len(f) - m]) + float(np.sum(f[len(f) - m:] ** 2))

    f, J = rows(q)
    cost = loss(f)
    lam = 1e-3
    for _ in range(max_iterations):
        z = (f / CAUCHY_PX) ** 2
        z[len(f) - m:] = 0.0  # the prior's rows: rho' = 1, curvature 1
        grad = J.T @ (f / (1.0 + z))
        H = (J * np.maximum((1.0 - z) / (1.0 + z) ** 2, 1e-6)[:, None]).T @ J
        diag = np.diag(np.maximum(np.diag(H), 1e-12 * max(float(np.max(np.diag(H))), 1e-300)))
        try:
            gauss_newton = np.linalg.solve(H + 1e-9 * diag, grad)
        except np.linalg.LinAlgError:
            gauss_newton = None
        if gauss_newton is not None and float(grad @ gauss_newton) <= 2e-12 * cost:
            break  # what is left to gain is rounding
        while True:
            try:
                step = -np.linalg.solve(H + lam * diag, grad)
            except np.linalg.LinAlgError:
                step = None
            if step is not None and np.all(np.isfinite(step)):
                new = q + step
                new_cost = loss(rows(new, jacobian=False)[0])
                if new_cost <= cost:
                    break
            lam *= 10.0
            if lam > 1e10:
                return q
        flat = cost - new_cost <= 1e-14 * cost
        q, cost = new, new_cost
        if flat:
            break
        lam = max(lam * 0.1, 1e-9)
        f, J = rows(q)
    return q


__all__ = ["GRAVITY_M_S2", "BALL_RADIUS_M", "KINDS", "CAUCHY_PX", "LINEAR_ROUNDS", "LabelTable", "stop_time",
           "positions", "shifted", "robust_cost", "determined", "linear_fits", "residuals_and_jacobian", "refine",
           "position_prior", "plausible"]
