"""What backs a 3D ball (``app.geometry.ball_evidence``): the tier and reasons of the rule, and the measures it reads
(a detection at a label, a box where the ball projects, the views that all agree), on cameras with a known ball."""
from __future__ import annotations

import numpy as np
import pytest

from app.db.models import BallEvidence
from app.geometry.ball import sphere_image_box
from app.geometry.ball_evidence import (
    RULE_VERSION,
    TIER_DOUBTED,
    TIER_NONE,
    TIER_UNCONFIRMED,
    TIER_VOUCHED,
    TWO_VIEW_MAX_ERROR_TAU,
    VOUCH_MAX_SIGMA_M,
    BallFacts,
    OtherView,
    ViewFacts,
    agreeing_views,
    ball_evidence,
    copied_detection,
    depth_shift_px,
    detection_at_ball,
    detection_at_label,
    label_size_ratio,
)

from .test_doubts import BALL, R_BALL, W, look_at

CAMERA = look_at([0.0, 60.0, -15.0], BALL)


def _two(**kw) -> BallFacts:
    """Two views that make one kept pair, nothing else known."""
    return BallFacts(has_ball=True, views=(ViewFacts("V1"), ViewFacts("V2")), agreeing=2, sigma_m=0.2, **kw)


def test_the_tiers_are_the_stored_enums_values_and_the_rule_has_a_version():
    assert {t.value for t in BallEvidence} == {TIER_VOUCHED, TIER_UNCONFIRMED, TIER_DOUBTED, TIER_NONE}
    assert isinstance(RULE_VERSION, int) and RULE_VERSION >= 1


def test_no_ball_is_none_and_a_doubt_on_a_view_of_the_ball_is_doubted_whatever_else_agrees():
    assert ball_evidence(BallFacts(has_ball=False)) == (TIER_NONE, [])
    three = BallFacts(has_ball=True, views=tuple(ViewFacts(f"V{i}", detected=True) for i in (1, 2, 3)), agreeing=3,
                      doubted=("V2",))
    assert ball_evidence(three) == (TIER_DOUBTED, ["a label doubt names V2"])


def test_three_views_that_all_agree_vouch_but_three_views_of_two_pairs_do_not():
    views = (ViewFacts("V1"), ViewFacts("V2"), ViewFacts("V3"))
    tier, reasons = ball_evidence(BallFacts(has_ball=True, views=views, agreeing=3, sigma_m=0.1, players_pairs=3))
    assert tier == TIER_VOUCHED and reasons == ["three views agree", "the players agree on both cameras"]
    # V1-V2 and V1-V3 kept, V2-V3 dropped: a replay of another instant meets the action's ray, not the other replay's
    assert agreeing_views([(1, 2), (1, 3)]) == 2
    tier, reasons = ball_evidence(BallFacts(has_ball=True, views=views, agreeing=2, sigma_m=0.1))
    assert tier == TIER_UNCONFIRMED and reasons[0] == "its views do not all agree: nothing else checks it"


def test_agreeing_views_is_the_largest_set_whose_every_pair_is_kept():
    assert agreeing_views([]) == 0
    assert agreeing_views([("a", "b")]) == 2
    assert agreeing_views([(1, 2), (1, 3), (2, 3), (3, 4)]) == 3
    assert agreeing_views([(1, 2), (1, 3), (1, 4), (2, 3), (2, 4), (3, 4)]) == 4


def test_two_views_alone_are_unconfirmed_and_say_so():
    tier, reasons = ball_evidence(_two())
    assert tier == TIER_UNCONFIRMED and reasons == ["only two views: nothing else checks it"]


def test_another_view_whose_detection_or_label_lies_where_the_ball_projects_vouches_within_tau_only():
    near = OtherView("V3", distance_1920=12.0, size_ratio=1.1)
    assert ball_evidence(_two(others=(near,))) == (TIER_VOUCHED, ["the detector sees it in V3 too"])
    assert ball_evidence(_two(labelled_others=(near,)))[0] == TIER_VOUCHED
    far = OtherView("V3", distance_1920=25.0, size_ratio=1.0)  # beyond tau (20 px at 1920 width)
    wrong_size = OtherView("V3", distance_1920=5.0, size_ratio=1.8)  # a head, not the ball
    assert ball_evidence(_two(others=(far,)))[0] == TIER_UNCONFIRMED
    assert ball_evidence(_two(others=(wrong_size,)))[0] == TIER_UNCONFIRMED
    # a near duplicate of V1 or V2: a ball 1 m off along its ray would project 3 px away, nearer the box than 2 px
    beside = OtherView("V3", distance_1920=2.0, size_ratio=1.0, depth_1920=3.0)
    assert ball_evidence(_two(others=(beside,)))[0] == TIER_UNCONFIRMED
    sideways = OtherView("V3", distance_1920=2.0, size_ratio=1.0, depth_1920=8.0)  # 1 m off: 8 px away, 2 is nearer
    assert ball_evidence(_two(others=(sideways,)))[0] == TIER_VOUCHED
    loose = BallFacts(has_ball=True, views=(ViewFacts("V1"), ViewFacts("V2")), agreeing=2,
                      sigma_m=VOUCH_MAX_SIGMA_M + 0.5, others=(near,))
    tier, reasons = ball_evidence(loose)
    assert tier == TIER_UNCONFIRMED and reasons[-1] == "its sigma is 1.50 m"


@pytest.mark.parametrize(("change", "vouched"), [
    ({}, True),
    ({"players_pairs": 0}, False),  # the cameras unchecked: off along the epipolar line
    ({"pair_error_tau": TWO_VIEW_MAX_ERROR_TAU + 0.1}, False),  # rays that meet anywhere within tau
    ({"sigma_m": 0.7}, False),
    ({"one_detected": True}, False),  # a label the detector does not confirm: another object, or no ball there
])
def test_two_views_vouch_only_when_the_detector_confirms_both_labels_the_players_agree_and_the_rays_meet_well(
        change, vouched):
    detected = (True, not change.pop("one_detected", False))
    views = (ViewFacts("V1", detected=detected[0]), ViewFacts("V2", detected=detected[1]))
    known = {"players_pairs": 1, "pair_error_tau": 0.1, "sigma_m": 0.2, **change}
    facts = BallFacts(has_ball=True, views=views, agreeing=2, **known)
    tier, reasons = ball_evidence(facts)
    assert (tier == TIER_VOUCHED) is vouched, reasons
    if vouched:
        assert reasons == ["the detector confirms V1 and V2", "the players agree on both cameras",
                           "its rays meet well within tau"]


def test_a_detection_confirms_a_label_when_its_centre_lies_within_the_label_radius_at_the_labels_size():
    label = [100.0, 100.0, 120.0, 120.0]  # 20 px across
    assert detection_at_label(label, [[102.0, 101.0, 121.0, 122.0]])
    assert not detection_at_label(label, [[115.0, 100.0, 135.0, 120.0]])  # its centre 15 px off: beyond 10
    assert not detection_at_label(label, [[95.0, 95.0, 125.0, 135.0]])  # 35 px across: 75 % larger
    assert not detection_at_label(label, [])
    assert detection_at_label(label, [[400.0, 400.0, 420.0, 420.0], [101.0, 99.0, 119.0, 121.0]])


def test_a_label_the_fix_key_copied_from_a_detection_is_that_detections_box_and_no_other():
    """The key places a detector's box rounded to the pixel: that label is the detection's copy (it confirms nothing
    there); the same box as imported (a person's), a box a pixel off, or another detection's box are not copies."""
    det = [862.41, 493.17, 871.02, 501.73]
    assert copied_detection([862.0, 493.0, 871.0, 502.0], None, det)
    assert copied_detection(det, None, det)  # placed without rounding
    assert copied_detection([862.0, 493.0, 871.0, 502.0], [850.0, 490.0, 860.0, 500.0], det)  # moved onto it
    assert not copied_detection([862.0, 493.0, 871.0, 502.0], [862.0, 493.0, 871.0, 502.0], det)  # as imported
    assert not copied_detection([863.0, 493.0, 871.0, 502.0], None, det)
    assert not copied_detection([862.0, 493.0, 871.0, 502.0], None, [849.94, 175.48, 861.82, 188.76])


def test_a_box_where_the_ball_projects_is_near_it_at_its_size_and_a_label_box_has_the_silhouettes_size():
    sil = sphere_image_box(CAMERA, BALL, R_BALL)
    assert sil is not None
    near = detection_at_ball(CAMERA, BALL, [sil + np.array([3.0, 0.0, 3.0, 0.0])], 2 * R_BALL, W)
    assert near is not None and near[0] == pytest.approx(3.0) and near[1] == pytest.approx(1.0)
    far = detection_at_ball(CAMERA, BALL, [sil + 50.0, sil + np.array([0.0, 8.0, 0.0, 8.0])], 2 * R_BALL, W / 2)
    assert far is not None and far[0] == pytest.approx(16.0)  # the nearest, scaled to 1920 px width
    assert detection_at_ball(CAMERA, BALL, [], 2 * R_BALL, W) is None
    double = sil + np.array([-1.0, -1.0, 1.0, 1.0]) * (sil[2] - sil[0]) / 2
    assert label_size_ratio(CAMERA, BALL, double, 2 * R_BALL) == pytest.approx(2.0, rel=1e-6)


def test_a_view_beside_one_of_the_balls_views_sees_a_ball_moved_along_that_views_ray_where_it_was():
    """A near duplicate of a view of the ball sees the ball moved 1 m along that view's ray hardly move (it checks
    nothing of the depth); a view from across the pitch sees it move by tens of pixels."""
    main = np.array([0.0, 60.0, -15.0])
    beside = look_at(main + np.array([0.3, 0.0, 0.0]), BALL)
    across = look_at([70.0, 3.0, -15.0], BALL)
    assert depth_shift_px(beside, BALL, [main], W) < 5.0
    assert depth_shift_px(across, BALL, [main], W) > 30.0
    assert depth_shift_px(across, BALL, [main, main + np.array([0.3, 0.0, 0.0])], W) == pytest.approx(
        min(depth_shift_px(across, BALL, [c], W) for c in (main, main + np.array([0.3, 0.0, 0.0]))))
    assert depth_shift_px(across, BALL, [], W) == float("inf")
