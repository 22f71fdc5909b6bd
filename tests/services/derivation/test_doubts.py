"""Doubts in the service (``app.services.derivation.doubts``): stored with every recomputation in the edit's
transaction, counted per system, mapped from the settings, and left untouched by an edit that fails."""
from __future__ import annotations

import dataclasses
from collections import Counter

import numpy as np
import pytest
from sqlalchemy.orm import Session

from app.core.config import Settings
from app.core.errors import InvalidInputError
from app.db.models import System
from app.geometry.ball import sphere_image_box
from app.geometry.calibration.result import Refusal
from app.geometry.doubts import LABEL_KINDS, DoubtSettings
from app.services.curation import editing, states
from app.services.derivation import doubts as doubt_service
from app.services.derivation.doubts import doubt_settings
from tests.api.factories import BALL, CENTRES, ball_box, make_game, make_system

#: Two of the default scene's cameras: the main one and a replay angle.
CENTRES_TWO = CENTRES[:2]


def _stored(session: Session, system_id: int) -> System:
    session.expire_all()
    return session.get(System, system_id)


def _counts_match(system: System) -> None:
    assert system.doubt_counts == dict(Counter(d.kind for d in system.doubts))
    assert system.label_doubts == sum(d.kind in LABEL_KINDS for d in system.doubts)
    assert all(d.accuses_label == (d.kind in LABEL_KINDS) for d in system.doubts)


def test_settings_map_onto_the_judge_field_by_field() -> None:
    settings = Settings(triangulation_tau_px=17.0)
    mapped = doubt_settings(settings)
    for f in dataclasses.fields(DoubtSettings):
        if f"doubt_{f.name}" in Settings.model_fields:
            assert getattr(mapped, f.name) == getattr(settings, f"doubt_{f.name}"), f.name
        elif f.name in Settings.model_fields:
            assert getattr(mapped, f.name) == getattr(settings, f.name), f.name
    assert mapped.triangulation_tau_px == 17.0
    assert mapped.play_volume.max_height_m == settings.doubt_max_ball_height_m  # the volume's height is a setting
    assert doubt_settings(Settings(doubt_max_ball_height_m=12.0)).play_volume.max_height_m == 12.0


def test_a_clean_system_has_no_label_doubt(db_session: Session, db_settings: Settings) -> None:
    scene = make_system(db_session, db_settings, make_game(db_session))
    system = _stored(db_session, scene.system_id)
    assert system.label_doubts == 0
    _counts_match(system)


def test_removing_a_label_stores_a_missing_ball_doubt_with_the_true_box(db_session: Session,
                                                                     db_settings: Settings) -> None:
    scene = make_system(db_session, db_settings, make_game(db_session))
    missing_id = scene.frame_ids[2]
    editing.update_ball_label(db_session, missing_id, settings=db_settings)  # the ball is "not visible"
    system = _stored(db_session, scene.system_id)
    _counts_match(system)
    (doubt,) = [d for d in system.doubts if d.kind == "ball_missing"]
    assert doubt.frame_id == missing_id and doubt.suggestion["action"] == "snap_box"
    truth = sphere_image_box(scene.cameras[2], BALL, db_settings.ball_diameter_m / 2)
    np.testing.assert_allclose(doubt.suggestion["box"], truth, atol=1.0)

    # snapping to the suggestion (the fix) clears the doubt, in the edit's own transaction
    editing.update_ball_label(db_session, missing_id, box=doubt.suggestion["box"], settings=db_settings)
    system = _stored(db_session, scene.system_id)
    assert not [d for d in system.doubts if d.kind == "ball_missing"]
    _counts_match(system)


def test_a_failing_judge_leaves_the_label_and_the_doubts_unchanged(db_session: Session, db_settings: Settings,
                                                                   monkeypatch: pytest.MonkeyPatch) -> None:
    scene = make_system(db_session, db_settings, make_game(db_session), shift_px=(0.0, 0.0, 80.0))
    before = [(d.kind, d.frame_id, d.message) for d in _stored(db_session, scene.system_id).doubts]
    box_before = _stored(db_session, scene.system_id).frames[2].ball_label.box

    def broken(*args, **kwargs):
        raise RuntimeError("judge exploded")

    monkeypatch.setattr(doubt_service, "judge_system", broken)
    with pytest.raises(RuntimeError):
        editing.update_ball_label(db_session, scene.frame_ids[2], box=[10.0, 10.0, 20.0, 20.0], settings=db_settings)
    system = _stored(db_session, scene.system_id)
    assert [(d.kind, d.frame_id, d.message) for d in system.doubts] == before
    assert system.frames[2].ball_label.box == box_before


def test_exclusion_is_stored_reversible_and_leaves_the_view_out(db_session: Session, db_settings: Settings) -> None:
    scene = make_system(db_session, db_settings, make_game(db_session), shift_px=(0.0, 0.0, 80.0))
    fid = scene.frame_ids[2]
    editing.set_view_excluded(db_session, fid, True, settings=db_settings)
    system = _stored(db_session, scene.system_id)
    frame = next(f for f in system.frames if f.id == fid)
    assert frame.review.excluded is True and frame.review.status.value == "pending"
    assert all(fid not in (p.frame_a_id, p.frame_b_id) for p in system.triangulation.pairs)
    np.testing.assert_allclose(system.triangulation.ball3d, BALL, atol=1e-6)  # the two good views
    assert not [d for d in system.doubts if d.frame_id == fid and d.accuses_label]
    editing.set_view_excluded(db_session, fid, False, settings=db_settings)
    system = _stored(db_session, scene.system_id)
    assert len(system.triangulation.pairs) == 3
    assert next(f for f in system.frames if f.id == fid).review.excluded is False
    with pytest.raises(InvalidInputError):
        editing.set_view_excluded(db_session, fid, "yes", settings=db_settings)  # type: ignore[arg-type]  # a string on purpose: refused


def test_systems_stored_by_an_older_version_are_recomputed_once(db_session: Session, db_settings: Settings) -> None:
    """After a schema upgrade the stored doubts and queue figures are empty (``derived_version`` 0):
    ``refresh_stale_systems`` recomputes exactly those systems, and then nothing."""
    from app.services.derivation.recompute import DERIVED_VERSION, refresh_stale_systems

    scene = make_system(db_session, db_settings, make_game(db_session), shift_px=(0.0, 0.0, 80.0))
    system = _stored(db_session, scene.system_id)
    figures = (system.views_total, system.views_admitted, system.worst_error_px, system.label_doubts)
    system.derived_version, system.views_total, system.worst_error_px, system.label_doubts = 0, 0, None, 0
    system.doubts.clear()
    db_session.commit()
    assert refresh_stale_systems(db_session, db_settings) == 1
    system = _stored(db_session, scene.system_id)
    assert system.derived_version == DERIVED_VERSION
    assert (system.views_total, system.views_admitted, system.worst_error_px, system.label_doubts) == figures
    assert refresh_stale_systems(db_session, db_settings) == 0


def test_a_label_made_from_a_suggestion_is_no_evidence_until_a_person_places_it(db_session: Session,
                                                                               db_settings: Settings) -> None:
    """Issue 18: the fix key's request carries the doubt's provenance; the label it makes joins no
    triangulation (the 3D ball comes from the other views alone) and says so, until a person confirms it
    (the same box sent without provenance) or moves it."""
    scene = make_system(db_session, db_settings, make_game(db_session))
    missing_id = scene.frame_ids[2]
    editing.update_ball_label(db_session, missing_id, settings=db_settings)
    system = _stored(db_session, scene.system_id)
    (doubt,) = [d for d in system.doubts if d.kind == "ball_missing"]
    provenance_in = doubt_service.doubt_provenance(doubt)
    request = doubt_service.suggestion_json(doubt.frame_id, doubt.suggestion, provenance_in)["request"]
    provenance = request["body"]["provenance"]
    assert provenance == {"doubt": "ball_missing", "code": "consensus", "from_views": doubt.evidence["agreeing_views"]}
    editing.update_ball_label(db_session, missing_id, box=request["body"]["box"], provenance=provenance,
                              settings=db_settings)
    system = _stored(db_session, scene.system_id)
    frame = next(f for f in system.frames if f.id == missing_id)
    assert frame.ball_label.suggested and frame.ball_label.provenance["from_views"] == provenance["from_views"]
    pairs = system.triangulation.pairs
    assert pairs and all(missing_id not in (p.frame_a_id, p.frame_b_id) for p in pairs)  # not evidence
    assert [d.kind for d in system.doubts if d.frame_id == missing_id] == ["suggested_label"]
    assert states.ball_state(frame)["ball"]["provenance"]["doubt"] == "ball_missing"  # audited with it
    # a person confirms it: the same box without provenance; now it is a label like any other
    editing.update_ball_label(db_session, missing_id, box=request["body"]["box"], settings=db_settings)
    system = _stored(db_session, scene.system_id)
    frame = next(f for f in system.frames if f.id == missing_id)
    assert not frame.ball_label.suggested and frame.ball_label.provenance is None
    assert any(missing_id in (p.frame_a_id, p.frame_b_id) for p in system.triangulation.pairs)
    assert not [d for d in system.doubts if d.frame_id == missing_id and d.kind in ("suggested_label", "ball_missing")]
    with pytest.raises(InvalidInputError):
        editing.update_ball_label(db_session, missing_id, box=request["body"]["box"], provenance={"from_views": "x"},
                                  settings=db_settings)


def test_a_refused_main_view_whose_mirrored_labels_calibrate_is_flagged_with_the_refit(monkeypatch) -> None:
    """The mirrored re-fit (issue 18): a main-camera frame refused as labelled whose mirrored labelling
    calibrates under the same side prior is flagged probably mirrored, with the mirrored fit's camera in
    its evidence; the labels themselves are not changed."""
    from app.geometry.annotations import lines_to_json_lists, mirror_lines
    from app.geometry.calibration import calibrate_frame as real
    from app.geometry.projection import project_pitch_polylines
    from app.services.calibration import calibrating
    from tests.api.factories import HEIGHT, WIDTH, look_at

    cam = look_at(np.array([0.0, 60.0, -15.0]), np.array([20.0, 5.0, 0.0]), 1200.0)
    truth = project_pitch_polylines(cam, WIDTH, HEIGHT, 2.0, 1.0)
    labels = lines_to_json_lists(mirror_lines(truth))  # an annotator's slip: left for right
    calls = []

    def refuse_as_labelled(lines, width, height, **kw):
        calls.append(lines)
        if len(calls) == 1:  # as labelled: refused (the side prior finds no camera on the near side)
            return dataclasses.replace(real(lines, width, height, **kw), status="refused", camera=None,
                                       refusal=Refusal("no_camera_fits"))
        return real(lines, width, height, **kw)

    monkeypatch.setattr(calibrating, "calibrate_frame", refuse_as_labelled)
    fields = calibrating.calibrate_lines(labels, WIDTH, HEIGHT, side=1)
    assert fields.status.value == "refused" and "probably_mirrored" in fields.flags and len(calls) == 2
    refit = fields.mirror_evidence["refit"]
    np.testing.assert_allclose(refit["position_m"], cam.C, atol=0.5)  # the mirrored labels give the true camera
    assert fields.mirror_evidence["sentence"].startswith("Labels probably mirrored")
    # a replay (no side prior) is not re-fitted: labels and their mirror fit equally well there
    calls.clear()
    assert "probably_mirrored" not in calibrating.calibrate_lines(labels, WIDTH, HEIGHT, side=None).flags


def test_weak_fitted_calibrations_neither_make_nor_move_the_3d_ball(db_session: Session, db_settings: Settings) -> None:
    """Issue 18 (the yield: seed-204's system made wrong by a 1-class main view and a 2-class rig replay): a
    view whose camera v3d fitted to fewer than ``min_line_classes`` classes is worth half a vote
    (``calibration_weight``); two such views make no 3D ball together, and beside two sure views they do not
    move it. A camera a person set (source "edited", not fitted to the lines it shows) counts full."""
    from app.db.models import CalibrationSource
    from app.services.derivation.recompute import recompute_system

    centres = ([0.0, 58.0, -16.0], [-32.0, 48.0, -12.0], [36.0, 50.0, -14.0], [-60.0, -10.0, -15.0])
    scene = make_system(db_session, db_settings, make_game(db_session), centres=centres)
    system = _stored(db_session, scene.system_id)
    weak = system.frames[1:4:2]  # two views: their cameras turned by 1.5 deg, as two few-class rig fits do
    a = np.radians(1.5)
    turn = np.array([[np.cos(a), -np.sin(a), 0.0], [np.sin(a), np.cos(a), 0.0], [0.0, 0.0, 1.0]])
    sure_u = {"position_m": {"x": 0.0, "y": 0.0, "z": 0.0}, "pan_deg": 0.01, "tilt_deg": 0.01, "roll_deg": 0.01,
              "focal_px": 1.0, "line_noise_px": 1.0, "points": 20}
    for f in weak:
        cam = scene.cameras[f.position]
        f.calibration.camera = type(cam)(K=cam.K, R=cam.R @ turn, C=cam.C).to_soccernet()
        f.calibration.source = CalibrationSource.COMPUTED
        f.calibration.uncertainty = sure_u
        f.field_lines.lines = dict(list(f.field_lines.lines.items())[:2])  # two line classes
    weak_ids = {f.id for f in weak}
    by_class = db_settings.model_copy(update={"ball_rule": "weights"})  # the rule by class vetoes them
    recompute_system(db_session, system, by_class)
    db_session.commit()
    system = _stored(db_session, scene.system_id)
    assert len(system.triangulation.pairs) == 6
    np.testing.assert_allclose(system.triangulation.ball3d, BALL, atol=1e-6)  # the sure views alone
    reasons = {frozenset((p.frame_a_id, p.frame_b_id)): p.reason for p in system.triangulation.pairs}
    assert reasons[frozenset(weak_ids)] == "weak_calibrations"
    # the mixed pairs are kept out: outweighed by the sure pair, or meeting under the grass (outside the play volume)
    assert sum(r is None for r in reasons.values()) == 1 and "outweighed" in reasons.values()
    assert set(reasons.values()) <= {None, "weak_calibrations", "outweighed", "outside_play_volume"}
    # the two weak views alone: their rays meet metres off, yet no 3D ball is made
    for fid in scene.frame_ids:
        if fid not in weak_ids:
            editing.set_view_excluded(db_session, fid, True, settings=by_class)
    system = _stored(db_session, scene.system_id)
    assert system.triangulation.ball3d is None and system.triangulation.status.value == "no_pair_kept"
    # by evidence (the default) their pair is not vetoed by class: it makes a ball metres off, but one whose sigma
    # says so (each camera known only to the consensus tolerance), which the queue's sigma filter finds
    recompute_system(db_session, system, db_settings)
    db_session.commit()
    tri = _stored(db_session, scene.system_id).triangulation
    off = np.linalg.norm(np.subtract(tri.ball3d, BALL))
    assert tri.sigma_m is not None and 0.5 < tri.sigma_m and off < 3 * tri.sigma_m, (off, tri.sigma_m)
    recompute_system(db_session, system, by_class)
    db_session.commit()
    system = _stored(db_session, scene.system_id)
    # the same cameras set by a person (not fitted to these lines) count full: their pair makes the ball
    for f in system.frames:
        if f.id in weak_ids:
            f.calibration.source = CalibrationSource.EDITED
    recompute_system(db_session, system, by_class)
    db_session.commit()
    system = _stored(db_session, scene.system_id)
    ball3d = system.triangulation.ball3d
    assert ball3d is not None and np.linalg.norm(np.subtract(ball3d, BALL)) > 0.5


def _import_game(factory, shared_dir, tmp_path, folder: str, game: str):
    """One game of a shared synthetic set (labels only) imported as a user would: (frames by (system, view name),
    the set's truth of that game's systems by action)."""
    import json
    import shutil
    from pathlib import Path

    import sqlalchemy as sa

    from app.db.models import Frame, Game
    from app.services.transfer.importing import import_soccernet_v3

    root = shared_dir / "data/synthetic" / folder
    (tmp_path / folder / game).mkdir(parents=True)
    shutil.copy(root / game / "Labels-v3.json", tmp_path / folder / game)
    session = factory(Path(folder).name)
    import_soccernet_v3(session, tmp_path / folder, Settings(calibration_workers=1))
    session.commit()
    truth = json.loads(root.with_name(f"{root.name}.truth.json").read_text())
    systems = next(g["systems"] for g in truth["games"] if g["match"] == Path(game).name)
    frames = {(f.system.name, f.name): f for f in session.scalars(sa.select(Frame).join(System).join(Game))}
    return frames, {s["action"]: s for s in systems}


def test_a_players_placed_camera_snaps_a_label_far_off_the_agreed_ball_and_never_a_right_one(
        shared_dir, tmp_path, fresh_session_factory) -> None:
    """A view whose camera its players placed takes no part in the consensus (its few lines do not fix it), yet its
    players do: its ball label 700 px@1920 from where it sees the ball the other views agree on is accused with the
    one-key snap to that ball's box (the dev set's 8.png, the label on the wrong spot). Never on a ball a replay out
    of time made (seed-203: the players-placed view is the one out of time; seed-201: a voter is), where its label
    is right and the snap would move it hundreds of px off."""
    import math

    frames, truth = _import_game(fresh_session_factory, shared_dir, tmp_path, "soccernet-v3-dev",
                                 "synth_league_a/2031-2032/2031-08-01 - 14-00 Dunmore 0 - 3 Glenrock")
    view = frames[("8.png", "8.png")]
    assert "player_assisted" in view.calibration.flags and truth["8.png"]["corruption"] == "wrong_ball"
    seen = next(v for v in truth["8.png"]["views"] if v["image"] == "8.png")
    true_centre = seen["ball_center_px"]
    (doubt,) = [d for d in view.system.doubts if d.frame_id == view.id and d.kind == "ball_off_consensus"]
    assert doubt.evidence["error_px_1920"] > 500 and doubt.suggestion["action"] == "snap_box"
    x1, y1, x2, y2 = doubt.suggestion["box"]
    # on the ball, by the scorer's tolerance (tools/detector_fill_eval.py: max(3 px, half the ball's diameter))
    assert math.dist(((x1 + x2) / 2, (y1 + y2) / 2), true_centre) <= max(3.0, seen["d_true"] / 2)
    assert math.dist(view.ball_label.centre, true_centre) > 300
    for folder, game in (("doubts-seeds/seed-203", "2031-12-08 - 16-00 Oakhurst 0 - 0 Marden"),
                         ("doubts-seeds/seed-201", "2031-08-01 - 14-00 Northby 1 - 3 Glenrock")):
        game = f"synth_league_a/2031-2032/{game}"
        frames, truth = _import_game(fresh_session_factory, shared_dir, tmp_path, folder, game)
        for (action, name), f in frames.items():
            if f.calibration is not None and "player_assisted" in (f.calibration.flags or []):
                accused = [d for d in f.system.doubts if d.frame_id == f.id and d.kind == "ball_off_consensus"]
                assert not accused or truth[action]["corruption"] == "wrong_ball", (folder, action, name)


def test_by_evidence_weak_fitted_calibrations_move_the_3d_ball_only_within_their_sigma(
        db_session: Session, db_settings: Settings) -> None:
    """Under ``ball_rule`` "evidence" the same two few-class views (cameras turned 1.5 deg) beside two sure ones are
    not vetoed by their class: known only to the consensus tolerance, they move the ball within its sigma, not the
    metres their turned rays would; the ball stands with its sigma stored. Under the default rule the ball is the
    sure views' and its sigma is stored too."""
    from app.db.models import CalibrationSource
    from app.services.derivation.recompute import recompute_system

    centres = ([0.0, 58.0, -16.0], [-32.0, 48.0, -12.0], [36.0, 50.0, -14.0], [-60.0, -10.0, -15.0])
    scene = make_system(db_session, db_settings, make_game(db_session), centres=centres)
    system = _stored(db_session, scene.system_id)
    a = np.radians(1.5)
    turn = np.array([[np.cos(a), -np.sin(a), 0.0], [np.sin(a), np.cos(a), 0.0], [0.0, 0.0, 1.0]])
    for f in system.frames[1:4:2]:
        cam = scene.cameras[f.position]
        f.calibration.camera = type(cam)(K=cam.K, R=cam.R @ turn, C=cam.C).to_soccernet()
        f.calibration.source = CalibrationSource.COMPUTED
        f.calibration.uncertainty = {"position_m": {"x": 0.0, "y": 0.0, "z": 0.0}, "pan_deg": 0.01,
                                     "tilt_deg": 0.01, "roll_deg": 0.01, "focal_px": 1.0, "line_noise_px": 1.0,
                                     "points": 20}
        f.field_lines.lines = dict(list(f.field_lines.lines.items())[:2])  # two line classes
    recompute_system(db_session, system, db_settings.model_copy(update={"ball_rule": "weights"}))
    db_session.commit()
    tri = _stored(db_session, scene.system_id).triangulation
    np.testing.assert_allclose(tri.ball3d, BALL, atol=1e-6)
    assert tri.sigma_m is not None and 0.0 < tri.sigma_m < 0.5
    evidence = db_settings.model_copy(update={"ball_rule": "evidence"})
    system = _stored(db_session, scene.system_id)
    recompute_system(db_session, system, evidence)
    db_session.commit()
    tri = _stored(db_session, scene.system_id).triangulation
    moved = np.linalg.norm(np.subtract(tri.ball3d, BALL))
    assert tri.sigma_m is not None and 0.0 < tri.sigma_m < evidence.ball_max_sigma_m
    assert 1e-3 < moved < min(0.5, 3 * tri.sigma_m)
    assert not {p.reason for p in tri.pairs} & {"weak_calibrations", "outweighed", "parallax_below_min"}


def test_a_box_placed_from_labels_the_ball_keeps_no_ball_from_or_from_detections_alone_gets_no_fix_key(
        db_session: Session, db_settings: Settings) -> None:
    from app.geometry.doubts import Doubt
    from app.services.wording.doubt_words import doubt_message

    scene = make_system(db_session, db_settings, make_game(db_session))
    system = _stored(db_session, scene.system_id)
    a, b, c = scene.frame_ids[:3]
    box = {"action": "snap_box", "box": [100.0, 100.0, 112.0, 112.0]}
    placed = Doubt("ball_missing", c, "consensus", {"agreeing_views": [a, b], "projected_px": [106.0, 106.0]}, box)
    lone = Doubt("ball_detected", c, "one_ray", {"agreeing_views": [a], "detector": "d", "score": 0.9}, box)
    alone = Doubt("ball_detected", c, "detections_agree", {"agreeing_views": [b], "detector": "d", "score": 0.9}, box)
    up = {"agreeing_views": [a], "detector": "d", "score": 0.9, "ball3d": [6.0, 4.0, -3.0]}
    in_air = Doubt("ball_detected", c, "one_ray", up, box)
    seen = Doubt("ball_detected", c, "one_ray", {**up, "agreeing_views": [a, -1]}, box)  # a third view's detection
    grass = Doubt("ball_detected", c, "one_ray", {**up, "ball3d": [6.0, 4.0, -0.11]}, box)
    found = [placed, lone, alone, in_air, seen, grass]
    assert system.triangulation.ball3d is not None
    assert doubt_service.without_unbacked_fixes(system, found) == found  # a ball: every key stays
    system.triangulation.ball3d = None  # the ball's rule refused the labels' pairs
    assert doubt_service.without_unbacked_fixes(system, found) == found  # c's own label snapped back: keys stay
    next(f for f in system.frames if f.id == c).ball_label = None  # a fill of a view nobody labelled
    kept = doubt_service.without_unbacked_fixes(system, found)
    assert kept[1] == lone  # one labelled ray and a detection: its own checks pair them
    assert kept[0].suggestion is None and kept[0].evidence["no_key"] == "agreeing"
    assert kept[2].suggestion is None and kept[2].evidence["no_key"] == "detections"
    assert kept[3].suggestion is None and kept[3].evidence["no_key"] == "one_ray"  # the box alone sets its depth
    assert kept[4:] == [seen, grass]  # a third view sees it; the grass places it
    names = {f.id: f.name for f in system.frames}
    assert "No fix key: the 3D ball keeps no ball from the labels of" in doubt_message(kept[0], names)
    assert "detections alone" in doubt_message(kept[2], names)
    assert "No fix key" not in doubt_message(lone, names)
    db_session.rollback()


def _one_ray_doubt(db_session: Session, db_settings: Settings, game: object, name: str, ball: np.ndarray,
                   boxed: np.ndarray) -> tuple[object, np.ndarray]:
    """A three-view system of the true ``ball`` (world metres, z down) labelled in its first view only, whose
    detector found nothing in the second view and one box in the third: a ball's silhouette at ``boxed``. Returns
    that third view's doubt once recomputed, and the ball its pairing places."""
    from app.db.models import Prediction
    from app.services.derivation.recompute import recompute_system

    scene = make_system(db_session, db_settings, game, name, ball=ball, labelled=(True, False, False))
    x1, y1, x2, y2 = (float(v) for v in sphere_image_box(scene.cameras[2], boxed, 0.11))
    db_session.add(Prediction(frame_id=scene.frame_ids[2], source="det", score=0.9, x1=x1, y1=y1, x2=x2, y2=y2))
    db_session.flush()
    system = _stored(db_session, scene.system_id)
    recompute_system(db_session, system, db_settings)
    db_session.commit()
    system = _stored(db_session, scene.system_id)
    assert system.triangulation.ball3d is None  # one labelled view
    (d,) = [d for d in system.doubts if d.frame_id == scene.frame_ids[2] and d.kind == "ball_detected"]
    assert d.evidence["code"] == "one_ray" and d.evidence["agreeing_views"] == [scene.frame_ids[0]]
    return d, np.asarray(d.evidence["ball3d"], float)


def test_a_box_on_a_lone_labelled_ray_with_its_ball_in_the_air_gets_no_fix_key_on_the_grass_it_keeps_it(
        db_session: Session, db_settings: Settings) -> None:
    """Known truth: a ball 3 m up. A false box in the third view, a ball's size where it lies, on the labelled
    view's ray 4 m nearer that camera, meets the ray as well as the ball's own box would: two views cannot tell
    them apart, so the box keeps its doubt and numbers but no fix key (its words say why). A box whose ball lies
    on the grass, where the labelled ray meets it, keeps its key."""
    air = np.array([6.0, 4.0, -3.0])
    centre = np.array([0.0, 58.0, -16.0])  # the factory's first camera
    along = (air - centre) / np.linalg.norm(air - centre)
    false = air - 4.0 * along
    assert -false[2] > 3.0  # still in the air, and 4 m from the ball
    game = make_game(db_session)
    d, placed = _one_ray_doubt(db_session, db_settings, game, "1.png", air, false)
    assert np.linalg.norm(placed - false) < 0.5 and np.linalg.norm(placed - air) > 3.0  # a wrong ball, confirmed
    assert d.suggestion is None and d.evidence["no_key"] == "one_ray"
    assert "No fix key: only this box says where along 1.png's ray the ball is (3.9 m above the grass" in d.message
    assert "s places its box" not in d.message and "its box lies at x " in d.message  # no key to press
    assert d.evidence["score"] == 0.9 and d.evidence["error_px_1920"] is not None  # the doubt keeps its numbers

    d, placed = _one_ray_doubt(db_session, db_settings, game, "2.png", BALL, BALL)
    assert np.linalg.norm(placed - BALL) < 0.3
    assert d.suggestion is not None and d.suggestion["action"] == "snap_box" and "no_key" not in d.evidence
    assert "No fix key" not in d.message


def _one_view_doubts(db_session: Session, db_settings: Settings, game: object, name: str, boxed: np.ndarray
                     ) -> tuple[object, list[object]]:
    """A three-view system of the true ball (``BALL``, on the grass) labelled in its first view only, its cameras
    sure to a few pixels (a stored uncertainty of 0.05 degree in pan and tilt), whose detector found one box in each
    other view: a ball's silhouette at ``boxed`` (world metres, z down) in the second, at the ball in the third.
    Returns the system once recomputed and those two views' ``ball_detected`` doubts."""
    from app.db.models import Prediction
    from app.services.derivation.recompute import recompute_system

    scene = make_system(db_session, db_settings, game, name, labelled=(True, False, False))
    for v, where in ((1, boxed), (2, BALL)):
        x1, y1, x2, y2 = (float(c) for c in sphere_image_box(scene.cameras[v], where, 0.11))
        db_session.add(Prediction(frame_id=scene.frame_ids[v], source="det", score=0.9, x1=x1, y1=y1, x2=x2, y2=y2))
    system = _stored(db_session, scene.system_id)
    for f in system.frames:
        f.calibration.uncertainty = {"pan_deg": 0.05, "tilt_deg": 0.05, "roll_deg": 0.0, "focal_px": 0.0}
    db_session.flush()
    recompute_system(db_session, system, db_settings)
    db_session.commit()
    system = _stored(db_session, scene.system_id)
    assert system.triangulation.ball3d is None  # one labelled view
    found = sorted((d for d in system.doubts if d.kind == "ball_detected"), key=lambda d: d.frame_id)
    assert [d.frame_id for d in found] == scene.frame_ids[1:]
    assert all(d.evidence["code"] == "one_view" for d in found)  # one labelled ray, two detected views
    return system, found


def test_boxes_placed_from_one_labelled_ray_and_two_detected_views_whose_pairs_the_ball_refuses_get_no_fix_key(
        db_session: Session, db_settings: Settings) -> None:
    """Known truth: a ball on the grass labelled in one view. A false box in the second view, a ball's size, on the
    labelled ray 1.5 m nearer that camera, and the ball's own box in the third meet the labelled ray within the
    doubts' tau at one ball 0.8 m off: the pairing accepts them. Confirmed, the false box alone with the labelled ray
    makes a ball 1.5 m off, and with the third box the ball's rule refuses two of the three pairs (beyond their joint
    sigma): the rule the ball applies once the boxes are placed does not keep the pairing's agreement, so neither box
    gets a fix key (each keeps its doubt, numbers and box). Where the second box is the ball's too, the keys stay."""
    from app.services.curation import editing

    game = make_game(db_session)
    centre = np.array([0.0, 58.0, -16.0])  # the factory's first camera
    along = (BALL - centre) / np.linalg.norm(BALL - centre)
    false = BALL - 1.5 * along
    system, found = _one_view_doubts(db_session, db_settings, game, "1.png", false)
    placed = np.asarray(found[0].evidence["ball3d"], float)
    assert np.linalg.norm(placed - BALL) > 0.5  # the pairing's ball is not the ball
    for d in found:
        assert d.suggestion is None and d.evidence["no_key"] == "one_view"
        assert d.evidence["score"] == 0.9 and len(d.evidence["box"]) == 4  # the doubt keeps its numbers and box
        assert "No fix key: confirmed beside 1.png" in d.message and "rays disagree" in d.message
    # what the keys would have made: the boxes confirmed as the pass confirms them, one after the other
    errors = []
    for d in found:
        editing.update_ball_label(db_session, d.frame_id, box=d.evidence["box"], settings=db_settings)
        tri = _stored(db_session, system.id).triangulation
        errors.append(float(np.linalg.norm(np.subtract(tri.ball3d, BALL))))
    assert errors[0] > 1.0  # the false box and the labelled ray: a wrong ball
    reasons = {p.reason for p in _stored(db_session, system.id).triangulation.pairs}
    assert reasons & set(doubt_service.DISAGREEING)  # the rule refuses a pair of them for disagreeing

    system, found = _one_view_doubts(db_session, db_settings, game, "2.png", BALL)
    for d in found:
        assert d.suggestion is not None and d.suggestion["action"] == "snap_box" and "no_key" not in d.evidence
        assert "No fix key" not in d.message


def test_a_two_view_ball_whose_rays_meet_only_at_the_edge_of_tau_is_withheld(db_session: Session,
                                                                              db_settings: Settings) -> None:
    """Two labelled views whose rays cross by chance, as a replay of another instant's do: the replay's label moved
    across its image until the pair's error lies in the outer part of tau (0.75-0.95 tau). The paper's rules keep the
    pair and make a ball; the ball's rule refuses it (``lone_pair_at_tau_edge``): no 3D ball, tier none, the pair's
    reason stored for the page. The same views with the label a few px off (well within tau) keep their ball."""
    from app.services.derivation.recompute import recompute_system
    from app.services.evaluation.ball_yield import paper_ball

    scene = make_system(db_session, db_settings, make_game(db_session), centres=CENTRES_TWO)
    system = _stored(db_session, scene.system_id)
    replay = system.frames[1]
    true_box = ball_box(scene.cameras[1])
    tau = db_settings.triangulation_tau_px
    found = None
    for shift in np.arange(1.0, 60.0, 0.5):
        replay.ball_label.box = [true_box[0], true_box[1] + shift, true_box[2], true_box[3] + shift]
        recompute_system(db_session, system, db_settings)
        pair = system.triangulation.pairs[0]
        if pair.error_px is not None and 0.75 * tau < pair.error_px < 0.95 * tau:
            found = shift
            break
    assert found is not None, "no shift puts the pair's error in the outer part of tau"
    db_session.commit()
    system = _stored(db_session, scene.system_id)
    tri = system.triangulation
    assert tri.ball3d is None and tri.status.value == "no_pair_kept"
    assert [p.reason for p in tri.pairs] == ["lone_pair_at_tau_edge"]
    assert system.ball_evidence.value == "none"
    assert paper_ball(system, db_settings) is not None  # the paper's rules keep the pair: tau alone passes it
    # a label a few px off: the pair meets well within tau and the ball stands, near the true one
    system = _stored(db_session, scene.system_id)
    system.frames[1].ball_label.box = [true_box[0], true_box[1] + 3.0, true_box[2], true_box[3] + 3.0]
    recompute_system(db_session, system, db_settings)
    db_session.commit()
    tri = _stored(db_session, scene.system_id).triangulation
    assert tri.pairs[0].error_px < 0.5 * tau
    assert tri.ball3d is not None and np.linalg.norm(np.subtract(tri.ball3d, BALL)) < 0.5
