"""The camera model: documented shapes, the pan/tilt/roll round trip, and the intrinsics it refuses."""
from __future__ import annotations

import numpy as np
import pytest

from app.geometry.camera import Camera, as_points


def camera() -> Camera:
    return Camera.from_parameters(focal_px=1200.0, principal_point=(960.0, 540.0), pan_deg=20.0,
                                  tilt_deg=75.0, roll_deg=1.0, position_m=[0.0, 55.0, -14.0])


def test_documented_shapes_hold_for_one_point_and_for_many():
    cam = camera()
    X = np.array([[0.0, 0.0, 0.0], [10.0, -5.0, 0.0], [-20.0, 30.0, -2.0]])
    uv, ok = cam.project(X)
    assert uv.shape == (3, 2) and ok.shape == (3,) and ok.all()
    assert cam.points_in_camera(X[0]).shape == (1, 3)
    d = cam.rays(uv)
    assert d.shape == (3, 3)
    np.testing.assert_allclose(np.linalg.norm(d, axis=1), 1.0)
    # Each ray from C passes through its world point.
    v = X - cam.C
    np.testing.assert_allclose(d, v / np.linalg.norm(v, axis=1, keepdims=True), atol=1e-12)
    assert cam.projection_matrix.shape == (3, 4)
    assert as_points([1.0, 2.0], 2, "uv").shape == (1, 2)
    with pytest.raises(ValueError, match="uv"):
        as_points(np.zeros((2, 3)), 2, "uv")


def test_soccernet_json_round_trip_keeps_the_camera():
    cam = camera()
    back = Camera.from_soccernet(cam.to_soccernet())
    np.testing.assert_allclose(back.R, cam.R, atol=1e-12)
    np.testing.assert_allclose(back.K, cam.K)
    np.testing.assert_allclose(back.C, cam.C)


def test_cameras_without_a_positive_focal_length_are_refused():
    """Regression: ``from_soccernet`` refused non-positive focal lengths but ``Camera(...)``,
    ``Camera.from_parameters`` and ``Camera.scaled`` did not: ``scaled(0)`` returned a camera with a
    singular K, whose ``rays`` then raised LinAlgError far from the cause, and a negative focal
    length silently flipped the image."""
    with pytest.raises(ValueError, match="focal"):
        Camera.from_parameters(focal_px=-1000.0, principal_point=(960.0, 540.0), pan_deg=0.0, tilt_deg=90.0,
                               roll_deg=0.0, position_m=[0.0, 50.0, -10.0])
    with pytest.raises(ValueError, match="focal"):
        Camera(K=np.diag([0.0, 1.0, 1.0]), R=np.eye(3), C=np.zeros(3))
    for sx in (0.0, -2.0, float("nan")):
        with pytest.raises(ValueError, match="scale factors"):
            camera().scaled(sx)
    half = camera().scaled(0.5)
    np.testing.assert_allclose(half.K[:2], camera().K[:2] / 2)
