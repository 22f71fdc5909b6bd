"""The 3D ball judged by its evidence (``app.geometry.evidence``): synthetic cameras with a known ball, pure numpy."""
from __future__ import annotations

import numpy as np
import pytest

from app.geometry.evidence import LONE_PAIR_MAX_ERROR_TAU, judge_by_evidence
from app.geometry.pitch import distance_to_play_volume
from app.geometry.triangulation import BallObservation, triangulate_ball
from tests.geometry.test_triangulation import BALL, look_at, observe


def _paper(obs: list[BallObservation]):
    return triangulate_ball(obs, tau_px=20.0, rule="max_scaled_1920", min_baseline_m=1.0, min_parallax_deg=0.0)


def test_a_low_parallax_pair_moves_the_ball_only_along_what_it_knows():
    """Two near-duplicate viewpoints (rays 1 degree apart) and a wide one: the low-parallax pair's point lies metres
    off along its depth when its labels are a pixel off, the paper's mean follows it; judged by evidence the pair's
    long ellipsoid counts only across its depth and the ball stays within a decimetre, with a small sigma."""
    wide = look_at([0.0, 75.0, -22.0], BALL, focal=3000.0)
    near_a = look_at([70.0, 4.0, -15.0], BALL, focal=2500.0)
    near_b = look_at([70.0, 5.3, -15.0], BALL, focal=2500.0)  # 1.3 m apart at 50 m: about 1.5 degrees
    obs = observe([wide, near_a, near_b])
    # the two near views' labels a pixel and a half apart, in opposite directions along the image's x
    obs[1] = BallObservation("v1", near_a, obs[1].point_px + [1.5, 0.0], 1920.0)
    obs[2] = BallObservation("v2", near_b, obs[2].point_px - [1.5, 0.0], 1920.0)
    paper = _paper(obs)
    assert paper.point is not None and np.linalg.norm(paper.point - BALL) > 0.5  # the plain mean is pulled off
    judged = judge_by_evidence(obs, paper, {"v0": 2.0, "v1": 2.0, "v2": 2.0}, max_sigma_m=1.0,
                               distance_to_volume_m=distance_to_play_volume)
    assert judged.result.point is not None and np.linalg.norm(judged.result.point - BALL) < 0.1
    assert judged.sigma_m is not None and 0.0 < judged.sigma_m < 0.2
    assert all(p.kept for p in judged.result.pairs)  # nothing dropped: the pair only tells what it knows


def test_a_lone_low_parallax_pair_makes_no_ball_beyond_the_bound():
    """The two near-duplicate views alone: their ball's sigma along the depth is metres, above the bound (the
    paper's rules keep it)."""
    near_a = look_at([70.0, 4.0, -15.0], BALL, focal=2500.0)
    near_b = look_at([70.0, 5.3, -15.0], BALL, focal=2500.0)
    obs = observe([near_a, near_b])
    paper = _paper(obs)
    assert paper.point is not None
    judged = judge_by_evidence(obs, paper, {"v0": 2.0, "v1": 2.0}, max_sigma_m=1.0)
    assert judged.result.point is None and judged.result.status == "no_pair_kept"
    assert judged.sigma_m is not None and judged.sigma_m > 1.0
    assert {p.reason for p in judged.result.pairs} == {"sigma_above_bound"}
    # a wider bound lets the same ball stand: the bound, not the parallax, refused it
    assert judge_by_evidence(obs, paper, {"v0": 2.0, "v1": 2.0}, max_sigma_m=50.0).result.point is not None


def test_a_view_off_beyond_the_joint_sigma_is_left_out():
    """Four views; one label 12 px off (within tau, so the paper averages its pairs): its pairs lie beyond the
    others' joint sigma of 1 px and are dropped one by one until the rest agree; the ball is the others'."""
    cams = [look_at([0.0, 75.0, -22.0], BALL, focal=3000.0), look_at([70.0, 4.0, -15.0], BALL, focal=2500.0),
            look_at([10.0, -55.0, -12.0], BALL, focal=4000.0), look_at([-60.0, 40.0, -18.0], BALL, focal=2500.0)]
    obs = observe(cams)
    obs[3] = BallObservation("v3", cams[3], obs[3].point_px + [12.0, 0.0], 1920.0)
    paper = _paper(obs)
    assert paper.point is not None and len(paper.kept_pairs) >= 4
    judged = judge_by_evidence(obs, paper, {f"v{k}": 1.0 for k in range(4)}, max_sigma_m=1.0)
    assert judged.result.point is not None and np.linalg.norm(judged.result.point - BALL) < 0.02
    dropped = [p for p in judged.result.pairs if p.reason == "beyond_joint_sigma"]
    assert dropped and all("v3" in (p.view_a, p.view_b) for p in dropped)
    assert np.linalg.norm(paper.point - BALL) > np.linalg.norm(judged.result.point - BALL)


def test_a_ball_outside_the_play_volume_stands_only_within_its_uncertainty():
    """A ball 3 m outside the play volume: refused with a sigma of a decimetre, kept when the bound and the ball's
    own sigma reach the volume (three sigmas)."""
    outside = np.array([0.0, 0.0, 3.5])  # 3.5 m under the grass: 3 m below the volume's floor
    cams = [look_at([0.0, 75.0, -22.0], outside, focal=3000.0), look_at([70.0, 4.0, -15.0], outside, focal=2500.0)]
    obs = observe(cams, point=outside)
    paper = _paper(obs)
    assert distance_to_play_volume(outside) == pytest.approx(3.0)
    sure = judge_by_evidence(obs, paper, {"v0": 1.0, "v1": 1.0}, max_sigma_m=1.0,
                             distance_to_volume_m=distance_to_play_volume)
    assert sure.result.point is None and {p.reason for p in sure.result.pairs} == {"outside_play_volume"}
    unsure = judge_by_evidence(obs, paper, {"v0": 400.0, "v1": 400.0}, max_sigma_m=100.0,
                               distance_to_volume_m=distance_to_play_volume)
    assert unsure.sigma_m is not None and unsure.sigma_m * 3 > 3.0 and unsure.result.point is not None


def test_bad_bound_is_refused():
    obs = observe([look_at([0.0, 75.0, -22.0], BALL), look_at([70.0, 4.0, -15.0], BALL)])
    with pytest.raises(ValueError, match="max_sigma_m"):
        judge_by_evidence(obs, _paper(obs), {"v0": 1.0, "v1": 1.0}, max_sigma_m=0.0)


def test_a_pair_whose_cameras_disagree_on_their_players_makes_no_ball():
    """Two views whose rays meet (no residual: the ball's pair alone cannot tell a camera wrong along the epipolar
    line) make a ball with a small sigma; told that the two cameras disagree on their players, the pair is left out
    (``players_disagree``) and no ball stands. In a three-view system the other pairs still make it."""
    cams = [look_at([0.0, 75.0, -22.0], BALL, focal=3000.0), look_at([70.0, 4.0, -15.0], BALL, focal=2500.0),
            look_at([10.0, -55.0, -12.0], BALL, focal=4000.0)]
    two = observe(cams[:2])
    sig = {"v0": 2.0, "v1": 2.0, "v2": 2.0}
    assert judge_by_evidence(two, _paper(two), sig, max_sigma_m=10.0).result.point is not None
    asked = []

    def disagree(a, b):
        asked.append((a, b))
        return {a, b} == {"v0", "v1"}

    judged = judge_by_evidence(two, _paper(two), sig, max_sigma_m=10.0, players_disagree=disagree)
    assert judged.result.point is None and judged.result.status == "no_pair_kept"
    assert [p.reason for p in judged.result.pairs] == ["players_disagree"] and asked == [("v0", "v1")]
    three = observe(cams)
    judged = judge_by_evidence(three, _paper(three), sig, max_sigma_m=10.0, players_disagree=disagree)
    assert judged.result.point is not None and np.linalg.norm(judged.result.point - BALL) < 0.05
    assert {(p.view_a, p.view_b): p.reason for p in judged.result.pairs} == {
        ("v0", "v1"): "players_disagree", ("v0", "v2"): None, ("v1", "v2"): None}


def _replay_of_another_instant(error_tau: tuple[float, float]):
    """Two views: the action's sees the ball at ``BALL``, the replay's the ball 0.1 s on (moved up and across); the
    moved ball is the first along that motion whose two rays meet with a pair error (px at 1920 width) within
    ``error_tau`` of tau (20 px). Returns the observations and the paper's triangulation of them."""
    action = look_at([0.0, 75.0, -22.0], BALL, focal=3000.0)
    replay = look_at([70.0, 4.0, -15.0], BALL, focal=2500.0)
    motion = np.array([0.3, 0.8, -0.5]) / np.linalg.norm([0.3, 0.8, -0.5])
    for step in np.arange(0.05, 8.0, 0.05):
        obs = [observe([action])[0], BallObservation("v1", replay, observe([replay], BALL + step * motion)[0].point_px,
                                                     1920.0)]
        paper = _paper(obs)
        error = paper.pairs[0].error
        if paper.point is not None and error is not None and error_tau[0] * 20.0 < error < error_tau[1] * 20.0:
            return obs, paper
    raise AssertionError("no moved ball gives that pair error")


def test_a_lone_pair_meeting_at_the_edge_of_tau_makes_no_ball():
    """A replay of another instant whose ray meets the action's at 0.75-0.95 tau: the paper keeps the pair and its
    ball lies metres off; judged by evidence with the lone-pair bound the ball is refused (``lone_pair_at_tau_edge``);
    without it (None) the same ball stands. A replay of the same instant (the pair within the bound) keeps its ball."""
    obs, paper = _replay_of_another_instant((0.75, 0.95))
    sig = {"v0": 2.0, "v1": 2.0}
    assert paper.point is not None and np.linalg.norm(paper.point - BALL) > 1.0
    loose = judge_by_evidence(obs, paper, sig, max_sigma_m=50.0)
    assert loose.result.point is not None and np.linalg.norm(loose.result.point - BALL) > 1.0
    judged = judge_by_evidence(obs, paper, sig, max_sigma_m=50.0, lone_pair_max_error_tau=LONE_PAIR_MAX_ERROR_TAU)
    assert judged.result.point is None and judged.result.status == "no_pair_kept"
    assert [p.reason for p in judged.result.pairs] == ["lone_pair_at_tau_edge"]
    assert judged.sigma_m is not None  # the refused ball's sigma is still told
    same = observe([look_at([0.0, 75.0, -22.0], BALL, focal=3000.0), look_at([70.0, 4.0, -15.0], BALL, focal=2500.0)],
                   noise_px=1.0)
    kept = judge_by_evidence(same, _paper(same), sig, max_sigma_m=50.0, lone_pair_max_error_tau=LONE_PAIR_MAX_ERROR_TAU)
    assert kept.result.point is not None and np.linalg.norm(kept.result.point - BALL) < 0.2


def test_the_lone_pair_bound_leaves_a_ball_of_several_pairs_alone():
    """The same replay beside a third view of the action's instant: the replay's pair with it is above tau, its pair
    with the action's beyond the joint sigma of the pair left; the ball rests on the two views of the instant, whose
    pair meets well within tau, and stands where the ball is."""
    obs, _ = _replay_of_another_instant((0.75, 0.95))
    third = look_at([10.0, -55.0, -12.0], BALL, focal=4000.0)
    three = [*obs, BallObservation("v2", third, observe([third])[0].point_px, 1920.0)]
    paper = _paper(three)
    judged = judge_by_evidence(three, paper, {"v0": 2.0, "v1": 2.0, "v2": 2.0}, max_sigma_m=50.0,
                               lone_pair_max_error_tau=LONE_PAIR_MAX_ERROR_TAU)
    assert [p.reason for p in judged.result.pairs] == ["beyond_joint_sigma", None, "error_above_tau"]
    assert judged.result.point is not None and np.linalg.norm(judged.result.point - BALL) < 0.01


def _desynchronised_beside_unsure(unsure_views: int):
    """The action's view (a sharp camera, pixel sigma 2) and ``unsure_views`` views of the same instant whose cameras
    are known to 25 px (a few-lined camera's floor), beside a sharp replay (sigma 2) of the ball 2 m on, whose ray
    crosses the others' within tau by chance (the paper keeps every pair). Returns the observations, the paper's
    triangulation and the sigmas."""
    action = look_at([0.0, 75.0, -22.0], BALL, focal=3000.0)
    replay = look_at([70.0, 4.0, -15.0], BALL, focal=2500.0)
    unsure = [look_at([10.0, -55.0, -12.0], BALL, focal=4000.0), look_at([12.0, -52.0, -12.0], BALL, focal=4000.0)]
    obs = [observe([action])[0],
           BallObservation("v1", replay, observe([replay], BALL + [0.0, 2.0, 0.0])[0].point_px, 1920.0)]
    obs += [BallObservation(f"v{2 + k}", cam, observe([cam])[0].point_px, 1920.0)
            for k, cam in enumerate(unsure[:unsure_views])]
    sigmas = {"v0": 2.0, "v1": 2.0, "v2": 25.0, "v3": 25.0}
    return obs, _paper(obs), {o.view_id: sigmas[o.view_id] for o in obs}


def test_a_sharp_replay_of_another_instant_does_not_outweigh_the_views_that_agree():
    """Three views: the replay's pairs with the action's and with the unsure view meet within tau (0.75 and 0.96
    tau), sharper than the right pair, whose unsure camera weighs little: weighed first, the right pair is dropped
    beyond the joint sigma and the ball is the replay's, almost 2 m off. Chosen first by their consensus (no third
    view agrees with any pair's point within tau or 3 of its sigmas, and the right pair's rays meet closest), the
    replay's pairs are left out (``outside_consensus``) and the ball is the right one."""
    obs, paper, sig = _desynchronised_beside_unsure(1)
    assert all(p.kept for p in paper.pairs)  # the paper keeps the replay's pairs: within tau
    weighed = judge_by_evidence(obs, paper, sig, max_sigma_m=10.0)
    assert weighed.result.point is not None and np.linalg.norm(weighed.result.point - BALL) > 1.0
    assert [p.reason for p in weighed.result.pairs] == [None, "beyond_joint_sigma", "beyond_joint_sigma"]
    judged = judge_by_evidence(obs, paper, sig, max_sigma_m=10.0, consensus=True)
    assert judged.result.point is not None and np.linalg.norm(judged.result.point - BALL) < 0.05
    assert {(p.view_a, p.view_b): p.reason for p in judged.result.pairs} == {
        ("v0", "v1"): "outside_consensus", ("v0", "v2"): None, ("v1", "v2"): "outside_consensus"}


def test_three_views_that_agree_outnumber_a_sharp_replay():
    """Four views: the action's and two unsure ones agree on the ball, the replay's pairs cross two of them within
    tau. Every pair of the three that agree has the other two within tau of its point; the replay's pairs have at
    most three: weighed alone the replay's sharp pairs win and the ball is more than a metre off; with the consensus
the replay's pairs are left out and the ball is the three views'."""
    obs, paper, sig = _desynchronised_beside_unsure(2)
    weighed = judge_by_evidence(obs, paper, sig, max_sigma_m=10.0)
    assert weighed.result.point is not None and np.linalg.norm(weighed.result.point - BALL) > 1.0
    judged = judge_by_evidence(obs, paper, sig, max_sigma_m=10.0, consensus=True)
    assert judged.result.point is not None and np.linalg.norm(judged.result.point - BALL) < 0.05
    left_out = {(p.view_a, p.view_b) for p in judged.result.pairs if p.reason == "outside_consensus"}
    assert left_out and all("v1" in pair for pair in left_out)
    assert all(p.kept for p in judged.result.pairs if "v1" not in (p.view_a, p.view_b) and p.reason is None)


def test_views_that_all_agree_are_judged_as_without_the_consensus():
    """Four views with a pixel of label noise, one of them unsure: every pair's point has every view within tau, so
    the consensus leaves nothing out and the ball, its sigma and every pair's reason are those of the weighing
    alone."""
    cams = [look_at([0.0, 75.0, -22.0], BALL, focal=3000.0), look_at([70.0, 4.0, -15.0], BALL, focal=2500.0),
            look_at([10.0, -55.0, -12.0], BALL, focal=4000.0), look_at([-60.0, 40.0, -18.0], BALL, focal=2500.0)]
    obs = observe(cams, noise_px=1.0)
    sig = {"v0": 2.0, "v1": 2.0, "v2": 25.0, "v3": 2.0}
    plain = judge_by_evidence(obs, _paper(obs), sig, max_sigma_m=10.0)
    judged = judge_by_evidence(obs, _paper(obs), sig, max_sigma_m=10.0, consensus=True)
    assert judged.result.point is not None and np.allclose(judged.result.point, plain.result.point)
    assert judged.sigma_m == plain.sigma_m
    assert [p.reason for p in judged.result.pairs] == [p.reason for p in plain.result.pairs]
    assert all(p.kept for p in judged.result.pairs)


def test_a_camera_known_to_nothing_supports_every_ball_and_decides_none():
    """Three views; the third's camera is undetermined (pixel sigma 2000 px) and its label's ray crosses the action's
    exactly, 3 m nearer the action's camera than the ball: that pair meets closest of all, yet the third view is
    within its own sigma of every pair's point, so it supports every hypothesis; the sure pair's (a label 8 px off)
    then holds every view, nothing is left out, and the weighing makes the ball the sure pair's. Counted by tau
    alone, the close pair would win and leave no ball (its sigma beyond the bound)."""
    cams = [look_at([0.0, 75.0, -22.0], BALL, focal=3000.0), look_at([70.0, 4.0, -15.0], BALL, focal=2500.0),
            look_at([10.0, -55.0, -12.0], BALL, focal=4000.0)]
    obs = observe(cams)
    obs[1] = BallObservation("v1", cams[1], obs[1].point_px + [0.0, 8.0], 1920.0)
    towards = (cams[0].C - BALL) / np.linalg.norm(cams[0].C - BALL)
    obs[2] = BallObservation("v2", cams[2], observe([cams[2]], BALL + 3.0 * towards)[0].point_px, 1920.0)
    paper = _paper(obs)
    assert [p.kept for p in paper.pairs] == [True, True, False]  # v1 + v2 above tau
    sig = {"v0": 2.0, "v1": 2.0, "v2": 2000.0}
    judged = judge_by_evidence(obs, paper, sig, max_sigma_m=10.0, consensus=True)
    assert judged.result.point is not None and np.linalg.norm(judged.result.point - BALL) < 0.3
    assert "outside_consensus" not in {p.reason for p in judged.result.pairs}
