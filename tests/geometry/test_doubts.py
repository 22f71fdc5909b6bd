"""The doubt judge (app.geometry.doubts.judge_system) on scenes with known truth, and a small run of
benchmarks/doubts.py on the synthetic dev data (skipped without ../shared)."""
from __future__ import annotations

import dataclasses
import json
import math
from pathlib import Path

import numpy as np
import pytest

from app.core.config import Settings
from app.geometry.ball import sphere_image_box
from app.geometry.camera import Camera, pan_tilt_roll_from_rotation
from app.geometry.consensus import ball_consensus
from app.geometry.doubts import (
    CODES,
    INFO_KINDS,
    LABEL_KINDS,
    SUGGESTION_ACTIONS,
    DoubtView,
    epipolar_pair_error,
    judge_system,
)
from app.geometry.mirror import mirror_camera
from app.geometry.pitch import PLAY_VOLUME
from app.geometry.triangulation import BallObservation
from app.geometry.weighting import pixel_sigma
from app.services.derivation.doubts import doubt_settings
from app.services.wording.doubt_words import doubt_message

BALL = np.array([10.0, 5.0, -0.11])  # on the grass
R_BALL = 0.11
W, H = 1920, 1080


#: The judge's thresholds as the service builds them from the settings' defaults (the geometry has none).
SETTINGS = doubt_settings(Settings())

def look_at(position, target, focal=2500.0, width=W, height=H) -> Camera:
    """An undistorted camera at ``position`` whose optical axis passes through ``target`` (world, z down)."""
    c = np.asarray(position, float)
    f = np.asarray(target, float) - c
    f /= np.linalg.norm(f)
    down = np.array([0.0, 0.0, 1.0])
    y = down - (down @ f) * f
    y /= np.linalg.norm(y)
    R = np.stack([np.cross(y, f), y, f])
    pan, tilt, roll = pan_tilt_roll_from_rotation(R)
    return Camera.from_parameters(focal_px=focal * width / W, principal_point=(width / 2, height / 2),
                                  pan_deg=pan, tilt_deg=tilt, roll_deg=roll, position_m=c)


CAMERAS = {
    "main": ([0.0, 60.0, -15.0], 2500.0),
    "goal": ([70.0, 3.0, -15.0], 3500.0),
    "opposite": ([5.0, -60.0, -20.0], 3000.0),
    "corner": ([35.0, 45.0, -8.0], 3000.0),
}


def camera(name: str) -> Camera:
    """The camera of ``CAMERAS[name]``, aimed at the ball."""
    position, focal = CAMERAS[name]
    return look_at(position, BALL, focal)


def view(name, position, focal, *, ball=BALL, box="exact", target=None, role="replay", **kw) -> DoubtView:
    cam = kw.pop("camera", None) or look_at(position, BALL if target is None else target, focal)
    if isinstance(box, str):
        box = sphere_image_box(cam, ball, R_BALL)
    return DoubtView(view_id=name, name=f"{name}.png", role=role, width=W, height=H, camera=cam,
                     admitted=kw.pop("admitted", True), jac=kw.pop("jac", 0.95), line_classes=kw.pop("line_classes", 8),
                     box=None if box is None else np.asarray(box), **kw)


def scene(**overrides) -> list[DoubtView]:
    """The four views of ``CAMERAS`` with exact boxes; ``overrides[name]`` = view kwargs."""
    out = []
    for name, (pos, focal) in CAMERAS.items():
        out.append(view(name, pos, focal, role="action" if name == "main" else "replay", **overrides.get(name, {})))
    return out


def accusing(doubts):
    return [d for d in doubts if d.kind in LABEL_KINDS]


def test_a_clean_system_has_no_label_doubt_and_every_doubt_follows_the_contract():
    doubts = judge_system(scene(), SETTINGS)
    assert accusing(doubts) == []
    for d in judge_system(scene(corner={"box": None}, goal={"box": [5.0, 5.0, 20.0, 20.0]}), settings=SETTINGS):
        assert d.kind in LABEL_KINDS + INFO_KINDS
        assert d.suggestion is None or d.suggestion["action"] in SUGGESTION_ACTIONS
        assert d.code in CODES[d.kind] and not hasattr(d, "message")  # geometry: codes and numbers only
        assert doubt_message(d, {}).endswith(".")  # the words are composed above it
        json.dumps(d.evidence), json.dumps(d.suggestion)  # JSON-ready


@pytest.mark.parametrize("corrupt", ["wrong_box", "desync"])
def test_the_one_bad_view_among_four_is_named_and_offered_the_consensus_box(corrupt):
    if corrupt == "wrong_box":
        bad = {"box": sphere_image_box(camera("opposite"), BALL, R_BALL) + [160.0, -40.0, 160.0, -40.0]}
    else:  # the replay shows the ball 4 m from where the other views see it
        bad = {"ball": BALL + [3.0, -2.5, 0.0]}
    doubts = accusing(judge_system(scene(opposite=bad), settings=SETTINGS))
    assert [(d.kind, d.view_id) for d in doubts] == [("ball_off_consensus", "opposite")]
    d = doubts[0]
    assert d.evidence["error_px_1920"] > 60 and sorted(d.evidence["agreeing_views"]) == ["corner", "goal", "main"]
    # the one-key fix is the box the other views agree on (issue 28 item 6); excluding the view stays offered
    assert d.suggestion["action"] == "snap_box" and d.suggestion["alternatives"] == ["exclude_view"]
    truth = sphere_image_box(camera("opposite"), BALL, R_BALL)
    assert np.abs(np.asarray(d.suggestion["box"]) - truth).max() < 0.5
    # exact cameras and labels: the agreeing views meet exactly, the cameras carry no uncertainty
    assert d.suggestion["box_sigma_px"] == pytest.approx(0.0, abs=0.05)


def test_the_consensus_box_carries_the_uncertainty_of_the_agreeing_views_and_of_the_camera():
    """The box's sigma: the agreeing views' RMS error to the consensus ball and the accused view's calibration
    sigma in quadrature, in the view's pixels; the truth lies within a few sigmas of the box."""
    rng = np.random.default_rng(3)
    noisy = {}
    for name in ("main", "goal", "corner"):
        cam = camera(name)
        box = sphere_image_box(cam, BALL, R_BALL) + np.repeat(rng.normal(0.0, 2.0, 2), 2)[[0, 2, 1, 3]]
        noisy[name] = {"box": box}
    u = {"pan_deg": 0.02, "tilt_deg": 0.02, "roll_deg": 0.02, "focal_px": 2.0}
    bad = {"box": sphere_image_box(camera("opposite"), BALL, R_BALL) + [160.0, -40.0, 160.0, -40.0], "uncertainty": u}
    views = scene(opposite=bad, **noisy)
    (d,) = accusing(judge_system(views, settings=SETTINGS))
    assert d.kind == "ball_off_consensus" and d.suggestion["action"] == "snap_box"
    opposite = next(v for v in views if v.view_id == "opposite")
    own = pixel_sigma(opposite, np.asarray(d.evidence["ball3d"]), SETTINGS)
    assert own > 1.0  # the camera's uncertainty counts
    sigma = d.suggestion["box_sigma_px"]
    assert own <= sigma < 15.0  # at least the camera's own sigma, and no more than a few px of label noise
    truth = sphere_image_box(camera("opposite"), BALL, R_BALL)

    def centre(b):
        return np.array([(b[0] + b[2]) / 2, (b[1] + b[3]) / 2])

    assert np.linalg.norm(centre(np.asarray(d.suggestion["box"])) - centre(truth)) < 3 * sigma


def test_a_missing_ball_label_gets_the_exact_sphere_box_where_the_other_views_agree():
    doubts = accusing(judge_system(scene(corner={"box": None}), settings=SETTINGS))
    assert [(d.kind, d.view_id) for d in doubts] == [("ball_missing", "corner")]
    truth = sphere_image_box(camera("corner"), BALL, R_BALL)
    assert doubts[0].suggestion["action"] == "snap_box"
    assert np.abs(np.asarray(doubts[0].suggestion["box"]) - truth).max() < 0.5


def test_with_one_other_view_the_missing_ball_is_a_segment_and_a_box_only_where_it_is_short():
    views = [v for v in scene(goal={"box": None}) if v.view_id in ("main", "goal")]
    doubts = accusing(judge_system(views, settings=SETTINGS))
    assert [(d.kind, d.view_id) for d in doubts] == [("ball_missing", "goal")]
    d = doubts[0]
    assert d.evidence["placed"] == "grass" and d.evidence["inside_chance"] >= 0.5
    seg = np.asarray(d.evidence["epipolar_px"])
    assert len(seg) >= 10 and np.all((seg >= 0) & (seg <= [W, H]))
    truth = sphere_image_box(camera("goal"), BALL, R_BALL)
    centre = (truth[:2] + truth[2:]) / 2
    # the true ball lies on the segment, whatever its height
    assert _polyline_distance(seg, centre) < 1.0
    if d.code == "epipolar":  # a long segment: one ray does not fix the depth, no box to snap
        assert d.suggestion is None and d.evidence["segment_length_px_1920"] / 2 > SETTINGS.consensus_tau_px
    else:  # a short one: the box is a guess on it, within tau of anywhere on it
        assert d.code == "epipolar_box" and np.abs(np.asarray(d.suggestion["box"]) - truth).max() < 0.5
    assert "label on the segment" in doubt_message(d, {"main": "main.png"}) or d.code == "epipolar_box"
    # far from the segment's middle the box would be a guess: shortened tolerance, no box
    d2 = accusing(judge_system(views, dataclasses.replace(SETTINGS, consensus_tau_px=1.0)))[0]
    assert d2.code == "epipolar" and d2.suggestion is None


def _polyline_distance(poly: np.ndarray, p: np.ndarray) -> float:
    best = math.inf
    for a, b in zip(poly[:-1], poly[1:], strict=True):
        t = np.clip((p - a) @ (b - a) / max((b - a) @ (b - a), 1e-12), 0, 1)
        best = min(best, float(np.linalg.norm(a + t * (b - a) - p)))
    return best


def test_a_ball_in_the_air_seen_by_one_view_is_placed_by_its_box_and_lies_on_the_segment():
    ball = np.array([10.0, 5.0, -6.0])
    views = [view("main", *CAMERAS["main"], ball=ball, role="action"), view("goal", *CAMERAS["goal"], box=None)]
    d = accusing(judge_system(views, settings=SETTINGS))[0]
    assert d.kind == "ball_missing" and d.evidence["placed"] == "box"
    truth = sphere_image_box(views[1].camera, ball, R_BALL)
    # the true ball lies on the drawn segment, whatever its height
    assert _polyline_distance(np.asarray(d.evidence["epipolar_px"]), (truth[:2] + truth[2:]) / 2) < 3.0


def test_an_out_of_frame_ball_seen_by_one_view_is_not_called_missing_when_it_is_more_likely_outside():
    # the goal camera looks 35 m to the side of the ball: on the grass the ball would lie outside its image
    off = view("off", *CAMERAS["goal"], target=BALL + [0.0, 35.0, 0.0], box=None)
    uv, _ = off.camera.project(BALL)
    assert not (0 <= uv[0][0] <= W and 0 <= uv[0][1] <= H)
    assert accusing(judge_system([scene()[0], off], settings=SETTINGS)) == []


def test_two_views_too_close_in_direction_to_triangulate_are_judged_by_their_epipolar_segments():
    twin_pos, f = [0.6, 60.4, -15.2], 4000.0
    good = [scene()[0], view("twin", twin_pos, f)]
    assert epipolar_pair_error(*good, SETTINGS) < 5.0
    assert [d.kind for d in accusing(judge_system(good, settings=SETTINGS))] == ["near_duplicate_view"]
    bad = [scene()[0], view("twin", twin_pos, f, ball=BALL + [0.0, 0.0, -3.0])]  # the replay shows another instant
    assert epipolar_pair_error(*bad, SETTINGS) > 25.0
    kinds = [(d.kind, d.code) for d in accusing(judge_system(bad, settings=SETTINGS))]
    assert ("views_disagree", "epipolar") in kinds


def test_two_rays_that_meet_only_under_the_grass_do_not_agree():
    under = BALL + [0.0, 0.0, 6.0]  # 6 m below the grass: what two wrong labels can agree on by coincidence
    views = [v for v in scene(goal={"ball": under}, main={"ball": under}) if v.view_id in ("main", "goal")]
    assert [(d.kind, d.view_id) for d in accusing(judge_system(views, settings=SETTINGS))] == [("views_disagree", None)]


def test_votes_are_weighted_by_what_the_calibration_is_worth():
    sure = {"pan_deg": 0.02, "tilt_deg": 0.02, "roll_deg": 0.02, "focal_px": 3.0,
            "position_m": {"x": .1, "y": .1, "z": .1}}
    unsure = {**sure, "pan_deg": 2.0, "tilt_deg": 2.0}
    s = SETTINGS
    assert pixel_sigma(scene(main={"uncertainty": sure})[0], BALL, s) < 5.0
    assert pixel_sigma(scene(main={"uncertainty": unsure})[0], BALL, s) > 50.0
    # a view below admission whose calibration is sure still votes: two against one, the culprit is named
    wrong = {"box": sphere_image_box(camera("opposite"), BALL, R_BALL) + [200.0, 0.0, 200.0, 0.0]}
    views = [v for v in scene(opposite=wrong, goal={"admitted": False, "jac": 0.7, "uncertainty": sure})
             if v.view_id in ("main", "goal", "opposite")]
    assert [(d.kind, d.view_id)
            for d in accusing(judge_system(views, settings=SETTINGS))] == [("ball_off_consensus", "opposite")]
    # unsure and below admission, it takes no part: one against one, the culprit cannot be told
    views = [v for v in scene(opposite=wrong, goal={"admitted": False, "jac": 0.7, "uncertainty": unsure})
             if v.view_id in ("main", "goal", "opposite")]
    assert [(d.kind, d.view_id) for d in accusing(judge_system(views, settings=SETTINGS))] == [("views_disagree", None)]
    # an admitted view whose calibration is unsure is not accused within its own pixel sigma
    views = scene(opposite={**wrong, "uncertainty": {**sure, "pan_deg": 8.0, "tilt_deg": 8.0}})
    assert accusing(judge_system(views, settings=SETTINGS)) == []


def test_a_view_looking_away_from_the_ball_is_not_called_missing():
    away = view("away", [70.0, 3.0, -15.0], 3500.0, target=[40.0, -25.0, 0.0], box=None)
    uv, _ = away.camera.project(BALL)
    assert uv[0][0] < -100  # the ball lies well outside that image
    for views in (scene() + [away], [scene()[0], away]):
        assert accusing(judge_system(views, settings=SETTINGS)) == []


def test_a_near_duplicate_view_is_named_and_a_camera_at_the_same_place_looking_elsewhere_is_not():
    twin = view("twin", [0.3, 60.2, -15.1], 4000.0)
    doubts = accusing(judge_system([scene()[0], twin], settings=SETTINGS))
    assert [(d.kind, d.view_id) for d in doubts] == [("near_duplicate_view", "twin")]
    assert doubts[0].evidence["angle_deg"] < 1.0 and doubts[0].suggestion == {"action": "exclude_view"}
    elsewhere = view("elsewhere", [0.3, 60.2, -15.1], 4000.0, target=[-40.0, 20.0, 0.0], box=None)
    assert accusing(judge_system(scene() + [elsewhere], settings=SETTINGS)) == []


def test_two_views_that_miss_cannot_name_the_culprit_and_say_what_would_decide():
    views = [v for v in scene(goal={"ball": BALL + [4.0, 0.0, 0.0]}) if v.view_id in ("main", "goal")]
    doubts = accusing(judge_system(views, settings=SETTINGS))
    assert [(d.kind, d.view_id) for d in doubts] == [("views_disagree", None)]
    assert "third view" in doubt_message(doubts[0], {}) and doubts[0].suggestion is None


def test_excluded_mirrored_and_few_line_views_are_not_accused_of_their_ball():
    off = {"ball": BALL + [5.0, 5.0, 0.0]}
    doubts = judge_system(scene(opposite={**off, "excluded": True}), settings=SETTINGS)
    assert accusing(doubts) == []
    # flagged by a prior alone: the doubt, but no fix (nothing confirms the mirrored camera)
    doubts = accusing(judge_system(scene(opposite={**off, "mirror_flagged": True}), settings=SETTINGS))
    assert [(d.kind, d.view_id, d.suggestion) for d in doubts] == [("mirrored_labels", "opposite", None)]
    assert "no fix is offered" in doubt_message(doubts[0], {}) and doubts[0].evidence["fix_agrees"] is False
    # truly mirrored labels: the camera as calibrated is the mirror image of the true one; mirrored back, the
    # label meets the ball the other views agree on, so the fix is offered, with both errors
    mirrored_cam = mirror_camera(camera("opposite"))
    true_box = sphere_image_box(camera("opposite"), BALL, R_BALL)
    doubts = accusing(judge_system(scene(opposite={"camera": mirrored_cam, "box": true_box, "mirror_flagged": True}),
                                   settings=SETTINGS))
    assert [(d.kind, d.view_id, d.suggestion) for d in doubts] == [
        ("mirrored_labels", "opposite", {"action": "mirror_labels"})]
    assert doubts[0].evidence["error_mirrored_px_1920"] < 1.0 < doubts[0].evidence["error_as_labelled_px_1920"]
    # a clean view flagged by a prior: mirrored it would move away from the ball, no fix, and it says why
    doubts = accusing(judge_system(scene(opposite={"mirror_flagged": True}), settings=SETTINGS))
    assert doubts[0].suggestion is None and doubts[0].evidence["no_fix"] == "as_labelled_fits"
    assert "do not agree better" in doubt_message(doubts[0], {})
    # without a ball the others agree on, the pair relations decide: as labelled its ray meets another's
    same = {"verdict": "mirrored", "margin": 3.0, "pairs": [{"other": "main", "relation": "same"}]}
    two = [v for v in scene(opposite={**off, "mirror_flagged": True, "mirror_evidence": same})
           if v.view_id in ("main", "opposite")]
    doubts = accusing(judge_system(two, settings=SETTINGS))
    assert doubts[0].suggestion is None and doubts[0].evidence["no_fix"] == "as_labelled_meets"
    # one other view meeting it only mirrored cannot tell which of the two is mirrored; the game's rig can
    different = {"verdict": "probably_mirrored", "margin": 6.0, "pairs": [{"other": "main", "relation": "different"}],
                 "rig_distance_m": 40.0, "rig_distance_mirrored_m": 41.0}
    pair = [v for v in scene(opposite={"camera": mirrored_cam, "box": true_box, "mirror_flagged": True,
                                       "mirror_evidence": different}) if v.view_id in ("main", "opposite")]
    d = accusing(judge_system(pair, settings=SETTINGS))[0]
    assert d.suggestion is None and d.evidence["no_fix"] == "one_view_cannot_tell"
    at_rig = {**different, "rig_distance_mirrored_m": 0.2}
    pair = [v for v in scene(opposite={"camera": mirrored_cam, "box": true_box, "mirror_flagged": True,
                                       "mirror_evidence": at_rig}) if v.view_id in ("main", "opposite")]
    d = accusing(judge_system(pair, settings=SETTINGS))[0]
    assert d.suggestion == {"action": "mirror_labels"} and d.evidence["rig_confirms"] is True
    doubts = judge_system(scene(opposite={**off, "line_classes": 2}), settings=SETTINGS)
    assert accusing(doubts) == [] and [d.kind for d in doubts if d.view_id == "opposite"] == ["few_lines"]


def test_an_unflagged_view_whose_mirrored_camera_stands_at_the_rig_is_suspected_mirrored():
    evidence = {"verdict": "undecided", "margin": 0.0, "rig_distance_m": 4.6, "rig_distance_mirrored_m": 0.07,
                "pairs": [{"other": "main", "relation": "different"}]}
    doubts = accusing(judge_system(scene(opposite={"mirror_evidence": evidence}), settings=SETTINGS))
    assert [(d.kind, d.view_id) for d in doubts] == [("mirrored_labels", "opposite")]
    same = {**evidence, "pairs": [{"other": "main", "relation": "same"}]}
    assert accusing(judge_system(scene(opposite={"mirror_evidence": same}), settings=SETTINGS)) == []


def test_info_doubts_say_why_a_view_takes_no_part():
    refused = DoubtView("r", "r.png", "replay", W, H, None, False, calibration_reason="no camera fits the labels")
    low = dataclasses.replace(scene()[1], view_id="low", admitted=False, jac=0.6, rig_assisted=True)
    kinds = {(d.kind, d.view_id) for d in judge_system(scene()[:1] + [refused, low], settings=SETTINGS)}
    assert kinds == {("calibration_refused", "r"), ("few_lines", "r"), ("below_admission", "low"),
                     ("rig_assisted", "low")}


def test_the_consensus_is_general_for_n_views_and_ambiguous_between_two_camps():
    cams = [camera(k) for k in CAMERAS] + [look_at([-70.0, 0.0, -12.0], BALL, 3000.0),
                                                      look_at([-30.0, -50.0, -10.0], BALL, 3000.0)]
    obs = [BallObservation(i, c, c.project(BALL)[0][0], W) for i, c in enumerate(cams)]
    r = ball_consensus(obs, tau_px=20.0, min_parallax_deg=2.0, min_baseline_m=1.0)
    assert r.inliers == tuple(range(6)) and np.linalg.norm(r.point - BALL) < 1e-6 and not r.ambiguous
    other = BALL + [6.0, -4.0, 0.0]
    split = obs[:2] + [BallObservation(i, cams[i], cams[i].project(other)[0][0], W) for i in (2, 3)]
    assert ball_consensus(split, tau_px=20.0, min_baseline_m=1.0, min_parallax_deg=0.0).ambiguous


def test_the_judges_operating_point_is_the_settings_defaults():
    """The judge has no defaults of its own: its operating point (benchmarks/doubts.py) is the settings' defaults,
    read without an environment file."""
    s = doubt_settings(Settings(_env_file=None))
    assert (s.triangulation_tau_px, s.pair_error_rule,
            s.min_baseline_m, s.min_parallax_deg) == (20.0, "max_scaled_1920",
                                                                                                   1.0, 2.0)
    assert (s.consensus_tau_px, s.near_duplicate_max_deg, s.inside_margin_px,
            s.ground_box_tolerance, s.mirror_rig_near_m, s.mirror_rig_gap_m, s.min_line_classes) == (
        25.0, 3.0, 0.0, 0.35, 1.0, 2.0, 4)
    assert s.play_volume == PLAY_VOLUME and s.ball_diameter_m == 0.22


# ----- the benchmark on the synthetic dev data --------------------------------------------------------------
@pytest.mark.shared
def test_the_judge_meets_the_issue_figures_on_the_dev_set_and_one_dev_large_game(shared_dir: Path, tmp_path):
    """Imports the 2 dev games (40 systems) and one dev-large game (32 systems) with the service (about 8 s)."""
    from benchmarks import doubts as bench

    large = shared_dir / "data" / "synthetic" / "soccernet-v3-dev-large"
    game = next(large.glob("*/*/*Glenrock 0 - 1 Arden"))
    subset = tmp_path / "subset"
    (subset / game.relative_to(large)).mkdir(parents=True)
    # copied, not linked: a link leading out of the imported folder is refused
    (subset / game.relative_to(large) / "Labels-v3.json").write_bytes((game / "Labels-v3.json").read_bytes())
    judged, truth = [], {}
    for name, root in (("dev", None), ("dev-large", subset)):
        url = bench.ensure_database(shared_dir, name, tmp_path / "db", source=root)
        inputs = bench.load_judged_input(url)
        judged += bench.judge_all(inputs, SETTINGS)[0]
        truth.update(bench.load_truth(shared_dir, name))
    sc = bench.score(judged, truth)
    # measured: caught 7/7, guilty 7/7, clean flagged 1/52, near duplicates 2/2, out of frame 0/5, suggestion 1.5 px
    assert sc.observable >= 6 and sc.caught / sc.observable >= 0.9
    assert sc.guilty_total >= 5 and sc.guilty_named / sc.guilty_total >= 0.85
    assert sc.clean >= 45 and sc.clean_flagged / sc.clean <= 0.05
    assert sc.near_dup >= 1 and sc.near_dup_named == sc.near_dup
    assert sc.out_of_frame >= 3 and sc.out_of_frame_called == 0
    assert sc.suggestion_px and float(np.median(sc.suggestion_px)) < 15.0


def test_each_views_consensus_without_it_is_the_judges_with_that_view_excluded():
    """The consensuses of the per-annotator distances are decided once for all the views (``consensuses_without``);
    each is what the judge finds when that view is marked excluded and everything is decided again, also with the
    recomputation's calibration weights given, over scenes where views are off, mirrored, helpers or suggested."""
    from app.geometry.doubts.judge import _voters_consensus, _votes, consensuses_without
    from app.geometry.triangulation import pair_geometry
    from app.geometry.weighting import calibration_weight

    off = {"ball": BALL + [5.0, 5.0, 0.0]}
    mirrored_cam = mirror_camera(camera("opposite"))
    scenes = [scene(), scene(goal=off), scene(opposite={"camera": mirrored_cam, "mirror_flagged": True}),
              scene(corner={"line_classes": 2}), scene(goal={"suggested": True}, main={"admitted": False}),
              scene(corner={"excluded": True}, goal=off)]
    compared = 0
    for views in scenes:
        weighed = {v.view_id: calibration_weight(v, SETTINGS) for v in views if v.camera is not None}
        for given in (None, weighed):
            found = consensuses_without(views, [v.view_id for v in views], SETTINGS, pair_geometry, given)
            for v in views:
                others = [dataclasses.replace(w, excluded=True) if w.view_id == v.view_id else w for w in views]
                want = _voters_consensus(_votes(others, SETTINGS, None), SETTINGS, pair_geometry)[0]
                got = found[v.view_id]
                assert (got.point is None) == (want.point is None)
                if want.point is not None:
                    np.testing.assert_allclose(got.point, want.point, atol=1e-9)
                assert (sorted(got.inliers), got.ambiguous) == (sorted(want.inliers), want.ambiguous)
                compared += want.point is not None
    assert compared >= 20  # most leave-one-out consensuses place a ball


def _pair(goal: dict, **extra) -> list[DoubtView]:
    """The main and goal views of :func:`scene` (both full votes, exact cameras), ``goal`` its overrides, and
    ``extra`` views added."""
    return [v for v in scene(goal=goal) if v.view_id in ("main", "goal")] + list(extra.values())


def test_a_ball_two_views_agree_on_only_at_the_edge_of_tau_is_doubted_without_naming_either():
    """The goal replay shows the ball 2 m along y from where the main camera does (another instant): the two rays
    still meet within the consensus tolerance (25 px), but only at its edge (17.6 px, above 0.7 of the
    triangulation's 20 px), and both cameras are sure (no stated uncertainty): views_disagree, code lone_pair, no
    view named, no fix. 1 m along y meets at 8.6 px: a right pair's, no doubt."""
    (d,) = accusing(judge_system(_pair({"ball": BALL + [0.0, 2.0, 0.0]}), SETTINGS))
    assert (d.kind, d.code, d.view_id, d.suggestion) == ("views_disagree", "lone_pair", None, None)
    assert sorted(d.evidence["views"]) == ["goal", "main"]
    assert 14.0 < d.evidence["best_pair_error_px_1920"] < 25.0 and d.evidence["edge_px"] == 14.0
    assert d.evidence["joint_sigma_px_1920"] == 0.0
    assert "third view" in doubt_message(d, {}) and doubt_message(d, {}).endswith(".")
    assert accusing(judge_system(_pair({"ball": BALL + [0.0, 1.0, 0.0]}), SETTINGS)) == []


def test_an_edge_pair_the_cameras_uncertainty_explains_or_a_third_view_checks_is_not_doubted():
    """The same 2 m pair is not doubted when a camera's stated sigma exceeds the error (a camera that unsure puts a
    right label that far off), when one of the two views is a few-lined helper (no full vote: its sigma is not its
    camera's word), or when a third viewpoint agrees with the ball (it checks the pair). A near duplicate of a view
    (0.5 m away, same ball) is no third viewpoint: the doubt stays."""
    moved = {"ball": BALL + [0.0, 2.0, 0.0]}
    unsure = {"pan_deg": 0.3, "tilt_deg": 0.3, "roll_deg": 0.05, "focal_px": 5.0}
    assert accusing(judge_system(_pair({**moved, "uncertainty": unsure}), SETTINGS)) == []
    helper = _pair({**moved, "line_classes": 2, "uncertainty": {"pan_deg": 0.001, "tilt_deg": 0.001,
                                                               "roll_deg": 0.001, "focal_px": 0.1}})
    assert all(d.code != "lone_pair" for d in judge_system(helper, SETTINGS))
    third = _pair(moved, corner=view("corner", *CAMERAS["corner"]))
    assert all(d.code != "lone_pair" for d in judge_system(third, SETTINGS))
    twin = view("twin", [0.5, 60.0, -15.0], 2500.0)
    (d,) = [d for d in judge_system(_pair(moved, twin=twin), SETTINGS) if d.kind == "views_disagree"]
    assert d.code == "lone_pair" and sorted(d.evidence["views"]) == ["goal", "main", "twin"]


def test_one_labelled_view_whose_box_agrees_with_the_grass_calls_the_view_showing_that_spot_missing():
    """The main view's box is 15 % larger than the ball's (a box drawn loosely): its size puts the ball a little
    nearer than the grass, still within the tolerance, so the ball is placed on the grass. A zoomed replay that shows
    the grass spot but not the nearer part of the ray is called missing (the inside chance of the box-size depth law
    alone is 0.41), without a box (the segment leaves the image); aimed 8 m away, the spot is outside: nothing."""
    main_cam = look_at(CAMERAS["main"][0], BALL, 2500.0)
    box = sphere_image_box(main_cam, BALL, R_BALL)
    c, half = (box[:2] + box[2:]) / 2, (box[2:] - box[:2]) / 2 * 1.15
    main = view("main", *CAMERAS["main"], box=np.concatenate([c - half, c + half]), role="action")
    zoomed = view("goal", CAMERAS["goal"][0], 9000.0, box=None)
    (d,) = accusing(judge_system([main, zoomed], SETTINGS))
    assert (d.kind, d.view_id, d.code, d.suggestion) == ("ball_missing", "goal", "epipolar", None)
    assert d.evidence["placed"] == "grass" and d.evidence["inside_chance"] < 0.5
    away = view("goal", CAMERAS["goal"][0], 9000.0, box=None, target=BALL + [0.0, 8.0, 0.0])
    assert accusing(judge_system([main, away], SETTINGS)) == []
