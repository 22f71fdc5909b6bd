"""Temporal 3D trajectory (app.geometry.trajectory) on synthetic sequences of known truth.

The truth is simulated here with the physics of the module docstring written out independently
(events: roll with deceleration, kick, flight under gravity, bounce with restitution, kick), seen by
four static cameras around the pitch with 0.7 px label noise.
"""
from __future__ import annotations

import numpy as np
import pytest

from app.geometry import trajectory as trajectory_module
from app.geometry.camera import Camera
from app.geometry.trajectory import fit as fit_module
from app.geometry.trajectory import (
    fit_trajectory,
    local_span,
    refit_local,
    refit_span,
    refit_window,
    triangulate_frame,
)
from app.geometry.trajectory import refit as refit_module
from app.geometry.trajectory import segmentation as segmentation_module
from app.geometry.triangulation import BallObservation

FPS = 25.0
G = 9.81
R_BALL = 0.11


def look_at(centre, target, focal=2500.0) -> Camera:
    c, t = np.asarray(centre, float), np.asarray(target, float)
    z = (t - c) / np.linalg.norm(t - c)
    x = np.cross([0.0, 0.0, 1.0], z)
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    K = np.array([[focal, 0, 960.0], [0, focal, 540.0], [0, 0, 1.0]])
    return Camera(K=K, R=np.stack([x, y, z]), C=c)


CAMERAS = [look_at([0, 45, -12], [5, 5, 0]), look_at([0, -45, -12], [5, 5, 0]),
           look_at([-40, 10, -10], [5, 5, 0]), look_at([45, 30, -15], [5, 5, 0])]


def simulate(n_frames=150, restitution=0.6, decel=1.5):
    """(F, 3) true positions: roll from the centre spot (frames 0-49), a lofted kick at t = 2.02 s
    (between frames), a bounce, a second kick at t = 4.41 s."""
    kicks = {2.02: np.array([-2.0, 4.0, -9.0]), 4.41: np.array([4.0, -6.0, -3.0])}
    dt = 1e-4
    p, v, phase = np.array([0.0, 0.0, -R_BALL]), np.array([6.0, 2.0, 0.0]), "roll"
    out, t, next_kicks = [], 0.0, sorted(kicks)
    for f in range(n_frames):
        target = f / FPS
        while t < target - 1e-12:
            step = min(dt, target - t)
            if next_kicks and t + step >= next_kicks[0]:  # the kick happens inside this step
                step = next_kicks[0] - t
                p, t = p + v * step + 0.5 * _acc(phase, v, decel) * step ** 2, t + step
                v, phase = kicks[next_kicks.pop(0)].copy(), "flight"
                continue
            a = _acc(phase, v, decel)
            p, v, t = p + v * step + 0.5 * a * step ** 2, v + a * step, t + step
            if phase == "flight" and p[2] > -R_BALL and v[2] > 0:
                p[2], v[2] = -R_BALL - (p[2] + R_BALL), -restitution * v[2]
        out.append(p.copy())
    return np.array(out)


def _acc(phase, v, decel):
    if phase == "flight":
        return np.array([0.0, 0.0, G])
    speed = np.linalg.norm(v[:2])
    return np.zeros(3) if speed < 1e-9 else np.append(-decel * v[:2] / speed, 0.0)


def labels(truth, cameras=CAMERAS, sigma=0.7, seed=0):
    rng = np.random.default_rng(seed)
    pts = np.full((len(truth), len(cameras), 2), np.nan)
    for k, cam in enumerate(cameras):
        uv, front = cam.project(truth)
        inside = front & (uv[:, 0] >= 0) & (uv[:, 0] < 1920) & (uv[:, 1] >= 0) & (uv[:, 1] < 1080)
        pts[inside, k] = uv[inside] + rng.normal(0, sigma, (int(inside.sum()), 2))
    return pts


@pytest.fixture(scope="module")
def scene():
    truth = simulate()
    pts = labels(truth)
    assert np.all(np.isfinite(pts).all(axis=2).sum(axis=1) >= 2), "every frame seen by two cameras or more"
    return truth, pts


def fit(pts):
    return fit_trajectory(pts, CAMERAS, [1920] * len(CAMERAS), FPS, tau_px=20.0, rule="max_scaled_1920",
                          min_baseline_m=1.0, min_parallax_deg=0.0)


def test_roll_lob_bounce_kick_recovered(scene):
    truth, pts = scene
    res = fit(pts)
    err = np.linalg.norm(res.positions - truth, axis=1)
    assert np.all(np.isfinite(err))
    assert np.median(err) < 0.02 and err.max() < 0.2
    tri = np.linalg.norm(res.ball_3d - truth, axis=1)
    assert np.median(err) < np.median(tri)  # the trajectory beats single frames
    kinds = [p.kind for p in res.pieces]
    assert kinds[0] == "roll" and "flight" in kinds
    breaks = [p.first_frame for p in res.pieces[1:]]
    assert any(abs(b - 51) <= 1 for b in breaks)  # kick at t = 2.02 s: between frames 50 and 51
    assert any(abs(b - 111) <= 1 for b in breaks)  # kick at t = 4.41 s
    assert any(abs(b - 97) <= 1 for b in breaks) and any(abs(b - 135) <= 1 for b in breaks)  # the two bounces
    assert not res.outliers.any()
    assert set(res.sources) == {"triangulated"}


def test_wrong_label_is_flagged_and_left_out(scene):
    truth, pts = scene
    pts = pts.copy()
    f = 30
    two = [k for k in range(4) if np.all(np.isfinite(pts[f, k]))]
    for k in two[2:]:
        pts[f, k] = np.nan  # a frame with two labels: one frame alone cannot tell which is wrong
    pts[f, two[0]] += (120.0, -90.0)
    res = fit(pts)
    assert res.outliers[f, two[0]] and res.outliers.sum() == 1
    assert res.cam_lists[f] == (two[1],)  # the good label is kept, the wrong one left out
    assert np.linalg.norm(res.positions[f] - truth[f]) < 0.05
    assert res.sources[f] == "fitted"  # one kept label: position from the trajectory


def test_gaps_single_camera_and_none_are_filled(scene):
    truth, pts = scene
    pts = pts.copy()
    pts[60:70, 1:] = np.nan   # flight seen by camera 0 only
    pts[80:92] = np.nan       # no camera at all
    res = fit(pts)
    assert all(res.sources[f] == "fitted" for f in range(60, 70) if np.isfinite(pts[f, 0]).all())
    assert all(res.sources[f] == "interpolated" for f in range(80, 92))
    err = np.linalg.norm(res.positions - truth, axis=1)
    assert np.all(np.isfinite(err))
    assert err[60:70].max() < 0.15 and err[80:92].max() < 0.15
    assert np.all(np.isnan(res.ball_3d[80:92]))


def assert_same_rows(part, full):
    """The rows of the windowed fit ``part`` equal those of the whole fit ``full`` (positions within 1 mm)."""
    rows = slice(part.first_frame, part.first_frame + len(part.positions))
    np.testing.assert_allclose(part.positions, full.positions[rows], atol=1e-3)
    assert part.sources == full.sources[rows]
    assert np.array_equal(part.outliers, full.outliers[rows])
    assert part.cam_lists == full.cam_lists[rows]
    np.testing.assert_allclose(part.ball_3d, full.ball_3d[rows], atol=1e-9)


def test_refit_window_matches_full_fit_after_an_edit(scene):
    truth, pts = scene
    bad = pts.copy()
    bad[100, 0] += (300.0, 0.0)
    first = fit(bad)
    assert first.outliers[100, 0]
    fixed = refit_window(first, pts, CAMERAS, [1920] * 4, 100, 100, tau_px=20.0, rule="max_scaled_1920",
                         min_baseline_m=1.0, min_parallax_deg=0.0)
    full = fit(pts)
    assert fixed.first_frame <= 100 < fixed.first_frame + len(fixed.positions)
    assert not fixed.outliers.any()
    assert_same_rows(fixed, full)
    assert [(p.first_frame, p.last_frame) for p in fixed.pieces] == [(p.first_frame, p.last_frame) for p in full.pieces]


@pytest.mark.parametrize("edit", ["moved", "removed", "wrong"])
def test_refit_of_a_window_equals_a_fit_from_scratch(scene, edit, monkeypatch):
    """The re-fit reads only the frames of ``refit_span`` (a window of the previous fit, as the service
    stores it), re-triangulates only the frames whose kept labels changed, and gives the rows of a fit
    of the whole edited sequence from scratch."""
    truth, pts = scene
    before = fit(pts)
    piece = max(before.pieces, key=lambda p: p.last_frame - p.first_frame)
    f = (piece.first_frame + piece.last_frame) // 2  # well inside a piece: the fast path
    edited = pts.copy()
    k = int(np.nonzero(np.isfinite(pts[f]).all(axis=1))[0][0])
    if edit == "moved":
        edited[f, k] += (3.0, -2.0)
    elif edit == "removed":
        edited[f, k] = np.nan
    else:
        edited[f, k] += (90.0, 40.0)
    a, b = refit_span(before.pieces, f, f)
    assert a <= f <= b and b - a + 1 < len(pts)
    calls = []
    real = trajectory_module.triangulate_frame
    monkeypatch.setattr(fit_module, "triangulate_frame", lambda obs, **kw: calls.append(1) or real(obs, **kw))
    part = refit_window(before.window(a, b), edited[a:b + 1], CAMERAS, [1920] * 4, f, f, tau_px=20.0,
                        rule="max_scaled_1920", min_baseline_m=1.0, min_parallax_deg=0.0)
    monkeypatch.undo()
    scratch = fit(edited)
    assert [(p.kind, p.first_frame, p.last_frame) for p in part.pieces] == \
        [(p.kind, p.first_frame, p.last_frame) for p in scratch.pieces]
    assert_same_rows(part, scratch)
    assert part.outliers[f - part.first_frame, k] == (edit == "wrong")
    assert len(calls) < len(part.positions) // 4  # most frames keep their own triangulation
    narrow = local_span(before.pieces, f, f)  # the fast path alone reads the piece's frames only
    assert narrow[1] - narrow[0] < b - a
    alone = refit_local(before.window(*narrow), edited[narrow[0]:narrow[1] + 1], CAMERAS, [1920] * 4, f, f, tau_px=20.0,
                        rule="max_scaled_1920", min_baseline_m=1.0, min_parallax_deg=0.0)
    assert alone is not None and [(p.kind, p.first_frame, p.last_frame) for p in alone.pieces] == \
        [(p.kind, p.first_frame, p.last_frame) for p in part.pieces]
    assert_same_rows(alone, scratch)
    with pytest.raises(ValueError, match="needs frames"):
        refit_window(before.window(f, f), edited[f:f + 1], CAMERAS, [1920] * 4, f, f, tau_px=20.0,
                     rule="max_scaled_1920", min_baseline_m=1.0, min_parallax_deg=0.0)


@pytest.mark.parametrize("where", ["at a break", "at the first frame"])
def test_refit_near_a_break_or_the_sequence_start(scene, where):
    """At a break the two pieces around it are fitted again and the break moved to the lowest cost
    (``refit_local``); at the sequence's first frame (too near the end of the stretch to trust the
    pieces) the stretch is segmented again (``refit_window``). Both give the fit from scratch."""
    truth, pts = scene
    before = fit(pts)
    f = before.pieces[1].first_frame if where == "at a break" else 0
    edited = pts.copy()
    k = int(np.nonzero(np.isfinite(pts[f]).all(axis=1))[0][0])
    edited[f, k] += (2.0, 2.0)
    a, b = refit_span(before.pieces, f, f)
    local = refit_local(before.window(a, b), edited[a:b + 1], CAMERAS, [1920] * 4, f, f, tau_px=20.0,
                        rule="max_scaled_1920", min_baseline_m=1.0, min_parallax_deg=0.0)
    assert (local is None) == (where == "at the first frame")
    part = refit_window(before.window(a, b), edited[a:b + 1], CAMERAS, [1920] * 4, f, f, tau_px=20.0,
                        rule="max_scaled_1920", min_baseline_m=1.0, min_parallax_deg=0.0)
    scratch = fit(edited)
    assert [(p.first_frame, p.last_frame) for p in part.pieces] == [(p.first_frame, p.last_frame)
                                                                    for p in scratch.pieces]
    assert_same_rows(part, scratch)
    if local is not None:
        assert (local.first_frame, len(local.positions)) == (part.first_frame, len(part.positions))
        assert_same_rows(local, scratch)


def test_triangulate_frame_leaves_out_one_wrong_camera(scene):
    truth, pts = scene
    f = next(f for f in range(len(truth)) if np.isfinite(pts[f]).all(axis=1).sum() >= 3)
    ks = [k for k in range(4) if np.isfinite(pts[f, k]).all()]
    obs = [BallObservation(k, CAMERAS[k], pts[f, k] + ((80.0, 60.0) if k == ks[1] else (0.0, 0.0)), 1920)
           for k in ks]
    res = triangulate_frame(obs, tau_px=20.0, rule="max_scaled_1920", min_baseline_m=1.0, min_parallax_deg=0.0)
    assert ks[1] not in res.kept and len(res.kept) == len(ks) - 1
    assert np.linalg.norm(res.point - truth[f]) < 0.1
    assert res.errors_px[ks[1]] > 50
    two = triangulate_frame(obs[:2], tau_px=20.0, rule="max_scaled_1920",
                            min_baseline_m=1.0, min_parallax_deg=0.0)  # two labels that disagree: no point
    assert two.point is None and two.kept == ()


def test_bad_inputs_raise():
    with pytest.raises(ValueError, match="points"):
        fit_trajectory(np.zeros((5, 4)), CAMERAS, [1920] * 4, FPS, tau_px=20.0, rule="max_scaled_1920",
                       min_baseline_m=1.0, min_parallax_deg=0.0)
    with pytest.raises(ValueError, match="one per camera"):
        fit_trajectory(np.zeros((5, 3, 2)), CAMERAS, [1920] * 4, FPS, tau_px=20.0, rule="max_scaled_1920",
                       min_baseline_m=1.0, min_parallax_deg=0.0)
    with pytest.raises(ValueError, match="fps"):
        fit_trajectory(np.zeros((5, 4, 2)), CAMERAS, [1920] * 4, 0.0, tau_px=20.0, rule="max_scaled_1920",
                       min_baseline_m=1.0, min_parallax_deg=0.0)


def test_refit_given_only_the_pieces_within_reach_is_the_same(scene):
    """The service passes the re-fit only the pieces within ``REFIT_REACH`` of the edit (it never reads the
    whole sequence): the answer is the one the whole list of pieces gives, at a break and inside a piece."""
    truth, pts = scene
    pts = np.concatenate([pts, pts])  # the ball thrown back to the start: ten pieces
    pts[146:154] = np.nan  # and unseen around the throw: a gap between two pieces (Hermite-filled)
    before = fit(pts)
    middle = next(i for i, p in enumerate(before.pieces) if p.first_frame > 200)  # two pieces after the gap
    assert before.pieces[middle - 2].last_frame < 146 and before.pieces[middle - 1].first_frame > 153
    assert middle + trajectory_module.REFIT_REACH < len(before.pieces) - 1
    piece = before.pieces[middle]
    for f in (piece.first_frame, (piece.first_frame + piece.last_frame) // 2):
        edited = pts.copy()
        k = int(np.nonzero(np.isfinite(pts[f]).all(axis=1))[0][0])
        edited[f, k] += (2.0, -1.0)
        hit = next(i for i, p in enumerate(before.pieces) if p.first_frame <= f <= p.last_frame)
        reach = trajectory_module.REFIT_REACH
        run = before.pieces[max(hit - reach, 0):hit + reach + 1]
        a, b = refit_span(before.pieces, f, f)
        assert refit_span(run, f, f) == (a, b) and local_span(run, f, f) == local_span(before.pieces, f, f)
        whole = refit_window(before.window(a, b), edited[a:b + 1], CAMERAS, [1920] * 4, f, f, tau_px=20.0,
                             rule="max_scaled_1920", min_baseline_m=1.0, min_parallax_deg=0.0)
        part = before.window(a, b)
        part = trajectory_module.TrajectoryFit(part.fps, tuple(run), part.positions, part.sources, part.residuals_px,
                                               part.outliers, part.ball_3d, part.cam_lists, first_frame=a)
        ran = refit_window(part, edited[a:b + 1], CAMERAS, [1920] * 4, f, f, tau_px=20.0, rule="max_scaled_1920",
                           min_baseline_m=1.0, min_parallax_deg=0.0)
        assert [(p.kind, p.first_frame, p.last_frame) for p in ran.pieces] == \
            [(p.kind, p.first_frame, p.last_frame) for p in whole.pieces if p.last_frame >= run[0].first_frame
             and p.first_frame <= run[-1].last_frame]
        np.testing.assert_array_equal(ran.positions, whole.positions)
        assert ran.cam_lists == whole.cam_lists and np.array_equal(ran.outliers, whole.outliers)


def test_linear_fits_of_many_sets_equal_those_of_each_alone(scene):
    """The segmentation fits a break's candidate cuts together: a set's result is the same, bit for bit,
    whatever it is fitted with (its own normal equations, its own rows)."""
    from app.geometry import motion

    truth, pts = scene
    _, use = fit_module._check_inputs(pts, CAMERAS, [1920] * 4, FPS)
    L = motion.LabelTable(pts, CAMERAS, [1920] * 4, use)
    by_frame = segmentation_module._group(L)
    frames = sorted(by_frame)
    jobs = []
    for a, b in ((0, 40), (45, 60), (90, 100), (98, 99), (120, 149)):
        idx = np.concatenate([by_frame[f] for f in frames if a <= f <= b])
        jobs += [(idx, kind, a) for kind in motion.KINDS]
    together = motion.linear_fits(L, jobs, FPS)
    for job, (q, cost) in zip(jobs, together, strict=False):
        alone_q, alone_cost = motion.linear_fits(L, [job], FPS)[0]
        assert np.array_equal(q, alone_q) and cost == alone_cost
        assert np.all(np.isfinite(q)) and cost >= 0


def _residuals(q, sub, kind, t):
    from app.geometry import motion
    return motion.residuals_and_jacobian(sub, kind, q, t, False)[0]


def _jacobian(q, sub, kind, t):
    from app.geometry import motion
    return motion.residuals_and_jacobian(sub, kind, q, t)[1]


def _cost(q, sub, kind, t):
    from app.geometry import motion
    return motion._loss(_residuals(q, sub, kind, t))


def test_refinement_reaches_the_minimum_scipy_finds(scene):
    """``motion.refine`` minimises the function ``scipy.optimize.least_squares(loss="cauchy", f_scale=3)``
    minimises: from the same start it ends at a cost no higher (TRF stops at a relative change of 1e-8)
    and at the same place, for the model that fits and for the one that does not."""
    from scipy.optimize import least_squares

    from app.geometry import motion

    truth, pts = scene
    before = fit(pts)
    _, use = fit_module._check_inputs(pts, CAMERAS, [1920] * 4, FPS)
    L = motion.LabelTable(pts, CAMERAS, [1920] * 4, use)
    for piece in before.pieces[:3]:
        sub = L.take(np.nonzero((L.frame >= piece.first_frame) & (L.frame <= piece.last_frame))[0])
        t = (sub.frame - piece.first_frame) / FPS
        for kind in motion.KINDS:
            start = motion.linear_fits(sub, [(np.arange(len(t)), kind, piece.first_frame)], FPS)[0][0]
            ours = motion.refine(sub, kind, start, t)
            theirs = least_squares(_residuals, start, jac=_jacobian, args=(sub, kind, t), loss="cauchy",
                                   f_scale=motion.CAUCHY_PX, x_scale="jac").x
            assert _cost(ours, sub, kind, t) <= _cost(theirs, sub, kind, t) * (1 + 1e-8)
            if kind == piece.kind:  # the model the piece has: one well-defined minimum
                assert np.abs(motion.positions(kind, ours, t) - motion.positions(kind, theirs, t)).max() < 1e-4


def test_shifted_params_describe_the_same_motion_and_few_labels_do_not_determine_a_flight(scene):
    from app.geometry import motion

    t = np.linspace(0.0, 1.0, 11)
    flight = np.array([1.0, 2.0, -3.0, 4.0, -1.0, -6.0])
    roll = np.array([1.0, 2.0, 5.0, 1.0, -2.5, -0.5])  # stops at 2 s
    for kind, q in (("flight", flight), ("roll", roll)):
        moved = motion.shifted(kind, q, 0.4)
        np.testing.assert_allclose(motion.positions(kind, moved, t - 0.4)[4:], motion.positions(kind, q, t)[4:],
                                   atol=1e-12)
    truth, pts = scene
    _, use = fit_module._check_inputs(pts, CAMERAS, [1920] * 4, FPS)
    L = motion.LabelTable(pts, CAMERAS, [1920] * 4, use)
    two_frames_one_camera = L.take(np.nonzero((L.frame <= 1) & (L.cam == L.cam[0]))[0])
    many = L.take(np.nonzero(L.frame <= 30)[0])
    q = motion.linear_fits(many, [(np.arange(len(many.frame)), "flight", 0)], FPS)[0][0]
    assert motion.determined(many, "flight", q, many.frame / FPS)
    assert not motion.determined(two_frames_one_camera, "flight", q, two_frames_one_camera.frame / FPS)


def test_plausible_refuses_motions_no_ball_makes():
    """motion.plausible: a kicked flight and a decelerating roll pass; too fast, under the grass, far off the
    pitch, too high or stopping too hard do not (the pieces a wrong label at a break fits)."""
    from app.geometry.motion import plausible

    assert plausible("flight", np.array([0, 0, -0.11, 10, 5, -12]), 2.0)  # a lob that lands 2.4 s later
    assert plausible("roll", np.array([10, -5, 8, 1, -1.5, -0.2]), 3.0)
    assert not plausible("flight", np.array([0, 0, -0.11, 700, 0, 0]), 0.08)  # 700 m/s: a label 28 m off in 1 frame
    assert not plausible("flight", np.array([0, 0, -0.11, 10, 0, 5]), 1.0)  # ends 9.8 m under the grass
    assert not plausible("flight", np.array([36.8, -52.6, -6.7, 1, 1, 0]), 0.1)  # 18.6 m beyond the touch line
    assert not plausible("flight", np.array([0, 0, -0.11, 0, 0, -30]), 6.0)  # 46 m up
    assert not plausible("roll", np.array([0, 0, 5, 0, -40, 0]), 0.1)  # 40 m/s^2 on grass
    assert not plausible("roll", np.array([0, 0, np.nan, 0, 0, 0]), 0.1)


def test_a_wrong_label_at_a_kick_is_left_out_not_fitted_by_a_short_piece(scene):
    """A wrong label of the first frame after a kick, its frame's other labels missing: the segmentation
    fits it with a short piece of its own only if it is allowed to; with the plausibility rule the short
    piece goes, the frames between the pieces are crossed by the Hermite curve and the label is flagged."""
    truth, pts = scene
    pts = pts.copy()
    kick = int(np.ceil(2.02 * FPS))  # first frame after the lofted kick
    pts[kick, 1:] = np.nan
    pts[kick, 0] = pts[kick, 0] + np.array([400.0, -250.0])
    fit = fit_trajectory(pts, CAMERAS, [1920.0] * 4, FPS, tau_px=20.0, rule="max_scaled_1920", min_baseline_m=1.0,
                         min_parallax_deg=0.0)
    assert fit.outliers[kick, 0] and 0 not in fit.cam_lists[kick]
    for p in fit.pieces:
        assert p.last_frame - p.first_frame + 1 >= 4 or len(fit.pieces) == 1
    err = np.linalg.norm(fit.positions - truth, axis=1)
    assert np.nanmedian(err) < 0.05 and err[kick] < 1.0


def test_a_flight_seen_by_one_camera_is_tied_to_its_neighbours(scene, monkeypatch):
    """One camera alone sees the lob from the kick to the bounce: its labels fix the ball's direction, the
    depth only through gravity; tied at its ends to the roll before and the flight after (the ball does not
    jump), the flight stays nearer the truth than the untied fit of the same labels."""
    truth, pts = scene
    pts = pts.copy()
    one = slice(51, 97)  # the lofted kick acts between frames 50 and 51, the bounce between 96 and 97
    pts[one, [0, 2, 3]] = np.nan
    def err(f):
        return np.linalg.norm(f.positions[one] - truth[one], axis=1).max()
    tied = fit_trajectory(pts, CAMERAS, [1920.0] * 4, FPS, tau_px=20.0, rule="max_scaled_1920", min_baseline_m=1.0,
                          min_parallax_deg=0.0)
    for module in (segmentation_module, refit_module):
        monkeypatch.setattr(module, "_anchored", lambda L, by_frame, fps, pieces, which: list(pieces))
    untied = fit_trajectory(pts, CAMERAS, [1920.0] * 4, FPS, tau_px=20.0, rule="max_scaled_1920", min_baseline_m=1.0,
                            min_parallax_deg=0.0)
    assert err(tied) < 0.15 and err(tied) < err(untied) / 2, (err(tied), err(untied))
    assert all(k == (1,) for k in tied.cam_lists[one])
