"""Game camera rigs: a SoccerNet-v3 frame its lines alone cannot calibrate is calibrated with its
centre at one of the game's camera positions; calibration datasets (many stadiums) never use one."""
from __future__ import annotations

import numpy as np
import sqlalchemy as sa

from app.db.models import CalibrationStatus, System, SystemKind
from app.services.editing import replace_field_lines
from app.services.importing import import_sn_calibration
from app.services.recompute import RIG_FLAG, calibrate_lines, calibration_job, game_rig, uses_rig

from .datasets import true_cameras, write_calibration_zip


def test_a_frame_with_too_few_lines_is_calibrated_with_the_game_rig(db_session, settings, imported, shared_dir):
    frame = next(f for f in imported["0.png"].frames if f.name == "0.png")
    few = {cls: frame.field_lines.lines[cls] for cls in ("Side line top", "Big rect. right main")}
    alone = calibrate_lines(few, frame.width, frame.height, 1)
    assert alone.status is CalibrationStatus.REFUSED and "fewer than" in alone.reason

    rig = game_rig(db_session, imported["0.png"].game_id, settings, exclude_frame_ids=[frame.id])
    assert rig.positions and rig.positions[0].frames >= 2  # the other main-camera frames agree
    replace_field_lines(db_session, frame.id, few, settings=settings)

    cal = frame.calibration
    assert cal.status is CalibrationStatus.CALIBRATED and RIG_FLAG in cal.flags
    true_centre = true_cameras(shared_dir)[("0.png", "0.png")]["position_meters"]
    assert np.linalg.norm(np.subtract(cal.camera["position_meters"], true_centre)) < 1.0  # metres


def test_rig_assisted_frames_do_not_feed_the_rig_and_calibration_games_have_none(db_session, settings, imported):
    game_id = imported["0.png"].game_id
    full = game_rig(db_session, game_id, settings)
    for system in imported.values():
        for frame in system.frames:
            frame.calibration.flags = [RIG_FLAG]
    db_session.flush()
    assert full.positions and not game_rig(db_session, game_id, settings).positions


def test_calibration_datasets_never_use_a_rig(db_session, settings, imported, shared_dir, tmp_path):
    import_sn_calibration(db_session, write_calibration_zip(shared_dir, tmp_path / "a.zip"), settings,
                          width=960, height=540)
    single = db_session.scalars(sa.select(System).where(System.kind == SystemKind.SINGLE_VIEW)).first()
    assert not uses_rig(single) and uses_rig(imported["0.png"])
    assert calibration_job(imported["0.png"].frames[0])[4] is None


def test_a_rig_from_fresh_results_of_a_game_not_stored_yet(settings, shared_dir):
    from app.services.recompute import CalibrationFields

    mains = [cam for (system, frame), cam in true_cameras(shared_dir).items() if system == frame]  # actions
    good = [CalibrationFields(CalibrationStatus.CALIBRATED, cam, (1.0, 1.0, 1.0)) for cam in mains]
    rig = game_rig(None, None, settings, extra=good)  # no session needed without a stored game
    assert rig.positions and rig.positions[0].frames >= len(mains) // 2
    poor = [CalibrationFields(CalibrationStatus.CALIBRATED, cam, (0.5, 1.0, 1.0)) for cam in mains]
    assisted = [CalibrationFields(CalibrationStatus.CALIBRATED, cam, (1.0, 1.0, 1.0), flags=[RIG_FLAG]) for cam in mains]
    assert not game_rig(None, None, settings, extra=poor + assisted).positions
