"""A ball box whose centre weighs the annotated centre against the multi-view reprojection.

The paper's optimised box (Eq. min_diametre) keeps the annotated centre, so a box drawn off-centre
stays off-centre whatever the other views say. Where the system's 3D ball is well constrained, its
projection into the view is a second, independent estimate of where the ball's image is. With
independent, isotropic Gaussian errors of standard deviations ``sigma_a`` (annotated centre) and
``sigma_r`` (reprojection), the minimum-variance combination is the inverse-variance weighted mean

    c* = (c_a / sigma_a^2 + c_r / sigma_r^2) / (1 / sigma_a^2 + 1 / sigma_r^2),

and the box is the exact image of the ball placed at the fused depth on the ray through ``c*``
(:func:`app.geometry.ball.optimise_box` with ``exact_ray`` at ``c*``). ``sigma_r -> infinity`` gives
back v3d's optimised box, ``sigma_a -> infinity`` the exact box of the fused ball.

Frames: world = SoccerNet (metres, z down); image = continuous pixels; boxes ``[x1, y1, x2, y2]``.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from app.geometry.ball import optimise_box
from app.geometry.camera import Camera


@dataclass(frozen=True)
class RefinedBox:
    """Result of :func:`refine_box`: ``box`` (4,) px or None when the ball is not visible along the
    refined ray, ``centre`` (2,) px the weighted centre, ``weight`` in [0, 1] on the reprojection."""

    box: np.ndarray | None
    centre: np.ndarray
    weight: float


def reprojection_weight(sigma_annotated_px: float, sigma_reprojection_px: float) -> float:
    """Weight of the reprojection in the inverse-variance mean: ``sigma_a^2 / (sigma_a^2 + sigma_r^2)``.

    Raises:
        ValueError: a non-positive or non-finite sigma.

    >>> reprojection_weight(2.0, 2.0), reprojection_weight(3.0, 1.0)
    (0.5, 0.9)
    """
    a, r = float(sigma_annotated_px), float(sigma_reprojection_px)
    if not (np.isfinite(a) and np.isfinite(r) and a > 0 and r > 0):
        raise ValueError(f"sigmas must be positive and finite, got {sigma_annotated_px!r}, {sigma_reprojection_px!r}")
    return a * a / (a * a + r * r)


def refine_box(camera: Camera, annotated_centre_px: np.ndarray, ball_world: np.ndarray,
               sigma_annotated_px: float, sigma_reprojection_px: float, ball_diameter_m: float) -> RefinedBox:
    """Box of the ball at the fused depth on the ray through the inverse-variance weighted centre.

    Args:
        camera: the view's camera.
        annotated_centre_px: (2,) annotated ball centre, pixels.
        ball_world: (3,) the system's 3D ball, world metres (must be in front of the camera).
        sigma_annotated_px: standard deviation of the annotated centre, pixels.
        sigma_reprojection_px: standard deviation of the reprojected centre, pixels.
        ball_diameter_m: phi, metres.

    Returns:
        :class:`RefinedBox`.

    Raises:
        ValueError: bad shapes, non-positive sigmas, or a ball behind the camera.

    >>> cam = Camera.from_parameters(focal_px=1000.0, principal_point=(960.0, 540.0), pan_deg=0.0,
    ...                              tilt_deg=90.0, roll_deg=0.0, position_m=[0.0, 50.0, -10.0])
    >>> r = refine_box(cam, [964.0, 540.0], [0.0, 0.0, -10.0], 2.0, 2.0, 0.22)  # reprojection at (960, 540)
    >>> r.weight, np.round(r.centre, 6).tolist(), np.round((r.box[:2] + r.box[2:]) / 2, 3).tolist()
    (0.5, [962.0, 540.0], [962.0, 540.0])
    """
    c_a = np.asarray(annotated_centre_px, float).reshape(-1)
    p = np.asarray(ball_world, float).reshape(-1)
    if c_a.shape != (2,) or p.shape != (3,):
        raise ValueError("annotated_centre_px must be (2,) and ball_world (3,)")
    uv, in_front = camera.project(p[None, :])
    if not in_front[0]:
        raise ValueError("ball_world is behind the camera")
    w = reprojection_weight(sigma_annotated_px, sigma_reprojection_px)
    centre = (1.0 - w) * c_a + w * uv[0]
    r = optimise_box(camera, centre, p, ball_diameter_m, method="exact_ray")
    return RefinedBox(r.box if r.status == "ok" else None, centre, w)
