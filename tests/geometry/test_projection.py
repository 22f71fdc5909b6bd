"""Pitch polylines projected and clipped to the image (app/geometry/projection.py).

The main scene is a camera 60 m straight above the centre spot (tilt 0: the optical axis is the
world z axis, pointing down) with f = 500 px and principal point (480, 270): a ground point
(X, Y, 0) lands exactly at (480 + X * 500 / 60, 270 + Y * 500 / 60) pixels.
"""
from __future__ import annotations

import numpy as np
import pytest

from app.geometry.camera import Camera
from app.geometry.pitch import MODEL_CLASSES
from app.geometry.projection import (
    EVALUATOR_DIST_CIRCLES_M,
    EVALUATOR_DIST_M,
    _border_crossings,
    project_pitch_polylines,
)

W, H = 960, 540
SCALE = 500.0 / 60.0  # px per metre on the ground


def overhead(x: float = 0.0, y: float = 0.0, height: float = 60.0, **distortion) -> Camera:
    cam = Camera.from_parameters(focal_px=500.0, principal_point=(480.0, 270.0), pan_deg=0.0, tilt_deg=0.0,
                                 roll_deg=0.0, position_m=[x, y, -height])
    if distortion:
        cam = Camera(K=cam.K, R=cam.R, C=cam.C, **distortion)
    return cam


def test_overhead_camera_sees_everything_but_the_touch_lines():
    lines = project_pitch_polylines(overhead(), W, H)
    # Touch lines at y = +-34 m land at v = 270 -+ 283 px: outside; everything else is in view.
    assert set(lines) == set(MODEL_CLASSES) - {"Side line top", "Side line bottom"}


def test_clip_mode_cuts_the_middle_line_exactly_at_the_borders():
    (run,) = project_pitch_polylines(overhead(), W, H)["Middle line"]
    np.testing.assert_allclose(run[:, 0], 480.0, atol=1e-9)
    assert run[0].tolist() == pytest.approx([480.0, 0.0], abs=1e-9)
    assert run[-1].tolist() == pytest.approx([480.0, 540.0], abs=1e-9)
    assert np.all(np.diff(run[:, 1]) > 0)


def test_clip_mode_matches_the_analytic_projection_of_a_fully_visible_line():
    (run,) = project_pitch_polylines(overhead(), W, H)["Big rect. left main"]
    # x = -36 m, y from -20.16 to +20.16 m.
    np.testing.assert_allclose(run[:, 0], 480.0 - 36.0 * SCALE, atol=1e-9)
    assert run[0, 1] == pytest.approx(270.0 - 20.16 * SCALE, abs=1e-9)
    assert run[-1, 1] == pytest.approx(270.0 + 20.16 * SCALE, abs=1e-9)


def test_a_circle_cut_by_the_border_gives_two_runs_ending_on_the_border():
    # Camera 28 m towards the bottom touch line: the centre circle's centre lands at v = 270 - 28 * SCALE
    # = 36.7 px and its radius is 76.25 px, so its top leaves the image.
    cam = overhead(y=28.0)
    runs = project_pitch_polylines(cam, W, H)["Circle central"]
    assert len(runs) == 2
    centre = np.array([480.0, 270.0 - 28.0 * SCALE])
    r = 9.15 * SCALE
    ends = [runs[0][-1], runs[1][0]]
    for p in ends:
        assert p[1] == pytest.approx(0.0, abs=1e-9)
        # On the sampled chord, at most the sagitta (5e-3 px here) inside the true circle.
        assert np.linalg.norm(p - centre) == pytest.approx(r, abs=0.01)
    for run in runs:
        assert np.all(run[:, 1] >= 0.0)
        np.testing.assert_allclose(np.linalg.norm(run - centre, axis=1), r, atol=0.01)


def test_evaluator_mode_follows_the_official_quirks():
    (poly,) = project_pitch_polylines(overhead(), W, H, EVALUATOR_DIST_M, EVALUATOR_DIST_CIRCLES_M,
                                      mode="evaluator")["Middle line"]
    # The evaluator's border lines are x = W - 1 and y = H - 1: the run ends at 539, not 540.
    assert poly[0].tolist() == [480.0, 0.0]
    assert poly[-1].tolist() == [480.0, 539.0]
    # Straight elements sampled every 0.9 m (68 m: 75 samples + the end), 65 of them in view.
    inner = poly[1:-1]
    assert len(inner) == int(np.sum(np.abs((-34.0 + 0.9 * np.arange(76)) * SCALE) < 270.0))


def test_evaluator_mode_joins_the_runs_of_a_class_into_one_polyline():
    cam = overhead(y=28.0)
    (poly,) = project_pitch_polylines(cam, W, H, mode="evaluator")["Circle central"]
    on_border = np.flatnonzero(poly[:, 1] == 0.0)
    # Leaves through y = 0 and comes back: two consecutive crossings, joined by a segment along the border.
    assert len(on_border) == 2 and on_border[1] == on_border[0] + 1


def test_evaluator_crossing_is_the_in_image_intersection_nearest_to_the_later_point():
    # The infinite line through (10, 5) and (-10, -5) meets x = 0 at (0, 0) and y = 0 at (0, 0);
    # the line through (100, 10) and (-50, 40) meets x = 0 at (0, 30) and y = 0 at (150, 0): the
    # evaluator keeps (0, 30), nearest to the later point (-50, 40) (here: leaving through the left).
    ext = np.array([[-50.0, 40.0], [500.0, -20.0]])
    prev = np.array([[100.0, 10.0], [500.0, 20.0]])
    pts, found = _border_crossings(ext, prev, W, H)
    assert found.tolist() == [True, True]
    assert pts[0].tolist() == pytest.approx([0.0, 30.0])
    assert pts[1].tolist() == pytest.approx([500.0, 0.0])
    # A line that misses the image entirely has no admissible crossing.
    pts, found = _border_crossings(np.array([[-10.0, -10.0]]), np.array([[-20.0, -5.0]]), W, H)
    assert found.tolist() == [False]


def test_evaluator_mode_rounds_like_float32_and_agrees_with_clip_mode():
    cam = overhead(radial=[-0.2, 0.05, 0, 0, 0, 0], tangential=[1e-3, -5e-4], thin_prism=[1e-4, 0, 0, 2e-4])
    ev = project_pitch_polylines(cam, W, H, mode="evaluator")
    clip = project_pitch_polylines(cam, W, H)
    for cls, (poly,) in ev.items():
        inside = (poly[:, 0] > 0) & (poly[:, 0] < W - 1) & (poly[:, 1] > 0) & (poly[:, 1] < H - 1)
        assert np.array_equal(poly[inside], poly[inside].astype(np.float32).astype(np.float64)), cls
        ref = np.concatenate(clip[cls])
        # Every in-image evaluator point is a clip-mode vertex up to float32 rounding.
        d = np.min(np.linalg.norm(poly[inside][:, None, :] - ref[None, :, :], axis=2), axis=1)
        assert d.max() < 1e-3, cls


def test_distortion_moves_the_lines_as_the_camera_model_does():
    cam = overhead(radial=[-0.2, 0.0, 0, 0, 0, 0])
    (run,) = project_pitch_polylines(cam, W, H)["Big rect. left main"]
    # Each vertex lies on the distorted image of the line x = -36 m.
    normalised = cam.normalise_pixels(run)  # undistorted, camera frame = world frame / 60
    np.testing.assert_allclose(normalised[:, 0] * 60.0, -36.0, atol=1e-6)


def test_points_behind_the_camera_are_never_projected():
    # At the centre spot, 1.5 m up, looking horizontally towards the top touch line (y = -34).
    cam = Camera.from_parameters(focal_px=800.0, principal_point=(480.0, 270.0), pan_deg=0.0, tilt_deg=90.0,
                                 roll_deg=0.0, position_m=[0.0, 0.0, -1.5])
    for mode in ("clip", "evaluator"):
        lines = project_pitch_polylines(cam, W, H, mode=mode)
        assert "Side line top" in lines
        assert "Side line bottom" not in lines  # entirely behind the camera
        for runs in lines.values():
            for run in runs:
                assert np.all(np.isfinite(run))
                assert np.all((run >= 0) & (run <= [W, H]))


def test_clip_runs_stay_inside_the_image_for_a_broadcast_camera():
    cam = Camera.from_parameters(focal_px=1800.0, principal_point=(479.5, 269.5), pan_deg=-35.0, tilt_deg=78.0,
                                 roll_deg=0.5, position_m=[-5.0, 55.0, -16.0])
    lines = project_pitch_polylines(cam, W, H)
    assert lines
    for runs in lines.values():
        for run in runs:
            assert run.ndim == 2 and run.shape[1] == 2 and len(run) >= 2
            assert np.all((run >= -1e-9) & (run <= np.array([W, H]) + 1e-9))


@pytest.mark.parametrize("kwargs, field", [
    ({"mode": "exact"}, "mode"),
    ({"width": 0}, "width"),
    ({"height": 540.5}, "height"),
    ({"dist": 0.0}, "dist"),
])
def test_bad_arguments_name_the_field(kwargs, field):
    args = {"camera": overhead(), "width": W, "height": H, **kwargs}
    with pytest.raises(ValueError, match=field):
        project_pitch_polylines(**args)
