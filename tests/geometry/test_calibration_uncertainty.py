"""Uncertainty of a calibration (issue 17 b): the propagated standard deviations against the scatter
of fits of noisy synthetic labels (Monte Carlo on synthetic truth)."""
from __future__ import annotations

import numpy as np
import pytest

from app.geometry.calibration import calibrate_frame
from app.geometry.calibration.uncertainty import CalibrationUncertainty, calibration_uncertainty
from app.geometry.camera import Camera, look_at_rotation, pan_tilt_roll_from_rotation
from app.geometry.pitch import CIRCLES, KEY_POINTS, LINE_EXTREMITY_KEYS

W, H = 960, 540


def _camera(target=(-20.0, 0.0, 0.0), focal=900.0) -> Camera:
    C = np.array([0.0, 55.0, -18.0])
    R = look_at_rotation(C, np.asarray(target, float))
    K = np.array([[focal, 0.0, (W - 1) / 2], [0.0, focal, (H - 1) / 2], [0.0, 0.0, 1.0]])
    return Camera(K=K, R=R, C=C)


def _lines(cam: Camera, rng: np.random.Generator | None = None, noise: float = 0.0) -> dict:
    out = {}
    for cls, (a, b) in LINE_EXTREMITY_KEYS.items():
        if cls in CIRCLES:
            continue
        A, B = np.asarray(KEY_POINTS[a], float), np.asarray(KEY_POINTS[b], float)
        uv = cam.project(A + np.linspace(0.1, 0.9, 5)[:, None] * (B - A))[0]
        if np.all((uv[:, 0] > 0) & (uv[:, 0] < W) & (uv[:, 1] > 0) & (uv[:, 1] < H)):
            out[cls] = [uv + (rng.normal(0.0, noise, uv.shape) if rng is not None else 0.0)]
    return out


def _params(cam: Camera) -> np.ndarray:
    return np.concatenate([[cam.K[0, 0]], pan_tilt_roll_from_rotation(cam.R), cam.C])


def test_predicted_std_matches_the_scatter_of_noisy_fits() -> None:
    truth = _camera()
    exact = _lines(truth)
    assert len(exact) >= 5
    noise = 1.5
    u = calibration_uncertainty(truth, exact, line_noise_px=noise)
    assert u is not None and u.points == 5 * len(exact)
    predicted = np.array([u.focal_px, u.pan_deg, u.tilt_deg, u.roll_deg, *u.position_m])
    rng = np.random.default_rng(17)
    fits = []
    for _ in range(60):
        result = calibrate_frame(_lines(truth, rng, noise), W, H, compute_jac=False)
        assert result.camera is not None
        fits.append(_params(result.camera))
    scatter = np.std(np.array(fits), axis=0)
    # First-order propagation against 60 fits: within 35 % for every parameter (a 60-sample std has
    # about 9 % relative error; the fit's robust loss and class weights add a little).
    assert np.all(predicted > 0)
    assert np.allclose(scatter, predicted, rtol=0.35), (scatter, predicted)


def test_default_line_noise_is_the_residual_error_with_a_floor_and_json_round_trips() -> None:
    truth = _camera()
    u = calibration_uncertainty(truth, _lines(truth))
    assert u is not None and u.line_noise_px == 1.0  # exact labels: the floor
    noisy = _lines(truth, np.random.default_rng(3), 4.0)
    v = calibration_uncertainty(truth, noisy)
    assert v is not None and 3.0 < v.line_noise_px < 5.5
    assert CalibrationUncertainty.from_json(v.to_json()) == v
    assert v.position_std_m == pytest.approx(float(np.linalg.norm(v.position_m)))
    fixed = calibration_uncertainty(truth, noisy, fixed_centre=True)
    assert fixed is not None and fixed.position_m == (0.0, 0.0, 0.0)
    assert fixed.focal_px < v.focal_px  # the centre known, the focal is better determined


def test_under_determined_parameters_are_infinite_and_serialise_as_null() -> None:
    truth = _camera()
    one = {c: v for c, v in _lines(truth).items()}
    cls = sorted(one)[0]
    u = calibration_uncertainty(truth, {cls: one[cls]})  # one line fixes 2 of 7 parameters
    assert u is not None and not np.isfinite(u.focal_px)
    assert u.to_json()["focal_px"] is None
    assert calibration_uncertainty(truth, {}) is None
