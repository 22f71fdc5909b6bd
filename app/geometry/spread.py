"""How well a triangulated ball is placed: the spread its views' pixel sigmas leave it (pure numpy; world frame
SoccerNet, metres, z down; pixels at 1920 width)."""
from __future__ import annotations

import functools
from typing import Hashable, Mapping, Sequence

import numpy as np

from app.geometry.pair_error import REFERENCE_WIDTH_PX
from app.geometry.triangulation import BallObservation


def position_covariance(observations: Sequence[BallObservation], point_world: np.ndarray,
                        sigma_px_1920: Mapping[Hashable, float], step_m: float = 1e-3) -> np.ndarray | None:
    """The linearised covariance (3, 3), m^2, of the least-squares ball of ``observations`` at ``point_world`` when
    each view's pixel lies off by its sigma (Hartley & Zisserman, Multiple View Geometry, 2nd ed., sec. 5.2.3:
    ``inv(sum J_i^T J_i / sigma_i^2)`` with ``J_i`` (2, 3) the projection's Jacobian, :func:`projection_jacobian`).

    Args:
        observations: the views (their cameras and image widths; their pixels are not read).
        point_world: (3,) the ball, world metres (SoccerNet: origin at the centre spot, z down).
        sigma_px_1920: view id -> that view's pixel sigma (px at 1920 width, > 0) for every observation.
        step_m: the differences' step.

    Returns:
        The covariance; ``None`` where the point lies behind a camera or the views fix no point (rays along one
        line: the information matrix is singular).

    Raises:
        KeyError: a view without a sigma.
    """
    X = np.asarray(point_world, float).reshape(3)
    info = np.zeros((3, 3))
    for o in observations:
        J = projection_jacobian(o, X, step_m)
        if J is None:
            return None
        info += J.T @ J / float(sigma_px_1920[o.view_id]) ** 2
    eig = np.linalg.eigvalsh(info)
    if not eig[0] > 1e-12 * max(float(eig[-1]), 1e-300):
        return None
    return np.asarray(np.linalg.inv(info), float)


@functools.lru_cache(maxsize=8)
def _steps(step_m: float) -> np.ndarray:
    """(6, 3) the central differences' offsets of ``step_m`` metres (+x, +y, +z, -x, -y, -z), made once per step
    (read-only)."""
    steps = np.vstack([np.eye(3), -np.eye(3)]) * step_m
    steps.setflags(write=False)
    return steps


def projection_jacobian(o: BallObservation, point_world: np.ndarray, step_m: float = 1e-3) -> np.ndarray | None:
    """The Jacobian (2, 3) of ``o``'s camera's projection at ``point_world`` ((3,) world metres), px at 1920 width
    per metre, by central differences of ``step_m`` (distortion included); None where the point lies behind it."""
    X = np.asarray(point_world, float).reshape(3)
    k = REFERENCE_WIDTH_PX / o.image_width
    # the six points X + d, each sum the one a point at a time gives (an edit asks a dozen of these Jacobians)
    uv = o.camera.project_in_front(X + _steps(step_m))
    if uv is None:
        return None
    return np.asarray((uv[:3] - uv[3:]).T * k / (2 * step_m), float)


def position_sigma_m(observations: Sequence[BallObservation], point_world: np.ndarray,
                     sigma_px_1920: Mapping[Hashable, float], step_m: float = 1e-3) -> float | None:
    """How far (m, one standard deviation along the worst direction) the least-squares ball of ``observations``
    at ``point_world`` may move when each view's pixel lies off by its sigma: the square root of the largest
    eigenvalue of :func:`position_covariance` (its arguments, returns None where it does; raises as it does)."""
    cov = position_covariance(observations, point_world, sigma_px_1920, step_m)
    return None if cov is None else float(np.sqrt(np.linalg.eigvalsh(cov)[-1]))


def projected_sigma_px(o: BallObservation, point_world: np.ndarray, covariance: np.ndarray,
                       step_m: float = 1e-3) -> float | None:
    """How far (px at 1920 width, one standard deviation along the worst image direction) a ball at ``point_world``
    ((3,) world metres) with position ``covariance`` ((3, 3) m^2, :func:`position_covariance`) may project from its
    projection in ``o``'s camera: ``J C J^T``'s largest eigenvalue's root (first order); None where it lies behind
    the camera."""
    J = projection_jacobian(o, point_world, step_m)
    if J is None:
        return None
    return float(np.sqrt(max(float(np.linalg.eigvalsh(J @ np.asarray(covariance, float) @ J.T)[-1]), 0.0)))
