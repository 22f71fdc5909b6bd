"""Monocular 3D ball, optimised box and exact sphere silhouette (app.geometry.ball)."""
from __future__ import annotations

import json

import numpy as np
import pytest

from app.geometry.ball import (
    OPTIMISED_BOX_METHODS,
    ball_from_box,
    ball_from_box_exact,
    ball_from_centre_diameter,
    box_centre_and_diameter,
    optimise_box,
    sphere_image_box,
)
from app.geometry.camera import Camera

PHI = 0.22


def camera(distorted: bool = False) -> Camera:
    """Broadcast-like main camera: 1920x1080, f = 2500 px, 20 m high on the y > 0 side."""
    cam = Camera.from_parameters(focal_px=2500.0, principal_point=(960.0, 540.0), pan_deg=5.0, tilt_deg=78.0,
                                 roll_deg=0.3, position_m=[0.0, 60.0, -20.0])
    if not distorted:
        return cam
    return Camera(K=cam.K, R=cam.R, C=cam.C, radial=np.array([-0.15, 0.04, 0, 0, 0, 0]),
                  tangential=np.array([5e-4, -2e-4]), thin_prism=np.array([1e-4, 0, 0, 1e-4]))


def brute_force_box(cam: Camera, centre: np.ndarray, radius: float, n: int = 100_000) -> np.ndarray:
    """Box of the projections of n points spread over the sphere (Fibonacci lattice): the silhouette
    box seen from inside, independent of the conic algebra."""
    k = np.arange(n) + 0.5
    z = 1 - 2 * k / n
    t = np.pi * (1 + 5**0.5) * k
    r = np.sqrt(1 - z * z)
    pts = centre + radius * np.stack([r * np.cos(t), r * np.sin(t), z], axis=1)
    uv, ok = cam.project(pts)
    uv = uv[ok]
    return np.array([uv[:, 0].min(), uv[:, 1].min(), uv[:, 0].max(), uv[:, 1].max()])


def test_box_centre_and_diameter_uses_the_mean_of_width_and_height():
    c, d = box_centre_and_diameter(np.array([[10.0, 20.0, 30.0, 44.0], [0.0, 0.0, 4.0, 2.0]]))
    np.testing.assert_allclose(c, [[20.0, 32.0], [2.0, 1.0]])
    np.testing.assert_allclose(d, [22.0, 3.0])
    with pytest.raises(ValueError, match="x2 > x1"):
        box_centre_and_diameter([10.0, 0.0, 10.0, 5.0])
    with pytest.raises(ValueError, match=r"boxes must have shape \(4,\) or \(N, 4\)"):
        box_centre_and_diameter([1.0, 2.0, 3.0])


def test_monocular_ball_is_at_depth_phi_f_over_d_on_the_centre_ray():
    cam = camera()
    centres = np.array([[960.0, 540.0], [300.0, 900.0], [1700.0, 100.0]])
    d = np.array([10.0, 5.5, 22.0])
    p = ball_from_centre_diameter(cam, centres, d, PHI)
    assert p.shape == (3, 3)
    depth = cam.points_in_camera(p)[:, 2]
    np.testing.assert_allclose(depth, PHI * 2500.0 / d, rtol=1e-12)
    uv, _ = cam.project(p)
    np.testing.assert_allclose(uv, centres, atol=1e-9)


def test_monocular_ball_from_an_exact_on_axis_box():
    cam = camera()
    axis = cam.R[2]  # optical axis in the world frame
    D, r = 40.0, PHI / 2
    box = sphere_image_box(cam, cam.C + D * axis, r)
    # d = 2 f tan(asin(r / D)) and depth = phi f / d give depth sqrt(D^2 - r^2): the small-angle
    # model puts the ball 0.15 mm short at 40 m on the axis.
    np.testing.assert_allclose(ball_from_box(cam, box, PHI)[0], cam.C + np.sqrt(D * D - r * r) * axis, atol=1e-9)


def test_monocular_ball_rejects_bad_input():
    cam = camera()
    with pytest.raises(ValueError, match="diameters_px"):
        ball_from_centre_diameter(cam, [960.0, 540.0], 0.0, PHI)
    with pytest.raises(ValueError, match="ball_diameter_m"):
        ball_from_centre_diameter(cam, [960.0, 540.0], 5.0, -1.0)


def test_monocular_ball_rejects_a_flat_list_of_centres():
    """Regression: centres were read with ``reshape(-1, 2)``, so a (4,) box passed by mistake for a
    centre became two centres and returned two balls without a word, and a (3,) array failed with
    NumPy's "cannot reshape" message; a (3,) list of diameters for two centres failed inside
    ``broadcast_to``. All now raise a ValueError naming the argument."""
    cam = camera()
    with pytest.raises(ValueError, match="centres_px"):
        ball_from_centre_diameter(cam, [950.0, 530.0, 970.0, 550.0], 20.0, PHI)
    with pytest.raises(ValueError, match="centres_px"):
        ball_from_centre_diameter(cam, [960.0, 540.0, 1.0], 20.0, PHI)
    with pytest.raises(ValueError, match="diameters_px"):
        ball_from_centre_diameter(cam, [[960.0, 540.0], [100.0, 100.0]], [4.0, 4.0, 4.0], PHI)


@pytest.mark.parametrize("distorted", [False, True])
def test_optimised_box_inverts_the_monocular_estimate(distorted):
    cam = camera(distorted)
    for centre, d in (([960.0, 540.0], 9.0), ([200.0, 950.0], 14.0), ([1800.0, 150.0], 4.0)):
        p = ball_from_centre_diameter(cam, centre, d, PHI)[0]
        r = optimise_box(cam, centre, p, PHI)
        assert r.status == "ok" and r.method == "paper"
        assert r.d_px == pytest.approx(d, rel=1e-7)
        assert r.error_m == pytest.approx(0.0, abs=1e-9)
        np.testing.assert_allclose(r.box, [centre[0] - d / 2, centre[1] - d / 2, centre[0] + d / 2, centre[1] + d / 2])
        np.testing.assert_allclose(r.ray_point, p, atol=1e-9)


def test_optimised_box_error_is_the_distance_from_the_ball_to_the_annotated_ray():
    cam = camera()
    centre = np.array([700.0, 600.0])
    on_ray = ball_from_centre_diameter(cam, centre, 8.0, PHI)[0]
    ray = cam.rays(centre[None])[0]
    side = np.cross(ray, [0.0, 0.0, 1.0])
    side /= np.linalg.norm(side)
    p = on_ray + 0.7 * side  # 0.7 m off the ray, perpendicular to it
    r = optimise_box(cam, centre, p, PHI)
    assert r.error_m == pytest.approx(0.7, rel=1e-9)
    assert r.d_px == pytest.approx(8.0, rel=1e-9)  # same depth as the point on the ray


def test_optimised_box_for_a_ball_behind_the_camera():
    cam = camera()
    centre = np.array([960.0, 540.0])
    behind = cam.C - 30.0 * cam.R[2]
    for method in OPTIMISED_BOX_METHODS:
        r = optimise_box(cam, centre, behind, PHI, method=method)
        assert r.status == "behind_camera" and r.box is None and r.d_px is None and r.ray_point is None
        assert r.error_m == pytest.approx(30.0)


def test_exact_variants_are_the_silhouette_boxes():
    cam = camera()
    centre = np.array([1700.0, 950.0])  # far off-axis: the silhouette is a visibly stretched ellipse
    on_ray = ball_from_centre_diameter(cam, centre, 12.0, PHI)[0]
    p = on_ray + np.array([0.3, -0.2, 0.1])
    ray = optimise_box(cam, centre, p, PHI, method="exact_ray")
    fused = optimise_box(cam, centre, p, PHI, method="exact_fused")
    paper = optimise_box(cam, centre, p, PHI, method="paper")
    np.testing.assert_allclose(ray.box, sphere_image_box(cam, paper.ray_point, PHI / 2))
    np.testing.assert_allclose(fused.box, sphere_image_box(cam, p, PHI / 2))
    assert ray.error_m == fused.error_m == paper.error_m
    w, h = ray.box[2] - ray.box[0], ray.box[3] - ray.box[1]
    assert ray.d_px == pytest.approx((w + h) / 2)
    assert w > paper.d_px and h > paper.d_px  # off-axis stretch the small-angle model misses
    with pytest.raises(ValueError, match="method 'median'"):
        optimise_box(cam, centre, p, PHI, method="median")


def test_sphere_box_on_the_axis_matches_the_angular_diameter():
    cam = camera()
    D = 35.0
    box = sphere_image_box(cam, cam.C + D * cam.R[2], 0.11)
    expected = 2 * 2500.0 * np.tan(np.arcsin(0.11 / D))
    assert box[2] - box[0] == pytest.approx(expected, rel=1e-9)
    assert box[3] - box[1] == pytest.approx(expected, rel=1e-9)
    np.testing.assert_allclose((box[:2] + box[2:]) / 2, [960.0, 540.0], atol=1e-9)


@pytest.mark.parametrize("distorted", [False, True])
def test_sphere_box_off_axis_matches_a_brute_force_silhouette(distorted):
    cam = camera(distorted)
    centre = ball_from_centre_diameter(cam, [1750.0, 980.0], 30.0, PHI)[0]  # close and near the corner
    box = sphere_image_box(cam, centre, 0.11)
    brute = brute_force_box(cam, centre, 0.11)
    # the lattice sees the silhouette from inside: within a few thousandths of a pixel
    assert np.all(np.abs(box - brute) < 5e-3)
    assert box[0] <= brute[0] + 1e-9 and box[2] >= brute[2] - (1e-4 if distorted else 1e-9)


@pytest.mark.parametrize("distorted", [False, True])
def test_exact_monocular_ball_inverts_the_silhouette_box_off_axis(distorted):
    cam = camera(distorted)
    truth = ball_from_centre_diameter(cam, [[1750.0, 980.0], [150.0, 120.0], [960.0, 540.0]],
                                      [25.0, 6.0, 10.0], PHI)
    boxes = np.array([sphere_image_box(cam, t, PHI / 2) for t in truth])
    exact = ball_from_box_exact(cam, boxes, PHI)
    assert exact.shape == (3, 3)
    np.testing.assert_allclose(exact, truth, atol=1e-6)
    # the paper's formula on the same boxes is biased off the axis (tens of centimetres here)
    paper = ball_from_box(cam, boxes, PHI)
    assert np.linalg.norm(paper[0] - truth[0]) > 0.05


def test_exact_monocular_ball_of_a_loose_box_is_a_least_squares_compromise():
    cam = camera()
    truth = ball_from_centre_diameter(cam, [600.0, 700.0], 12.0, PHI)[0]
    box = sphere_image_box(cam, truth, PHI / 2)
    wide = box + np.array([-1.0, 0.0, 1.0, 0.0])  # 2 px wider, same height and centre
    est = ball_from_box_exact(cam, wide, PHI)[0]
    dist = np.linalg.norm(truth - cam.C)
    # the estimate moves toward the camera (bigger box = nearer ball), along the line of sight
    assert 0.0 < dist - np.linalg.norm(est - cam.C) < 0.2 * dist
    assert np.linalg.norm(np.cross(est - cam.C, truth - cam.C)) / (dist * dist) < 1e-2
    with pytest.raises(ValueError, match="ball_diameter_m"):
        ball_from_box_exact(cam, box, 0.0)


def test_sphere_box_not_entirely_in_front_is_none():
    cam = camera()
    assert sphere_image_box(cam, cam.C + 0.05 * cam.R[2], 0.11) is None  # camera inside the ball
    assert sphere_image_box(cam, cam.C - 10.0 * cam.R[2], 0.11) is None  # behind
    with pytest.raises(ValueError, match="radius_m"):
        sphere_image_box(cam, [0.0, 0.0, 0.0], 0.0)
    with pytest.raises(ValueError, match="centre_world"):
        sphere_image_box(cam, [0.0, 0.0], 0.11)


# ----- synthetic dev set (../shared) ---------------------------------------------------------------
def test_sphere_box_reproduces_the_dev_set_precise_boxes_and_inverts_them(shared_dir):
    truth = json.loads((shared_dir / "data/synthetic/soccernet-v3-dev.truth.json").read_text())
    assert truth["conventions"]["ball_diameter_m"] == PHI
    n = 0
    for game in truth["games"]:
        for system in game["systems"]:
            for view in system["views"]:
                cam = Camera.from_soccernet(view["camera"])
                box = sphere_image_box(cam, view["ball_3d_shown"], PHI / 2)
                np.testing.assert_allclose(box, view["precise_box"], atol=1e-6)
                exact = ball_from_box_exact(cam, view["precise_box"], PHI)[0]
                np.testing.assert_allclose(exact, view["ball_3d_shown"], atol=1e-6)
                n += 1
    assert n == 105


def _benchmark():
    from benchmarks import synthetic_ball

    return synthetic_ball


def test_dev_set_optimised_boxes_beat_the_annotated_boxes(shared_dir):
    """Paper, real data: IoU 0.57 -> 0.66, size error 19.0 % -> 7.3 %. Measured here (true cameras):
    annotated 0.566 / 19.0 %, paper 0.618 / 1.4 %, exact_ray 0.623 / 0.08 %; the IoU ceiling is set
    by the annotated centres, which all variants but exact_fused keep."""
    bench = _benchmark()
    systems = bench.load_dev_set(shared_dir)
    results = bench.triangulate_all(systems, 20.0, "max_scaled_1920")
    study = bench.box_study(systems, results)
    ann, paper, exact = study["annotated"], study["paper"], study["exact_ray"]
    assert ann["n"] == paper["n"] == exact["n"] >= 70
    assert 0.5 < ann["iou"] < 0.63 and 15.0 < ann["size_error_pct"] < 23.0  # the generator's loose boxes
    assert paper["iou"] > ann["iou"] + 0.03 and paper["size_error_pct"] < 4.0
    assert exact["iou"] >= paper["iou"] and exact["size_error_pct"] < 0.5
    # monocular ball: a box and the estimator of the same model agree with the triangulated ball to
    # centimetres (measured 0.064 m); loose annotated boxes put it metres away (measured 10.2 m)
    assert paper["paper_formula"]["mae_m"] < 0.2 and paper["paper_formula"]["p_at_2m"] == 1.0
    assert exact["exact_inverse"]["mae_m"] < 0.2 and exact["exact_inverse"]["p_at_2m"] == 1.0
    assert ann["paper_formula"]["mae_m"] > 3.0
    # precise boxes: the exact inverse is exact, the paper's small-angle formula is not (0.51 m)
    assert study["precise"]["exact_inverse"]["mae_m"] < 1e-6
    assert study["precise"]["paper_formula"]["mae_m"] > 0.2
