"""A detector's predictions checked against the other views (app.geometry.doubts.detections.check_detections), on
scenes with known truth: the ball's detection is chosen among false ones, a box of the wrong size or a high score
alone suggests nothing, one labelled view needs two detected views, an outvoted label gets the evidence."""
from __future__ import annotations

import dataclasses

import numpy as np

from app.geometry.ball import sphere_image_box
from app.geometry.doubts import INFO_KINDS, LABEL_KINDS, judge_system
from app.geometry.doubts.detections import LOOSE_BOX_RADII, Detection, check_detections
from app.geometry.weighting import calibration_weight, project_point
from app.services.wording.doubt_words import doubt_message
from tests.geometry.test_doubts import BALL, CAMERAS, R_BALL, SETTINGS, camera, look_at, scene, view

SIZE = 0.5


def true_box(name: str, shift=(0.0, 0.0), scale: float = 1.0) -> tuple[float, float, float, float]:
    b = sphere_image_box(camera(name), BALL, R_BALL)
    c = np.array([(b[0] + b[2]) / 2 + shift[0], (b[1] + b[3]) / 2 + shift[1]])
    h = np.array([b[2] - b[0], b[3] - b[1]]) * scale / 2
    return (float(c[0] - h[0]), float(c[1] - h[1]), float(c[0] + h[0]), float(c[1] + h[1]))


def det(name, score=0.8, **kw) -> Detection:
    return Detection("yolo-sn-ball", score, true_box(name, **kw))


#: The 3D ball judged by class (``V3D_BALL_RULE=weights``): a view below admission or an unsure camera weighs no full
#: vote, so the checks that fill only boxes that cannot make a ball (weak_ray, weak_view) have boxes to fill.
BY_CLASS = dataclasses.replace(SETTINGS, below_admission_takes_part=False)


def checked(views, detections, settings=SETTINGS):
    return check_detections(views, judge_system(views, settings), detections, settings, SIZE)


def test_the_balls_detection_is_chosen_among_false_ones_and_replaces_ball_missing():
    views = scene(corner={"box": None})
    assert [d.kind for d in judge_system(views, SETTINGS) if d.view_id == "corner"] == ["ball_missing"]
    head = det("corner", 0.97, shift=(0.0, -60.0))  # a player's head above the ball, a higher score
    feet = det("corner", 0.9, shift=(45.0, 25.0))
    ball = det("corner", 0.71, shift=(1.0, -0.5))
    doubts = checked(views, {"corner": [head, feet, ball]})
    found = [d for d in doubts if d.view_id == "corner" and d.kind in LABEL_KINDS]
    assert [d.kind for d in found] == ["ball_detected"]  # one suggestion for the view: the detection's box
    d = found[0]
    assert d.code == "consensus" and d.suggestion["action"] == "snap_box"
    assert np.allclose(d.suggestion["box"], ball.box, atol=0.01)
    assert sorted(d.evidence["agreeing_views"]) == ["goal", "main", "opposite"]
    assert d.evidence["candidates_passed"] == 1 and d.evidence["detector"] == "yolo-sn-ball"
    assert abs(d.evidence["size_ratio"] - 1.0) < 0.02 and np.allclose(d.evidence["ball3d"], BALL, atol=0.05)
    assert d.evidence["ball_missing_px"] < 1.5  # the geometry's own box was where the detection is
    assert "yolo-sn-ball, score 0.71" in doubt_message(d, {"corner": "corner.png", "main": "main.png"})


def test_a_box_of_the_wrong_size_or_a_high_score_alone_suggests_nothing():
    views = scene(corner={"box": None})
    for wrong in ([det("corner", 0.99, scale=3.0)],  # at the ball, three times a ball's size there
                  [det("corner", 0.99, shift=(0.0, -80.0))]):  # the best score, where the ball is not
        doubts = checked(views, {"corner": wrong})
        assert [d.kind for d in doubts if d.view_id == "corner" and d.kind in LABEL_KINDS] == ["ball_missing"]


def test_without_detections_the_doubts_are_the_judges():
    views = scene(corner={"box": None})
    judged = judge_system(views, SETTINGS)
    assert check_detections(views, judged, {}, SETTINGS, SIZE) == judged
    assert check_detections(views, judged, {"corner": []}, SETTINGS, SIZE) == judged


def test_where_the_detector_ran_a_missing_ball_placed_loosely_for_its_view_loses_its_box():
    """Two labelled views 3 m apart (2.8 deg of parallax) fix the ball's depth along their rays to about 0.7 m (a
    pixel each); the goal camera looks across that depth and would see its box wander by several radii. Without
    predictions the judge's box stays (a person reviews it); where the detector ran (one false box far off) the doubt
    stays without a box (``ball_loose``, saying how loose). A camera high behind the two looks along their rays: the
    same ball is tight there, and its box stays."""
    behind = [1.5, 90.0, -25.0]
    views = [view("main", [0.0, 60.0, -15.0], 2500.0, role="action"), view("beside", [3.0, 60.0, -15.0], 2500.0),
             view("goal", [70.0, 3.0, -15.0], 3500.0, box=None), view("behind", behind, 3000.0, box=None)]
    judged = judge_system(views, SETTINGS)
    assert {d.view_id for d in judged if d.kind == "ball_missing" and d.suggestion} == {"goal", "behind"}
    far = Detection("yolo-sn-ball", 0.9, tuple(float(x) for x in np.asarray(true_box("goal")) + [600, 300, 600, 300]))
    found = check_detections(views, judged, {"goal": [far]}, SETTINGS, SIZE)
    doubts = {d.view_id: d for d in found if d.kind == "ball_missing"}
    goal, tight = doubts["goal"], doubts["behind"]
    radius = R_BALL * 3500.0 / np.linalg.norm(np.array(CAMERAS["goal"][0]) - BALL)
    assert goal.suggestion is None and goal.evidence["ball_loose"] is True
    assert goal.evidence["ball_sigma_px"] > LOOSE_BOX_RADII * radius
    assert "place the label" in doubt_message(goal, {"main": "main.png", "beside": "beside.png"})
    assert "ball_loose" not in tight.evidence and tight.suggestion["action"] == "snap_box"
    truth = sphere_image_box(look_at(behind, BALL, 3000.0), BALL, R_BALL)
    assert np.abs(np.asarray(tight.suggestion["box"]) - truth).max() < 0.5


def test_tied_candidates_are_ordered_by_score_and_the_margin_is_given():
    views = scene(corner={"box": None})
    low, high = det("corner", 0.4, shift=(0.2, 0.0)), det("corner", 0.9, shift=(0.0, 0.2))
    (d,) = [d for d in checked(views, {"corner": [low, high]}) if d.kind == "ball_detected"]
    assert d.evidence["score"] == 0.9 and d.evidence["candidates_passed"] == 2
    assert d.evidence["margin_px_1920"] is not None and abs(d.evidence["margin_px_1920"]) < 1.0


def test_one_labelled_view_needs_two_detected_views_that_agree():
    only_main = {n: {"box": None} for n in CAMERAS if n != "main"}
    views = scene(**only_main)
    one = checked(views, {"goal": [det("goal"), det("goal", 0.95, shift=(40.0, 0.0))]})
    assert [d for d in one if d.kind == "ball_detected"] == []  # one ray leaves the depth open
    detections = {"goal": [det("goal", 0.6), det("goal", 0.95, shift=(40.0, 30.0))],
                  "opposite": [det("opposite", 0.7, shift=(-1.0, 1.0)), det("opposite", 0.9, shift=(-50.0, 0.0))],
                  "corner": [det("corner", 0.8, shift=(0.5, 0.5))]}
    found = {d.view_id: d for d in checked(views, detections) if d.kind == "ball_detected"}
    assert set(found) == {"goal", "opposite", "corner"}
    for name, d in found.items():
        assert d.code == "one_view" and "main" in d.evidence["agreeing_views"]
        c = np.array(true_box(name))
        b = np.asarray(d.suggestion["box"])
        assert np.linalg.norm((b[:2] + b[2:]) / 2 - (c[:2] + c[2:]) / 2) < 2.0, name


def test_a_detection_where_the_others_put_the_ball_is_evidence_against_an_outvoted_label():
    wrong = sphere_image_box(camera("opposite"), BALL, R_BALL) + [160.0, -40.0, 160.0, -40.0]
    views = scene(opposite={"box": wrong})
    doubts = checked(views, {"opposite": [det("opposite", 0.88)]})
    (off,) = [d for d in doubts if d.kind == "detection_off_label"]
    assert off.kind in INFO_KINDS and off.view_id == "opposite" and off.suggestion is None
    assert off.evidence["label_distance_px_1920"] > 150 and off.evidence["error_px_1920"] < 2
    assert [d.kind for d in doubts if d.view_id == "opposite" and d.kind in LABEL_KINDS] == ["ball_off_consensus"]


def test_a_view_with_few_line_classes_but_a_sure_camera_is_checked_too():
    """The judge lends the label of such a view half a vote; its detections are checked within its pixel sigma."""
    sure = {"pan_deg": 0.02, "tilt_deg": 0.02, "roll_deg": 0.02, "focal_px": 3.0,
            "position_m": {"x": .1, "y": .1, "z": .1}}
    views = scene(corner={"box": None, "line_classes": 2, "uncertainty": sure})
    assert [d.kind for d in judge_system(views, SETTINGS) if d.view_id == "corner" and d.kind in LABEL_KINDS] == []
    found = [d for d in checked(views, {"corner": [det("corner", 0.6), det("corner", 0.9, shift=(0.0, -70.0))]})
             if d.kind == "ball_detected"]
    assert [d.view_id for d in found] == ["corner"] and found[0].evidence["score"] == 0.6
    unsure = scene(corner={"box": None, "line_classes": 2, "uncertainty": {**sure, "pan_deg": 2.0, "tilt_deg": 2.0}})
    assert [d for d in checked(unsure, {"corner": [det("corner", 0.6)]}) if d.kind == "ball_detected"] == []


# --- one labelled ray and one detection; detections that agree among themselves (known truth: BALL, CAMERAS) ---

def box_at(name: str, point, scale: float = 1.0, score: float = 0.8) -> Detection:
    """A detection in view ``name`` at the exact silhouette of a ball centred at ``point`` (world), ``scale`` times
    its size."""
    b = sphere_image_box(camera(name), np.asarray(point, float), R_BALL)
    c, h = (b[:2] + b[2:]) / 2, (b[2:] - b[:2]) * scale / 2
    return Detection("yolo-sn-ball", score, (float(c[0] - h[0]), float(c[1] - h[1]), float(c[0] + h[0]),
                                             float(c[1] + h[1])))


def on_main_ray(t: float) -> np.ndarray:
    """The point at ``t`` times the way from the main camera to the ball, on main's ball ray."""
    c = np.asarray(CAMERAS["main"][0], float)
    return c + t * (BALL - c)


def head_on_main_ray(height_m: float = 1.8) -> np.ndarray:
    """Where main's ball ray passes ``height_m`` above the grass: a player's head there lies on main's epipolar line
    in every other view, at about the ball's depth (the distractor the rays alone cannot reject)."""
    c = np.asarray(CAMERAS["main"][0], float)
    return on_main_ray((-height_m - c[2]) / (BALL[2] - c[2]))


def detected(doubts):
    return {d.view_id: d for d in doubts if d.kind == "ball_detected"}


def near_truth(name: str, d) -> float:
    c = np.array(true_box(name))
    b = np.asarray(d.suggestion["box"])
    return float(np.linalg.norm((b[:2] + b[2:]) / 2 - (c[:2] + c[2:]) / 2))


def only_main_labelled():
    return scene(**{n: {"box": None} for n in CAMERAS if n != "main"})


def test_one_labelled_ray_and_one_detection_fill_the_view():
    views = only_main_labelled()
    far = box_at("goal", [-20.0, 10.0, -0.11], score=0.97)  # a confident false detection off main's ray
    found = detected(checked(views, {"goal": [far, det("goal", 0.7, shift=(1.0, -0.5))]}))
    assert set(found) == {"goal"}
    d = found["goal"]
    assert d.code == "one_ray" and d.evidence["agreeing_views"] == ["main"] and near_truth("goal", d) < 2.0
    assert np.allclose(d.evidence["ball3d"], BALL, atol=0.1) and d.evidence["candidates_passed"] == 1
    assert "one labelled view and this detection" in doubt_message(d, {"goal": "goal.png", "main": "main.png"})


def test_a_detection_whose_rays_meet_outside_the_play_volume_or_at_another_size_is_rejected():
    views = only_main_labelled()
    under = on_main_ray(1.06)  # on main's ray, 0.7 m under the grass (the play volume allows 0.5 m)
    assert under[2] > 0.5
    for wrong in (box_at("goal", under), det("goal", scale=3.0)):
        assert detected(checked(views, {"goal": [wrong]})) == {}


def test_a_head_on_the_labelled_ray_is_rejected_where_a_third_view_clearly_misses_it():
    views = only_main_labelled()
    head = box_at("goal", head_on_main_ray(), score=0.95)  # the ball itself missed by the detector in goal
    # alone, the rays and the sizes cannot reject it: it is on main's ray at about the ball's depth
    alone = detected(checked(views, {"goal": [head]}))
    assert set(alone) == {"goal"} and near_truth("goal", alone["goal"]) > 10.0
    # the opposite view shows the spot and its detection is elsewhere (at the ball): a clear miss; and goal, whose
    # detector saw the head only, clearly misses opposite's ball in turn: neither is filled
    assert detected(checked(views, {"goal": [head], "opposite": [det("opposite", 0.8)]})) == {}
    # with the ball's own detection in goal beside the head, opposite's ball is confirmed and the head rejected
    found = detected(checked(views, {"goal": [head, det("goal", 0.6)], "opposite": [det("opposite", 0.8)]}))
    assert set(found) == {"goal", "opposite"} and max(near_truth(n, d) for n, d in found.items()) < 2.0
    # a third view whose detection lies at the head's ball confirms it instead
    confirmed = detected(checked(views, {"goal": [head], "corner": [box_at("corner", head_on_main_ray())]}))
    assert "goal" in confirmed


def test_two_candidates_the_rays_cannot_tell_apart_fill_nothing_and_duplicates_are_no_rivals():
    views = only_main_labelled()
    ball, rival = det("goal", 0.6), box_at("goal", on_main_ray(0.97), score=0.9)  # both on main's ray, ball-sized
    assert detected(checked(views, {"goal": [ball, rival]})) == {}
    # two boxes on the same ball: the score breaks the tie
    found = detected(checked(views, {"goal": [det("goal", 0.6), det("goal", 0.9, shift=(0.3, 0.2))]}))
    assert found["goal"].evidence["score"] == 0.9 and found["goal"].evidence["candidates_passed"] == 2


def test_detections_agree_among_themselves_where_no_labelled_view_takes_part():
    views = scene(**{n: {"box": None} for n in CAMERAS})
    assert [d for d in judge_system(views, SETTINGS) if d.kind in LABEL_KINDS] == []
    false = {n: box_at(n, [-30.0, 20.0, -0.11], score=0.95) for n in CAMERAS}
    dets = {"main": [false["main"], det("main", 0.7, shift=(1.0, 0.5))], "goal": [det("goal", 0.8, shift=(-0.5, 1.0))],
            "opposite": [det("opposite", 0.75)], "corner": [false["corner"]]}
    found = detected(checked(views, dets))
    assert set(found) == {"main", "goal", "opposite"}  # corner's detector missed the ball: its false box stays
    for name, d in found.items():
        assert d.code == "detections_agree" and near_truth(name, d) < 2.0, name
    # exactly two views: the same checks, and a margin over every other pairing
    two = detected(checked(views, {"main": [det("main")], "goal": [det("goal")]}))
    assert set(two) == {"main", "goal"}
    rival = box_at("goal", on_main_ray(0.97))
    assert detected(checked(views, {"main": [det("main")], "goal": [det("goal"), rival]})) == {}


def test_two_views_detections_of_one_false_ball_are_rejected_by_a_third_view_that_misses_it():
    views = scene(**{n: {"box": None} for n in CAMERAS})
    fake = [0.0, 0.0, -1.0]  # ball-sized boxes on two players, consistent by chance
    dets = {"main": [box_at("main", fake)], "goal": [box_at("goal", fake)]}
    assert set(detected(checked(views, dets))) == {"main", "goal"}
    assert detected(checked(views, {**dets, "opposite": [det("opposite")]})) == {}


def test_a_labelled_ray_whose_camera_is_unsure_beyond_tau_pairs_with_no_detection():
    """One ray and one detection fix a ball only as well as the cameras: a labelled view whose pixel sigma exceeds
    tau (half a vote) would make a 3D ball metres off with a right detection, so nothing is placed from it."""
    unsure = {"pan_deg": 1.5, "tilt_deg": 1.5, "roll_deg": 0.5, "focal_px": 30.0,
              "position_m": {"x": .5, "y": .5, "z": .5}}
    views = scene(main={"uncertainty": unsure}, **{n: {"box": None} for n in CAMERAS if n != "main"})
    assert detected(checked(views, {"goal": [det("goal")]})) == {}
    assert set(detected(checked(only_main_labelled(), {"goal": [det("goal")]}))) == {"goal"}


def test_a_third_view_too_unsure_to_vote_still_contradicts_a_pairing_its_label_misses():
    """A labelled view that takes no part in the votes (few lines, a poor fit) still shows where the ball is not."""
    sure = {"pan_deg": 0.02, "tilt_deg": 0.02, "roll_deg": 0.02, "focal_px": 3.0,
            "position_m": {"x": .1, "y": .1, "z": .1}}
    head = box_at("goal", head_on_main_ray(), score=0.95)
    views = scene(goal={"box": None}, corner={"box": None},
                  opposite={"line_classes": 2, "jac": 0.3, "uncertainty": sure})  # its label at the ball
    assert detected(checked(views, {"goal": [head]})) == {}
    alone = scene(goal={"box": None}, corner={"box": None}, opposite={"box": None})
    assert set(detected(checked(alone, {"goal": [head]}))) == {"goal"}  # without it, the head passes


# --- a camera the players placed as the lone labelled ray (known truth: BALL, CAMERAS) ---

SURE = {"pan_deg": 0.02, "tilt_deg": 0.02, "roll_deg": 0.02, "focal_px": 3.0, "position_m": {"x": .1, "y": .1, "z": .1}}


def main_helper(players: bool):
    """Only main labelled, with 3 line classes and a sure camera (a helper's half vote): placed by its players or
    fitted to its few lines alone."""
    return scene(main={"line_classes": 3, "uncertainty": SURE, "player_assisted": players},
                 **{n: {"box": None} for n in CAMERAS if n != "main"})


def beside_main_ray(name: str, px: float) -> Detection:
    """A ball-sized detection in view ``name`` ``px`` pixels across main's epipolar line from the ball (not along
    it): a false box near the ray that no pairing with it can place."""
    a, b = camera(name).project(np.stack([on_main_ray(0.95), on_main_ray(1.05)]))[0]
    along = (b - a) / np.linalg.norm(b - a)
    box = np.asarray(true_box(name))
    return Detection("yolo-sn-ball", 0.9, tuple(float(x) for x in box + px * np.array([-along[1], along[0]] * 2)))


def test_a_camera_the_players_placed_is_the_lone_ray_one_its_few_lines_alone_fitted_is_not():
    placed = detected(checked(main_helper(True), {"goal": [det("goal", 0.7, shift=(1.0, -0.5))]}))
    assert set(placed) == {"goal"}
    d = placed["goal"]
    assert d.code == "one_ray" and d.evidence["agreeing_views"] == ["main"] and near_truth("goal", d) < 2.0
    assert np.allclose(d.evidence["ball3d"], BALL, atol=0.1)
    # the same label, its camera fitted to its three lines alone: helpers alone say nothing
    assert detected(checked(main_helper(False), {"goal": [det("goal", 0.7, shift=(1.0, -0.5))]})) == {}


def test_a_half_vote_ray_pairs_only_with_a_detection_alone_on_it_within_its_cameras_uncertainty():
    ball = det("goal", 0.7, shift=(1.0, -0.5))
    # a ball-sized box on main's ray at nine tenths of the ball's depth (a head there): the rays meet at both
    on_ray = box_at("goal", on_main_ray(0.9), score=0.9)
    assert detected(checked(main_helper(True), {"goal": [on_ray, ball]})) == {}
    # 2 tau across the ray: near it, but farther than both cameras' sigmas and the detector's centre error explain
    # (two standard deviations: a few pixels here), so no rival the half vote cannot tell from the ball
    off = beside_main_ray("goal", 50.0)
    found = detected(checked(main_helper(True), {"goal": [off, ball]}))
    assert set(found) == {"goal"} and near_truth("goal", found["goal"]) < 2.0
    # a labelled view's full vote chooses likewise; a box far from the ray is no rival either
    assert near_truth("goal", detected(checked(only_main_labelled(), {"goal": [off, ball]}))["goal"]) < 2.0
    far = box_at("goal", [-20.0, 10.0, -0.11], score=0.97)
    assert set(detected(checked(main_helper(True), {"goal": [far, ball]}))) == {"goal"}


def test_a_helpers_ray_places_two_detections_that_meet_it_and_its_label_still_contradicts_them_elsewhere():
    views = main_helper(True)
    # two views' detections of the ball meet the helper's ray: the triple rule places them from main
    found = detected(checked(views, {"goal": [det("goal")], "opposite": [det("opposite")]}))
    assert set(found) == {"goal", "opposite"} and all(d.code == "one_view" for d in found.values())
    # the helper's label far from the ball: its ray meets neither detection; the two detections still agree among
    # themselves, but the helper's label, a third view, clearly misses their ball: nothing is placed
    wrong = sphere_image_box(camera("main"), BALL, R_BALL) + [300.0, -150.0, 300.0, -150.0]
    views = scene(main={"line_classes": 3, "uncertainty": SURE, "player_assisted": True, "box": wrong},
                  **{n: {"box": None} for n in CAMERAS if n != "main"})
    assert detected(checked(views, {"goal": [det("goal")], "opposite": [det("opposite")]})) == {}
    # without any label there, they agree among themselves
    found = detected(checked(only_unlabelled(), {"goal": [det("goal")], "opposite": [det("opposite")]}))
    assert set(found) == {"goal", "opposite"} and all(d.code == "detections_agree" for d in found.values())


def only_unlabelled():
    return scene(**{n: {"box": None} for n in CAMERAS})


def test_a_labelled_view_contradicts_a_pairing_whose_ball_falls_outside_its_image():
    """A label is a person's word that the system's one ball is there: two false boxes that meet at a ball outside
    a labelled view's image are contradicted by that label, wherever their ball projects."""
    from tests.geometry.test_doubts import look_at

    narrow = look_at(CAMERAS["main"][0], BALL, 8000.0)  # main zoomed on the ball: the fake ball is outside its image
    fake = [0.0, 0.0, -1.0]
    uv = narrow.project(np.asarray([fake], float))[0][0]
    assert not (0 <= uv[0] < 1920 and 0 <= uv[1] < 1080)
    dets = {"goal": [box_at("goal", fake)], "opposite": [box_at("opposite", fake)]}
    labelled = scene(main={"camera": narrow, "line_classes": 3, "uncertainty": SURE, "player_assisted": True},
                     **{n: {"box": None} for n in CAMERAS if n != "main"})
    assert detected(checked(labelled, dets)) == {}
    # without main's label nothing contradicts the two boxes: they agree among themselves
    unlabelled = scene(main={"camera": narrow, "box": None}, **{n: {"box": None} for n in CAMERAS if n != "main"})
    assert set(detected(checked(unlabelled, dets))) == {"goal", "opposite"}
    # the ball's own detections there still fill the views, main's label confirming them
    found = detected(checked(labelled, {"goal": [det("goal")], "opposite": [det("opposite")]}))
    assert set(found) == {"goal", "opposite"} and max(near_truth(n, d) for n, d in found.items()) < 2.0


def test_one_ray_and_a_detection_that_fix_the_balls_depth_badly_place_nothing_in_the_air(monkeypatch):
    """Two rays fix the ball only as well as their cameras: main's camera sure to 18.5 px (within tau) and corner's
    ray about 30 degrees from main's leave the ball's depth 0.6 m uncertain (one sigma). In the air (3 m up) that is
    more than half a metre: nothing is placed; goal's ray, nearly perpendicular, fixes it. On the grass the ball
    lies where main's ray meets the grass, and a spread up to a metre places it; beyond that bound, nothing."""
    from app.geometry.doubts import pairings
    from app.geometry.doubts.judge import _votes
    from app.geometry.spread import position_sigma_m
    from app.geometry.triangulation import BallObservation

    unsure = {"pan_deg": 0.3, "tilt_deg": 0.3, "roll_deg": 0.02, "focal_px": 3.0,
              "position_m": {"x": .1, "y": .1, "z": .1}}
    air = BALL + np.array([0.0, 0.0, -3.0])
    views = scene(main={"uncertainty": unsure, "ball": air}, **{n: {"box": None} for n in CAMERAS if n != "main"})
    sigma = _votes(views, SETTINGS, None).sigma
    assert 15.0 < sigma["main"] < 25.0
    obs = {n: BallObservation(n, camera(n), np.zeros(2), 1920) for n in CAMERAS}
    for ball in (air, BALL):
        assert 0.5 < position_sigma_m([obs["main"], obs["corner"]], ball, {"main": sigma["main"], "corner": 1.0}) < 1.0
        assert position_sigma_m([obs["main"], obs["goal"]], ball, {"main": sigma["main"], "goal": 1.0}) < 0.5
    assert detected(checked(views, {"corner": [box_at("corner", air)]})) == {}
    found = detected(checked(views, {"goal": [box_at("goal", air)]}))
    assert set(found) == {"goal"} and np.allclose(found["goal"].evidence["ball3d"], air, atol=0.1)
    # on the grass the same pair fills corner, at the ball
    grass = scene(main={"uncertainty": unsure}, **{n: {"box": None} for n in CAMERAS if n != "main"})
    found = detected(checked(grass, {"corner": [det("corner")]}))
    assert set(found) == {"corner"} and near_truth("corner", found["corner"]) < 2.0
    # a spread beyond the bound on the grass places nothing either
    monkeypatch.setattr(pairings, "GRASS_SPREAD_M", 0.5)
    assert detected(checked(grass, {"corner": [det("corner")]})) == {}
    monkeypatch.undo()
    # the same pair in the air with main sure to 3 px fills corner
    sure = scene(main={"uncertainty": {**unsure, "pan_deg": 0.05, "tilt_deg": 0.05}, "ball": air},
                 **{n: {"box": None} for n in CAMERAS if n != "main"})
    assert set(detected(checked(sure, {"corner": [box_at("corner", air)]}))) == {"corner"}


def test_a_box_off_the_labelled_ray_by_more_than_the_cameras_and_the_detector_explain_is_not_the_ball():
    """Between two sure cameras (a pixel each) and a box of about 13 px (the detector's centre error 0.17 d), a box
    20 px across main's epipolar line is inside tau (25 px) yet four standard deviations off: nothing is placed;
    one 3 px across is the ball. A camera unsure to 15 px explains the 20 px."""
    views = only_main_labelled()
    assert detected(checked(views, {"goal": [beside_main_ray("goal", 20.0)]})) == {}
    near = detected(checked(views, {"goal": [beside_main_ray("goal", 3.0)]}))
    assert set(near) == {"goal"} and near_truth("goal", near["goal"]) < 4.0
    unsure = {"pan_deg": 0.25, "tilt_deg": 0.25, "roll_deg": 0.02, "focal_px": 3.0,
              "position_m": {"x": .1, "y": .1, "z": .1}}
    wide = scene(main={"uncertainty": unsure}, **{n: {"box": None} for n in CAMERAS if n != "main"})
    assert set(detected(checked(wide, {"goal": [beside_main_ray("goal", 20.0)]}))) == {"goal"}


def test_a_detection_that_drags_the_labelled_views_ball_farther_than_they_can_place_it_wrong_fills_nothing():
    """Two sure labelled views (a pixel each) with wide framings (1200 px focal, about 20 px a metre at their
    distance) place the ball to a few centimetres; a box in corner at the silhouette of a ball 2 m off keeps both
    their rays within tau (25 px) when the ball is refitted with it, and moves that ball about a metre: more than
    twice what the labelled views leave uncertain and more than the half metre within which a 3D ball is right.
    Nothing is suggested from it; the geometry's own box (where the labelled views' ball projects) stays the fix.
    The ball's own box still fills the view."""
    from tests.geometry.test_doubts import look_at

    wide = {n: {"camera": look_at(CAMERAS[n][0], BALL, 1200.0)} for n in ("goal", "opposite")}
    views = scene(main={"box": None}, corner={"box": None}, **wide)
    off = box_at("corner", BALL + np.array([0.0, 2.0, 0.0]))
    doubts = checked(views, {"corner": [off]})
    assert detected(doubts) == {}
    missing = [d for d in doubts if d.view_id == "corner" and d.kind in LABEL_KINDS]
    assert [d.kind for d in missing] == ["ball_missing"] and near_truth("corner", missing[0]) < 1.0
    right = detected(checked(views, {"corner": [box_at("corner", BALL)]}))
    assert set(right) == {"corner"} and near_truth("corner", right["corner"]) < 0.5
    assert np.allclose(right["corner"].evidence["ball3d"], BALL, atol=0.05)


# --- labels and views whose cameras take no part in the votes (known truth: BALL, CAMERAS) ---

#: A camera unsure to about 37 px at main's focal length (44 px at corner's): beyond tau, within what still tells
#: where the ball lies in a 1920 x 1080 image (pairings.MAX_WINDOW_SHARE).
UNSURE = {"pan_deg": 0.6, "tilt_deg": 0.6, "roll_deg": 0.02, "focal_px": 3.0, "position_m": {"x": .1, "y": .1, "z": .1}}


def test_two_labels_whose_cameras_few_lines_alone_fitted_place_a_detection_they_both_confirm():
    """Two helpers fitted to their few lines (half a vote each, never the only ray): one's label and goal's detection
    meet, and the other's label, a third view, confirms their ball: three views, goal is filled. A head on main's ray
    meets main's label too, but opposite's label clearly misses that ball: nothing."""
    helpers = {n: {"line_classes": 3, "uncertainty": SURE} for n in ("main", "opposite")}
    views = scene(goal={"box": None}, corner={"box": None}, **helpers)
    found = detected(checked(views, {"goal": [det("goal", 0.7, shift=(1.0, -0.5))]}))
    assert set(found) == {"goal"} and found["goal"].code == "detections_agree"
    assert near_truth("goal", found["goal"]) < 2.0 and set(found["goal"].evidence["agreeing_views"]) == {
        "main", "opposite"}
    assert detected(checked(views, {"goal": [box_at("goal", head_on_main_ray(), score=0.95)]})) == {}
    # one such label alone and a full view's detection would make a 3D ball from that label: nothing
    alone = scene(goal={"box": None}, corner={"box": None}, opposite={"box": None}, main=helpers["main"])
    assert detected(checked(alone, {"goal": [det("goal", 0.7, shift=(1.0, -0.5))]})) == {}


def test_a_weak_labels_ray_fills_the_one_detection_near_it_only_where_the_box_cannot_make_a_3d_ball():
    """Main's label, its camera fitted to three lines and below admission (the triangulation by class leaves it out),
    and one detection in goal near its ray: filled (code weak_ray), since goal's box cannot make a ball with that
    label. The same label admitted would make one (a full vote and a half): nothing. Two boxes near the ray: nothing.
    Judged by evidence, main's camera fits its own lines and joins the ball: goal's box would make one with it alone,
    so nothing is filled."""
    out = scene(main={"line_classes": 3, "uncertainty": SURE, "admitted": False},
                **{n: {"box": None} for n in CAMERAS if n != "main"})
    ball = det("goal", 0.7, shift=(1.0, -0.5))
    found = detected(checked(out, {"goal": [ball]}, BY_CLASS))
    assert set(found) == {"goal"} and found["goal"].code == "weak_ray" and near_truth("goal", found["goal"]) < 2.0
    assert np.allclose(found["goal"].evidence["ball3d"], BALL, atol=0.3)
    assert "cannot make a 3D ball" in doubt_message(found["goal"], {"goal": "goal.png", "main": "main.png"})
    assert detected(checked(main_helper(False), {"goal": [ball]}, BY_CLASS)) == {}
    assert detected(checked(out, {"goal": [ball, beside_main_ray("goal", 40.0)]}, BY_CLASS)) == {}
    assert detected(checked(out, {"goal": [ball]})) == {}


def test_a_weak_labels_ray_and_a_view_as_unsure_fill_nothing_a_sure_view_is_filled():
    """Main's label with a camera unsure to about 37 px (below admission: no vote) and corner's detection, its own
    camera unsure to about 44 px: nothing sure sees the ball where they put it. Goal's sure camera is filled."""
    views = scene(main={"uncertainty": UNSURE, "admitted": False},
                  corner={"box": None, "line_classes": 2, "jac": 1.0, "uncertainty": UNSURE},
                  goal={"box": None}, opposite={"box": None})
    assert detected(checked(views, {"corner": [det("corner")]}, BY_CLASS)) == {}
    found = detected(checked(views, {"goal": [det("goal")]}, BY_CLASS))
    assert set(found) == {"goal"} and found["goal"].code == "weak_ray" and near_truth("goal", found["goal"]) < 2.0


def test_a_view_whose_camera_is_too_unsure_to_vote_is_filled_where_the_others_ball_projects_alone_in_its_window():
    """Corner (two line classes, a camera unsure to about 44 px: no vote, its detections not checked by the votes):
    the labelled views agree on the ball, which projects within corner's sigma of one detection at a ball's size,
    the only one within twice that: filled (code weak_view), the ball left where the labelled views put it. A second
    box 60 px away could be the ball as well: nothing; one 200 px away is no rival. A camera unsure by degrees tells
    nothing."""
    views = scene(corner={"box": None, "line_classes": 2, "jac": 1.0, "uncertainty": UNSURE})
    ball = det("corner", 0.6, shift=(6.0, -4.0))
    found = detected(checked(views, {"corner": [ball]}))
    assert set(found) == {"corner"} and found["corner"].code == "weak_view"
    assert near_truth("corner", found["corner"]) < 8.0 and np.allclose(found["corner"].evidence["ball3d"], BALL,
                                                                          atol=0.05)
    assert detected(checked(views, {"corner": [ball, det("corner", 0.9, shift=(60.0, 0.0))]})) == {}
    assert set(detected(checked(views, {"corner": [ball, det("corner", 0.9, shift=(200.0, 0.0))]}))) == {"corner"}
    lost = scene(corner={"box": None, "line_classes": 2, "jac": 1.0, "uncertainty": {**UNSURE, "pan_deg": 3.0}})
    assert detected(checked(lost, {"corner": [ball]})) == {}


def test_a_third_view_whose_detector_missed_the_ball_anywhere_on_the_labelled_ray_contradicts_nothing():
    views = only_main_labelled()
    # opposite's detector missed the ball: its only box is a player far from main's ray across the play volume
    elsewhere = box_at("opposite", [-30.0, 20.0, -0.11], score=0.9)
    found = detected(checked(views, {"goal": [det("goal", 0.7)], "opposite": [elsewhere]}))
    # wherever the ball lies on main's ray, opposite shows nothing of it: its silence is no miss of goal's pairing
    assert set(found) == {"goal"} and found["goal"].code == "one_ray" and near_truth("goal", found["goal"]) < 2.0
    # a box of opposite on main's ray elsewhere (a head at about the ball's depth) is a miss: nothing is filled
    head = box_at("opposite", head_on_main_ray(), score=0.9)
    assert detected(checked(views, {"goal": [det("goal", 0.7)], "opposite": [head]})) == {}


def test_a_few_lined_sure_view_whose_detector_shows_nothing_near_the_agreed_ball_gets_its_projected_box():
    sure = {"pan_deg": 0.02, "tilt_deg": 0.02, "roll_deg": 0.02, "focal_px": 3.0,
            "position_m": {"x": .1, "y": .1, "z": .1}}
    views = scene(corner={"box": None, "line_classes": 2, "uncertainty": sure})
    # the detector ran on corner and missed the ball: its only box is far from where the labelled views' ball projects
    far = det("corner", 0.9, shift=(0.0, -400.0))
    missing = [d for d in checked(views, {"corner": [far]}) if d.view_id == "corner" and d.kind in LABEL_KINDS]
    assert [(d.kind, d.code) for d in missing] == [("ball_missing", "consensus")]
    b, t = np.asarray(missing[0].suggestion["box"]), np.asarray(true_box("corner"))
    assert np.linalg.norm((b[:2] + b[2:]) / 2 - (t[:2] + t[2:]) / 2) < 1.0
    # a box near the projection that is not the ball (40 px off: the rays do not meet): the camera or the box is off,
    # nothing is placed
    near = det("corner", 0.9, shift=(0.0, 40.0))
    assert [d for d in checked(views, {"corner": [near]}) if d.view_id == "corner" and d.kind in LABEL_KINDS] == []
    # a camera sure enough to vote, but whose box may lie farther than the ball's radius (about 7 px here): nothing
    loose = scene(corner={"box": None, "line_classes": 2, "uncertainty": {**sure, "pan_deg": 0.12, "tilt_deg": 0.12}})
    assert calibration_weight(loose[3], SETTINGS)[0] > 0 and loose[3].view_id == "corner"
    assert [d for d in checked(loose, {"corner": [far]}) if d.view_id == "corner" and d.kind in LABEL_KINDS] == []


def test_a_pairing_another_views_detection_on_the_labelled_ray_disputes_fills_nothing():
    views = only_main_labelled()
    # opposite's detector missed the ball and saw something on main's ray 6 m up, 23 m from the ball: that spot
    # projects outside goal's image, so goal says nothing of it, while goal's own detection (the ball) lies on
    # main's ray too; opposite in turn misses goal's pairing (its box on the ray is elsewhere)
    high = on_main_ray(0.6)
    assert high[2] < -6.0 and project_point(views[1], high)[0] < 0 and views[1].view_id == "goal"
    boxes = {"goal": [det("goal", 0.7)], "opposite": [box_at("opposite", high, score=0.9)]}
    # two views each with a ball-sized box on the ray, at spots 23 m apart: neither pairing is filled
    assert detected(checked(views, boxes)) == {}
    # without goal's detection opposite's pairing stands alone (nothing disputes it)
    assert set(detected(checked(views, {"opposite": boxes["opposite"]}))) == {"opposite"}


def test_a_box_at_the_agreed_balls_spot_but_of_another_size_withdraws_the_geometrys_box():
    views = scene(corner={"box": None})
    # the detector shows something where the labelled views' ball projects, three times a ball's size there: the
    # camera's scale there or the box is off, so the sphere box the camera projects is left to a person
    doubts = [d for d in checked(views, {"corner": [det("corner", 0.99, scale=3.0)]}) if d.view_id == "corner"]
    (missing,) = [d for d in doubts if d.kind in LABEL_KINDS]
    assert missing.kind == "ball_missing" and missing.suggestion is None
    assert missing.evidence["detection_size_disagrees"] is True
    # a box far from that spot says nothing of the camera there: the judge's box stays the fix
    far = [d for d in checked(views, {"corner": [det("corner", 0.99, shift=(0.0, -80.0))]})
           if d.view_id == "corner" and d.kind in LABEL_KINDS]
    assert [d.suggestion["action"] for d in far] == ["snap_box"]


def player_under(view, head_point, height_m: float = 1.85, width_m: float = 0.5):
    """The box (px of ``view``) of a person standing under ``head_point`` (world): from the grass below it to
    ``height_m`` up, ``width_m`` wide at that depth."""
    foot = np.array([head_point[0], head_point[1], 0.0])
    top = project_point(view, np.array([head_point[0], head_point[1], -height_m]))
    bottom = project_point(view, foot)
    side = project_point(view, foot + np.array([width_m, 0.0, 0.0]))
    half = max(abs(float(side[0] - bottom[0])), 4.0) / 2 + abs(float(top[0] - bottom[0])) / 2
    xc = (top[0] + bottom[0]) / 2
    return (float(xc - half), float(top[1]), float(xc + half), float(bottom[1]))


def test_a_lone_rays_detection_on_a_players_head_with_the_ball_in_the_air_fills_nothing_unless_confirmed():
    import dataclasses

    plain = only_main_labelled()
    goal = next(v for v in plain if v.view_id == "goal")
    spot = head_on_main_ray()
    head = box_at("goal", spot, score=0.95)  # the detector missed the ball in goal and boxed the head on main's ray
    person = player_under(goal, spot)
    assert person[1] < head.centre[1] < person[1] + 0.15 * (person[3] - person[1])  # the head, near the box's top
    views = [dataclasses.replace(v, players=(person,)) if v.view_id == "goal" else v for v in plain]
    # without the person's box the rays and the sizes cannot reject it: a fill 10 px and more off the ball
    assert near_truth("goal", detected(checked(plain, {"goal": [head]}))["goal"]) > 10.0
    # on a person's head it is what a ball detector's false boxes look like: nothing fills goal
    assert detected(checked(views, {"goal": [head]})) == {}
    # the ball's own detection, away from that person's head and feet, still fills it
    (right,) = detected(checked(views, {"goal": [det("goal", 0.7)]})).values()
    assert near_truth("goal", right) < 2.0
    # and so does the ball on the grass over the head of a person farther off: a box that puts the ball on the grass
    # puts it where main's ray meets the grass
    ball = det("goal", 0.7)
    far_person = (ball.centre[0] - 6.0, ball.centre[1] - 2.0, ball.centre[0] + 6.0, ball.centre[1] + 60.0)
    behind = [dataclasses.replace(v, players=(far_person,)) if v.view_id == "goal" else v for v in plain]
    (right,) = detected(checked(behind, {"goal": [ball]})).values()
    assert near_truth("goal", right) < 2.0
    # a third view's detection at the head's ball is the second witness: goal is filled (as the head says)
    confirmed = detected(checked(views, {"goal": [head], "corner": [box_at("corner", spot)]}))
    assert "goal" in confirmed


def test_a_view_whose_detector_missed_the_ball_a_pairing_places_gets_its_projected_box_when_sure_enough():
    """Only main is labelled; goal's detection and main's ray place the ball (one_ray). Corner's detector missed it
    (its one box is a player far off): corner gets the sphere box where that ball projects (ball_missing, code
    pairing), its centre within a pixel of the ball's, since the box's uncertainty (the pairing's ball spread into
    corner and corner's camera) keeps it within the ball's radius. A corner camera unsure enough that the box's sigma
    (15 px) exceeds one and a half of its radii (7 px), a box of corner's near that spot (which the checks refused),
    or no ball placed: nothing; at 9 px, within one and a half radii, the box is offered."""
    far = box_at("corner", [-20.0, 10.0, -0.11], score=0.9)
    views = only_main_labelled()
    doubts = checked(views, {"goal": [det("goal", 0.7)], "corner": [far]})
    assert set(detected(doubts)) == {"goal"}
    (placed,) = [d for d in doubts if d.view_id == "corner" and d.kind in LABEL_KINDS]
    assert (placed.kind, placed.code, placed.suggestion["action"]) == ("ball_missing", "pairing", "snap_box")
    assert near_truth("corner", placed) < 1.0 and placed.evidence["agreeing_views"][:2] == ["main", "goal"]
    radius = (placed.suggestion["box"][2] - placed.suggestion["box"][0]) / 2
    assert 0 < 2 * placed.suggestion["box_sigma_px"] <= radius
    assert "detector shows nothing there" in doubt_message(placed, {"corner": "corner.png", "main": "main.png",
                                                                    "goal": "goal.png"})
    # the judge's own ball_missing of corner (one labelled ray: no box) is replaced, one suggestion a view
    assert [d.kind for d in doubts if d.view_id == "corner"].count("ball_missing") == 1
    def corner_unsure(deg: float) -> list[str]:
        loose = scene(corner={"box": None, "uncertainty": {"pan_deg": deg, "tilt_deg": deg, "roll_deg": 0.02,
                                                           "focal_px": 3.0, "position_m": {"x": .1, "y": .1, "z": .1}}},
                      **{n: {"box": None} for n in ("goal", "opposite")})
        return [d.code for d in checked(loose, {"goal": [det("goal", 0.7)], "corner": [far]})
                if d.view_id == "corner" and d.kind in LABEL_KINDS]

    assert corner_unsure(0.2) != ["pairing"] and corner_unsure(0.12) == ["pairing"]
    refused = checked(views, {"goal": [det("goal", 0.7)], "corner": [det("corner", 0.9, shift=(0.0, 40.0))]})
    assert "pairing" not in [d.code for d in refused if d.view_id == "corner"]
    alone = checked(views, {"corner": [far]})  # no detection places the ball: main's ray alone leaves its depth open
    assert "pairing" not in [d.code for d in alone]


def test_the_grass_places_a_pairings_ball_only_where_each_of_its_rays_meets_the_grass_near_it():
    """Main's label and corner's detection of the ball on the grass: both rays meet the plane of a ball's centre on the
    grass at the ball. The same members with the ball put 1.2 m along main's ray (a shallow ray: 0.3 m lower,
    below the grass, as a pairing of little parallax placed one on a made set, 1.2 m off): main's ray meets the grass
    1.2 m from it, so the grass does not place it."""
    from app.geometry.doubts.judge import _votes
    from app.geometry.doubts.pairings import _grass_placed, _Member, _member, _Pairing

    views = scene(corner={"box": None})
    main, corner = views[0], views[3]
    ray = _Member(main, _votes(views, SETTINGS, None).obs[0], None, SIZE)
    members = (ray, _member(corner, det("corner"), SETTINGS, SIZE))
    assert ray.view.view_id == "main" and corner.view_id == "corner"

    def pairing(ball):
        return _Pairing(members, np.asarray(ball, float), {}, {}, 0.0)

    assert _grass_placed(pairing(BALL))
    along = (BALL - np.asarray(CAMERAS["main"][0])) / np.linalg.norm(BALL - np.asarray(CAMERAS["main"][0]))
    low = BALL + 1.2 * along
    assert 0.25 < low[2] - BALL[2] < 0.35
    assert not _grass_placed(pairing(low))


def test_a_false_box_on_the_labelled_ray_a_metre_off_is_disputed_by_the_balls_detection_in_a_far_view():
    """goal's detector missed the ball and shows a ball-sized box on main's ray 1.4 m from it, on the camera's side
    (0.37 m up: over the grass); opposite, looking along that ray from 66 m, shows the ball. Where the false ball
    projects in opposite lies within twice the doubts' tolerance of opposite's detection (the old agreement) yet many
    of the two cameras' standard deviations off it: opposite disputes goal's pairing and nothing is filled (goal's
    box, in turn, refuses opposite's pairing). The same box 1.4 m beyond the ball would meet main's ray under the
    grass, which refuses it alone (:func:`test_a_false_box_whose_rays_meet_under_the_grass_fills_nothing`)."""
    views = only_main_labelled()
    c = np.asarray(CAMERAS["main"][0], float)
    off = on_main_ray(1.0 - 1.4 / float(np.linalg.norm(BALL - c)))
    assert abs(float(np.linalg.norm(off - BALL)) - 1.4) < 1e-6 and off[2] < BALL[2] - 0.3
    false = box_at("goal", off, score=0.9)
    opposite = box_at("opposite", BALL, score=0.8)
    shift = float(np.linalg.norm(np.asarray(project_point(views[2], off)) - np.asarray(project_point(views[2], BALL))))
    assert views[2].view_id == "opposite" and 10.0 < shift < 2 * SETTINGS.consensus_tau_px
    assert detected(checked(views, {"goal": [false], "opposite": [opposite]})) == {}
    # alone, goal's false box has nothing to dispute it (the rays cannot tell): what opposite's word is worth here
    assert set(detected(checked(views, {"goal": [false]}))) == {"goal"}
    # and opposite's true detection alone fills opposite at the ball
    found = detected(checked(views, {"opposite": [opposite]}))
    assert set(found) == {"opposite"} and near_truth("opposite", found["opposite"]) < 2.0


def test_a_box_on_a_persons_feet_fills_only_where_the_labelled_ray_meets_the_grass_near_its_ball():
    """A low camera behind the goal (2 m up, 47 m off) labels the ball on the grass: its ray runs within half a metre
    of the grass over its last 8 m. main's detector missed the ball and boxed something on that ray 7 m short of the
    ball, at a ball's size there, 0.4 m up: "on the grass" by height, yet the labelled ray meets the grass 7 m from
    that ball, so the height says nothing of where on the ray the ball is; nothing is filled, on a person's feet or
    not (beyond three metres). A box 2 m short of the ball fills main where no person stands there (within three
    metres), not on a person's feet (beyond one). The ball's own detection on a person's feet, where the ray meets
    the grass, fills main."""
    import dataclasses

    low = view("low", [57.0, 5.0, -2.0], 3000.0)
    main = view("main", CAMERAS["main"][0], CAMERAS["main"][1], box=None, role="action")

    def short_of_ball(up_m: float) -> tuple[np.ndarray, Detection, tuple[float, ...]]:
        spot = np.array([57.0, 5.0, -2.0]) + (up_m - 2.0) / (0.11 - 2.0) * (BALL - np.array([57.0, 5.0, -2.0]))
        box = box_at("main", spot, score=0.9)
        return spot, box, (box.centre[0] - 12.0, box.centre[1] - 120.0, box.centre[0] + 12.0, box.centre[1] + 6.0)

    spot, feet, person = short_of_ball(0.4)
    assert abs(spot[2] + 0.4) < 1e-9 and 7.0 < float(np.linalg.norm(spot - BALL)) < 7.5
    assert detected(checked([low, main], {"main": [feet]})) == {}
    assert detected(checked([low, dataclasses.replace(main, players=(person,))], {"main": [feet]})) == {}
    spot, near, person = short_of_ball(0.19)
    assert 1.5 < float(np.linalg.norm(spot - BALL)) < 2.5
    assert set(detected(checked([low, main], {"main": [near]}))) == {"main"}
    assert detected(checked([low, dataclasses.replace(main, players=(person,))], {"main": [near]})) == {}
    ball = det("main", 0.7)
    at_ball = (ball.centre[0] - 12.0, ball.centre[1] - 120.0, ball.centre[0] + 12.0, ball.centre[1] + 6.0)
    (right,) = detected(checked([low, dataclasses.replace(main, players=(at_ball,))], {"main": [ball]})).values()
    assert near_truth("main", right) < 2.0


def test_two_views_boxes_on_one_persons_head_agree_among_themselves_yet_fill_nothing():
    """No view is labelled; main's and goal's detectors missed the ball and boxed the head of one player 1.8 m up,
    20 m from it: the two boxes meet at that head at a ball's size, as the ball's would. With the person's box in
    each view (both detections on a head, the ball they make in the air, no third view confirming) nothing is
    filled; the two views' detections of the ball itself, away from any person's head or feet, still are."""
    import dataclasses

    head = np.array([-8.0, 12.0, -1.8])
    views = [v for v in only_unlabelled() if v.view_id in ("main", "goal")]
    boxes = {n: box_at(n, head, score=0.9) for n in ("main", "goal")}
    persons = {n: player_under(v, head) for n, v in zip(("main", "goal"), views, strict=True)}
    for n in ("main", "goal"):
        p, c = persons[n], boxes[n].centre
        assert p[0] < c[0] < p[2] and p[1] < c[1] < p[1] + 0.15 * (p[3] - p[1]), n  # on the person's head
    assert set(detected(checked(views, {n: [b] for n, b in boxes.items()}))) == {"main", "goal"}
    seen = [dataclasses.replace(v, players=(persons[v.view_id],)) for v in views]
    assert detected(checked(seen, {n: [b] for n, b in boxes.items()})) == {}
    found = detected(checked(seen, {"main": [det("main")], "goal": [det("goal")]}))
    assert set(found) == {"main", "goal"} and all(near_truth(n, d) < 2.0 for n, d in found.items())


def test_a_lone_rays_detection_half_the_balls_size_where_the_rays_meet_fills_nothing():
    """goal's detector missed the ball and shows a box on main's ray 3 m up, 0.55 times the ball's size there: within
    the doubts' size tolerance (0.5) but not one a ball detector gives (sides within 20 %): with one labelled ray the
    size is the only other witness of the depth, so nothing fills. A box of the ball 0.7 times its size still does."""
    spot = on_main_ray(0.8)
    assert -spot[2] > 2.5  # in the air, on no person
    views = only_main_labelled()
    assert detected(checked(views, {"goal": [box_at("goal", spot, scale=0.55)]})) == {}
    assert set(detected(checked(views, {"goal": [box_at("goal", spot, scale=0.9)]}))) == {"goal"}
    (right,) = detected(checked(views, {"goal": [det("goal", 0.7, scale=0.7)]})).values()
    assert near_truth("goal", right) < 2.0


def test_two_rays_pin_a_ball_alone_only_when_one_camera_is_sure_to_half_of_tau():
    from app.geometry.doubts.detected import _pinned

    main, goal = scene()[:2]
    tau = max(SETTINGS.consensus_tau_px, SETTINGS.triangulation_tau_px)
    assert tau == 25.0
    assert _pinned(main, goal, {"main": 20.0, "goal": 24.0}, SETTINGS)  # both sure
    assert _pinned(main, goal, {"main": 79.0, "goal": 3.0}, SETTINGS)  # one unsure, the other to a few pixels
    assert not _pinned(main, goal, {"main": 26.1, "goal": 17.6}, SETTINGS)  # the made set's 15.8 m false ball
    assert not _pinned(main, goal, {"main": 30.0, "goal": 40.0}, SETTINGS)
    assert _pinned(main, goal, {}, SETTINGS)  # cameras without a fit's uncertainty count as exact
