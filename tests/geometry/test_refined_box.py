"""``app.geometry.refined_box``: the inverse-variance weighted centre and its exact box."""
from __future__ import annotations

import numpy as np
import pytest

from app.geometry.ball import optimise_box, sphere_image_box
from app.geometry.camera import Camera
from app.geometry.refined_box import refine_box, reprojection_weight

CAM = Camera.from_parameters(focal_px=1500.0, principal_point=(960.0, 540.0), pan_deg=10.0, tilt_deg=80.0,
                             roll_deg=0.0, position_m=[0.0, 60.0, -15.0])
BALL = np.array([5.0, 10.0, -0.11])


def test_weights_follow_the_variances():
    assert reprojection_weight(1.0, 1.0) == 0.5
    assert reprojection_weight(1.0, 3.0) == pytest.approx(0.1)
    with pytest.raises(ValueError, match="sigmas"):
        reprojection_weight(0.0, 1.0)


def test_limits_give_the_optimised_box_and_the_exact_box_of_the_fused_ball():
    uv = CAM.project(BALL[None])[0][0]
    annotated = uv + np.array([4.0, -3.0])
    # A tiny annotation sigma: the annotated centre wins, the box is v3d's exact_ray optimised box.
    near_a = refine_box(CAM, annotated, BALL, 1e-6, 1e3, 0.22)
    assert np.allclose(near_a.box, optimise_box(CAM, annotated, BALL, 0.22, "exact_ray").box, atol=1e-6)
    # A tiny reprojection sigma: the box is the exact image of the fused ball itself.
    near_r = refine_box(CAM, annotated, BALL, 1e3, 1e-6, 0.22)
    assert np.allclose(near_r.box, sphere_image_box(CAM, BALL, 0.11), atol=1e-6)
    # Equal sigmas: half-way (hand check: centre = uv + (2, -1.5)).
    half = refine_box(CAM, annotated, BALL, 2.0, 2.0, 0.22)
    assert np.allclose(half.centre, uv + [2.0, -1.5]) and half.weight == 0.5


def test_a_ball_behind_the_camera_is_refused():
    with pytest.raises(ValueError, match="behind"):
        refine_box(CAM, [960.0, 540.0], CAM.C + (CAM.C - BALL), 1.0, 1.0, 0.22)
