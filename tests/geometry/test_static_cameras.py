"""app.geometry.static_cameras.resect_from_ball: a static camera from ball positions and its labels, on synthetic
data of known truth (a camera like ISSIA's behind a touch line), with wrong correspondences mixed in."""
from __future__ import annotations

import numpy as np
import pytest

from app.geometry.camera import Camera
from app.geometry.static_cameras import resect_from_ball

W, H = 1920, 1080


def _camera() -> Camera:
    C = np.array([-1.1, -52.7, -6.0])
    z = np.array([0.0, 30.0, 0.0]) - C
    z /= np.linalg.norm(z)
    x = np.cross([0.0, 0.0, 1.0], z)
    x /= np.linalg.norm(x)
    K = np.array([[2564.0, 0, (W - 1) / 2], [0, 2564.0, (H - 1) / 2], [0, 0, 1.0]])
    return Camera(K=K, R=np.stack([x, np.cross(z, x), z]), C=C)


def _ball(rng, n, planar):
    """(n, 3) ball centres in the camera's view: rolls (z = -0.11) and, unless ``planar``, flights up to 8 m."""
    X = np.column_stack([rng.uniform(-18, 18, n), rng.uniform(-5, 30, n), np.full(n, -0.11)])
    if not planar:
        X[: n // 2, 2] = -rng.uniform(0.5, 8.0, n // 2)
    return X


@pytest.mark.parametrize("planar", [False, True])
def test_resection_survives_wrong_labels_and_positions(planar):
    """300 correspondences, 0.7 px label noise, 15 % of them wrong (a label or a position off the ball): the
    focal length within 1 % and the centre within 0.3 m; the DLT alone (every point weighing) fails here."""
    rng = np.random.default_rng(7)
    cam = _camera()
    X = _ball(rng, 300, planar)
    uv, front = cam.project(X)
    assert front.all()
    u = uv + rng.normal(0, 0.7, uv.shape)
    bad = rng.choice(len(X), 45, replace=False)
    u[bad[:30]] = rng.uniform([0, 0], [W, H], (30, 2))  # wrong labels
    X[bad[30:]] += rng.normal(0, 15.0, (15, 3)) * [1, 1, 0]  # positions of a trajectory gone wrong
    got = resect_from_ball(X, u, W, H)
    assert got is not None
    assert abs(got.K[0, 0] / cam.K[0, 0] - 1) < 0.01
    assert np.linalg.norm(got.C - cam.C) < 0.3


def test_resection_refuses_points_on_a_line():
    cam = _camera()
    X = np.column_stack([np.linspace(-10, 10, 40), np.full(40, 5.0), np.full(40, -0.11)])
    assert resect_from_ball(X, cam.project(X)[0], W, H) is None
