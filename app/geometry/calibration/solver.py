"""A small robust Levenberg-Marquardt for the calibration's few parameters, compiled.

Why not ``scipy.optimize.least_squares``: with 4 to 8 parameters and 10 to 150 residuals its
per-iteration overhead (and one Python call per finite-difference column) dominates. Here the whole
fit, residuals (:func:`.residuals.residuals_into`), forward-difference Jacobian and damped normal
equations, runs in one compiled call (numba; a fit takes tens of microseconds where numpy's calls on
such small arrays took milliseconds). The loss is soft-L1, ``rho(s) = 2 (sqrt(1 + s) - 1)`` on
``s = (r / scale)^2`` (the same as scipy's ``loss="soft_l1"``), minimised by iteratively reweighted
Gauss-Newton steps with Marquardt's diagonal damping (Nocedal and Wright, section 10.3; Triggs et
al., "Bundle adjustment - a modern synthesis", section 4.3 for the IRLS form of robust losses).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit

from app.geometry.calibration.observations import Observations
from app.geometry.calibration.residuals import JIT, CameraParametrisation, residuals_into, workspace


@dataclass(frozen=True)
class SolverResult:
    """Outcome of :func:`robust_lm`.

    Attributes:
        x: (k,) solution. cost: robust cost at ``x`` (px^2). residuals: (n,) residuals at ``x``, px.
        jacobian: (n, k) forward-difference Jacobian at ``x``. iterations: linearisations made.
        evaluations: trial points evaluated (each with its k forward-difference neighbours).
    """

    x: np.ndarray
    cost: float
    residuals: np.ndarray
    jacobian: np.ndarray
    iterations: int
    evaluations: int


#: Rows a :class:`PriorRows` appends to the residuals: three for the centre, one for the roll, one for
#: the radial term.
PRIOR_ROWS = 5


@dataclass(frozen=True)
class PriorRows:
    """Prior terms of a MAP fit, as pixel residuals appended to the lines' (:func:`robust_lm`).

    With the line noise ``sigma`` (px), the lines' cost ``sum r^2`` is ``sigma^2`` times their negative
    log-likelihood (times 2); a Gaussian prior ``N(mean, S)`` on the centre adds
    ``sigma^2 (C - mean)^T S^-1 (C - mean)``, i.e. the rows ``whitening (C - mean)`` with
    ``whitening = sigma S^-1/2`` (px per metre), and a zero-mean roll prior of std ``s_roll`` (radians)
    the row ``sigma / s_roll * roll`` (``roll_weight``, px per radian; roll in SoccerNet's convention,
    ``atan2(R[0, 2], R[1, 2])`` of the world-to-camera ``R``, method.md section 2), and a Gaussian prior
    on the radial term in pixel units, ``kappa = k1 / f^2`` (px^-2: the distortion ``k1 rho`` of a
    point ``r`` px from the principal point is ``kappa r^2`` whatever the zoom; :mod:`.priors` learns it
    as the distortion at the corner, ``kappa h^2``, and converts it per image) of mean ``kappa_0``
    and std ``s_kappa``, the row ``sigma / s_kappa (k1 / f^2 - kappa_0)`` (``k1_weight``; only when
    ``k1`` is fitted). Built by :mod:`.priors`. With the centre held fixed the centre rows are zero.

    Attributes:
        mean: (3,) prior centre, world metres (z down). whitening: (3, 3) px per metre (zeros: no
            centre prior).
        roll_weight: px per radian (0: no roll prior).
        k1_mean_px2: ``kappa_0``, px^-2. k1_weight: ``sigma / s_kappa``, px^3 (0: no radial prior).
    """

    mean: np.ndarray
    whitening: np.ndarray
    roll_weight: float
    k1_mean_px2: float = 0.0
    k1_weight: float = 0.0


_NO_PRIOR = PriorRows(mean=np.zeros(3), whitening=np.zeros((3, 3)), roll_weight=0.0)


@njit(**JIT)
def _soft_l1(r: np.ndarray, scale: float) -> float:
    total = 0.0
    for i in range(r.shape[0]):
        z = (r[i] / scale) ** 2
        total += 2.0 * (math.sqrt(1.0 + z) - 1.0)
    return scale * scale * total


@njit(**JIT)
def _soft_l1_rows(R: np.ndarray, scale: float) -> np.ndarray:
    out = np.empty(R.shape[0])
    for b in range(R.shape[0]):
        out[b] = _soft_l1(R[b], scale)
    return out


def soft_l1_cost(r: np.ndarray, scale: float) -> np.ndarray:
    """Soft-L1 cost ``scale^2 sum 2 (sqrt(1 + (r / scale)^2) - 1)`` over the last axis of the
    residuals ``r`` (..., n) px -> (...) px^2.

    >>> float(soft_l1_cost(np.array([0.0, 3.0]), 4.0))  # 4^2 2 (sqrt(1 + 9 / 16) - 1)
    8.0
    """
    r = np.asarray(r, dtype=float)
    out = _soft_l1_rows(np.ascontiguousarray(r.reshape(-1, r.shape[-1])), float(scale))
    return out.reshape(r.shape[:-1])


@njit(**JIT)
def _abs_percentile(r: np.ndarray, q: float) -> float:
    a = np.sort(np.abs(r))
    v = (a.shape[0] - 1) * q
    lo = int(math.floor(v))
    hi = min(lo + 1, a.shape[0] - 1)
    t = v - lo
    diff = a[hi] - a[lo]
    return a[lo] + diff * t if t < 0.5 else a[hi] - diff * (1.0 - t)


def abs_percentile(r: np.ndarray, percent: float) -> float:
    """``np.percentile(np.abs(r), percent)`` (linear interpolation, numpy's formula to the last bit) of
    residuals ``r`` (n,) px, n >= 1, without numpy's per-call overhead.

    >>> abs_percentile(np.array([-4.0, 1.0, 2.0, 3.0]), 90) == float(np.percentile([4.0, 1.0, 2.0, 3.0], 90))
    True
    """
    return float(_abs_percentile(np.ascontiguousarray(r, dtype=float), percent / 100.0))


@njit(**JIT)
def _clip(v: float, lo: float, hi: float) -> float:
    """``min(max(v, lo), hi)``, a NaN kept (as numpy's minimum and maximum)."""
    if math.isnan(v):
        return v
    return min(max(v, lo), hi)


@njit(**JIT)
def _solve_into(A: np.ndarray, g: np.ndarray, out: np.ndarray) -> bool:
    """``out = A^-1 g`` (k,) by Gaussian elimination with partial pivoting (``A`` and ``g`` are
    overwritten); False when a pivot is exactly 0 (singular, as LAPACK's ``dgesv`` reports)."""
    k = A.shape[0]
    for c in range(k):
        p, best = c, abs(A[c, c])
        for i in range(c + 1, k):
            if abs(A[i, c]) > best:
                p, best = i, abs(A[i, c])
        if A[p, c] == 0.0:
            return False
        if p != c:
            for j in range(k):
                A[c, j], A[p, j] = A[p, j], A[c, j]
            g[c], g[p] = g[p], g[c]
        for i in range(c + 1, k):
            m = A[i, c] / A[c, c]
            for j in range(c, k):
                A[i, j] -= m * A[c, j]
            g[i] -= m * g[c]
    for c in range(k - 1, -1, -1):
        s = g[c]
        for j in range(c + 1, k):
            s -= A[c, j] * out[j]
        out[c] = s / A[c, c]
    return True


@njit(**JIT)
def _robust_lm(x0: np.ndarray, lo: np.ndarray, hi: np.ndarray, scale: float, max_iter: int, rel_step: float,
               tol: float, max_evaluations: int, pp: np.ndarray, R0: np.ndarray, centre: np.ndarray, fixed: bool,
               fit_k1: bool, o: tuple, prior_on: bool, prior_mean: np.ndarray, prior_whitening: np.ndarray,
               roll_weight: float, k1_mean: float, k1_weight: float) -> tuple:
    R, P, sp, cp, d_line, d_ext, d_cir, scratch = workspace(o)
    k = x0.shape[0]
    n_lines = 2 * d_line.shape[0] + d_cir.shape[0]
    n = n_lines + (PRIOR_ROWS if prior_on else 0)
    x, x_new, probe = np.empty(k), np.empty(k), np.empty(k)
    for j in range(k):
        x[j] = _clip(x0[j], lo[j], hi[j])
    r, r_new, r_probe = np.empty(n), np.empty(n), np.empty(n)
    J, JW = np.empty((n, k)), np.empty((n, k))
    A, damped, g, rhs, d, step = np.empty((k, k)), np.empty((k, k)), np.empty(k), np.empty(k), np.empty(k), np.empty(k)

    def evaluate(at: np.ndarray, out: np.ndarray) -> None:
        residuals_into(at, pp, R0, centre, fixed, fit_k1, o, out, R, P, sp, cp, d_line, d_ext, d_cir, scratch)
        if prior_on:
            # The prior's rows (px): whitened centre offset, the roll (R holds the rotation now), then
            # the radial term in pixel units.
            for a in range(3):
                s = 0.0
                if not fixed:
                    for b in range(3):
                        s += prior_whitening[a, b] * (at[4 + b] - prior_mean[b])
                out[n_lines + a] = s
            out[n_lines + 3] = roll_weight * math.atan2(R[0, 2], R[1, 2])
            out[n_lines + 4] = k1_weight * (at[k - 1] / (at[0] * at[0]) - k1_mean) if fit_k1 else 0.0

    def jacobian(at: np.ndarray, r_at: np.ndarray) -> None:
        # Forward differences, step relative to max(1, |x|) per parameter.
        for j in range(k):
            h = rel_step * max(1.0, abs(at[j]))
            probe[:] = at
            probe[j] = at[j] + h
            evaluate(probe, r_probe)
            for i in range(n):
                J[i, j] = (r_probe[i] - r_at[i]) / h

    evaluate(x, r)
    jacobian(x, r)
    nfev = 1
    cost = _soft_l1(r, scale)
    lam = 1e-3
    it = 0
    for it in range(1, max_iter + 1):  # noqa: B007  # the last iteration's number is returned after the loop
        for i in range(n):
            w = 1.0 / math.sqrt(1.0 + (r[i] / scale) ** 2)  # rho'(s) of soft-L1
            for j in range(k):
                JW[i, j] = J[i, j] * w
        for a in range(k):
            ga = 0.0
            for i in range(n):
                ga += JW[i, a] * r[i]
            g[a] = ga
            for b in range(k):
                s = 0.0
                for i in range(n):
                    s += J[i, a] * JW[i, b]
                A[a, b] = s
        for j in range(k):
            d[j] = A[j, j] if A[j, j] > 0 else 1e-12
        improved = False
        gain = 0.0
        while lam < 1e12 and nfev < max_evaluations:
            damped[:, :] = A
            for j in range(k):
                damped[j, j] += lam * d[j]
            rhs[:] = g
            if not _solve_into(damped, rhs, step):
                lam *= 10.0
                continue
            for j in range(k):
                x_new[j] = _clip(x[j] - step[j], lo[j], hi[j])
            # Every trial counts as one evaluation with its Jacobian (the budget's unit); the
            # Jacobian itself is computed only for an accepted step, the one place it is used.
            nfev += 1
            evaluate(x_new, r_new)
            cost_new = _soft_l1(r_new, scale)
            if math.isfinite(cost_new) and cost_new < cost:
                gain = (cost - cost_new) / max(cost, 1e-300)
                x[:] = x_new
                r[:] = r_new
                cost = cost_new
                jacobian(x, r)
                lam = max(lam / 5.0, 1e-9)
                improved = True
                break
            lam *= 5.0
        if not improved or gain < tol:
            break
    return x, cost, r, J, it, nfev


def robust_lm(x0: np.ndarray, obs: Observations, param: CameraParametrisation, scale: float, *,
              lower: np.ndarray | None = None, upper: np.ndarray | None = None, max_iter: int = 40,
              rel_step: float = 1e-6, tol: float = 1e-6, max_evaluations: int = 1000,
              prior: PriorRows | None = None) -> SolverResult:
    """Minimise the soft-L1 cost of the frame's residuals (:func:`.residuals.residuals`) over the
    camera parameters ``x`` of ``param``, from ``x0``.

    Each iteration linearises at ``x`` (forward differences, step ``rel_step * max(1, |x|)``), and
    tries damped Gauss-Newton steps (damping multiplied by 5 after a rejected trial, divided by 5
    after an accepted one, by 10 when the damped system is singular) until the cost falls.

    Args:
        x0: (k,) start, ``k = param.size``. obs: the frame's observations. param: its camera
            parametrisation. scale: loss scale, px (residuals much larger count linearly).
        lower, upper: optional (k,) bounds; steps are clipped into them.
        max_iter: most linearisations. max_evaluations: most trial points (the start counts one).
        tol: stop when an accepted step lowers the cost by less than ``tol`` relative.
        prior: optional :class:`PriorRows` (a MAP fit): :data:`PRIOR_ROWS` rows appended to the
            residuals (and to the result's ``residuals`` / ``jacobian``), under the same loss; a centre
            prior only for a parametrisation with a free centre.

    Returns:
        :class:`SolverResult`.

    Raises:
        ValueError: ``x0`` is not a finite 1-D vector of ``param.size`` values, or a ``prior`` with a
            centre prior is given with the centre fixed.
    """
    x = np.ascontiguousarray(x0, dtype=float)
    if x.ndim != 1 or len(x) != param.size or not np.all(np.isfinite(x)):
        raise ValueError("robust_lm: x0 must be a finite 1-D vector of the parametrisation's size")
    if prior is not None and param.fixed_centre is not None and np.any(prior.whitening):
        raise ValueError("robust_lm: a centre prior needs a free centre")
    k = len(x)
    lo = np.full(k, -np.inf) if lower is None else np.ascontiguousarray(lower, dtype=float)
    hi = np.full(k, np.inf) if upper is None else np.ascontiguousarray(upper, dtype=float)
    fixed = param.fixed_centre is not None
    centre = np.ascontiguousarray(param.fixed_centre if fixed else np.zeros(3), dtype=float)
    xs, cost, r, J, it, nfev = _robust_lm(
        x, lo, hi, float(scale), int(max_iter), float(rel_step), float(tol), int(max_evaluations),
        np.ascontiguousarray(param.principal_point, dtype=float), np.ascontiguousarray(param.R0, dtype=float),
        centre, fixed, bool(param.fit_k1), obs.kernel_arrays, prior is not None,
        np.ascontiguousarray((prior or _NO_PRIOR).mean, dtype=float),
        np.ascontiguousarray((prior or _NO_PRIOR).whitening, dtype=float), float((prior or _NO_PRIOR).roll_weight),
        float((prior or _NO_PRIOR).k1_mean_px2), float((prior or _NO_PRIOR).k1_weight))
    return SolverResult(x=xs, cost=float(cost), residuals=r, jacobian=J, iterations=int(it), evaluations=int(nfev))
