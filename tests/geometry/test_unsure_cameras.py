"""Cameras with an uncertainty take part in the detector's check weighted by it (known truth: the ball at ``BALL``,
the four cameras of ``CAMERAS``): an unsure labelled ray or an unsure view pairs where the spread its sigma leaves
places the ball; a view whose own camera takes no part (few lines and an unsure fit, or a camera its players alone
placed) is checked along a lone labelled ray within its sigma, its box kept out of the triangulation."""
from __future__ import annotations

import numpy as np

from app.geometry.doubts.pairings import _telling
from app.geometry.doubts.weak import _uncounted
from app.geometry.weighting import calibration_weight
from tests.geometry.test_detections import (
    BY_CLASS,
    UNSURE,
    beside_main_ray,
    checked,
    det,
    detected,
    near_truth,
)
from tests.geometry.test_doubts import BALL, CAMERAS, SETTINGS, scene

#: Unsure to about 28 px at main's focal length (2500 px): just beyond tau (25 px), where a one-ray pairing used to be
#: refused whatever its spread.
BEYOND_TAU = {"pan_deg": 0.45, "tilt_deg": 0.45, "roll_deg": 0.02, "focal_px": 3.0,
              "position_m": {"x": .1, "y": .1, "z": .1}}
#: Unsure by degrees: the disc of twice its sigma covers more than a tenth of the image (it no longer tells).
LOST = {**UNSURE, "pan_deg": 3.0}


def _sigma(views, name):
    (v,) = [v for v in views if v.view_id == name]
    return calibration_weight(v, SETTINGS)


def test_an_unsure_labelled_ray_pairs_with_a_detection_where_its_spread_places_the_ball():
    views = scene(main={"uncertainty": BEYOND_TAU}, **{n: {"box": None} for n in CAMERAS if n != "main"})
    weight, sigma = _sigma(views, "main")
    assert weight == 0.5 and 25.0 < sigma < 32.0  # admitted, unsure: half a vote
    found = detected(checked(views, {"goal": [det("goal", 0.7, shift=(1.0, -0.5))]}))
    assert set(found) == {"goal"} and found["goal"].code == "one_ray" and near_truth("goal", found["goal"]) < 2.0
    assert np.allclose(found["goal"].evidence["ball3d"], BALL, atol=0.1)
    # a ray unsure by degrees no longer tells where the ball lies: nothing pairs with it
    lost = scene(main={"uncertainty": LOST}, **{n: {"box": None} for n in CAMERAS if n != "main"})
    assert not _telling(lost[0], _sigma(lost, "main")[1], SETTINGS)
    assert detected(checked(lost, {"goal": [det("goal", 0.7, shift=(1.0, -0.5))]})) == {}


def test_an_unsure_view_pairs_with_a_sure_labelled_ray_where_the_spread_places_the_ball():
    views = scene(corner={"box": None, "uncertainty": BEYOND_TAU}, goal={"box": None}, opposite={"box": None})
    weight, sigma = _sigma(views, "corner")
    assert weight == 0.5 and 25.0 < sigma < 40.0
    ball = det("corner", 0.7, shift=(2.0, -1.0))
    found = detected(checked(views, {"corner": [ball]}))
    assert set(found) == {"corner"} and found["corner"].code == "one_ray" and near_truth("corner", found["corner"]) < 3
    assert np.allclose(found["corner"].evidence["ball3d"], BALL, atol=0.1)
    # the pairing's ball as the triangulation would weigh it: main's pixel (at least 1 px) and corner's sigma leave
    # it within the grass's two metres; corner unsure to about 44 px leaves it 1.07 m loose (filled), to about 89 px
    # (still telling) more than 2 m: nothing
    for pan_tilt, fills in ((UNSURE["pan_deg"], {"corner"}), (2 * UNSURE["pan_deg"], set())):
        unsure = {**UNSURE, "pan_deg": pan_tilt, "tilt_deg": pan_tilt}
        views = scene(corner={"box": None, "uncertainty": unsure}, goal={"box": None}, opposite={"box": None})
        assert set(detected(checked(views, {"corner": [ball]}))) == fills


def test_a_view_whose_camera_takes_no_part_is_checked_along_a_lone_labelled_ray_within_its_sigma():
    """Corner: two line classes, a camera unsure to about 44 px (no vote). Main alone labelled: corner's one box near
    main's ray (within tau widened by both sigmas) that meets it at a ball's size fills corner (code weak_view); its
    box weighs nothing in the triangulation, so it cannot make a 3D ball. Two boxes near the ray: nothing."""
    weak = {"box": None, "line_classes": 2, "jac": 1.0, "uncertainty": UNSURE}
    views = scene(corner=weak, goal={"box": None}, opposite={"box": None})
    assert _sigma(views, "corner")[0] == 0.0
    ball = det("corner", 0.6, shift=(6.0, -4.0))
    found = detected(checked(views, {"corner": [ball]}, BY_CLASS))
    assert set(found) == {"corner"} and found["corner"].code == "weak_view"
    assert near_truth("corner", found["corner"]) < 8.0
    assert np.linalg.norm(np.asarray(found["corner"].evidence["ball3d"]) - BALL) < 1.0
    assert detected(checked(views, {"corner": [ball, beside_main_ray("corner", 40.0)]}, BY_CLASS)) == {}
    lost = scene(corner={**weak, "uncertainty": LOST}, goal={"box": None}, opposite={"box": None})
    assert detected(checked(lost, {"corner": [ball]}, BY_CLASS)) == {}
    # judged by evidence corner's camera (admitted, its two lines fitted) joins the ball weighed by its sigma: its
    # box and main's lone ray would make a ball nothing else checks, so it is not filled
    assert detected(checked(views, {"corner": [ball]})) == {}


def test_a_camera_its_players_alone_placed_is_weighed_by_its_players_fit_not_by_a_jac_it_has_no_lines_for():
    placed = {"box": None, "line_classes": 0, "jac": None, "player_assisted": True, "uncertainty": UNSURE}
    views = scene(corner=placed, goal={"box": None}, opposite={"box": None})
    assert _sigma(views, "corner")[0] == 0.0  # no vote: its few lines cannot vouch for it
    found = detected(checked(views, {"corner": [det("corner", 0.6, shift=(6.0, -4.0))]}, BY_CLASS))
    assert set(found) == {"corner"} and found["corner"].code == "weak_view"
    # a camera fitted to a line it fits badly (JaC 0.3) is a failed fit, whoever placed it
    failed = scene(corner={**placed, "line_classes": 1, "jac": 0.3}, goal={"box": None}, opposite={"box": None})
    assert detected(checked(failed, {"corner": [det("corner", 0.6, shift=(6.0, -4.0))]}, BY_CLASS)) == {}
    # judged by evidence, the same camera below admission (no JaC: no lines of its own to fit) takes no part in the
    # ball: its box makes none, and it is filled
    below = scene(corner={**placed, "admitted": False}, goal={"box": None}, opposite={"box": None})
    assert set(detected(checked(below, {"corner": [det("corner", 0.6, shift=(6.0, -4.0))]}))) == {"corner"}


def test_a_weak_views_box_is_asked_whether_it_counts_not_the_boxes_other_checks_placed():
    views = scene(corner={"box": None, "line_classes": 2, "jac": 1.0, "uncertainty": UNSURE}, goal={"box": None})
    corner, goal = det("corner"), det("goal")
    # goal's box, placed by a check as one that may make a ball, counts with main's label: asked of itself, the
    # pair weighs two votes; corner's box (no vote) makes no ball with either
    assert not _uncounted({"goal": goal, "corner": corner}, views, BY_CLASS)
    assert _uncounted({"corner": corner}, views, BY_CLASS, placed={"goal": goal})
    # corner with a sure camera would weigh half a vote: with a full one that is a ball
    sure = scene(corner={"box": None, "line_classes": 2, "jac": 1.0,
                         "uncertainty": {**UNSURE, "pan_deg": 0.02, "tilt_deg": 0.02}}, goal={"box": None})
    assert not _uncounted({"corner": corner}, sure, BY_CLASS, placed={"goal": goal})
    # judged by evidence every camera that takes part joins the ball: corner's box beside two labels (main's and
    # opposite's, or main's and goal's placed box) joins the ball they make; beside main's label alone it would make
    # one with it
    assert _uncounted({"corner": corner}, views, SETTINGS)
    lone = scene(corner={"box": None, "line_classes": 2, "jac": 1.0, "uncertainty": UNSURE}, goal={"box": None},
                 opposite={"box": None})
    assert _uncounted({"corner": corner}, lone, SETTINGS, placed={"goal": goal})
    assert not _uncounted({"corner": corner}, lone, SETTINGS)
