"""The import's learned dataset prior (issue 17): learned from a dataset's fresh calibrations, used to
refit only the frames whose lines leave the camera open, never those the lines fix."""
from __future__ import annotations

import numpy as np
import pytest
import sqlalchemy as sa

from app.db.models import Calibration, CalibrationStatus, Frame, Game
from app.db.scope import game_changed
from app.db.unit import write_unit
from app.geometry.annotations import lines_from_json_lists
from app.geometry.calibration import CameraPrior
from app.geometry.calibration.result import PRIOR_FLAG, RADIAL_PRIOR_FLAG
from app.geometry.camera import Camera, look_at_rotation
from app.services.calibration.calibrating import calibrate_lines
from app.services.calibration.priors import MIN_PRIOR_FRAMES, dataset_prior, wants_prior_retry
from app.services.curation.editing import replace_field_lines
from app.services.transfer.importing import import_sn_calibration
from tests.geometry.synthetic import visible_model_points

from ..datasets import write_calibration_zip

W, H = 960, 540
#: Two stadiums' main cameras (world metres, z down).
POSITIONS = (np.array([0.5, 60.0, -14.0]), np.array([-1.0, 58.0, -19.0]))


def _lines_json(centre: np.ndarray, target, focal: float, rng, classes=None, noise_px: float = 1.0,
               k1: float = 0.0) -> dict:
    C = np.asarray(centre, float)
    camera = Camera(K=np.array([[focal, 0.0, (W - 1) / 2], [0.0, focal, (H - 1) / 2], [0.0, 0.0, 1.0]]),
                    R=look_at_rotation(C, np.asarray(target, float)), C=C, radial=np.array([k1, 0, 0, 0, 0, 0.0]))
    points = visible_model_points(camera, W, H, rng, classes=classes, noise_px=noise_px)
    return {cls: [p.tolist() for p in polylines] for cls, polylines in points.items()}


def _dataset(rng) -> list:
    """Wide views of either half from the two positions (the lines fix these cameras)."""
    fields = []
    for k in range(MIN_PRIOR_FRAMES + 6):
        centre = POSITIONS[k % 2] + rng.normal(0.0, 0.15, 3)
        target = (-35.0 if k % 4 < 2 else 35.0, rng.uniform(-10.0, 10.0), 0.0)
        fields.append(calibrate_lines(_lines_json(centre, target, 650.0, rng), W, H, 1))
    return fields


def test_the_import_prior_is_learned_from_the_dataset_and_refits_only_open_cameras() -> None:
    rng = np.random.default_rng(5)
    fields = _dataset(rng)
    assert sum(f.status is CalibrationStatus.CALIBRATED for f in fields) >= MIN_PRIOR_FRAMES
    prior = dataset_prior(fields)
    assert prior is not None and len(prior.anchors_m) >= 2
    learned = np.array(prior.anchors_m[:2])
    for p in POSITIONS:
        assert np.min(np.linalg.norm(learned - p, axis=1)) < 0.5
    # Too few frames: no prior.
    assert dataset_prior(fields[:MIN_PRIOR_FRAMES - 1]) is None
    # The confident frames are not retried; half the dataset at most is above the confident cut.
    retried = [wants_prior_retry(f, prior) for f in fields]
    assert sum(retried) <= len(fields) // 2 + 1
    # A centre view of three classes from the first position: the lines leave it open.
    truth = POSITIONS[0]
    open_view = _lines_json(truth, (0.0, 10.0, 0.0), 1800.0, rng,
                            {"Middle line", "Side line top", "Circle central"}, noise_px=1.5)
    first = calibrate_lines(open_view, W, H, 1)
    assert first.status is CalibrationStatus.CALIBRATED and wants_prior_retry(first, prior)
    refit = calibrate_lines(open_view, W, H, 1, prior)
    assert refit.status is CalibrationStatus.CALIBRATED and PRIOR_FLAG in refit.flags
    c_first = np.array(first.camera["position_meters"])
    c_refit = np.array(refit.camera["position_meters"])
    assert np.linalg.norm(c_refit - truth) < 0.5 < np.linalg.norm(c_first - truth)
    # The stored std is the posterior's: far below the lines' own.
    assert refit.uncertainty["position_m"]["y"] < 0.5 * first.uncertainty["position_m"]["y"]


def test_with_their_lines_the_prior_learns_the_lens_and_every_calibrated_frame_is_refitted() -> None:
    rng = np.random.default_rng(11)
    kappa, focal = 1.2e-7, 1200.0  # px^-2: k1 = 0.17 at this focal length
    fields, lines, views = [], [], []
    for k in range(MIN_PRIOR_FRAMES + 6):
        centre = POSITIONS[k % 2] + rng.normal(0.0, 0.15, 3)
        target = (-35.0 if k % 4 < 2 else 35.0, rng.uniform(-8.0, 8.0), 0.0)
        view = _lines_json(centre, target, focal, rng, noise_px=0.7, k1=kappa * focal**2)
        fields.append(calibrate_lines(view, W, H, 1))
        lines.append((lines_from_json_lists(view), W, H))
        views.append(view)
    assert sum(f.status is CalibrationStatus.CALIBRATED for f in fields) >= MIN_PRIOR_FRAMES
    assert not dataset_prior(fields).has_radial  # without the lines, no lens
    prior = dataset_prior(fields, lines)
    assert prior.has_radial and prior.radial_corner == pytest.approx(kappa * (np.hypot(W, H) / 2) ** 2, rel=0.2)
    # With a lens prior every calibrated frame is refitted (the lines of one frame rarely fix the lens).
    assert all(wants_prior_retry(f, prior) for f in fields if f.status is CalibrationStatus.CALIBRATED)
    refit = calibrate_lines(views[0], W, H, 1, prior)
    assert refit.status is CalibrationStatus.CALIBRATED and RADIAL_PRIOR_FLAG in refit.flags
    assert refit.camera["radial_distortion"][0] / refit.camera["x_focal_length"] ** 2 == pytest.approx(kappa, rel=0.25)


@pytest.mark.shared
def test_the_imported_prior_is_stored_and_every_later_recalibration_uses_it(db_session, settings, shared_dir,
                                                                            tmp_path):
    """60 real WorldCup 2014 frames (a calibration dataset): the import learns the prior (anchors and the lens's
    radial term), keeps it on the game, refits every frame with its radial term (flag ``radial_prior``) and the
    frames its lines leave open with an anchor too (flag ``learned_prior``). A line edit of such a frame that gives
    back the same lines refits it with the stored prior too: the same camera, where without the stored prior it
    would be refitted from its lines alone and move."""
    names = [f"{k}.json" for k in range(1, 61)]
    report = import_sn_calibration(db_session, write_calibration_zip(shared_dir, tmp_path / "wc.zip", names),
                                   settings, width=960, height=540)
    game = db_session.scalars(sa.select(Game)).one()
    prior = CameraPrior.from_json(game.camera_prior)
    assert prior.anchors_m and prior == CameraPrior.from_json(prior.to_json())
    # The lens: learned from the confident half's refits, near the whole set's 0.042 (1.4e-7 px^-2 at 960x540).
    assert prior.has_radial and prior.radial_fits >= 20 and 0.024 < prior.radial_corner < 0.06
    frames = db_session.scalars(sa.select(Frame).join(Calibration)).all()
    with_prior = [f for f in frames if PRIOR_FLAG in (f.calibration.flags or ())]
    with_lens = [f for f in frames if RADIAL_PRIOR_FLAG in (f.calibration.flags or ())]
    assert with_prior and len(with_prior) < len(frames) // 2 + 1
    assert len(with_lens) >= 0.9 * len(frames)
    assert report.prior_fitted == len({f.id for f in with_prior + with_lens})
    frame = with_prior[0]
    camera, jac = frame.calibration.camera, frame.calibration.jac_0005
    alone = calibrate_lines(frame.field_lines.lines, 960, 540, 1)
    assert alone.camera != camera  # the lines alone put this camera elsewhere
    replace_field_lines(db_session, frame.id, frame.field_lines.lines, settings=settings)
    db_session.refresh(frame.calibration)
    assert PRIOR_FLAG in frame.calibration.flags
    assert frame.calibration.camera == camera and frame.calibration.jac_0005 == jac
    # A dataset whose import learned nothing: no prior stored, the edit fits from the lines alone.
    with write_unit(db_session):  # a write of the prior, through the unit with the bump of what it covers
        game.camera_prior = None
        game_changed(game)
    replace_field_lines(db_session, frame.id, frame.field_lines.lines, settings=settings)
    db_session.refresh(frame.calibration)
    assert PRIOR_FLAG not in (frame.calibration.flags or ()) and frame.calibration.camera == alone.camera
