"""Mirrored labels: the mirrored camera, and the evidence rule on synthetic scenes with known truth
(true cameras, true ball; a view "with mirrored labels" carries the camera its mirrored labels
calibrate to, ``mirror_camera`` of its true camera)."""
from __future__ import annotations

import numpy as np
import pytest

from app.geometry.annotations import mirror_lines
from app.geometry.calibration import calibrate_frame
from app.geometry.calibration.rig import CameraRig, RigPosition, calibrate_with_rig
from app.geometry.camera import Camera
from app.geometry.mirror import (
    AMBIGUOUS,
    DIFFERENT,
    MIRROR_ROTATION,
    NO_AGREEMENT,
    SAME,
    VERDICT_AS_LABELLED,
    VERDICT_MIRRORED,
    VERDICT_UNDECIDED,
    MirrorSettings,
    MirrorView,
    mirror_camera,
    mirror_evidence,
    mirrored_fit_at_rig,
    pair_relation,
    side_vote,
)

from .test_calibration import _camera, synthetic_lines

W, H = 1920, 1080
BALL = np.array([24.0, 9.0, -0.11])
#: A main camera on the y > 0 side and replays from the usual stadium positions, all aimed at the ball.
CENTRES = {
    "main": (0.0, 60.0, -20.0),
    "behind_goal": (62.0, 2.0, -8.0),
    "opposite": (15.0, -52.0, -14.0),
    "corner": (58.0, 40.0, -10.0),
}


def camera(name: str, ball: np.ndarray = BALL, focal: float = 2500.0) -> Camera:
    return _camera(CENTRES[name], tuple(ball), focal, W, H)


def view(name: str, *, mirrored: bool = False, ball: np.ndarray = BALL, label_px: np.ndarray | None = None,
         side: int | None = None, focal: float = 2500.0) -> MirrorView:
    """A calibrated view of the ball; with ``mirrored``, the camera its mirrored labels give."""
    cam = camera(name, ball, focal)
    uv = cam.project(ball.reshape(1, 3))[0][0] if label_px is None else label_px
    return MirrorView(name, mirror_camera(cam) if mirrored else cam, uv + 0.5, W,
                      expected_side=1 if name == "main" and side is None else side, name=name)


def test_mirror_camera_projects_the_rotated_world_to_the_same_pixels() -> None:
    cam = Camera(K=camera("main").K, R=camera("main").R, C=camera("main").C,
                 radial=np.array([0.05, -0.01, 0, 0, 0, 0]), tangential=np.array([1e-4, -2e-4]))
    X = np.random.default_rng(0).uniform([-50, -30, -5], [50, 30, 0], size=(50, 3))
    uv, ok = cam.project(X)
    uv_m, ok_m = mirror_camera(cam).project(X @ MIRROR_ROTATION.T)
    assert ok.all() and ok_m.all()
    np.testing.assert_allclose(uv_m, uv, atol=1e-9)
    twice = mirror_camera(mirror_camera(cam))
    np.testing.assert_allclose(twice.R, cam.R, atol=1e-15)
    np.testing.assert_allclose(twice.C, cam.C, atol=1e-15)
    # The mirrored ball ray is the rotated ray, from the rotated centre.
    np.testing.assert_allclose(mirror_camera(cam).rays(uv[:3]), cam.rays(uv[:3]) @ MIRROR_ROTATION.T, atol=1e-12)


def test_mirrored_labels_calibrate_to_the_mirrored_camera() -> None:
    truth = _camera((-8.0, 58.0, -16.0), (-38.0, -2.0, 0.0), 1300.0, 960, 540)
    lines = synthetic_lines(truth, 960, 540, sigma_px=0.5, seed=3)
    got = calibrate_frame(mirror_lines(lines), 960, 540, compute_jac=False)
    expected = mirror_camera(truth)
    assert got.calibrated and got.camera is not None
    assert np.linalg.norm(got.camera.C - expected.C) < 0.5
    cos = (np.trace(got.camera.R @ expected.R.T) - 1.0) / 2.0
    assert np.degrees(np.arccos(np.clip(cos, -1, 1))) < 0.1


def test_a_mirrored_replay_among_three_views_is_flagged_and_only_it() -> None:
    views = [view("main"), view("behind_goal"), view("opposite", mirrored=True)]
    verdicts = mirror_evidence(views, tau_px=20.0, rule="max_scaled_1920")
    assert [verdicts[v.view_id].verdict for v in views] == [VERDICT_AS_LABELLED, VERDICT_AS_LABELLED,
                                                             VERDICT_MIRRORED]
    flagged = verdicts["opposite"]
    assert {p.relation for p in flagged.pairs} == {DIFFERENT}
    for p in flagged.pairs:  # the ray misses as labelled and meets once mirrored
        assert p.error_mirrored_px < 5.0 and (p.error_as_labelled_px is None or p.error_as_labelled_px > 100.0)
    # the geometry returns numbers; the words are composed above it
    from app.services.wording.doubt_words import mirror_sentence
    sentence = mirror_sentence(flagged.as_dict(), {v.view_id: f"{v.view_id}.png" for v in views})
    assert "probably mirrored" in sentence and "main.png" in sentence and "sentence" not in flagged.as_dict()
    assert flagged.as_dict()["mirrored_camera_y_m"] == pytest.approx(-flagged.camera_y_m)


def test_without_the_side_prior_the_smaller_group_is_the_mirrored_one() -> None:
    # Three replays, no side prior: the two that agree outvote the one that agrees only mirrored.
    views = [view("behind_goal"), view("corner"), view("opposite", mirrored=True)]
    verdicts = mirror_evidence(views, tau_px=20.0, rule="max_scaled_1920")
    assert verdicts["opposite"].flagged
    assert not verdicts["behind_goal"].flagged and not verdicts["corner"].flagged


def test_two_views_are_decided_by_the_side_prior_or_not_at_all() -> None:
    # Mirroring either of two views makes their rays meet: only a prior can say which.
    with_main = mirror_evidence([view("main"), view("opposite", mirrored=True)], tau_px=20.0, rule="max_scaled_1920")
    assert with_main["opposite"].flagged and with_main["main"].verdict == VERDICT_AS_LABELLED
    two_replays = mirror_evidence([view("behind_goal"), view("opposite", mirrored=True)], tau_px=20.0,
                                  rule="max_scaled_1920")
    assert [v.verdict for v in two_replays.values()] == [VERDICT_UNDECIDED, VERDICT_UNDECIDED]
    # A main camera whose labels are mirrored stands beyond the far side line: it is the one.
    mirrored_main = mirror_evidence([view("main", mirrored=True), view("opposite")], tau_px=20.0,
                                    rule="max_scaled_1920")
    assert mirrored_main["main"].flagged and not mirrored_main["opposite"].flagged


def test_a_ball_near_the_centre_spot_says_nothing() -> None:
    ball = np.array([0.3, -0.2, -0.11])  # its mirror image is 0.7 m away
    views = [view("behind_goal", ball=ball), view("corner", ball=ball),
             view("opposite", mirrored=True, ball=ball)]
    verdicts = mirror_evidence(views, tau_px=20.0, rule="max_scaled_1920")
    assert all(p.relation == AMBIGUOUS for p in verdicts["opposite"].pairs)
    assert not any(v.flagged for v in verdicts.values())


def test_a_wrong_ball_label_is_no_mirror_evidence() -> None:
    views = [view("main"), view("behind_goal"), view("opposite", label_px=np.array([300.0, 200.0]))]
    verdicts = mirror_evidence(views, tau_px=20.0, rule="max_scaled_1920")
    assert {p.relation for p in verdicts["opposite"].pairs} == {NO_AGREEMENT}
    assert not any(v.flagged for v in verdicts.values())


def test_a_doubtful_other_view_does_not_make_a_false_flag() -> None:
    # The mirrored replay disagrees with everyone; judged jointly, the others stay unflagged even
    # though each of them disagrees with one view.
    views = [view("main"), view("behind_goal"), view("corner"), view("opposite", mirrored=True)]
    verdicts = mirror_evidence(views, tau_px=20.0, rule="max_scaled_1920")
    assert [v.flagged for v in verdicts.values()] == [False, False, False, True]
    # The margins grow with the evidence: two other views agree when mirrored.
    assert verdicts["opposite"].margin > mirror_evidence(views[:1] + views[3:], tau_px=20.0,
                                                         rule="max_scaled_1920")["opposite"].margin


def test_a_single_view_reduces_to_the_side_prior() -> None:
    right = mirror_evidence([view("main")], tau_px=20.0, rule="max_scaled_1920")["main"]
    wrong = mirror_evidence([view("main", mirrored=True)], tau_px=20.0, rule="max_scaled_1920")["main"]
    assert right.verdict == VERDICT_AS_LABELLED and wrong.flagged and wrong.side_vote == 1
    # A replay alone: no evidence.
    evidence = mirror_evidence([view("opposite", mirrored=True)], tau_px=20.0, rule="max_scaled_1920")
    assert evidence["opposite"].verdict == VERDICT_UNDECIDED
    # Between the side lines a main camera gives no vote (behind a goal, for example).
    assert side_vote(camera("behind_goal"), 1) == 0 and side_vote(camera("main"), 1) == -1
    assert side_vote(mirror_camera(camera("main")), 1) == 1 and side_vote(camera("main"), None) == 0


def test_rig_prior() -> None:
    rig = np.array([CENTRES["main"], CENTRES["behind_goal"], CENTRES["opposite"]], dtype=float)
    # A replay at a known position: its labels are presumed right.
    at_rig = mirror_evidence([view("opposite")], rig, tau_px=20.0, rule="max_scaled_1920")["opposite"]
    assert at_rig.rig_vote == -1 and at_rig.rig_distance_m < 1e-9 and at_rig.verdict == VERDICT_AS_LABELLED
    # Its mirror image at a known position: the vote alone does not flag (a camera seen once is
    # common), but it decides where the rays leave a tie.
    mirrored_alone = mirror_evidence([view("opposite", mirrored=True)], rig, tau_px=20.0,
                                     rule="max_scaled_1920")["opposite"]
    assert mirrored_alone.rig_vote == 1 and not mirrored_alone.flagged
    pair = mirror_evidence([view("corner"), view("opposite", mirrored=True)], rig, tau_px=20.0, rule="max_scaled_1920")
    assert pair["opposite"].flagged and not pair["corner"].flagged
    # the words name the distance each way to the nearest camera position, not to "any"
    from app.services.wording.doubt_words import mirror_sentence
    flagged = pair["opposite"].as_dict()
    sentence = mirror_sentence(flagged, {"corner": "V1", "opposite": "V2"})
    assert (f"its mirror image is {flagged['rig_distance_mirrored_m']:.1f} m from a camera position of the game, the "
            f"camera itself {flagged['rig_distance_m']:.0f} m from the nearest one") in sentence, sentence
    assert "from any" not in sentence
    labelled = mirror_sentence(at_rig.as_dict(), {"opposite": "V2"})
    assert "its mirror image" in labelled and labelled.count("from the nearest one") == 1, labelled


def test_pair_relation_is_symmetric_under_mirroring_both() -> None:
    a, b = view("main"), view("behind_goal")
    both = pair_relation(MirrorView("m", mirror_camera(a.camera), a.ball_px, W),
                         MirrorView("b", mirror_camera(b.camera), b.ball_px, W), tau_px=20.0, rule="max_scaled_1920")
    plain = pair_relation(a, b, tau_px=20.0, rule="max_scaled_1920")
    assert plain.relation == both.relation == SAME
    assert both.error_as_labelled_px == pytest.approx(plain.error_as_labelled_px, abs=1e-6)


def test_settings_and_inputs_are_checked() -> None:
    with pytest.raises(ValueError, match="unique"):
        mirror_evidence([view("main"), view("main")], tau_px=20.0, rule="max_scaled_1920")
    with pytest.raises(ValueError, match="expected_side"):
        MirrorView("x", camera("main"), None, W, expected_side=2)
    assert mirror_evidence([], tau_px=20.0, rule="max_scaled_1920") == {}
    # A view without a ball label gets the priors only.
    no_ball = MirrorView("main", mirror_camera(camera("main")), None, W, expected_side=1)
    assert mirror_evidence([no_ball, view("opposite")], tau_px=20.0, rule="max_scaled_1920")["main"].flagged
    # A stricter decision margin turns the same evidence undecided.
    strict = MirrorSettings(decision_margin=100.0)
    assert mirror_evidence([view("main", mirrored=True)], settings=strict,
                           tau_px=20.0, rule="max_scaled_1920")["main"].verdict == VERDICT_UNDECIDED


def test_rig_positions_of_the_wrong_shape_are_refused() -> None:
    """Regression: rig positions were read with ``reshape(-1, 3)``, so (K, 2) ground positions (x, y
    without height) were regrouped into made-up 3D positions and voted without a word."""
    flat = np.array([CENTRES["main"][:2], CENTRES["behind_goal"][:2], CENTRES["opposite"][:2]])
    with pytest.raises(ValueError, match="rig_positions"):
        mirror_evidence([view("opposite")], flat, tau_px=20.0, rule="max_scaled_1920")
    assert mirror_evidence([view("opposite")], np.zeros((0, 3)),
                           tau_px=20.0, rule="max_scaled_1920")["opposite"].rig_vote == 0
    one = mirror_evidence([view("opposite")], np.array(CENTRES["opposite"]), tau_px=20.0,
                          rule="max_scaled_1920")["opposite"]
    assert one.rig_distance_m is not None and one.rig_distance_m < 1e-9


def test_a_refused_frame_whose_mirrored_labels_fit_the_rig_is_flagged() -> None:
    truth = _camera((-2.0, 66.0, -14.0), (30.0, 20.0, 0.0), 2400.0, 960, 540)
    lines = synthetic_lines(truth, 960, 540, sigma_px=0.5, seed=8)
    rig = CameraRig(positions=(RigPosition(centre_m=(-2.0, 66.0, -14.0), frames=9, spread_m=0.3),
                               RigPosition(centre_m=(62.0, 2.0, -8.0), frames=5, spread_m=0.3)))
    wrong = mirror_lines(lines)
    assert not calibrate_with_rig(wrong, 960, 540, rig, expected_side=1, compute_jac=False).calibrated
    verdict = mirrored_fit_at_rig(wrong, 960, 540, rig, expected_side=1)
    assert verdict is not None and verdict.flagged and verdict.side_vote == 1
    assert verdict.camera_y_m == pytest.approx(-66.0, abs=0.5)
    # The labels as given fit the rig: nothing to say about their mirror.
    assert mirrored_fit_at_rig(lines, 960, 540, rig, expected_side=1) is None
    # A replay (no side prior): the rig's "mirrored" vote alone does not flag.
    assert mirrored_fit_at_rig(wrong, 960, 540, rig) is None
