"""Calibration from field lines: synthetic frames with a known camera, refusals, the mirror flag,
and the residual model against an independent projection."""
from __future__ import annotations

import numpy as np
import pytest

from app.geometry.annotations import AnnotationError, FieldLines, mirror_lines
from app.geometry.calibration import CalibrationPrior, calibrate_frame, principal_point
from app.geometry.calibration.initialisation import camera_from_homography
from app.geometry.calibration.observations import build_observations
from app.geometry.calibration.residuals import point_distances, projection_matrix
from app.geometry.camera import Camera, look_at_rotation, pan_tilt_roll_from_rotation
from app.geometry.pitch import CIRCLES, sample_pitch_polylines


def _camera(centre: tuple[float, float, float], target: tuple[float, float, float], focal: float,
            width: int, height: int, roll_deg: float = 0.0) -> Camera:
    R = look_at_rotation(np.array(centre, float), np.array(target, float))
    c, s = np.cos(np.radians(roll_deg)), np.sin(np.radians(roll_deg))
    R = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]]) @ R
    pp = principal_point(width, height)
    K = np.array([[focal, 0.0, pp[0]], [0.0, focal, pp[1]], [0.0, 0.0, 1.0]])
    return Camera(K=K, R=R, C=np.array(centre, float))


def synthetic_lines(camera: Camera, width: int, height: int, sigma_px: float, seed: int,
                    min_extent_px: float = 40.0) -> FieldLines:
    """Label a frame as an annotator would: every model element whose visible part spans at least
    ``min_extent_px``, a handful of points along it (more on circles), Gaussian noise ``sigma_px``."""
    rng = np.random.default_rng(seed)
    out: FieldLines = {}
    for cls, X in sample_pitch_polylines().items():
        uv, ok = camera.project(X)
        inside = ok & (uv[:, 0] >= 0) & (uv[:, 0] <= width - 1) & (uv[:, 1] >= 0) & (uv[:, 1] <= height - 1)
        pts = uv[inside]
        if len(pts) < 2 or (np.linalg.norm(pts[-1] - pts[0]) < min_extent_px
                            and np.ptp(pts, axis=0).max() < min_extent_px):
            continue
        n = 12 if cls in CIRCLES else 4
        pick = pts[np.linspace(0, len(pts) - 1, n).round().astype(int)]
        out[cls] = [pick + rng.normal(0.0, sigma_px, pick.shape)]
    return out


def _angle_between_deg(Ra: np.ndarray, Rb: np.ndarray) -> float:
    cos = (np.trace(Ra @ Rb.T) - 1.0) / 2.0
    return float(np.degrees(np.arccos(np.clip(cos, -1.0, 1.0))))


SCENES = {
    # name: (centre, target, focal px, width, height)
    "main centre wide": ((0.0, 62.0, -18.0), (0.0, -4.0, 0.0), 900.0, 960, 540),
    "main left box": ((-8.0, 58.0, -16.0), (-38.0, -2.0, 0.0), 1300.0, 960, 540),
    "main right box 1080p": ((5.0, 70.0, -22.0), (40.0, 2.0, 0.0), 2600.0, 1920, 1080),
    "behind goal high": ((72.0, 3.0, -15.0), (38.0, 0.0, 0.0), 800.0, 960, 540),
    "opposite side": ((0.0, -60.0, -20.0), (-20.0, 5.0, 0.0), 1000.0, 960, 540),
}


@pytest.mark.parametrize("scene", sorted(SCENES))
def test_synthetic_camera_is_recovered(scene: str) -> None:
    centre, target, focal, width, height = SCENES[scene]
    truth = _camera(centre, target, focal, width, height, roll_deg=0.4)
    sigma = 1.0 * width / 960.0
    lines = synthetic_lines(truth, width, height, sigma_px=sigma, seed=7)
    assert len(lines) >= 4, f"scene {scene} must show enough lines, got {sorted(lines)}"
    result = calibrate_frame(lines, width, height, compute_jac=False)
    assert result.calibrated, result.refusal
    cam = result.camera
    assert cam is not None
    assert abs(cam.K[0, 0] / focal - 1.0) < 0.03
    assert np.linalg.norm(cam.C - truth.C) < 0.03 * np.linalg.norm(truth.C - np.array(target))
    assert _angle_between_deg(cam.R, truth.R) < 0.3
    # Residuals are near the noise level, per class.
    assert max(result.residuals_px.values()) < 5.0 * sigma
    assert result.rms_px is not None and result.rms_px < 2.0 * sigma
    assert result.elapsed_ms > 0


def test_exact_labels_give_exact_camera() -> None:
    truth = _camera((-3.0, 55.0, -14.0), (-30.0, 0.0, 0.0), 1100.0, 960, 540)
    lines = synthetic_lines(truth, 960, 540, sigma_px=0.0, seed=0)
    cam = calibrate_frame(lines, 960, 540, compute_jac=False).camera
    assert cam is not None
    np.testing.assert_allclose(cam.C, truth.C, atol=1e-4)
    np.testing.assert_allclose(cam.K, truth.K, atol=1e-3)
    np.testing.assert_allclose(pan_tilt_roll_from_rotation(cam.R), pan_tilt_roll_from_rotation(truth.R), atol=1e-5)


def test_jac_of_synthetic_frame_is_high() -> None:
    truth = _camera((0.0, 62.0, -18.0), (0.0, -4.0, 0.0), 900.0, 960, 540)
    lines = synthetic_lines(truth, 960, 540, sigma_px=1.0, seed=3)
    result = calibrate_frame(lines, 960, 540)
    assert result.calibrated
    assert result.jac["0.005"] >= 0.9
    assert result.jac["0.02"] == 1.0


def test_point_distances_match_dense_projection() -> None:
    """The line/conic residual model against an independent one: the distance of each labelled
    point to the densely projected model element (Camera.project)."""
    cam = _camera((-8.0, 58.0, -16.0), (-38.0, -2.0, 0.0), 1300.0, 960, 540)
    rng = np.random.default_rng(1)
    lines = synthetic_lines(cam, 960, 540, sigma_px=0.0, seed=1)
    # Move every point by a known offset off its element, 0 to 3 px.
    moved: FieldLines = {}
    dense = sample_pitch_polylines(0.01, 0.01)
    expected = []
    for cls, polys in sorted(lines.items()):
        uv, _ = cam.project(dense[cls])
        pts = polys[0]
        out = []
        for p in pts:
            j = int(np.argmin(np.linalg.norm(uv - p, axis=1)))
            tangent = uv[min(j + 1, len(uv) - 1)] - uv[max(j - 1, 0)]
            normal = np.array([-tangent[1], tangent[0]]) / np.linalg.norm(tangent)
            off = rng.uniform(0.0, 3.0)
            q = p + off * normal
            out.append(q)
            expected.append((cls, float(np.min(np.linalg.norm(uv - q, axis=1)))))
        moved[cls] = [np.array(out)]
    obs = build_observations(moved)
    P = projection_matrix(cam.K[0, 0], cam.K[:2, 2], cam.R, cam.C)
    d_seg, d_cir = point_distances(P, obs)
    got = {c: np.abs(d_seg[obs.seg_index == i]) for i, c in enumerate(obs.seg_classes)}
    got.update({c: np.abs(d_cir[obs.circle_index == i]) for i, c in enumerate(obs.circle_classes)})
    for cls in got:
        want = np.array([d for c, d in expected if c == cls])
        order = np.argsort(want)
        if cls in CIRCLES:
            # Sampson's distance is first order: within a few per cent a few pixels off the curve.
            np.testing.assert_allclose(np.sort(got[cls]), want[order], rtol=0.08, atol=0.02)
        else:
            np.testing.assert_allclose(np.sort(got[cls]), want[order], atol=0.02)


def test_camera_from_homography_inverts_projection() -> None:
    truth = _camera((10.0, 65.0, -20.0), (25.0, 0.0, 0.0), 1500.0, 960, 540)
    P = truth.projection_matrix
    f, R, C = camera_from_homography(P[:, (0, 1, 3)] * -3.0, principal_point(960, 540))
    assert f == pytest.approx(1500.0, rel=1e-9)
    np.testing.assert_allclose(R, truth.R, atol=1e-9)
    np.testing.assert_allclose(C, truth.C, atol=1e-6)


def test_a_homography_from_exactly_eight_equations_is_the_true_one() -> None:
    """Four labelled lines, two points each, two along each pitch direction: eight point-on-line
    equations, the fewest that fix the ground homography; its null vector needs the full SVD of the
    (8, 9) DLT matrix (a thin SVD has no ninth vector)."""
    from app.geometry.calibration.initialisation import ground_homographies

    truth = _camera((-5.0, 60.0, -18.0), (-30.0, 0.0, 0.0), 1200.0, 960, 540)
    ends = {"Side line top": ([-45.0, -34.0, 0.0], [-20.0, -34.0, 0.0]),
            "Big rect. left bottom": ([-50.0, 20.16, 0.0], [-38.0, 20.16, 0.0]),
            "Big rect. left main": ([-36.0, -15.0, 0.0], [-36.0, 15.0, 0.0]),
            "Middle line": ([0.0, -25.0, 0.0], [0.0, 25.0, 0.0])}
    lines = {}
    for cls, (a, b) in ends.items():
        uv, ok = truth.project(np.array([a, b]))
        assert ok.all()
        lines[cls] = [uv]
    obs = build_observations(lines)
    (name, H), *_ = ground_homographies(obs, principal_point(960, 540), 960.0)
    assert name == "lines"
    H_true = truth.projection_matrix[:, (0, 1, 3)]
    H_true = H_true / np.linalg.norm(H_true) * np.sign(H_true[2, 2] * H[2, 2])
    np.testing.assert_allclose(H, H_true, atol=1e-9)


def test_one_line_is_refused_with_reason() -> None:
    lines = {"Side line top": [np.array([[10.0, 100.0], [900.0, 120.0]])]}
    result = calibrate_frame(lines, 960, 540, compute_jac=False)
    assert result.status == "refused" and result.camera is None
    assert result.refusal.code == "few_constraints" and result.refusal.numbers["need"] == 7, result.refusal
    assert "few_lines" in result.flags


def test_parallel_lines_only_are_refused_as_degenerate() -> None:
    lines = {
        "Side line top": [np.array([[0.0, 100.0], [959.0, 110.0]])],
        "Big rect. left top": [np.array([[0.0, 180.0], [700.0, 190.0]])],
        "Small rect. left top": [np.array([[50.0, 260.0], [500.0, 270.0]])],
        "Small rect. left bottom": [np.array([[0.0, 400.0], [400.0, 420.0]])],
    }
    result = calibrate_frame(lines, 960, 540, compute_jac=False)
    assert result.status == "refused"
    assert result.refusal.code == "parallel_lines", result.refusal


def test_collinear_labels_are_refused_as_degenerate() -> None:
    # Four classes along both pitch directions, but every point lies on one image line.
    def line(x0, x1):
        return np.array([[x0, 200.0 + 0.1 * x0], [x1, 200.0 + 0.1 * x1]])
    lines = {"Side line top": [line(0, 300)], "Middle line": [line(320, 500)],
             "Big rect. left main": [line(520, 700)], "Side line bottom": [line(720, 950)]}
    result = calibrate_frame(lines, 960, 540, compute_jac=False)
    assert result.status == "refused"
    assert result.refusal.code == "collinear_points", result.refusal


def test_bad_input_raises_naming_the_field() -> None:
    with pytest.raises(ValueError, match="width and height"):
        calibrate_frame({}, 0, 540)
    with pytest.raises(AnnotationError, match="Side line top"):
        calibrate_frame({"Side line top": [np.array([[1.0, np.nan]])]}, 960, 540)
    with pytest.raises(ValueError, match="expected_side"):
        CalibrationPrior(expected_side=2)


def test_unknown_class_or_ragged_polyline_raises_annotation_error() -> None:
    """Regression: an unknown class escaped ``calibrate_frame`` as a bare KeyError from
    ``build_observations`` and a ragged polyline as NumPy's "inhomogeneous shape" ValueError,
    although the docstring promises an AnnotationError naming the class (the services turn
    AnnotationError into a 422 that names the field)."""
    with pytest.raises(AnnotationError, match="unknown line class 'Side line middle'"):
        calibrate_frame({"Side line middle": [np.zeros((3, 2))]}, 960, 540)
    with pytest.raises(AnnotationError, match="Middle line"):
        calibrate_frame({"Middle line": [[[1.0, 2.0], [3.0]]]}, 960, 540)
    # Labels without a model element are valid and simply unused.
    assert calibrate_frame({"Line unknown": [np.zeros((3, 2))]}, 960, 540).status == "refused"


def test_mirrored_labels_are_flagged_with_the_side_prior() -> None:
    truth = _camera((-8.0, 58.0, -16.0), (-38.0, -2.0, 0.0), 1300.0, 960, 540)
    lines = synthetic_lines(truth, 960, 540, sigma_px=1.0, seed=5)
    prior = CalibrationPrior(expected_side=1)
    right = calibrate_frame(lines, 960, 540, prior=prior, compute_jac=False)
    assert right.calibrated and "probably_mirrored" not in right.flags and right.mirrored_lines is None
    wrong = calibrate_frame(mirror_lines(lines), 960, 540, prior=prior, compute_jac=False)
    assert wrong.calibrated and "probably_mirrored" in wrong.flags
    assert wrong.camera is not None and wrong.camera.C[1] < -34.0
    # The mirrored camera fits the mirrored labels as well as the true one fits the true labels.
    assert wrong.rms_px == pytest.approx(right.rms_px, rel=1e-3, abs=1e-3)
    # The offered fix is the original labelling, and it calibrates without the flag.
    assert wrong.mirrored_lines is not None and sorted(wrong.mirrored_lines) == sorted(lines)
    # Without the prior nothing is flagged: one frame alone cannot tell.
    assert "probably_mirrored" not in calibrate_frame(mirror_lines(lines), 960, 540, compute_jac=False).flags


def test_known_centre_fits_focal_and_rotation_only() -> None:
    truth = _camera((0.0, 62.0, -18.0), (-30.0, 0.0, 0.0), 1400.0, 960, 540)
    lines = synthetic_lines(truth, 960, 540, sigma_px=1.0, seed=11)
    few = {c: lines[c] for c in sorted(c for c in lines if c not in CIRCLES)[:3]}  # 6 constraints < 7
    assert calibrate_frame(few, 960, 540, compute_jac=False).status == "refused"
    result = calibrate_frame(few, 960, 540, prior=CalibrationPrior(centre_m=tuple(truth.C)), compute_jac=False)
    assert result.calibrated and "rig_assisted" in result.flags
    assert result.camera is not None
    np.testing.assert_allclose(result.camera.C, truth.C)
    assert abs(result.camera.K[0, 0] / 1400.0 - 1.0) < 0.03
    assert _angle_between_deg(result.camera.R, truth.R) < 0.3


def test_game_rig_calibrates_a_frame_with_too_few_lines() -> None:
    from app.geometry.calibration import calibrate_with_rig, estimate_rig

    main = (2.0, 64.0, -19.0)
    targets = [(-40.0, 0.0, 0.0), (-20.0, -5.0, 0.0), (0.0, -3.0, 0.0), (25.0, 0.0, 0.0), (42.0, 3.0, 0.0)]
    cameras = []
    for i, t in enumerate(targets):
        truth = _camera(main, t, 900.0 + 150.0 * i, 960, 540)
        r = calibrate_frame(synthetic_lines(truth, 960, 540, sigma_px=1.0, seed=20 + i), 960, 540, compute_jac=False)
        assert r.calibrated, r.refusal
        cameras.append(r.camera)
    # A replay position seen once is not a rig position.
    cameras.append(_camera((40.0, 45.0, -10.0), (40.0, 0.0, 0.0), 1000.0, 960, 540))
    rig = estimate_rig([c.C for c in cameras])
    assert len(rig.positions) == 1 and rig.positions[0].frames == 5
    assert np.linalg.norm(np.array(rig.positions[0].centre_m) - main) < 1.0

    truth = _camera(main, (-35.0, -10.0, 0.0), 1500.0, 960, 540)
    lines = synthetic_lines(truth, 960, 540, sigma_px=1.0, seed=40)
    few = {c: lines[c] for c in sorted(c for c in lines if c not in CIRCLES)[:3]}
    assert calibrate_frame(few, 960, 540, compute_jac=False).status == "refused"
    result = calibrate_with_rig(few, 960, 540, rig, compute_jac=False)
    assert result.calibrated and "rig_assisted" in result.flags
    assert result.camera is not None
    assert _angle_between_deg(result.camera.R, truth.R) < 1.0
    assert abs(result.camera.K[0, 0] / 1500.0 - 1.0) < 0.05


def test_rig_computes_jac_once_for_the_chosen_position(monkeypatch: pytest.MonkeyPatch) -> None:
    """Work done twice: ``calibrate_with_rig`` computed JaC for the fit at every rig position and
    kept one; JaC never chooses, so it is now computed once, for the chosen fit, with the same
    values as before (those of ``calibrate_frame`` at that centre)."""
    from app.geometry.calibration import CalibrationPrior, CameraRig, calibrate_with_rig
    from app.geometry.calibration import rig as rig_module
    from app.geometry.calibration.rig import RigPosition

    main = (2.0, 64.0, -19.0)
    truth = _camera(main, (-35.0, -10.0, 0.0), 1500.0, 960, 540)
    lines = synthetic_lines(truth, 960, 540, sigma_px=1.0, seed=40)
    few = {c: lines[c] for c in sorted(c for c in lines if c not in CIRCLES)[:3]}
    rig = CameraRig((RigPosition(main, 5, 0.3), RigPosition((40.0, 45.0, -10.0), 3, 0.3),
                     RigPosition((-60.0, 0.0, -12.0), 2, 0.3)))
    calls = []
    real = rig_module.frame_jac
    monkeypatch.setattr(rig_module, "frame_jac", lambda *a, **k: calls.append(a) or real(*a, **k))
    result = calibrate_with_rig(few, 960, 540, rig)
    assert result.calibrated and len(calls) == 1
    alone = calibrate_frame(few, 960, 540, prior=CalibrationPrior(centre_m=main))
    assert result.jac == alone.jac and set(result.jac) == {"0.005", "0.01", "0.02"}


def test_frames_calibrated_together_equal_one_call_each() -> None:
    """``calibrate_frames_together`` (the rig's call: jobs with the same lines share their
    observations and what is computed once from them) gives every job exactly ``calibrate_frame``'s
    result, bit for bit: fixed centres at three positions, one free fit and a frame of other labels
    in the same call."""
    from app.geometry.calibration.frame import calibrate_frames_together

    main = (2.0, 64.0, -19.0)
    truth = _camera(main, (-35.0, -10.0, 0.0), 1500.0, 960, 540)
    lines = synthetic_lines(truth, 960, 540, sigma_px=1.0, seed=40)
    few = {c: lines[c] for c in sorted(c for c in lines if c not in CIRCLES)[:3]}
    other = synthetic_lines(_camera((-10.0, 58.0, -16.0), (20.0, 5.0, 0.0), 1200.0, 960, 540), 960, 540,
                            sigma_px=1.0, seed=41)
    jobs = [(few, 960, 540, CalibrationPrior(expected_side=1, centre_m=c))
            for c in (main, (40.0, 45.0, -10.0), (-60.0, 0.0, -12.0))]
    jobs += [(lines, 960, 540, CalibrationPrior(expected_side=1)), (other, 960, 540, None)]
    together = calibrate_frames_together(jobs)
    assert [r.status for r in together][3:] == ["calibrated", "calibrated"] and together[0].calibrated
    for (job_lines, w, h, prior), got in zip(jobs, together, strict=False):
        alone = calibrate_frame(job_lines, w, h, prior=prior)
        assert (got.status, got.refusal, got.flags, got.rms_px, dict(got.jac), dict(got.residuals_px)) == \
               (alone.status, alone.refusal, alone.flags, alone.rms_px, dict(alone.jac), dict(alone.residuals_px))
        if alone.camera is not None:
            assert np.array_equal(got.camera.K, alone.camera.K) and np.array_equal(got.camera.R, alone.camera.R)
            assert np.array_equal(got.camera.C, alone.camera.C) and np.array_equal(got.camera.radial,
                                                                                   alone.camera.radial)


def test_rig_without_positions_refuses() -> None:
    from app.geometry.calibration import CameraRig, calibrate_with_rig

    result = calibrate_with_rig({"Side line top": [np.array([[0.0, 10.0], [900.0, 20.0]])]}, 960, 540, CameraRig(()))
    assert result.status == "refused" and result.refusal.code == "no_rig_position"


# A zoomed main-camera view (focal 3.4 W) whose only labels, the 18-yard line and the penalty arc,
# sit off the image centre: the case where pointing the optical axis at the labelled part of the
# pitch starts the fixed-centre fit too far off (dev frame 2031-09-08 3.png).
ZOOMED = ((-2.0, 66.7, -14.0), (-31.0, -3.0, 0.0), 3234.0, 960, 540)
ZOOMED_CLASSES = ("Big rect. left main", "Circle left")


def test_anchor_correspondences_are_images_of_their_world_points() -> None:
    from app.geometry.calibration.initialisation import anchor_correspondences

    centre, target, focal, width, height = ZOOMED
    truth = _camera(centre, target, focal, width, height)
    obs = build_observations(synthetic_lines(truth, width, height, sigma_px=0.0, seed=3))
    pairs = anchor_correspondences(obs, float(width))
    penalty_mark = np.array([-41.5, 0.0, 0.0])  # centre of "Circle left"
    assert sum(not np.allclose(X, penalty_mark) for _, X in pairs) >= 4
    for uv, X in pairs:
        projected, in_front = truth.project(X[None])
        assert in_front[0]
        # Corners (crossings of labelled lines) are exact; a circle's ellipse centre is off the
        # image of its centre by perspective (about 10 px at this zoom).
        assert np.linalg.norm(projected[0] - uv) < (15.0 if np.allclose(X, penalty_mark) else 1e-6)


def test_wahba_rotation_recovers_a_rotation_from_noisy_directions() -> None:
    from app.geometry.calibration.initialisation import wahba_rotation
    from app.geometry.calibration.residuals import rotation_from_vector

    rng = np.random.default_rng(0)
    R = rotation_from_vector(np.array([0.3, -1.2, 0.5]))
    world = rng.normal(size=(6, 3))
    world /= np.linalg.norm(world, axis=1, keepdims=True)
    cam = world @ R.T + rng.normal(0.0, 1e-3, (6, 3))
    est = wahba_rotation(cam / np.linalg.norm(cam, axis=1, keepdims=True), world)
    assert np.linalg.det(est) == pytest.approx(1.0)
    assert _angle_between_deg(est, R) < 0.2


def test_wahba_rotations_at_once_are_each_set_s_own_rotation_to_the_bit() -> None:
    """The players' starts solve 20 focal hypotheses in one compiled call: each rotation is exactly the one
    ``wahba_rotation`` gives that set alone (a start's rotation, hence every fit from it, is unchanged)."""
    from app.geometry.calibration.initialisation import wahba_rotation, wahba_rotations

    rng = np.random.default_rng(4)
    world = rng.normal(size=(7, 3))
    world /= np.linalg.norm(world, axis=1, keepdims=True)
    cams = rng.normal(size=(20, 7, 3))
    cams /= np.linalg.norm(cams, axis=2, keepdims=True)
    got = wahba_rotations(cams, world)
    assert got.shape == (20, 3, 3)
    for c, R in zip(cams, got, strict=True):
        assert np.array_equal(R, wahba_rotation(c, world))


@pytest.mark.parametrize("roll_deg", [0.0, 0.4])
def test_fixed_centre_start_puts_off_centre_labels_where_the_image_shows_them(roll_deg: float) -> None:
    """With the centre known, the Wahba start (image rays of the labels' anchors <-> their world
    directions, upright prior) is within half a degree of the true rotation at the true focal
    length; the look-at start is 8 degrees off."""
    from app.geometry.calibration.initialisation import fixed_centre_rotations, labelled_target

    centre, target, focal, width, height = ZOOMED
    truth = _camera(centre, target, focal, width, height, roll_deg=roll_deg)
    lines = synthetic_lines(truth, width, height, sigma_px=0.0, seed=3)
    obs = build_observations({c: lines[c] for c in ZOOMED_CLASSES})
    (R,) = fixed_centre_rotations(obs, truth.C, principal_point(width, height), np.array([focal]))
    assert _angle_between_deg(R, truth.R) < roll_deg + 0.25
    assert _angle_between_deg(look_at_rotation(truth.C, labelled_target(obs)), truth.R) > 5.0
    # Every anchor (a corner where two labelled lines cross is exact) lands where the labels show it.
    full = build_observations(lines)
    (R_full,) = fixed_centre_rotations(full, truth.C, principal_point(width, height), np.array([focal]))
    assert _angle_between_deg(R_full, truth.R) < 0.3


def test_a_zoomed_view_with_off_centre_labels_is_calibrated_at_its_known_centre() -> None:
    centre, target, focal, width, height = ZOOMED
    truth = _camera(centre, target, focal, width, height, roll_deg=0.4)
    lines = synthetic_lines(truth, width, height, sigma_px=1.0, seed=3)
    few = {c: lines[c] for c in ZOOMED_CLASSES}
    result = calibrate_frame(few, width, height, prior=CalibrationPrior(centre_m=centre), compute_jac=False)
    assert result.calibrated, result.refusal
    assert result.camera is not None and result.rms_px is not None and result.rms_px < 2.0
    assert abs(result.camera.K[0, 0] / focal - 1.0) < 0.01
    # 1 px of noise on two short elements in a 17-degree field of view leaves the roll a few
    # tenths of a degree free (measured 0.28 degrees).
    assert _angle_between_deg(result.camera.R, truth.R) < 0.5


def test_a_known_centre_the_labels_do_not_fit_is_refused() -> None:
    """At a wrong centre a fixed-centre fit of few lines can stay within the single-frame refusal
    limit (3 % of the diagonal per class) yet be useless: it is refused beyond the RMS tolerance of
    a good calibration (accept_gamma of the diagonal)."""
    centre, target, focal, width, height = ZOOMED
    truth = _camera(centre, target, focal, width, height)
    lines = synthetic_lines(truth, width, height, sigma_px=1.0, seed=3)
    few = {c: lines[c] for c in ZOOMED_CLASSES}
    limit = 0.005 * np.hypot(width, height)
    for wrong in ((-51.75, -41.4, -1.2), (59.3, 3.5, -2.7), (14.7, -61.3, -13.9)):
        result = calibrate_frame(few, width, height, prior=CalibrationPrior(centre_m=wrong), compute_jac=False)
        assert result.status == "refused", (wrong, result.rms_px)
        assert result.rms_px is None or result.rms_px > limit
