"""Pairwise DLT triangulation, pair filtering and fusion (app.geometry.triangulation)."""
from __future__ import annotations

import cv2
import numpy as np
import pytest

from app.geometry.camera import Camera
from app.geometry.pair_error import PAIR_ERROR_RULES, pair_error
from app.geometry.spread import position_covariance, position_sigma_m, projected_sigma_px
from app.geometry.triangulation import (
    DROP_REASONS,
    STATUS_INSUFFICIENT_VIEWS,
    STATUS_NO_PAIR_KEPT,
    STATUS_TRIANGULATED,
    BallObservation,
    parallax_angle_deg,
    triangulate_ball,
    triangulate_dlt,
    undistort_pixels,
)

BALL = np.array([20.0, -10.0, -1.5])


def look_at(position, target, focal=2000.0, size=(1920, 1080), roll=0.0) -> Camera:
    """An undistorted camera at ``position`` whose optical axis passes through ``target`` (world, z down)."""
    position, target = np.asarray(position, float), np.asarray(target, float)
    z = target - position
    z /= np.linalg.norm(z)
    x = np.cross(z, [0.0, 0.0, 1.0])  # image x: horizontal; image y then points down (world +z) for level cameras
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    R = np.stack([x, y, z])
    c, s = np.cos(np.radians(roll)), np.sin(np.radians(roll))
    R = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1.0]]) @ R
    K = np.array([[focal, 0, size[0] / 2], [0, focal, size[1] / 2], [0, 0, 1.0]])
    return Camera(K=K, R=R, C=position)


def rig() -> list[Camera]:
    """Main camera on the y > 0 side, a replay behind the right goal and one from the opposite side."""
    return [
        look_at([0.0, 75.0, -22.0], BALL + [3.0, 1.0, 0.0], focal=3000.0),
        look_at([70.0, 4.0, -15.0], BALL + [-2.0, 2.0, 0.5], focal=2500.0, size=(960, 540), roll=1.0),
        look_at([10.0, -55.0, -12.0], BALL, focal=4000.0),
    ]


def observe(cameras, point=BALL, noise_px=0.0, seed=0) -> list[BallObservation]:
    rng = np.random.default_rng(seed)
    obs = []
    for k, cam in enumerate(cameras):
        uv, ok = cam.project(np.asarray(point, float)[None])
        assert ok[0]
        width = cam.K[0, 2] * 2
        obs.append(BallObservation(f"v{k}", cam, uv[0] + rng.normal(0.0, noise_px, 2), width))
    return obs


def test_noise_free_rig_recovers_the_ball_exactly():
    result = triangulate_ball(observe(rig()), tau_px=20.0, rule="max_scaled_1920", min_baseline_m=1.0,
                              min_parallax_deg=0.0)
    assert result.status == STATUS_TRIANGULATED
    assert result.point.shape == (3,)
    np.testing.assert_allclose(result.point, BALL, atol=1e-7)
    assert len(result.pairs) == 3 and all(p.kept and p.reason is None for p in result.pairs)
    assert all(p.point.shape == (3,) and p.error < 1e-5 for p in result.pairs)
    assert set(result.view_errors_px) == {"v0", "v1", "v2"}
    assert max(result.view_errors_px.values()) < 1e-5
    assert result.contributing_views == {"v0", "v1", "v2"}


def test_distorted_pixels_are_undistorted_before_the_dlt():
    cams = rig()
    aim = look_at(cams[0].C, BALL + [20.0, 0.0, 0.0], focal=3000.0)  # the ball ~14 degrees off the axis
    cams[0] = Camera(K=aim.K, R=aim.R, C=aim.C, radial=np.array([-0.2, 0.05, 0, 0, 0, 0]),
                     tangential=np.array([1e-3, -5e-4]))
    obs = observe(cams)
    # Distortion moves the ball by several pixels in view 0: ignoring it would bias the point.
    shift = np.linalg.norm(obs[0].point_px - cams[0].project(BALL[None], distort=False)[0][0])
    assert shift > 5.0
    result = triangulate_ball(obs, tau_px=20.0, rule="max_scaled_1920", min_baseline_m=1.0, min_parallax_deg=0.0)
    np.testing.assert_allclose(result.point, BALL, atol=1e-6)


def test_dlt_agrees_with_opencv_triangulate_points():
    cams = rig()
    obs = observe(cams, noise_px=3.0, seed=4)
    for a, b in ((0, 1), (0, 2), (1, 2)):
        P = np.stack([cams[a].projection_matrix, cams[b].projection_matrix])
        uv = np.vstack([obs[a].point_px, obs[b].point_px])
        h = triangulate_dlt(P, uv)
        ref = cv2.triangulatePoints(P[0], P[1], uv[0].reshape(2, 1), uv[1].reshape(2, 1))[:, 0]
        np.testing.assert_allclose(h[:3] / h[3], ref[:3] / ref[3], rtol=0, atol=1e-6)
        # noise moves the point: the comparison is not trivially against the truth
        assert np.linalg.norm(h[:3] / h[3] - BALL) > 1e-3


def test_fused_ball_is_the_mean_of_kept_pairs_and_per_view_errors_are_its_reprojection():
    obs = observe(rig(), noise_px=2.0, seed=1)
    result = triangulate_ball(obs, tau_px=50.0, rule="max_scaled_1920", min_baseline_m=1.0, min_parallax_deg=0.0)
    np.testing.assert_allclose(result.point, np.mean([p.point for p in result.pairs], axis=0))
    for o in obs:
        uv = o.camera.project(result.point[None])[0][0]
        assert result.view_errors_px[o.view_id] == pytest.approx(np.linalg.norm(uv - o.point_px))


def test_wrong_label_is_dropped_by_tau_and_does_not_move_the_ball():
    obs = observe(rig())
    bad = obs[2].point_px + [300.0, -150.0]
    obs[2] = BallObservation("v2", obs[2].camera, bad, obs[2].image_width)
    result = triangulate_ball(obs, tau_px=20.0, rule="max_scaled_1920", min_baseline_m=1.0, min_parallax_deg=0.0)
    by_views = {(p.view_a, p.view_b): p for p in result.pairs}
    assert by_views[("v0", "v1")].kept
    assert by_views[("v0", "v2")].reason == "error_above_tau"
    assert by_views[("v1", "v2")].reason == "error_above_tau"
    assert by_views[("v0", "v2")].error > 20.0
    np.testing.assert_allclose(result.point, BALL, atol=1e-7)
    assert result.contributing_views == {"v0", "v1"}
    assert result.view_errors_px["v2"] == pytest.approx(np.hypot(300.0, 150.0), rel=1e-6)


def test_pair_as_dict_has_the_system_view_keys():
    result = triangulate_ball(observe(rig()), tau_px=20.0, rule="max_scaled_1920", min_baseline_m=1.0,
                              min_parallax_deg=0.0)
    d = result.pairs[0].as_dict()
    assert list(d) == ["view_a", "view_b", "point", "error_px", "parallax_deg", "baseline_m", "kept", "reason"]
    assert d["view_a"] == "v0" and d["kept"] is True and d["reason"] is None
    np.testing.assert_allclose(d["point"], BALL, atol=1e-7)
    assert isinstance(d["point"][0], float)


def test_pair_error_rules_scale_to_1920_wide_images():
    assert pair_error((2.0, 3.0), (960.0, 1920.0), "max_scaled_1920") == 4.0
    assert pair_error((2.0, 3.0), (960.0, 1920.0), "mean_scaled_1920") == 3.5
    assert pair_error((2.0, 3.0), (960.0, 1920.0), "max_px") == 3.0
    assert set(PAIR_ERROR_RULES) == {"max_scaled_1920", "mean_scaled_1920", "max_px"}
    with pytest.raises(ValueError, match="pair_error_rule 'median'"):
        pair_error((1.0, 1.0), (1920.0, 1920.0), "median")
    with pytest.raises(ValueError, match="pair_error_rule"):
        triangulate_ball(observe(rig()), tau_px=20.0, rule="median", min_baseline_m=1.0, min_parallax_deg=0.0)


def test_pair_error_uses_the_rule_on_real_reprojections():
    obs = observe(rig(), noise_px=2.0, seed=2)
    pair = triangulate_ball(obs[:2], tau_px=1e6, rule="max_scaled_1920", min_baseline_m=1.0,
                            min_parallax_deg=0.0).pairs[0]
    e0, e1 = pair.errors_px
    assert pair.error == pytest.approx(max(e0 * 1920 / 1920, e1 * 1920 / 960))
    mean = triangulate_ball(obs[:2], tau_px=1e6, rule="mean_scaled_1920", min_baseline_m=1.0,
                            min_parallax_deg=0.0).pairs[0]
    assert mean.error == pytest.approx((e0 + 2 * e1) / 2)


def test_fewer_than_two_views_is_a_result_not_an_exception():
    for obs in ([], observe(rig())[:1]):
        result = triangulate_ball(obs, tau_px=20.0, rule="max_scaled_1920", min_baseline_m=1.0, min_parallax_deg=0.0)
        assert result.status == STATUS_INSUFFICIENT_VIEWS
        assert result.point is None and result.pairs == () and result.view_errors_px == {}


def test_identical_cameras_are_degenerate():
    cam = rig()[0]
    obs = [BallObservation("a", cam, cam.project(BALL[None])[0][0], 1920),
           BallObservation("b", cam, cam.project(BALL[None])[0][0], 1920)]
    result = triangulate_ball(obs, tau_px=20.0, rule="max_scaled_1920", min_baseline_m=1.0, min_parallax_deg=0.0)
    assert result.status == STATUS_NO_PAIR_KEPT and result.point is None
    assert result.pairs[0].reason == "degenerate"
    assert result.pairs[0].baseline_m == 0.0 and result.pairs[0].parallax_deg == pytest.approx(0.0, abs=1e-6)


def test_parallel_rays_meet_at_infinity():
    a = look_at([0.0, 60.0, -10.0], [0.0, 0.0, -10.0])
    b = look_at([5.0, 60.0, -10.0], [5.0, 0.0, -10.0])  # same orientation, 5 m to the side
    centre = np.array([960.0, 540.0])
    result = triangulate_ball([BallObservation("a", a, centre, 1920), BallObservation("b", b, centre, 1920)],
                              tau_px=20.0, rule="max_scaled_1920", min_baseline_m=1.0, min_parallax_deg=0.0)
    assert result.pairs[0].reason == "point_at_infinity" and result.pairs[0].point is None
    assert result.pairs[0].parallax_deg == pytest.approx(0.0, abs=1e-9)
    assert result.pairs[0].baseline_m == pytest.approx(5.0)
    assert result.status == STATUS_NO_PAIR_KEPT


def test_intersection_behind_a_camera_is_dropped():
    a = rig()[0]
    # b looks away from the ball, at the point mirrored through its centre: the two viewing LINES
    # still meet at BALL, which lies behind b.
    centre_b = np.array([10.0, -55.0, -12.0])
    b = look_at(centre_b, 2 * centre_b - BALL)
    obs = [BallObservation("a", a, a.project(BALL[None])[0][0], 1920),
           BallObservation("b", b, b.project((2 * centre_b - BALL)[None])[0][0], 1920)]
    result = triangulate_ball(obs, tau_px=1e9, rule="max_scaled_1920", min_baseline_m=1.0, min_parallax_deg=0.0)
    pair = result.pairs[0]
    assert pair.reason == "behind_camera" and not pair.kept
    np.testing.assert_allclose(pair.point, BALL, atol=1e-6)
    assert pair.error is None and pair.errors_px is None
    assert result.status == STATUS_NO_PAIR_KEPT


def test_fused_ball_behind_one_view_has_no_error_for_it():
    obs = observe(rig()[:2])
    centre = np.array([10.0, -55.0, -12.0])
    c = look_at(centre, 2 * centre - BALL)  # looks away from the ball
    obs.append(BallObservation("v2", c, c.project((2 * centre - BALL)[None])[0][0], 1920))
    result = triangulate_ball(obs, tau_px=20.0, rule="max_scaled_1920", min_baseline_m=1.0, min_parallax_deg=0.0)
    assert result.status == STATUS_TRIANGULATED
    assert result.view_errors_px["v2"] is None
    assert {p.reason for p in result.pairs if not p.kept} == {"behind_camera"}


def test_short_baseline_is_dropped_whatever_the_error():
    a = rig()[0]
    b = look_at(a.C + [0.6, 0.0, 0.0], BALL, focal=3000.0)
    result = triangulate_ball(observe([a, b]), tau_px=20.0, min_baseline_m=1.0, min_parallax_deg=0.0,
                              rule="max_scaled_1920")
    pair = result.pairs[0]
    assert pair.reason == "baseline_below_min" and pair.baseline_m == pytest.approx(0.6)
    assert pair.error < 1e-4  # a perfectly consistent pair, dropped only for its baseline
    assert result.status == STATUS_NO_PAIR_KEPT
    assert triangulate_ball(observe([a, b]), tau_px=20.0, min_baseline_m=0.5,
                            min_parallax_deg=0.0, rule="max_scaled_1920").status == STATUS_TRIANGULATED


def test_parallax_of_perpendicular_rays_is_90_degrees():
    a = look_at([0.0, 50.0, -5.0], [0.0, 0.0, -5.0])
    b = look_at([-50.0, 0.0, -5.0], [0.0, 0.0, -5.0])
    centre = np.array([960.0, 540.0])
    assert parallax_angle_deg(a, centre, b, centre) == pytest.approx(90.0, abs=1e-9)


def test_bad_input_names_the_field():
    cam = rig()[0]
    with pytest.raises(ValueError, match="point_px"):
        BallObservation("a", cam, [1.0, np.nan], 1920)
    with pytest.raises(ValueError, match="image_width"):
        BallObservation("a", cam, [1.0, 2.0], 0)
    with pytest.raises(ValueError, match="camera"):
        BallObservation("a", "not a camera", [1.0, 2.0], 1920)
    obs = observe(rig())
    with pytest.raises(ValueError, match="view ids must be unique"):
        triangulate_ball([obs[0], obs[0]], tau_px=20.0, rule="max_scaled_1920", min_baseline_m=1.0,
                         min_parallax_deg=0.0)
    with pytest.raises(ValueError, match="tau_px"):
        triangulate_ball(obs, tau_px=0.0, rule="max_scaled_1920", min_baseline_m=1.0, min_parallax_deg=0.0)
    with pytest.raises(ValueError, match=r"projections must have shape \(V, 3, 4\)"):
        triangulate_dlt(np.zeros((2, 3, 3)), np.zeros((2, 2)))
    with pytest.raises(ValueError, match="at least two views"):
        triangulate_dlt(np.zeros((1, 3, 4)), np.zeros((1, 2)))


# ----- synthetic dev set (../shared) ---------------------------------------------------------------
def _benchmark():
    from benchmarks import synthetic_ball

    return synthetic_ball


def test_dev_set_triangulation_with_true_cameras(shared_dir):
    """Dev-set figures (benchmarks/synthetic_ball.py): 3D error of uncorrupted systems, corrupted views out."""
    bench = _benchmark()
    systems = bench.load_dev_set(shared_dir)
    results = bench.triangulate_all(systems, 20.0, "max_scaled_1920", mirror_calibration=True)
    err = bench.fused_errors_m(systems, results)
    assert len(err) >= 28  # 32 uncorrupted systems, 2 of which have only a near-duplicate pair
    assert np.median(err) < 0.10 and np.percentile(err, 90) < 0.25  # measured 0.051 / 0.106 m
    counts = bench.sweep_counts(systems, results, mirror_calibration=True)
    assert counts["bad_pairs"] >= 10 and counts["bad_pairs_dropped"] == counts["bad_pairs"]
    assert counts["good_pairs_kept"] == counts["good_pairs"]
    near_duplicate = [r for s, r in zip(systems, results, strict=False)
                      if any(p.reason == "baseline_below_min" for p in r.pairs)]
    assert len(near_duplicate) == 2


def test_near_duplicate_viewpoint_is_dropped_by_parallax_even_past_the_baseline_rule():
    """Regression: two calibrated cameras 1.5 m apart (a near-duplicate replay whose centres drifted
    along the viewing axis) pass the paper's 1 m baseline rule; their rays meet at under a degree, so
    the pair must be dropped by the parallax rule, and kept when the rule is off (paper behaviour)."""
    main = look_at([0.0, 75.0, -22.0], BALL, focal=3000.0)
    near = look_at([0.0, 76.5, -22.0], BALL, focal=3000.0)
    obs = observe([main, near], noise_px=0.3)
    beta = parallax_angle_deg(main, obs[0].point_px, near, obs[1].point_px)
    assert 0.1 < beta < 2.0
    paper = triangulate_ball(obs, tau_px=20.0, min_baseline_m=1.0, min_parallax_deg=0.0, rule="max_scaled_1920")
    assert paper.pairs[0].kept
    guarded = triangulate_ball(obs, tau_px=20.0, min_baseline_m=1.0, min_parallax_deg=2.0, rule="max_scaled_1920")
    assert not guarded.pairs[0].kept and guarded.pairs[0].reason == "parallax_below_min"
    assert guarded.status == STATUS_NO_PAIR_KEPT
    wide = triangulate_ball(observe(rig()), tau_px=20.0, min_parallax_deg=2.0, rule="max_scaled_1920",
                            min_baseline_m=1.0)
    assert all(p.kept for p in wide.pairs)  # wide-angle replays are untouched
    with pytest.raises(ValueError, match="min_parallax_deg"):
        triangulate_ball(obs, tau_px=20.0, min_parallax_deg=-1.0, rule="max_scaled_1920", min_baseline_m=1.0)


def test_parallax_drop_reason_is_one_of_the_documented_reasons():
    """Regression: ``triangulate_pair`` reports ``parallax_below_min`` (tested after the baseline,
    before tau), but :data:`DROP_REASONS`, which ``PairResult.reason`` is documented to take its
    values from, did not list it."""
    main = look_at([0.0, 75.0, -22.0], BALL, focal=3000.0)
    near = look_at([0.0, 76.5, -22.0], BALL, focal=3000.0)
    pair = triangulate_ball(observe([main, near], noise_px=0.3), tau_px=20.0, min_parallax_deg=2.0,
                            rule="max_scaled_1920", min_baseline_m=1.0).pairs[0]
    assert pair.reason in DROP_REASONS
    assert DROP_REASONS.index("baseline_below_min") < DROP_REASONS.index(pair.reason) < DROP_REASONS.index(
        "error_above_tau")


def test_bad_widths_and_pixel_shapes_raise_value_errors_naming_the_field():
    """Regression: ``BallObservation`` took ``True`` as a width of 1 px and failed on a string with
    NumPy's ufunc TypeError; ``undistort_pixels`` read any input with ``reshape(-1, 2)`` and failed
    on a (3,) array with "cannot reshape"."""
    cam = rig()[0]
    for width in (True, "1920", float("nan")):
        with pytest.raises(ValueError, match="image_width"):
            BallObservation("a", cam, [1.0, 2.0], width)
    with pytest.raises(ValueError, match="points_px"):
        undistort_pixels(cam, [1.0, 2.0, 3.0])
    assert undistort_pixels(cam, [1.0, 2.0]).shape == (1, 2)


def test_uncertainty_weighting_lets_a_weakly_calibrated_view_count_less():
    """Issue 17: a view whose camera is off by 2 m (its calibration says so: std 2 m) pulls the plain
    mean; the inverse-variance weights of ``view_position_std_m`` bring the ball back."""
    cams = rig()
    obs = observe(cams)  # labels from the true cameras
    off = cams[1]
    obs[1] = BallObservation("v1", Camera(K=off.K, R=off.R, C=off.C + np.array([0.0, 2.0, -1.0])), obs[1].point_px,
                             obs[1].image_width)
    plain = triangulate_ball(obs, tau_px=500.0, rule="max_scaled_1920", min_baseline_m=1.0, min_parallax_deg=0.0)
    std = {"v0": 0.05, "v1": 2.0, "v2": 0.08}
    weighted = triangulate_ball(obs, tau_px=500.0, view_position_std_m=std, rule="max_scaled_1920", min_baseline_m=1.0,
                                min_parallax_deg=0.0)
    assert all(p.kept for p in plain.pairs)
    pts = [p.point for p in weighted.pairs]
    w = [1.0 / (0.1**2 + std[p.view_a] ** 2 + std[p.view_b] ** 2) for p in weighted.pairs]
    np.testing.assert_allclose(weighted.point, np.average(pts, axis=0, weights=w))
    err_plain, err_weighted = np.linalg.norm(plain.point - BALL), np.linalg.norm(weighted.point - BALL)
    assert err_weighted < 0.25 * err_plain and err_plain > 0.1
    # An undetermined camera (inf) gets no weight; every pair undetermined falls back to the mean.
    inf = triangulate_ball(obs, tau_px=500.0, view_position_std_m={"v1": float("inf")}, rule="max_scaled_1920",
                           min_baseline_m=1.0, min_parallax_deg=0.0)
    np.testing.assert_allclose(inf.point, plain.pairs[1].point)  # (v0, v2): the only pair without v1
    all_inf = triangulate_ball(obs, tau_px=500.0, view_position_std_m={k: float("inf") for k in std},
                               rule="max_scaled_1920", min_baseline_m=1.0, min_parallax_deg=0.0)
    np.testing.assert_allclose(all_inf.point, plain.point)


def _turned(camera: Camera, pan_deg: float) -> Camera:
    """``camera`` turned by ``pan_deg`` about the world vertical (a calibration that turns the ball ray, as
    a rig camera fitted to two line classes does)."""
    a = np.radians(pan_deg)
    turn = np.array([[np.cos(a), -np.sin(a), 0.0], [np.sin(a), np.cos(a), 0.0], [0.0, 0.0, 1.0]])
    return Camera(K=camera.K, R=camera.R @ turn, C=camera.C)


def test_weak_calibrations_neither_make_nor_move_a_ball():
    """Issue 18 (seed-204's made-wrong system): two views whose few lines turned their cameras by 1.5 deg meet
    metres off the ball; with ``view_weights`` their pair makes no ball (``weak_calibrations``), and beside a
    pair of sure views their pairs do not move it (``outweighed``); a weak view still confirms a sure one."""
    cams = rig() + [look_at([-70.0, 6.0, -16.0], BALL + [1.0, -1.0, 0.0], focal=2800.0)]
    obs = observe(cams)  # labels as the true cameras see the ball
    weak = {"v1", "v3"}
    obs = [BallObservation(o.view_id, _turned(o.camera, 1.5), o.point_px, o.image_width) if o.view_id in weak else o
           for o in obs]
    weights = {"v0": 1.0, "v2": 1.0, "v1": 0.5, "v3": 0.5}
    weak_pair = triangulate_ball([obs[1], obs[3]], tau_px=500.0, rule="max_scaled_1920", min_baseline_m=1.0,
                                 min_parallax_deg=0.0)
    assert weak_pair.status == STATUS_TRIANGULATED and np.linalg.norm(weak_pair.point - BALL) > 1.0

    plain = triangulate_ball(obs, tau_px=500.0, rule="max_scaled_1920", min_baseline_m=1.0, min_parallax_deg=0.0)
    weighted = triangulate_ball(obs, tau_px=500.0, view_weights=weights, rule="max_scaled_1920", min_baseline_m=1.0,
                                min_parallax_deg=0.0)
    assert np.linalg.norm(plain.point - BALL) > 0.5
    np.testing.assert_allclose(weighted.point, BALL, atol=1e-6)  # the sure pair (v0, v2) alone
    reasons = {(p.view_a, p.view_b): p.reason for p in weighted.pairs}
    assert reasons == {("v0", "v1"): "outweighed", ("v0", "v2"): None, ("v0", "v3"): "outweighed",
                       ("v1", "v2"): "outweighed", ("v1", "v3"): "weak_calibrations", ("v2", "v3"): "outweighed"}
    assert set(reasons.values()) - {None} <= set(DROP_REASONS)

    # two half votes make no ball; a full vote and a half one do; a view worth nothing joins no pair
    assert triangulate_ball([obs[1], obs[3]], tau_px=500.0, view_weights=weights, rule="max_scaled_1920",
                            min_baseline_m=1.0, min_parallax_deg=0.0).status == STATUS_NO_PAIR_KEPT
    assert triangulate_ball([obs[0], obs[1]], tau_px=500.0, view_weights=weights, rule="max_scaled_1920",
                            min_baseline_m=1.0, min_parallax_deg=0.0).status == STATUS_TRIANGULATED
    none = triangulate_ball([obs[0], obs[1]], tau_px=500.0, view_weights={"v1": 0.0}, rule="max_scaled_1920",
                            min_baseline_m=1.0, min_parallax_deg=0.0)
    assert none.status == STATUS_NO_PAIR_KEPT and none.pairs[0].reason == "weak_calibrations"
    # without weights (or all full) nothing changes: the paper's mean
    np.testing.assert_allclose(triangulate_ball(obs, tau_px=500.0, view_weights={}, rule="max_scaled_1920",
                                                min_baseline_m=1.0, min_parallax_deg=0.0).point, plain.point)


def test_one_undistortion_per_view_gives_the_rays_pixels_and_errors_of_the_camera_model():
    """Issue 29: ``pair_geometry`` undistorts each view's pixel once (``view_ray``) and projects one point without
    ``Camera.project``'s array handling; its parallax, DLT and reprojection errors are those of the camera model's
    own functions (``Camera.rays``, ``undistort_pixels``, ``Camera.project``), with and without distortion, and a
    memo that shares rays across pairs gives the same geometry."""
    from app.geometry.triangulation import PairGeometryMemo, _dlt, pair_geometry, reprojection_error_px

    rng = np.random.default_rng(29)
    for i in range(200):
        cams = []
        for _ in range(2):
            cam = Camera.from_parameters(focal_px=rng.uniform(1500, 3000), principal_point=(960.0, 540.0),
                                         pan_deg=rng.uniform(-180, 180), tilt_deg=rng.uniform(60, 85),
                                         roll_deg=rng.uniform(-2, 2),
                                         position_m=[rng.uniform(-60, 60), rng.uniform(40, 70), rng.uniform(-30, -10)])
            if i % 2:
                cam = Camera(K=cam.K, R=cam.R, C=cam.C, tangential=np.array([1e-4, -1e-4]),
                             radial=np.array([rng.uniform(-0.05, 0.05), rng.uniform(-0.01, 0.01), 0, 0, 0, 0]))
            cams.append(cam)
        pa, pb = rng.uniform(0, 1920, 2), rng.uniform(0, 1080, 2)
        a, b = (BallObservation(view_id=k, camera=c, point_px=p, image_width=1920)
                for k, (c, p) in enumerate(zip(cams, (pa, pb), strict=False)))
        g = pair_geometry(a, b)
        ra, rb = cams[0].rays(pa.reshape(1, 2))[0], cams[1].rays(pb.reshape(1, 2))[0]
        assert g.parallax_deg == pytest.approx(np.degrees(np.arctan2(np.linalg.norm(np.cross(ra, rb)), ra @ rb)),
                                               abs=1e-9)
        h, _ = _dlt(np.stack([cams[0].projection_matrix, cams[1].projection_matrix]),
                    np.vstack([undistort_pixels(cams[0], pa), undistort_pixels(cams[1], pb)]))
        assert np.allclose(np.abs(g.h), np.abs(h), atol=1e-12)
        assert g.baseline_m == pytest.approx(float(np.linalg.norm(cams[0].C - cams[1].C)), rel=1e-12)
        point = rng.uniform(-50, 50, 3) * [1.0, 1.0, 0.1]
        for cam, p in zip(cams, (pa, pb), strict=False):
            uv, in_front = cam.project(point.reshape(1, 3))
            expected = float(np.linalg.norm(uv[0] - p)) if in_front[0] else None
            assert reprojection_error_px(cam, point, p) == (pytest.approx(expected, rel=1e-12)
                                                            if expected is not None else None)
        shared = PairGeometryMemo()(a, b)
        assert shared.parallax_deg == g.parallax_deg and np.array_equal(shared.h, g.h)


def test_the_balls_sigma_from_two_perpendicular_views_is_the_pixel_sigma_at_its_distance():
    """Two cameras 50 m from the ball, looking along x and along y with focal 1000 px at 1920 width: a metre across
    either ray moves the ball's image by 20 px, so 10 px of sigma leave 0.5 m along x and y (each seen by one
    view) and 0.5 / sqrt(2) m along z (seen by both); the spread is the worst, 0.5 m. Half the width reads the
    sigma in px at 1920: the same spread. Rays along one line fix nothing."""
    ball = np.array([0.0, 0.0, -10.0])
    a = BallObservation("a", look_at([-50.0, 0.0, -10.0], ball, focal=1000.0), np.zeros(2), 1920)
    b = BallObservation("b", look_at([0.0, -50.0, -10.0], ball, focal=1000.0), np.zeros(2), 1920)
    assert position_sigma_m([a, b], ball, {"a": 10.0, "b": 10.0}) == pytest.approx(0.5, rel=1e-3)
    assert position_sigma_m([a, b], ball, {"a": 10.0, "b": 5.0}) == pytest.approx(0.5, rel=1e-3)  # x: a alone
    assert position_sigma_m([a], ball, {"a": 10.0}) is None
    half = BallObservation("h", look_at([0.0, -50.0, -10.0], ball, focal=500.0, size=(960, 540)), np.zeros(2), 960)
    assert position_sigma_m([a, half], ball, {"a": 10.0, "h": 10.0}) == pytest.approx(0.5, rel=1e-3)
    behind = BallObservation("c", look_at([0.0, -50.0, -10.0], ball + [0.0, -100.0, 0.0]), np.zeros(2), 1920)
    assert position_sigma_m([a, behind], ball, {"a": 10.0, "c": 10.0}) is None


def test_the_balls_covariance_projected_into_a_third_view_is_its_pixel_spread_there():
    """Two orthogonal cameras 50 m from the ball (focal 1000 px at 1920 width), 10 px each: the ball's covariance is
    0.5 m along x and along y (each fixed by one camera alone), and z is fixed by both (0.5 / sqrt 2). A third camera
    100 m up the y axis, focal 2000 px, sees x across its image: 0.5 m at 100 m is 10 px there; one looking down
    the x axis sees y and z, the larger 0.5 m: 10 px too; one behind the ball: None."""
    ball = np.array([0.0, 0.0, -10.0])
    a = BallObservation("a", look_at([-50.0, 0.0, -10.0], ball, focal=1000.0), np.zeros(2), 1920)
    b = BallObservation("b", look_at([0.0, -50.0, -10.0], ball, focal=1000.0), np.zeros(2), 1920)
    cov = position_covariance([a, b], ball, {"a": 10.0, "b": 10.0})
    assert np.allclose(np.sqrt(np.diag(cov)), [0.5, 0.5, 0.5 / np.sqrt(2)], rtol=1e-3)
    assert position_covariance([a], ball, {"a": 10.0}) is None
    third = BallObservation("t", look_at([0.0, 100.0, -10.0], ball, focal=2000.0), np.zeros(2), 1920)
    assert projected_sigma_px(third, ball, cov) == pytest.approx(10.0, rel=1e-2)
    along_x = BallObservation("x", look_at([100.0, 0.0, -10.0], ball, focal=2000.0), np.zeros(2), 1920)
    assert projected_sigma_px(along_x, ball, cov) == pytest.approx(10.0, rel=1e-2)
    behind = BallObservation("c", look_at([0.0, -50.0, -10.0], ball + [0.0, -100.0, 0.0]), np.zeros(2), 1920)
    assert projected_sigma_px(behind, ball, cov) is None
