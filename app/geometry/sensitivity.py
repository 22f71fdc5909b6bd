"""Sensitivity of monocular 3D ball localisation to the box (paper, Fig. sensitivity).

The paper perturbs annotated boxes of 100 SoccerNet-v3D-train views: the box size by up to +-10 %
(about its centre) and the box centre by up to 2 % of the image diagonal, and plots the 3D error of
the monocular ball (paper Eq. ball3Destimation, :func:`app.geometry.ball.ball_from_box`) against the
perturbation, one curve per view coloured by the camera-to-ball distance.

Frames: world = SoccerNet (metres, z down); boxes ``[x1, y1, x2, y2]`` in pixels.
"""
from __future__ import annotations

import numpy as np

from app.geometry.ball import ball_from_box, ball_from_box_exact, box_centre_and_diameter
from app.geometry.camera import Camera


def scale_boxes(boxes: np.ndarray, factors: np.ndarray) -> np.ndarray:
    """Boxes scaled about their centres.

    Args:
        boxes: (N, 4) ``[x1, y1, x2, y2]`` pixels.
        factors: scalar or (N,) scale factors (1.1 = 10 % larger).

    Returns:
        (N, 4) pixels.

    >>> scale_boxes(np.array([[0.0, 0.0, 10.0, 20.0]]), 1.1).tolist()
    [[-0.5, -1.0, 10.5, 21.0]]
    """
    b = np.asarray(boxes, float).reshape(-1, 4)
    f = np.broadcast_to(np.asarray(factors, float), (len(b),))[:, None]
    c = np.hstack([(b[:, :2] + b[:, 2:]) / 2] * 2)
    return c + (b - c) * f


def size_sensitivity(camera: Camera, box: np.ndarray, ball_ref: np.ndarray, size_pct: np.ndarray,
                     ball_diameter_m: float, exact: bool = False) -> np.ndarray:
    """3D error (m) of the monocular ball when the box is scaled by ``1 + size_pct / 100`` about its centre.

    Args:
        camera: the view's camera.
        box: (4,) reference box, pixels.
        ball_ref: (3,) reference 3D ball, world metres.
        size_pct: (S,) size variations in percent (e.g. -10 .. 10).
        ball_diameter_m: phi, metres.
        exact: use :func:`app.geometry.ball.ball_from_box_exact` instead of the paper's formula.

    Returns:
        (S,) distances in metres between the monocular ball of each scaled box and ``ball_ref``.
    """
    s = np.asarray(size_pct, float).reshape(-1)
    boxes = scale_boxes(np.repeat(np.asarray(box, float).reshape(1, 4), len(s), axis=0), 1.0 + s / 100.0)
    return np.linalg.norm(_estimate(exact)(camera, boxes, ball_diameter_m) - np.asarray(ball_ref, float), axis=1)


def centre_sensitivity(camera: Camera, box: np.ndarray, ball_ref: np.ndarray, shift_pct: np.ndarray,
                       ball_diameter_m: float, image_size: tuple[float, float], exact: bool = False) -> np.ndarray:
    """3D error (m) of the monocular ball when the box centre moves by ``shift_pct`` % of the image diagonal.

    The shift is applied in the four diagonal directions ``(+-1, +-1) / sqrt(2)`` and the errors are
    averaged (the paper does not say which direction it used).

    Args:
        camera: the view's camera.
        box: (4,) reference box, pixels.
        ball_ref: (3,) reference 3D ball, world metres.
        shift_pct: (S,) shifts in percent of the image diagonal (e.g. 0 .. 2).
        ball_diameter_m: phi, metres.
        image_size: ``(width, height)`` pixels (their diagonal scales the shift).
        exact: as in :func:`size_sensitivity`.

    Returns:
        (S,) mean distances in metres.
    """
    s = np.asarray(shift_pct, float).reshape(-1)
    diag = float(np.hypot(*image_size))
    b = np.asarray(box, float).reshape(4)
    box_centre_and_diameter(b)  # validates
    errs = np.zeros(len(s))
    for dx, dy in ((1, 1), (1, -1), (-1, 1), (-1, -1)):
        d = s[:, None] * diag / 100.0 * np.array([dx, dy]) / np.sqrt(2.0)
        moved = b[None, :] + np.hstack([d, d])
        errs += np.linalg.norm(_estimate(exact)(camera, moved, ball_diameter_m) - np.asarray(ball_ref, float), axis=1)
    return errs / 4.0


def _estimate(exact: bool):  # returns a box -> ball function
    return ball_from_box_exact if exact else ball_from_box
