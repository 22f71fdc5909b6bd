"""Learned calibration priors (issue 17): learning on synthetic cameras with known truth, the anchor
order, and the MAP fit's pull (strong where the lines leave the centre open, weak where they fix it)."""
from __future__ import annotations

import numpy as np
import pytest

from app.geometry.calibration import CalibrationPrior, calibrate_frame, calibration_uncertainty
from app.geometry.calibration.learning import learn_camera_prior
from app.geometry.calibration.priors import CameraPrior, anchor_order, prior_rows
from app.geometry.calibration.result import PRIOR_FLAG
from app.geometry.camera import Camera, look_at_rotation, pan_tilt_roll_from_rotation, rotation_from_pan_tilt_roll
from tests.geometry.synthetic import visible_model_points

W, H = 960, 540


def _camera(centre, target=(0.0, 0.0, 0.0), focal=1500.0, roll_deg=0.0) -> Camera:
    C = np.asarray(centre, dtype=float)
    pan, tilt, _ = pan_tilt_roll_from_rotation(look_at_rotation(C, np.asarray(target, dtype=float)))
    K = np.array([[focal, 0.0, (W - 1) / 2], [0.0, focal, (H - 1) / 2], [0.0, 0.0, 1.0]])
    return Camera(K=K, R=rotation_from_pan_tilt_roll(pan, tilt, roll_deg), C=C)


def _lines(camera: Camera, classes=None, noise_px=0.0, seed=0) -> dict[str, list[np.ndarray]]:
    """Ten evenly chosen model points of each class in view, with Gaussian pixel noise."""
    return visible_model_points(camera, W, H, np.random.default_rng(seed), classes=classes, noise_px=noise_px)


def test_learning_recovers_the_positions_their_spread_and_the_roll_from_confident_fits() -> None:
    rng = np.random.default_rng(3)
    truth = np.array([[0.0, 62.0, -15.0], [1.5, 80.0, -24.0]])
    sigma_m, sigma_roll = 0.3, 0.4
    cams, stds = [], []
    for k, n in ((0, 40), (1, 25)):
        for _ in range(n):
            c = truth[k] + rng.normal(0.0, sigma_m, 3)
            cams.append(_camera(c, roll_deg=float(rng.normal(0.0, sigma_roll))))
            stds.append(float(rng.uniform(0.2, 0.8)))
    # Poorly determined fits scattered along the axis, with a large std: they must not feed the prior.
    for _ in range(65):
        cams.append(_camera(truth[0] + rng.normal(0.0, 6.0, 3), roll_deg=float(rng.normal(0.0, 3.0))))
        stds.append(float(rng.uniform(2.0, 9.0)))
    prior = learn_camera_prior(cams, stds, confident_quantile=0.5)
    assert prior.confident_fits == 65
    assert len(prior.anchors_m) >= 2 and prior.anchor_frames[:2] == (40, 25)
    for k in range(2):
        assert np.linalg.norm(np.asarray(prior.anchors_m[k]) - truth[k]) < 0.2
        # Isotropic std from the group's median radius: sigma within 35 % (25-40 draws).
        assert prior.anchor_std_m[k] == pytest.approx(sigma_m, rel=0.35)
    assert prior.roll_std_deg == pytest.approx(sigma_roll, rel=0.3)
    # Fed every fit instead, the scattered ones spoil the roll: the quantile is what keeps it out.
    assert learn_camera_prior(cams, stds, confident_quantile=1.0).roll_std_deg > 1.5 * prior.roll_std_deg


def test_learning_without_finite_fits_or_with_bad_arguments() -> None:
    empty = learn_camera_prior([_camera((0.0, 60.0, -15.0))], [float("inf")])
    assert empty.anchors_m == () and empty.confident_fits == 0
    with pytest.raises(ValueError):
        learn_camera_prior([_camera((0.0, 60.0, -15.0))], [1.0, 2.0])
    with pytest.raises(ValueError):
        learn_camera_prior([], [], confident_quantile=0.0)
    with pytest.raises(ValueError):
        CameraPrior(anchors_m=((0.0, 60.0, -15.0),), anchor_std_m=(0.0,), anchor_frames=(3,), roll_std_deg=0.4,
                    confident_fits=3)


def test_anchor_order_follows_the_fits_covariance() -> None:
    prior = CameraPrior(anchors_m=((0.0, 64.0, -15.0), (2.0, 60.0, -15.0)), anchor_std_m=(0.3, 0.3),
                        anchor_frames=(5, 5), roll_std_deg=0.4, confident_fits=10)
    centre = np.array([0.0, 60.0, -15.0])
    # Isotropic 0.5 m: the nearer anchor (2 m across) first.
    order, d2 = anchor_order(prior, centre, 0.25 * np.eye(3))
    assert order.tolist() == [1, 0] and d2[0] == pytest.approx(4.0 / (0.25 + 0.09))
    # The lines leave the centre free along y (a 5 m std): the anchor 4 m along y is the consistent one.
    order, d2 = anchor_order(prior, centre, np.diag([0.01, 25.0, 0.01]))
    assert order.tolist() == [0, 1] and d2[0] < 2.0 < d2[1]
    rows = prior_rows(prior, 0, 1.5, 550.0)
    assert np.allclose(rows.whitening, 5.0 * np.eye(3)) and rows.roll_weight == pytest.approx(1.5 / np.radians(0.4))


def _prior_at(centre, std=0.3, confident_std_m=0.0) -> CalibrationPrior:
    return CalibrationPrior(camera_prior=CameraPrior(anchors_m=(tuple(float(v) for v in centre),), anchor_std_m=(std,),
                                                     anchor_frames=(10,), roll_std_deg=0.4, confident_fits=10,
                                                     confident_std_m=confident_std_m))


def test_map_fit_settles_an_under_determined_camera_at_the_learned_position() -> None:
    # A centre view with the middle line, one side line and the central circle, 1.5 px label noise:
    # the lines leave the camera sliding along its axis (focal against distance).
    truth = _camera((0.5, 60.0, -14.0), target=(0.0, 10.0, 0.0), focal=1800.0)
    classes = {"Middle line", "Side line top", "Circle central", "Side line bottom"}
    errors_free, errors_map = [], []
    for seed in range(6):
        lines = _lines(truth, classes, noise_px=1.5, seed=seed)
        assert len(lines) >= 3
        free = calibrate_frame(lines, W, H, compute_jac=False)
        fitted = calibrate_frame(lines, W, H, prior=_prior_at(truth.C), compute_jac=False)
        assert free.camera is not None and fitted.camera is not None
        assert PRIOR_FLAG in fitted.flags and fitted.centre_prior is not None
        errors_free.append(np.linalg.norm(free.camera.C - truth.C))
        errors_map.append(np.linalg.norm(fitted.camera.C - truth.C))
        # The posterior std (lines and prior) is below the lines' own.
        u_free = calibration_uncertainty(fitted.camera, lines)
        u_map = calibration_uncertainty(fitted.camera, lines, prior=fitted.centre_prior)
        assert u_map.position_std_m < u_free.position_std_m
        assert u_map.position_std_m < 0.6
    assert np.median(errors_free) > 1.0  # the lines alone do not fix the centre
    assert np.median(errors_map) < 0.4 < np.median(errors_free) / 2


def test_map_fit_hardly_moves_a_camera_the_lines_fix() -> None:
    # A wide view of one half with a dozen classes: the lines fix the centre to a few centimetres, so
    # an anchor 1.5 m off (within the consistency gate) moves the fit by a small part of that.
    truth = _camera((-20.0, 55.0, -16.0), target=(-35.0, 0.0, 0.0), focal=700.0)
    lines = _lines(truth, noise_px=1.0, seed=1)
    assert len(lines) >= 10
    free = calibrate_frame(lines, W, H, compute_jac=False)
    fitted = calibrate_frame(lines, W, H, prior=_prior_at(truth.C + np.array([0.0, 1.0, -1.1]), std=0.5),
                             compute_jac=False)
    assert free.camera is not None and fitted.camera is not None
    moved = np.linalg.norm(fitted.camera.C - free.camera.C)
    assert moved < 0.2  # ~ s_fit^2 / (s_fit^2 + s_a^2) of the 1.5 m offset, s_fit ~0.13 m per axis
    assert np.linalg.norm(free.camera.C - truth.C) < 0.3


def test_a_fit_as_sure_as_the_confident_ones_is_left_as_the_lines_have_it() -> None:
    # The JaC guard: the prior was learned from fits whose position std is at or below
    # confident_std_m; a fit that sure of its centre is not moved (no MAP fit, no flag).
    truth = _camera((-20.0, 55.0, -16.0), target=(-35.0, 0.0, 0.0), focal=700.0)
    lines = _lines(truth, noise_px=1.0, seed=1)
    free = calibrate_frame(lines, W, H, compute_jac=False)
    std = calibration_uncertainty(free.camera, lines).position_std_m
    offset = truth.C + np.array([0.0, 1.0, -1.1])
    kept = calibrate_frame(lines, W, H, prior=_prior_at(offset, std=0.5, confident_std_m=1.5 * std), compute_jac=False)
    assert PRIOR_FLAG not in kept.flags and kept.centre_prior is None
    assert np.array_equal(kept.camera.C, free.camera.C)
    moved = calibrate_frame(lines, W, H, prior=_prior_at(offset, std=0.5, confident_std_m=0.5 * std), compute_jac=False)
    assert PRIOR_FLAG in moved.flags


def test_the_service_stores_the_posterior_std_of_a_map_fit() -> None:
    from app.geometry.annotations import lines_to_json_lists
    from app.services.calibration.calibrating import calibrate_lines, fit_uncertainty

    truth = _camera((0.5, 60.0, -14.0), target=(0.0, 10.0, 0.0), focal=1800.0)
    lines = _lines(truth, {"Middle line", "Side line top", "Circle central"}, noise_px=1.5, seed=0)
    prior = _prior_at(truth.C)
    result = calibrate_frame(lines, W, H, prior=prior, compute_jac=False)
    assert result.centre_prior is not None
    # as an edit stores it
    stored = calibrate_lines(lines_to_json_lists(lines), W, H, rig=prior.camera_prior).uncertainty
    posterior = calibration_uncertainty(result.camera, lines, prior=result.centre_prior).to_json()
    assert stored == posterior
    lines_only = fit_uncertainty(result.camera, lines, result.flags)
    assert stored["position_m"]["y"] < 0.5 < lines_only["position_m"]["y"]
