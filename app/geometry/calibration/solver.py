"""A small robust Levenberg-Marquardt for the calibration's few parameters.

Why not ``scipy.optimize.least_squares``: with 4 to 8 parameters and 10 to 100 residuals its
per-iteration overhead (and one Python call per finite-difference column) dominates; the residuals
here are vectorised over a batch of parameter vectors, so the forward-difference Jacobian costs one
call. The loss is soft-L1, ``rho(s) = 2 (sqrt(1 + s) - 1)`` on ``s = (r / scale)^2`` (the same as
scipy's ``loss="soft_l1"``), minimised by iteratively reweighted Gauss-Newton steps with Marquardt's
diagonal damping (Nocedal and Wright, section 10.3; Triggs et al., "Bundle adjustment - a modern
synthesis", section 4.3 for the IRLS form of robust losses).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Callable, Generator, Sequence, TypeVar

import numpy as np

T = TypeVar("T")


@dataclass(frozen=True)
class SolverResult:
    """Outcome of :func:`robust_lm`.

    Attributes:
        x: (k,) solution. cost: robust cost at ``x`` (px^2). residuals: (n,) residuals at ``x``, px.
        jacobian: (n, k) forward-difference Jacobian at the last linearisation. iterations: count.
        evaluations: calls of ``fun`` (each on a batch of up to k + 1 vectors).
    """

    x: np.ndarray
    cost: float
    residuals: np.ndarray
    jacobian: np.ndarray
    iterations: int
    evaluations: int


def soft_l1_cost(r: np.ndarray, scale: float) -> np.ndarray:
    """Soft-L1 cost ``scale^2 sum 2 (sqrt(1 + (r / scale)^2) - 1)`` over the last axis (px^2)."""
    z = (np.asarray(r) / scale) ** 2
    return scale**2 * np.sum(2.0 * (np.sqrt(1.0 + z) - 1.0), axis=-1)


#: The steps of one fit (:func:`robust_lm_steps`): it yields parameter vectors to evaluate and is
#: sent back their residuals.
Steps = Generator[np.ndarray, np.ndarray, "SolverResult"]


def run_steps(steps: Generator[Any, Any, T], evaluate: Callable[[Any], Any]) -> T:
    """Drive a step generator to its end: every request it yields is answered with ``evaluate(request)``
    (an exception of ``evaluate`` is thrown into the generator at its ``yield``, as if raised there).
    Returns the generator's return value."""
    try:
        request = next(steps)
        while True:
            try:
                answer = evaluate(request)
            except Exception as exc:  # noqa: BLE001 - re-raised inside the generator
                request = steps.throw(exc)
                continue
            request = steps.send(answer)
    except StopIteration as stop:
        return stop.value


def run_lockstep(all_steps: Sequence[Generator[Any, Any, T]], evaluate_many: Callable[[list[Any]], list[Any]],
                 evaluate: Callable[[Any], Any]) -> list[T]:
    """Drive several independent step generators together: at each round the requests of every
    generator still running are answered by one call ``evaluate_many(requests)`` (one answer per
    request, in order), so that vectorised work is shared. When that call raises, each request is
    answered alone with ``evaluate`` (its exception thrown into its own generator), so a generator
    sees exactly what :func:`run_steps` would give it. Returns the generators' return values, in order."""
    results: list[Any] = [None] * len(all_steps)
    pending: dict[int, Any] = {}
    for i, steps in enumerate(all_steps):
        try:
            pending[i] = next(steps)
        except StopIteration as stop:
            results[i] = stop.value
    while pending:
        order = list(pending)
        try:
            answers: list[Any] = evaluate_many([pending[i] for i in order])
            errors: list[Exception | None] = [None] * len(order)
        except Exception:  # noqa: BLE001 - answered one by one below
            answers, errors = [], []
            for i in order:
                try:
                    answers.append(evaluate(pending[i]))
                    errors.append(None)
                except Exception as exc:  # noqa: BLE001 - re-raised inside the generator
                    answers.append(None)
                    errors.append(exc)
        for i, answer, error in zip(order, answers, errors):
            try:
                pending[i] = all_steps[i].throw(error) if error is not None else all_steps[i].send(answer)
            except StopIteration as stop:
                results[i] = stop.value
                del pending[i]
    return results


def robust_lm(fun: Callable[[np.ndarray], np.ndarray], x0: np.ndarray, scale: float, *,
              lower: np.ndarray | None = None, upper: np.ndarray | None = None, max_iter: int = 40,
              rel_step: float = 1e-6, tol: float = 1e-6, max_evaluations: int = 1000) -> SolverResult:
    """Minimise the soft-L1 cost of ``fun`` from ``x0`` (:func:`robust_lm_steps` driven with ``fun``).

    Args:
        fun: maps (B, k) parameter vectors to (B, n) residuals (pixels); must accept a batch.
        x0: (k,) start. scale: loss scale, px (residuals much larger count linearly).
        lower, upper: optional (k,) bounds; steps are clipped into them.
        max_iter: most linearisations. max_evaluations: most calls of ``fun``. rel_step: forward-difference step relative to ``max(1, |x|)``.
        tol: stop when a step lowers the cost by less than ``tol`` relative.

    Returns:
        :class:`SolverResult`.

    Raises:
        ValueError: ``x0`` is not a finite 1-D vector.

    >>> fit = robust_lm(lambda X: X - np.array([3.0, -1.0]), np.zeros(2), 1.0)
    >>> np.round(fit.x, 6).tolist()
    [3.0, -1.0]
    """
    return run_steps(robust_lm_steps(x0, scale, lower=lower, upper=upper, max_iter=max_iter, rel_step=rel_step,
                                     tol=tol, max_evaluations=max_evaluations), fun)


def robust_lm_steps(x0: np.ndarray, scale: float, *, lower: np.ndarray | None = None,
                    upper: np.ndarray | None = None, max_iter: int = 40, rel_step: float = 1e-6, tol: float = 1e-6,
                    max_evaluations: int = 1000) -> Steps:
    """:func:`robust_lm` as a generator: it yields each (k + 1, k) batch of parameter vectors (a point
    and its forward-difference neighbours) and is sent their (k + 1, n) residuals; it returns the
    :class:`SolverResult`. Several fits can so share one vectorised residual evaluation
    (:func:`run_lockstep`) with exactly the arithmetic of one fit alone. Arguments as :func:`robust_lm`.

    Raises:
        ValueError: ``x0`` is not a finite 1-D vector (at the first ``next``).
    """
    x = np.asarray(x0, dtype=float).copy()
    if x.ndim != 1 or not np.all(np.isfinite(x)):
        raise ValueError("robust_lm: x0 must be a finite 1-D vector")
    k = len(x)
    lo = np.full(k, -np.inf) if lower is None else np.asarray(lower, dtype=float)
    hi = np.full(k, np.inf) if upper is None else np.asarray(upper, dtype=float)
    x = np.clip(x, lo, hi)
    eye = np.eye(k)
    diagonal = np.arange(k)

    nfev = 0

    def jacobian_batch(at: np.ndarray) -> Generator[np.ndarray, np.ndarray, tuple[np.ndarray, np.ndarray]]:
        # One call evaluates the residuals at ``at`` and at its k forward-difference neighbours.
        nonlocal nfev
        nfev += 1
        h = rel_step * np.maximum(1.0, np.abs(at))
        X = np.empty((k + 1, k))
        X[0] = at
        np.add(at, eye * h[:, None], out=X[1:])
        R = yield X
        return R[0], ((R[1:] - R[0][None, :]) / h[:, None]).T

    r, J = yield from jacobian_batch(x)
    cost = float(soft_l1_cost(r, scale))
    lam = 1e-3
    it = 0
    for it in range(1, max_iter + 1):
        w = 1.0 / np.sqrt(1.0 + (r / scale) ** 2)  # rho'(s) of soft-L1
        JW = J * w[:, None]
        A = J.T @ JW
        g = JW.T @ r
        d = A.diagonal().copy()
        d[d <= 0] = 1e-12
        improved = False
        gain = 0.0
        while lam < 1e12 and nfev < max_evaluations:
            try:
                damped = A.copy()
                damped[diagonal, diagonal] += lam * d
                step = -np.linalg.solve(damped, g)
            except np.linalg.LinAlgError:
                lam *= 10.0
                continue
            x_new = np.minimum(np.maximum(x + step, lo), hi)
            # Evaluate the trial point together with its Jacobian: accepted steps (the common case)
            # then need no further call.
            r_new, J_new = yield from jacobian_batch(x_new)
            cost_new = float(soft_l1_cost(r_new, scale))
            if np.isfinite(cost_new) and cost_new < cost:
                gain = (cost - cost_new) / max(cost, 1e-300)
                x, r, J, cost = x_new, r_new, J_new, cost_new
                lam = max(lam / 5.0, 1e-9)
                improved = True
                break
            lam *= 5.0
        if not improved or gain < tol:
            break
    return SolverResult(x=x, cost=cost, residuals=r, jacobian=J, iterations=it, evaluations=nfev)
