"""The projection's Jacobian (``app.geometry.spread.projection_jacobian``) and ``Camera.project_in_front``, which it
projects with: the same numbers, to the bit, as the projection of every point through ``Camera.project``."""
from __future__ import annotations

import dataclasses

import numpy as np

from app.geometry.camera import Camera
from app.geometry.spread import projection_jacobian
from app.geometry.triangulation import BallObservation


def reference_jacobian(o: BallObservation, point_world: np.ndarray, step_m: float = 1e-3) -> np.ndarray | None:
    """The Jacobian as first written: each point ``X + d`` made alone, the six stacked and projected by
    ``Camera.project``, None when any lies behind the camera."""
    X = np.asarray(point_world, float).reshape(3)
    k = 1920.0 / o.image_width
    uv, front = o.camera.project(np.stack([X + d for d in np.vstack([np.eye(3), -np.eye(3)]) * step_m]))
    if not bool(np.all(front)):
        return None
    return np.asarray((uv[:3] - uv[3:]).T * k / (2 * step_m), float)


def random_camera(rng: np.random.Generator, distorted: bool) -> Camera:
    """A broadcast-like camera above the pitch looking at it, with SoccerNet's distortion terms when ``distorted``."""
    cam = Camera.from_parameters(focal_px=float(rng.uniform(800, 4000)),
                                 principal_point=(float(rng.uniform(900, 1020)), float(rng.uniform(500, 580))),
                                 pan_deg=float(rng.uniform(-40, 40)), tilt_deg=float(rng.uniform(70, 85)),
                                 roll_deg=float(rng.uniform(-2, 2)),
                                 position_m=[float(rng.uniform(-20, 20)), float(rng.uniform(40, 60)),
                                             float(rng.uniform(-25, -8))])
    if not distorted:
        return cam
    return dataclasses.replace(cam, radial=rng.normal(0, 0.05, 6), tangential=rng.normal(0, 1e-3, 2),
                               thin_prism=rng.normal(0, 1e-3, 4))


def test_the_jacobian_is_the_one_of_every_point_projected_alone_to_the_bit() -> None:
    rng = np.random.default_rng(7)
    behind = 0
    for i in range(400):
        cam = random_camera(rng, distorted=i % 2 == 1)
        o = BallObservation(view_id=1, camera=cam, point_px=np.array([960.0, 540.0]),
                            image_width=float(rng.choice([1280, 1920, 3840])))
        # points on and above the pitch, and some behind the camera (its centre's side, past it)
        X = (np.array([rng.uniform(-55, 55), rng.uniform(-35, 35), rng.uniform(-3, 0)]) if i % 5
             else cam.C + np.array([0.0, 5.0, -2.0]))
        step = 1e-3 if i % 3 else float(rng.choice([1e-2, 1e-4]))
        got, want = projection_jacobian(o, X, step), reference_jacobian(o, X, step)
        if want is None:
            behind += 1
            assert got is None
        else:
            assert got is not None and got.shape == (2, 3) and got.tobytes() == want.tobytes()
    assert 0 < behind < 400  # both branches asked


def test_project_in_front_gives_projects_pixels_or_none() -> None:
    rng = np.random.default_rng(11)
    for i in range(200):
        cam = random_camera(rng, distorted=i % 2 == 0)
        pts = np.column_stack([rng.uniform(-55, 55, 6), rng.uniform(-35, 35, 6), rng.uniform(-3, 0, 6)])
        if i % 4 == 0:
            pts[int(rng.integers(6))] = cam.C + np.array([0.0, 5.0, -2.0])  # one point behind the camera
        uv, front = cam.project(pts)
        got = cam.project_in_front(pts)
        if front.all():
            assert got is not None and got.tobytes() == uv.tobytes()
        else:
            assert got is None
