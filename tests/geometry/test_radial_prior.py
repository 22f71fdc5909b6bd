"""The learned radial prior (issue 17): a set's lens, as its relative radial distortion at the image corner
``c = k1 (h / f)^2``, learned from its own fits refitted with ``k1`` free, and used under a prior row by every
fit, so that a frame whose lines do not fix the lens still places the lines it did not see. Synthetic cameras
with a known lens (the real sets' order: ``k1 / f^2`` = 1.2e-7 px^-2 at 960x540, c = 0.036)."""
from __future__ import annotations

import numpy as np
import pytest

from app.geometry.calibration import CalibrationPrior, calibrate_frame, calibration_uncertainty, radial_corner
from app.geometry.calibration.held_out import class_point_distances, without_class
from app.geometry.calibration.learning import learn_camera_prior
from app.geometry.calibration.priors import CameraPrior, prior_rows
from app.geometry.calibration.result import RADIAL_PRIOR_FLAG
from app.geometry.camera import Camera, look_at_rotation
from tests.geometry.synthetic import visible_model_points

W, H = 960, 540
KAPPA = 1.2e-7  # px^-2
HALF_DIAGONAL = float(np.hypot(W, H)) / 2.0
CORNER = KAPPA * HALF_DIAGONAL**2  # the same lens as the distortion at the corner


def _camera(centre, target, focal: float, kappa: float = KAPPA) -> Camera:
    C = np.asarray(centre, dtype=float)
    K = np.array([[focal, 0.0, (W - 1) / 2], [0.0, focal, (H - 1) / 2], [0.0, 0.0, 1.0]])
    radial = np.zeros(6)
    radial[0] = kappa * focal * focal
    return Camera(K=K, R=look_at_rotation(C, np.asarray(target, dtype=float)), C=C, radial=radial)


def _radial_prior(corner: float = CORNER, std: float = 0.006) -> CalibrationPrior:
    return CalibrationPrior(camera_prior=CameraPrior(anchors_m=(), anchor_std_m=(), anchor_frames=(), roll_std_deg=0.4,
                                                     confident_fits=0, radial_corner=corner, radial_corner_std=std,
                                                     radial_fits=20))


def test_the_radial_term_is_learned_from_the_sets_own_fits() -> None:
    rng = np.random.default_rng(7)
    cams, stds, corners = [], [], []
    for i in range(24):
        # Wide views of either penalty area from the main camera, focal 900-1500 px.
        side = -1.0 if i % 2 else 1.0
        truth = _camera((rng.normal(0.0, 1.0), 58.0 + rng.normal(0.0, 1.0), -16.0),
                        (side * rng.uniform(30.0, 40.0), rng.uniform(-5.0, 5.0), 0.0),
                        float(rng.uniform(900.0, 1500.0)))
        lines = visible_model_points(truth, W, H, rng, per_class=12, noise_px=0.7)
        fit = calibrate_frame(lines, W, H, compute_jac=False)
        assert fit.camera is not None
        cams.append(fit.camera)
        stds.append(calibration_uncertainty(fit.camera, lines).position_std_m)
        corners.append(radial_corner(fit.camera, lines, W, H))
    assert np.all(np.isfinite(corners))
    prior = learn_camera_prior(cams, stds, radial_corner=corners)
    assert prior.has_radial and prior.radial_fits == 12  # the confident half
    assert prior.radial_corner == pytest.approx(CORNER, rel=0.15)
    assert 0 < prior.radial_corner_std < 0.5 * CORNER
    # One lens filmed at 960x540 and at 1920x1080 (k1 unchanged, f doubled): the same corner distortion.
    for size in (1, 2):
        w, h, f = W * size, H * size, 1200.0 * size
        C = np.array([0.0, 58.0, -16.0])
        lens = Camera(K=np.array([[f, 0.0, (w - 1) / 2], [0.0, f, (h - 1) / 2], [0.0, 0.0, 1.0]]),
                      R=look_at_rotation(C, np.array([35.0, 0.0, 0.0])), C=C,
                      radial=np.array([KAPPA * 1200.0**2, 0.0, 0.0, 0.0, 0.0, 0.0]))
        labels = visible_model_points(lens, w, h, np.random.default_rng(2), per_class=12)
        assert radial_corner(lens, labels, w, h) == pytest.approx(CORNER, rel=0.02)
    # Without the fits' radial terms, no radial prior; too few of them, none either.
    assert not learn_camera_prior(cams, stds).has_radial
    assert not learn_camera_prior(cams[:8], stds[:8], radial_corner=corners[:8]).has_radial


def test_with_the_radial_prior_a_fit_places_the_class_it_did_not_see() -> None:
    # A penalty-area view at 2,000 px whose lines leave the lens open: without the prior the fit is a
    # pinhole and the held-out class lands px off; with it, within the label noise.
    errors_free, errors_prior = [], []
    for seed in range(5):
        rng = np.random.default_rng(seed)
        truth = _camera((rng.normal(0.0, 1.0), 60.0, -15.0), (36.0 + rng.normal(0.0, 2.0), 8.0, 0.0), 2000.0)
        lines = visible_model_points(truth, W, H, rng, per_class=10, noise_px=0.5)
        held = "Circle right" if "Circle right" in lines else sorted(lines)[0]
        assert len(lines) >= 4
        clean = visible_model_points(truth, W, H, np.random.default_rng(99), per_class=10)
        free = calibrate_frame(without_class(lines, held), W, H, compute_jac=False)
        fitted = calibrate_frame(without_class(lines, held), W, H, prior=_radial_prior(), compute_jac=False)
        assert free.camera is not None and fitted.camera is not None
        assert RADIAL_PRIOR_FLAG in fitted.flags and fitted.centre_prior is not None
        assert fitted.camera.radial[0] / fitted.camera.K[0, 0] ** 2 == pytest.approx(KAPPA, rel=0.3)
        errors_free.append(float(np.median(class_point_distances(free.camera, clean)[held])))
        errors_prior.append(float(np.median(class_point_distances(fitted.camera, clean)[held])))
        # The posterior covariance takes the radial row: finite stds.
        u = calibration_uncertainty(fitted.camera, without_class(lines, held), prior=fitted.centre_prior)
        assert u is not None and np.isfinite(u.focal_px)
    assert np.median(errors_prior) < 1.0 < np.median(errors_free)


def test_prior_rows_and_the_stored_prior_carry_the_radial_term() -> None:
    prior = _radial_prior().camera_prior
    rows = prior_rows(prior, None, 1.5, HALF_DIAGONAL)
    assert not np.any(rows.whitening) and rows.k1_mean_px2 == pytest.approx(KAPPA)
    assert rows.k1_weight == pytest.approx(1.5 * HALF_DIAGONAL**2 / 0.006)
    # Twice the image size: a quarter of the pixel-unit term for the same lens.
    assert prior_rows(prior, None, 1.5, 2 * HALF_DIAGONAL).k1_mean_px2 == pytest.approx(KAPPA / 4)
    back = CameraPrior.from_json(prior.to_json())
    assert back == prior
    old = prior.to_json()
    for key in ("radial_corner", "radial_corner_std", "radial_fits"):
        old.pop(key)
    assert not CameraPrior.from_json(old).has_radial  # a prior stored before the radial term
    with pytest.raises(ValueError):
        CameraPrior(anchors_m=(), anchor_std_m=(), anchor_frames=(), roll_std_deg=0.4, confident_fits=0,
                    radial_corner=CORNER, radial_corner_std=0.0)
    # A stored prior whose lens is not a number is refused, not fitted with (the service then ignores it).
    for bad in ({"radial_corner": float("nan")}, {"radial_corner_std": float("nan")}, {"radial_corner_std": -0.01},
                {"radial_corner": "0.03; drop"}):
        with pytest.raises(ValueError):
            CameraPrior.from_json(dict(prior.to_json(), **bad))
