"""Mirror flags in the service: recomputation flags views from all the evidence, and
``apply_mirrored_labels`` fixes them in one transaction."""
from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest
import sqlalchemy as sa
from sqlalchemy.orm import Session

from app.core.config import Settings
from app.core.errors import ConflictError, InvalidInputError, NotFoundError
from app.db.models import Frame
from app.geometry.annotations import lines_from_json_lists, lines_to_json_lists, mirror_lines
from app.geometry.calibration.result import MIRROR_FLAG, PLAYERS_FLAG
from app.geometry.camera import Camera
from app.geometry.mirror import mirror_camera
from app.services.curation.editing import apply_mirrored_labels, ball_error_to_others, replace_field_lines
from app.services.derivation.recompute import recompute_system
from app.services.transfer.importing import import_soccernet_v3
from tests.api.factories import make_game, make_system


def _flagged(frame: Frame) -> bool:
    return frame.calibration is not None and MIRROR_FLAG in (frame.calibration.flags or [])


def _mirror_view(session: Session, settings: Settings, frame: Frame) -> None:
    """Give ``frame`` mirrored labels and the camera they calibrate to, as an annotator's slip would."""
    frame.field_lines.lines = lines_to_json_lists(mirror_lines(lines_from_json_lists(frame.field_lines.lines)))
    frame.calibration.camera = mirror_camera(Camera.from_soccernet(frame.calibration.camera)).to_soccernet()
    recompute_system(session, frame.system, settings)
    session.commit()


def test_a_mirrored_replay_is_flagged_with_its_evidence_and_fixed_in_one_call(db_session: Session,
                                                                              db_settings: Settings) -> None:
    scene = make_system(db_session, db_settings, make_game(db_session))
    frames = [db_session.get(Frame, i) for i in scene.frame_ids]
    assert not any(_flagged(f) for f in frames)
    assert all(f.calibration.mirror_evidence["verdict"] == "as_labelled" for f in frames)
    replay = frames[2]
    _mirror_view(db_session, db_settings, replay)
    assert [_flagged(f) for f in frames] == [False, False, True]
    evidence = replay.calibration.mirror_evidence
    assert evidence["verdict"] == "probably_mirrored" and evidence["margin"] >= 1.0
    assert {p["relation"] for p in evidence["pairs"]} == {"different"}
    assert "1.png" in evidence["sentence"] and "mirrored it meets it" in evidence["sentence"]
    assert replay.reprojection is None or replay.reprojection.error_px > 100.0

    apply_mirrored_labels(db_session, replay.id, settings=db_settings)
    db_session.expire_all()
    replay = db_session.get(Frame, scene.frame_ids[2])
    assert not _flagged(replay) and replay.calibration.status.value == "calibrated"
    assert replay.calibration.source.value == "computed"
    assert replay.reprojection.error_px < 3.0
    # The slip was made after the import: the fix gives back exactly the imported labels.
    assert replay.field_lines.lines == replay.field_lines.original_lines
    # Applying it again would mirror a right camera across the pitch: the mirrored calibration and the ball
    # do not agree better, so nothing is stored and the refusal says by how much.
    lines = replay.field_lines.lines
    with pytest.raises(ConflictError, match="do not agree better"):
        apply_mirrored_labels(db_session, replay.id, settings=db_settings)
    db_session.expire_all()
    replay = db_session.get(Frame, scene.frame_ids[2])
    assert not _flagged(replay) and replay.field_lines.lines == lines


def test_apply_mirrored_labels_refuses_unknown_frames_and_frames_without_lines(db_session: Session,
                                                                              db_settings: Settings) -> None:
    scene = make_system(db_session, db_settings, make_game(db_session))
    with pytest.raises(NotFoundError):
        apply_mirrored_labels(db_session, 10**9, settings=db_settings)
    frame = db_session.get(Frame, scene.frame_ids[1])
    frame.field_lines.lines = {}
    db_session.commit()
    with pytest.raises(InvalidInputError) as err:
        apply_mirrored_labels(db_session, frame.id, settings=db_settings)
    assert err.value.field == "lines"


@pytest.mark.shared
def test_dev_set_every_mirrored_view_is_flagged_and_no_other(shared_dir: Path, fresh_session_factory,
                                                             tmp_path: Path) -> None:
    """Measured: 2 mirrored views (a replay caught by its rays, an action its lines refuse, flagged by the rig
    and side priors, whose players place its camera with its lines fitted mirrored), both flagged; none of the
    103 others. Mirroring any other view in turn flags 71 of 92 and no bystander (``benchmarks/mirror_flags.py``).
    The fix keeps the players' camera of the view they placed: placed again with its lines mirrored."""
    truth = json.loads((shared_dir / "data/synthetic/soccernet-v3-dev.truth.json").read_text())
    mirrored = {(g["match"], v["image"]) for g in truth["games"] for s in g["systems"] for v in s["views"]
                if v["lines_mirrored"]}
    session = fresh_session_factory("dev")
    settings = Settings(_env_file=None, database_url=str(session.get_bind().url), calibration_workers=1)
    import_soccernet_v3(session, shared_dir / "data/synthetic/soccernet-v3-dev", settings)
    frames = session.scalars(sa.select(Frame)).all()
    flagged = {(f.system.game.match, f.name) for f in frames if _flagged(f)}
    assert len(frames) == 105 and len(mirrored) >= 2
    assert flagged == mirrored
    for f in frames:
        if (f.system.game.match, f.name) in mirrored:
            assert f.calibration.mirror_evidence["sentence"].startswith("Labels probably mirrored")
    by_players = {(f.system.game.match, f.name) for f in frames if _flagged(f) and PLAYERS_FLAG in f.calibration.flags}
    assert by_players == {("2031-09-08 - 16-00 Arden 1 - 0 Quarry", "8.png")}
    # The fix: the flag goes and each view calibrates where the truth says its camera is.
    cameras = {(g["match"], v["image"]): v["camera"] for g in truth["games"] for s in g["systems"]
               for v in s["views"]}
    for f in [f for f in frames if (f.system.game.match, f.name) in mirrored]:
        labelled = f.field_lines.lines
        apply_mirrored_labels(session, f.id, settings=settings)
        session.refresh(f)
        session.refresh(f.calibration)
        assert not _flagged(f) and f.calibration.status.value == "calibrated"
        true_c = Camera.from_soccernet(cameras[(f.system.game.match, f.name)]).C
        assert abs(Camera.from_soccernet(f.calibration.camera).C - true_c).max() < 3.0
        assert (PLAYERS_FLAG in f.calibration.flags) == ((f.system.game.match, f.name) in by_players)
        if (f.system.game.match, f.name) in by_players:
            # Its lines put back as labelled (the fix undone): the players place it again, flagged mirrored.
            replace_field_lines(session, f.id, labelled, settings=settings)
            session.refresh(f)
            session.refresh(f.calibration)
            assert _flagged(f) and PLAYERS_FLAG in f.calibration.flags
            assert abs(Camera.from_soccernet(f.calibration.camera).C - true_c).max() < 3.0


#: Games of the doubts seed ``seed-202`` holding its three views whose labels are mirrored and whose cameras the
#: players place (two with 2 line classes, refused by their lines; one with 4).
SEED_GAMES = ("synth_league_a/2031-2032/2031-12-08 - 16-00 Belvoir 0 - 2 Eskdale",
              "synth_league_b/2031-2032/2031-08-15 - 18-00 Oakhurst 1 - 2 Arden",
              "synth_league_b/2031-2032/2031-10-22 - 20-00 Oakhurst 1 - 2 Arden")


@pytest.mark.shared
def test_the_fix_of_a_mirrored_view_the_players_placed_keeps_its_right_camera(shared_dir: Path, fresh_session_factory,
                                                                             tmp_path: Path) -> None:
    """Measured on seed-202: its three mirrored views the players place are flagged, with a camera within 20 px of the
    true ball; the fix leaves each right and unflagged. The fix's guard compares the ball with the camera the labels as
    they are give (the players' camera's mirror image): against the players' camera itself, two of the three fixes
    were refused (the ball as near as after)."""
    seed = shared_dir / "data/synthetic/doubts-seeds/seed-202"
    truth = json.loads((seed.parent / "seed-202.truth.json").read_text())
    views = {(g["match"], s["action"], v["image"]): (s["ball_3d"], v) for g in truth["games"] for s in g["systems"]
             for v in s["views"]}
    for game in SEED_GAMES:
        shutil.copytree(seed / game, tmp_path / "tree" / game)
    session = fresh_session_factory("seed")
    settings = Settings(_env_file=None, database_url=str(session.get_bind().url), calibration_workers=1)
    import_soccernet_v3(session, tmp_path / "tree", settings)
    session.commit()

    def ball_px(f: Frame) -> float:
        ball, view = views[(f.system.game.match, f.system.name, f.name)]
        uv = Camera.from_soccernet(f.calibration.camera).project(np.array([ball]))[0][0]
        true = Camera.from_soccernet(view["camera"]).project(np.array([ball]))[0][0]
        return float(np.linalg.norm(uv - true)) * 1920 / f.width

    placed = [f for f in session.scalars(sa.select(Frame)) if _flagged(f) and PLAYERS_FLAG in f.calibration.flags]
    assert sorted(f.name for f in placed) == ["27.png", "3.png", "3.png"]
    agreed = 0
    for f in placed:
        assert views[(f.system.game.match, f.system.name, f.name)][1]["lines_mirrored"] and ball_px(f) < 20.0
        before = ball_error_to_others(f, settings)
        agreed += before is not None and before[0] is not None
        apply_mirrored_labels(session, f.id, settings=settings)
        session.refresh(f)
        session.refresh(f.calibration)
        assert not _flagged(f) and f.calibration.status.value == "calibrated" and ball_px(f) < 20.0
        after = ball_error_to_others(f, settings)
        assert (after is None or after[0] is None) if before is None else after[0] < 20.0
    assert agreed == 2
