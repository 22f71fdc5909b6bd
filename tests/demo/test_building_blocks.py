"""Unit tests of the demo's building blocks: camera aiming, clipping, label noise, the ball image."""
from __future__ import annotations

import numpy as np
import pytest

from app.demo.labels import (
    box_iou,
    box_size_error,
    clip_segments_to_rect,
    jitter_box,
    loose_ball_box,
    misplaced_ball_box,
    visible_runs,
)
from app.demo.render import clip_polygon_near, render_ball
from app.demo.rig import RIG, framing_camera
from app.demo.scene import precise_ball_box, sphere_silhouette
from app.geometry.camera import look_at_rotation, pan_tilt_roll_from_rotation


@pytest.mark.parametrize("name", sorted(RIG))
def test_look_at_is_a_level_rotation_through_the_target(name: str) -> None:
    c = np.array(RIG[name].position_m)
    target = np.array([10.0, -5.0, -0.11])
    R = look_at_rotation(c, target)
    assert np.allclose(R @ R.T, np.eye(3)) and np.isclose(np.linalg.det(R), 1.0)
    assert np.allclose(R[2], (target - c) / np.linalg.norm(target - c))
    assert abs(R[0, 2]) < 1e-12  # image x axis horizontal (no roll)
    assert R[1, 2] > 0  # image y axis points down the world (+z)


def test_look_at_roll_is_the_soccernet_roll() -> None:
    R = look_at_rotation(np.array([0.0, 79.0, -20.0]), np.array([30.0, 0.0, 0.0]), roll_deg=1.5)
    pan, tilt, roll = pan_tilt_roll_from_rotation(R)
    assert roll == pytest.approx(1.5) and 60 < tilt < 90


def test_framing_camera_spans_the_requested_width() -> None:
    c, t = np.array([0.0, 70.0, -18.0]), np.array([5.0, 0.0, 0.0])
    cam = framing_camera(c, t, 40.0, 960, 540)
    side = np.cross(t - c, [0.0, 0.0, 1.0])
    side /= np.linalg.norm(side)
    uv, _ = cam.project(np.stack([t - 20.0 * side, t + 20.0 * side]))
    assert abs(abs(uv[1, 0] - uv[0, 0]) - 960.0) < 1.0  # 40 m at the target fill the width


def test_clip_segments_and_visible_runs_end_on_the_border() -> None:
    t0, t1, keep = clip_segments_to_rect(np.array([[-5.0, 5.0], [1.0, 1.0], [20.0, 20.0]]),
                                         np.array([[5.0, 5.0], [2.0, 2.0], [30.0, 30.0]]), 10.0, 10.0)
    assert keep.tolist() == [True, True, False]
    assert (t0[0], t1[0], t0[1], t1[1]) == (0.5, 1.0, 0.0, 1.0)
    uv = np.array([[-2.0, 5.0], [2.0, 5.0], [6.0, 5.0], [12.0, 5.0], [np.nan, np.nan], [4.0, 2.0], [4.0, 4.0]])
    ok = np.array([True, True, True, True, False, True, True])
    runs = visible_runs(uv, ok, 10.0, 10.0)
    assert len(runs) == 2  # broken where a point is behind the camera
    assert np.allclose(runs[0], [[0.0, 5.0], [2.0, 5.0], [6.0, 5.0], [10.0, 5.0]])
    assert np.allclose(runs[1], [[4.0, 2.0], [4.0, 4.0]])


def test_clip_polygon_near_keeps_the_front_part() -> None:
    square = np.array([[-1.0, -1.0, -1.0], [1.0, -1.0, -1.0], [1.0, -1.0, 3.0], [-1.0, -1.0, 3.0]])
    out = clip_polygon_near(square, near=1.0)
    assert out[:, 2].min() == pytest.approx(1.0) and out[:, 2].max() == pytest.approx(3.0) and len(out) == 4
    assert len(clip_polygon_near(square - [0, 0, 10.0], near=1.0)) == 0


def test_loose_ball_boxes_match_the_paper_statistics() -> None:
    """Against precise boxes, real SoccerNet-v3 ball boxes have IoU 0.57 and size error 19 %
    (paper Table "bboxopt"); the noise model reproduces both over many draws."""
    rng = np.random.default_rng(0)
    ious, errs = [], []
    for d in np.tile([4.0, 7.0, 12.0, 25.0], 500):
        c = rng.uniform(100, 400, 2)
        precise = np.array([c[0] - d / 2, c[1] - d / 2, c[0] + d / 2, c[1] + d / 2])
        box = loose_ball_box(precise, 960, 540, rng)
        assert np.all(box == np.round(box)) and box[2] > box[0] and box[3] > box[1]
        ious.append(box_iou(box, precise))
        errs.append(box_size_error(box, precise))
    assert 0.52 < np.mean(ious) < 0.64 and 0.15 < np.mean(errs) < 0.24, (np.mean(ious), np.mean(errs))


def test_misplaced_box_is_far_and_jittered_box_drops_outside_figures() -> None:
    rng = np.random.default_rng(1)
    box = np.array([500.0, 300.0, 508.0, 308.0])
    moved = misplaced_ball_box(box, 960, 540, rng, np.array([504.0, 304.0]))
    assert box_iou(moved, box) == 0.0 and np.hypot(moved[0] - box[0], moved[1] - box[1]) > 0.14 * 960
    assert moved[2] - moved[0] == 8 and moved[3] - moved[1] == 8
    assert jitter_box(np.array([-60.0, 100.0, 10.0, 200.0]), 960, 540, rng) is None  # mostly outside
    kept = jitter_box(np.array([100.0, 100.0, 140.0, 220.0]), 960, 540, rng)
    assert kept is not None and np.all(np.abs(kept - [100, 100, 140, 220]) <= 4)


def test_ball_silhouette_is_the_ray_cast_sphere_off_axis() -> None:
    """Near the image corner the ball's image is an ellipse stretched away from the principal
    point; the ray-cast rendering covers exactly the silhouette's box."""
    cam = framing_camera(np.array([0.0, 4.0, -1.5]), np.array([0.0, 0.0, 0.0]), 4.0, 960, 540)
    ball = np.array([1.6, 0.5, -0.11])  # 4 m away, near the right edge: a 60 px ellipse
    uv = sphere_silhouette(cam, ball)
    box = precise_ball_box(cam, ball)
    assert uv[:, 0].max() < 960
    centre_px = cam.project(ball[None, :])[0][0]
    assert box[2] - box[0] > 1.05 * (box[3] - box[1])  # stretched along the (mostly horizontal) radius
    assert (box[0] + box[2]) / 2 - centre_px[0] > 0.3  # its centre is off the projected centre, outwards
    img = np.zeros((540, 960, 3), np.uint8)
    render_ball(img, cam, ball, supersample=8)
    ys, xs = np.nonzero(img.any(axis=2))
    assert xs.min() == int(np.floor(box[0])) and xs.max() == int(np.ceil(box[2])) - 1
    assert ys.min() == int(np.floor(box[1])) and ys.max() == int(np.ceil(box[3])) - 1
