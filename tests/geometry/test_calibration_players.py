"""Cameras from players' foot points (``app.geometry.calibration.grass``, ``players``, ``player_problem``): synthetic
cameras of known truth."""
from __future__ import annotations

import numpy as np

from app.geometry.annotations import mirror_lines
from app.geometry.calibration.grass import (
    HEAD_HEIGHT_M,
    HEAD_OFFSET_M,
    foot_pixel,
    foot_world,
    grass_point,
    grass_points,
    head_pixel,
    head_world,
    players_on_grass,
)
from app.geometry.calibration.player_problem import PlayerProblem
from app.geometry.calibration.players import (
    LINES_CONTRADICTED_SIGMA,
    PlayerFit,
    PlayerFitSettings,
    PlayerRefusal,
    fit_camera_to_players,
    pair_players_disagreement,
    players_disagreement,
    row_medians,
)
from app.geometry.calibration.residuals import CameraParametrisation
from app.geometry.camera import Camera, look_at_rotation
from app.geometry.mirror import mirror_camera
from tests.geometry.synthetic import visible_model_points

W, H = 1920, 1080
PP = ((W - 1) / 2, (H - 1) / 2)
#: Where the truth's camera stands (high behind the left goal) and a rig with two other positions.
CENTRE = np.array([-70.0, 5.0, -18.0])
RIG = [(0.0, 60.0, -14.0), (-70.0, 5.0, -18.0), (70.0, -5.0, -18.0)]


def camera_at(centre: np.ndarray, target: tuple[float, float, float], focal: float) -> Camera:
    R = look_at_rotation(np.asarray(centre, float), np.asarray(target, float))
    K = np.array([[focal, 0, PP[0]], [0, focal, PP[1]], [0, 0, 1.0]])
    return Camera(K=K, R=R, C=np.asarray(centre, float), radial=np.zeros(6))


def players(n: int, rng: np.random.Generator, centre=(-35.0, 0.0), spread=12.0) -> dict[tuple[str, str], np.ndarray]:
    pts = np.asarray(centre) + rng.uniform(-spread, spread, size=(n, 2))
    return {("Player team left", str(i)): p for i, p in enumerate(pts)}


def feet_in(camera: Camera, grass: dict, noise_px: float = 0.0, rng: np.random.Generator | None = None) -> dict:
    keys = list(grass)
    world = foot_world(np.array([grass[k] for k in keys]), camera.C)  # the boxes' bottom edges: their near side
    uv, ok = camera.project(world)
    assert ok.all()
    if noise_px:
        assert rng is not None
        uv = uv + rng.normal(0, noise_px, uv.shape)
    return {k: uv[i] for i, k in enumerate(keys)}


def as_grass(points: dict) -> dict:
    """Where the players stand as two well-lined views of their system see them (the main camera, a replay)."""
    anchors = [camera_at(np.array([0.0, 60.0, -14.0]), (-35.0, 0.0, 0.0), 1800.0),
               camera_at(np.array([-20.0, 45.0, -10.0]), (-35.0, 0.0, 0.0), 2400.0)]
    return players_on_grass([(a, feet_in(a, points)) for a in anchors])


def ball_error(fit: PlayerFit, truth: Camera) -> float:
    ball = np.array([[-33.0, 3.0, -1.5]])
    return float(np.linalg.norm(fit.camera.project(ball)[0][0] - truth.project(ball)[0][0]))


def test_foot_point_is_the_bottom_centre_and_a_cut_box_has_none() -> None:
    assert foot_pixel((10, 20, 30, 80), W, H).tolist() == [20.0, 80.0]
    assert foot_pixel((10, 20, 30, H - 1), W, H) is None  # feet cut off
    assert foot_pixel((0, 20, 30, 80), W, H) is None  # half a player: its centre moved


def test_a_foot_point_goes_back_to_where_the_player_stands() -> None:
    cam = camera_at(CENTRE, (-35.0, 0.0, 0.0), 2500.0)
    uv, _ = cam.project(foot_world(np.array([[-30.0, 4.0]]), cam.C))
    assert np.allclose(grass_point(cam, uv[0]), [-30.0, 4.0], atol=1e-6)


def test_a_view_s_foot_points_go_back_together_as_one_by_one() -> None:
    """The batched back-projection (one per view, as ``players_on_grass`` does it) is the single one's, a pixel above
    the horizon (no ground ahead) NaN where the single one says None."""
    cam = camera_at(CENTRE, (-35.0, 0.0, 0.0), 2500.0)
    pixels = np.array([[900.0, 700.0], [100.0, 1000.0], [1800.0, 600.0], [960.0, -4000.0]])
    together = grass_points(cam, pixels)
    for uv, got in zip(pixels[:3], together[:3], strict=True):
        assert np.array_equal(got, grass_point(cam, uv))
    assert grass_point(cam, pixels[3]) is None and np.isnan(together[3]).all()


def _fused_one_by_one(views: list, max_spread_m: float = 1.5) -> dict:
    """``players_on_grass`` as it was written before a view's players were fused at once: each player's ground
    Jacobian, covariance and information made alone."""
    from app.geometry.calibration.grass import FOOT_OFFSET_SIGMA_M, FOOT_SIGMA_PX, PITCH_LENGTH_M, PITCH_WIDTH_M
    from app.geometry.pair_error import REFERENCE_WIDTH_PX

    seen: dict = {}
    for camera, feet in views:
        sigma = FOOT_SIGMA_PX * float(camera.K[0, 2] * 2 + 1) / REFERENCE_WIDTH_PX
        keys = list(feet)
        uv = np.array([np.asarray(feet[k], float) for k in keys])
        g = grass_points(camera, np.concatenate([uv, uv + [0.5, 0.0], uv + [0.0, 0.5]])).reshape(3, len(keys), 2)
        for key, p, px, py in zip(keys, g[0], g[1], g[2], strict=True):
            if np.isnan(p[0]) or np.isnan(px[0]) or np.isnan(py[0]):
                continue
            J = np.column_stack([(px - p) / 0.5, (py - p) / 0.5])
            seen.setdefault(key, []).append((p, sigma**2 * J @ J.T + FOOT_OFFSET_SIGMA_M**2 * np.eye(2)))
    out = {}
    for key, points in seen.items():
        P = np.array([p for p, _ in points])
        info = [np.linalg.inv(c) for _, c in points]
        cov = np.linalg.inv(sum(info))
        centre = cov @ sum(i @ p for i, (p, _) in zip(info, points, strict=True))
        spread = float(np.max(np.linalg.norm(P - centre, axis=1)))
        if (len(points) > 1 and spread > max_spread_m) or abs(centre[0]) > PITCH_LENGTH_M / 2 + 5.0 \
                or abs(centre[1]) > PITCH_WIDTH_M / 2 + 5.0:
            continue
        out[key] = (tuple(centre.tolist()), len(points), spread, cov.tolist())
    return out


def test_a_view_s_players_fused_at_once_are_the_one_by_one_fusion_to_the_bit() -> None:
    """Where the players stand is the fusion of each player alone, to the last bit: three views (one whose pixel of a
    player lies above the horizon, one player seen by one view only, one whose views disagree: left out)."""
    rng = np.random.default_rng(8)
    pts = players(9, rng)
    views = [camera_at(np.array([0.0, 60.0, -14.0]), (-35.0, 0.0, 0.0), 1800.0),
             camera_at(np.array([-20.0, 45.0, -10.0]), (-35.0, 0.0, 0.0), 2400.0), camera_at(CENTRE, (-35.0, 2.0, 0.0),
                                                                                            2600.0)]
    seen = [feet_in(cam, pts, 1.0, rng) for cam in views]
    seen[0][("Player team left", "0")] = np.array([960.0, -4000.0])  # no ground ahead in this view
    del seen[1][("Player team left", "1")], seen[2][("Player team left", "1")]  # one view only
    seen[2][("Player team left", "2")] = seen[2][("Player team left", "2")] + [300.0, 0.0]  # views disagree
    got = players_on_grass(list(zip(views, seen, strict=True)))
    want = _fused_one_by_one(list(zip(views, seen, strict=True)))
    assert ("Player team left", "2") not in got and got.keys() == want.keys() and len(got) == 8
    for key, player in got.items():
        assert (player.point_m, player.views, player.spread_m, [list(r) for r in player.cov_m2]) == want[key]


def test_the_starts_row_medians_are_numpy_s_to_the_bit() -> None:
    """The rig starts rank their focal hypotheses by median error: ``row_medians`` gives numpy's median of each row,
    to the bit, for odd and even rows, ties, and a row with NaN."""
    rng = np.random.default_rng(2)
    for m in (1, 2, 7, 12, 31):
        d = rng.lognormal(3.0, 2.0, (20, m))
        d[3] = d[3, 0]  # a row of ties
        assert np.array_equal(row_medians(d), np.median(d, axis=1))
        d[5, 0] = np.nan
        assert np.array_equal(row_medians(d), np.median(d, axis=1), equal_nan=True)


def test_rewhitening_from_the_parts_made_once_is_the_whitening_made_anew() -> None:
    """``rewhiten`` reads the grass points' neighbours and covariances made once when the problem is made: its
    whitening at any camera, and again at another, is the one made from scratch, to the bit."""
    from app.geometry.calibration.grass import FOOT_SIGMA_PX, HEAD_SIGMA_M
    from app.geometry.calibration.player_problem import project_points

    rng = np.random.default_rng(6)
    truth, g, uv, foot_of, head_of, uv_head = _seven_players(rng)
    cov_g = np.repeat(np.eye(2)[None] * 0.02, 7, 0) * np.arange(1, 8)[:, None, None]
    problem = PlayerProblem(uv=uv, world=np.column_stack([g, np.zeros(7)]),
                            lines={}, pp=np.asarray(PP), width=W, height=H, scale=1.0, cov_g=cov_g,
                            uv_head=uv_head, head_of=head_of, foot_of=foot_of)
    assert problem.head_alone().tolist() == [False, False, False, True]
    sigma = FOOT_SIGMA_PX

    def from_scratch(x: np.ndarray, param: CameraParametrisation) -> tuple[np.ndarray, np.ndarray]:
        f_arr, R, C_arr, _ = param.split(x)
        f, C = float(f_arr), np.asarray(C_arr, float)
        gf, gh = g[foot_of], g[head_of]
        dx, dy = np.array([0.01, 0.0]), np.array([0.0, 0.01])
        heads = head_world(np.concatenate([gh, gh + dx, gh + dy]), C)
        up = heads[:4].copy()
        up[:, 2] = -(HEAD_HEIGHT_M + 0.01)
        feet_w = foot_world(np.concatenate([gf, gf + dx, gf + dy]), C)
        uv = project_points(f, R, C, np.asarray(PP), np.concatenate([feet_w, heads, up]))
        fu, hu = uv[:15].reshape(3, 5, 2), uv[15:].reshape(4, 4, 2)
        J = np.stack([(fu[1] - fu[0]) / 0.01, (fu[2] - fu[0]) / 0.01], axis=-1)
        L = np.linalg.inv(np.linalg.cholesky(np.einsum("nij,njk,nlk->nil", J, cov_g[foot_of], J)
                                             + sigma**2 * np.eye(2)))
        Jh = np.stack([(hu[k] - hu[0]) / 0.01 for k in (1, 2, 3)], axis=-1)
        cov_p = np.zeros((4, 3, 3))
        cov_p[:, :2, :2] = cov_g[head_of]
        cov_p[:, 2, 2] = HEAD_SIGMA_M**2
        return L, np.linalg.inv(np.linalg.cholesky(np.einsum("nij,njk,nlk->nil", Jh, cov_p, Jh) + sigma**2 * np.eye(2)))

    for param, x in ((CameraParametrisation(principal_point=np.asarray(PP), R0=truth.R, fixed_centre=CENTRE),
                      np.array([2500.0, 0.01, -0.02, 0.005])),
                     (CameraParametrisation(principal_point=np.asarray(PP), R0=truth.R),
                      np.array([2600.0, -0.01, 0.02, 0.0, -68.0, 6.0, -17.0]))):
        problem.rewhiten(x, param)
        L, L_head = from_scratch(x, param)
        assert np.array_equal(problem.L, L) and np.array_equal(problem.L_head, L_head)


def test_a_rig_position_s_residuals_are_the_free_pose_s_at_that_centre() -> None:
    """At a rig position the foot points' world points are made once per centre: the residuals equal those of the
    full pose (which makes them anew at every vector) at the same camera."""
    rng = np.random.default_rng(3)
    truth = camera_at(CENTRE, (-35.0, 2.0, 0.0), 2600.0)
    pts = players(6, rng)
    feet = feet_in(truth, pts, 1.5, rng)
    keys = list(pts)
    problem = PlayerProblem(uv=np.array([feet[k] for k in keys]), world=np.array([[*pts[k], 0.0] for k in keys]),
                            lines={}, pp=np.asarray(PP), width=W, height=H, scale=1.0,
                            cov_g=np.repeat(np.eye(2)[None] * 0.01, 6, 0))
    rig = CameraParametrisation(principal_point=np.asarray(PP), R0=truth.R, fixed_centre=CENTRE)
    free = CameraParametrisation(principal_point=np.asarray(PP), R0=truth.R)
    X = np.array([[2600.0, 0.0, 0.0, 0.0], [2500.0, 0.01, -0.02, 0.005]])
    for _ in range(2):  # the second time from the centre's stored points
        at_rig = problem.rows_batch(X, rig)
        assert np.allclose(at_rig, problem.rows_batch(np.column_stack([X, np.tile(CENTRE, (2, 1))]), free),
                           rtol=1e-9, atol=1e-9)
    assert np.allclose(problem.jacobian(X[1], rig)[0], at_rig[1], rtol=0, atol=0)


def _seven_players(rng: np.random.Generator) -> tuple:
    """A rig-position camera and seven players around the play (1.5 px of noise): the camera, their grass points
    (7, 2) m, the foot pixels of the first five, which players show their heads (the last two have their feet cut:
    one with its head, one without) and those head pixels (4, 2)."""
    truth = camera_at(CENTRE, (-35.0, 2.0, 0.0), 2600.0)
    pts = players(7, rng)
    feet = feet_in(truth, pts, 1.5, rng)
    keys = list(pts)
    g = np.array([pts[k] for k in keys])
    foot_of, head_of = np.arange(5), np.array([0, 2, 3, 6])
    uv_head = truth.project(head_world(g[head_of], truth.C))[0] + rng.normal(0, 1.5, (4, 2))
    return truth, g, np.array([feet[keys[i]] for i in foot_of]), foot_of, head_of, uv_head


def test_the_compiled_rows_are_the_camera_s_projections_of_the_feet_and_heads_whitened() -> None:
    """The players' rows (one compiled call for a batch of vectors) are, per vector, the camera's projections of the
    foot and head points' world points (``foot_world``, ``head_world`` from its centre) less their pixels, whitened
    by each point's 2x2 whitening, in the order feet, lines, heads: at a rig position and for a full pose; a player
    whose feet are cut has a head row only (here the last two players: one with its head, one without)."""
    rng = np.random.default_rng(5)
    truth, g, uv, foot_of, head_of, uv_head = _seven_players(rng)
    lines = visible_model_points(truth, W, H, rng, per_class=6)
    problem = PlayerProblem(uv=uv, world=np.column_stack([g, np.zeros(7)]),
                            lines=lines, pp=np.asarray(PP), width=W, height=H, scale=1.0,
                            cov_g=np.repeat(np.eye(2)[None] * 0.02, 7, 0) * np.arange(1, 8)[:, None, None],
                            uv_head=uv_head, head_of=head_of, foot_of=foot_of)
    assert problem.obs is not None  # the lines' rows sit between the feet's and the heads'
    assert problem.head_alone().tolist() == [False, False, False, True]
    for param, X in ((CameraParametrisation(principal_point=np.asarray(PP), R0=truth.R, fixed_centre=CENTRE),
                      np.array([[2600.0, 0.0, 0.0, 0.0], [2500.0, 0.01, -0.02, 0.005]])),
                     (CameraParametrisation(principal_point=np.asarray(PP), R0=truth.R),
                      np.array([[2600.0, 0.0, 0.0, 0.0, *CENTRE], [2500.0, 0.01, -0.02, 0.005, -68.0, 6.0, -17.0]]))):
        problem.rewhiten(X[1], param)
        L = np.concatenate([problem.L, problem.L_head])
        assert L.shape == (9, 2, 2) and not np.allclose(L, L[:1])  # each point's own whitening
        for whiten in (True, False):
            rows = problem.rows_batch(X, param, whiten)
            for b in range(2):
                cam = param.camera(X[b])
                world = np.vstack([foot_world(g[foot_of], cam.C), head_world(g[head_of], cam.C)])
                d = cam.project(world)[0] - np.vstack([problem.uv, uv_head])
                want = np.einsum("nij,nj->ni", L, d) if whiten else d
                got = np.vstack([rows[b, :10].reshape(-1, 2), rows[b, -8:].reshape(-1, 2)])
                assert np.allclose(got, want, rtol=1e-9, atol=1e-7)


def test_a_rig_position_camera_is_recovered_to_sub_pixel_from_noise_free_players() -> None:
    rng = np.random.default_rng(1)
    truth = camera_at(CENTRE, (-35.0, 2.0, 0.0), 2600.0)
    pts = players(6, rng)
    fit = fit_camera_to_players(feet_in(truth, pts), as_grass(pts), {}, W, H, RIG)
    assert isinstance(fit, PlayerFit), fit
    assert fit.rig_index == 1
    assert ball_error(fit, truth) < 0.5
    assert abs(fit.camera.K[0, 0] - 2600.0) < 2.0
    assert fit.uncertainty.position_m == (0.0, 0.0, 0.0)  # the centre was the rig's
    assert len(fit.players) == 6


def test_one_pixel_of_noise_keeps_the_camera_within_a_few_pixels_and_its_uncertainty_says_so() -> None:
    errors, sigmas = [], []
    for seed in range(10):
        rng = np.random.default_rng(100 + seed)
        truth = camera_at(CENTRE, (-35.0, 2.0, 0.0), 2600.0)
        pts = players(6, rng)
        fit = fit_camera_to_players(feet_in(truth, pts, 1.0, rng), as_grass(pts), {}, W, H, RIG)
        assert isinstance(fit, PlayerFit), fit
        errors.append(ball_error(fit, truth))
        sigmas.append(fit.sigma_px)
    assert max(errors) < 5.0
    assert 0.1 < np.median(sigmas) < 8.0  # the fit knows it is not exact


def test_a_camera_away_from_every_rig_position_gets_a_full_pose_from_enough_players() -> None:
    rng = np.random.default_rng(7)
    truth = camera_at(np.array([-40.0, -45.0, -9.0]), (-35.0, 0.0, 0.0), 1800.0)
    pts = players(10, rng)
    fit = fit_camera_to_players(feet_in(truth, pts), as_grass(pts), {}, W, H, [RIG[0], RIG[2]])
    assert isinstance(fit, PlayerFit), fit
    assert fit.rig_index is None
    assert ball_error(fit, truth) < 1.0


def test_too_few_or_collinear_players_are_refused() -> None:
    rng = np.random.default_rng(3)
    truth = camera_at(CENTRE, (-35.0, 2.0, 0.0), 2600.0)
    pts = players(2, rng)
    got = fit_camera_to_players(feet_in(truth, pts), as_grass(pts), {}, W, H, RIG)
    assert isinstance(got, PlayerRefusal) and got.code == "few_players"
    line = {("Player team left", str(i)): np.array([-40.0 + 3 * i, -0.5 + 0.0 * i]) for i in range(6)}
    # on one image row: players on a line through the camera's foot along its view... any collinear set
    feet = {k: np.array([300.0 + 200 * i, 600.0]) for i, k in enumerate(line)}
    got = fit_camera_to_players(feet, as_grass(line), {}, W, H, RIG)
    assert isinstance(got, PlayerRefusal) and got.code == "collinear_players"


def test_foot_points_no_camera_fits_are_refused() -> None:
    rng = np.random.default_rng(5)
    pts = players(6, rng)
    feet = {k: rng.uniform([0, 0], [W, H]) for k in pts}  # boxes that are nobody's
    got = fit_camera_to_players(feet, as_grass(pts), {}, W, H, RIG)
    assert isinstance(got, PlayerRefusal)


def test_a_wrong_id_is_left_out_of_where_players_stand() -> None:
    a = camera_at(np.array([0.0, 60.0, -14.0]), (-35.0, 0.0, 0.0), 1400.0)
    b = camera_at(np.array([-70.0, 5.0, -18.0]), (-35.0, 0.0, 0.0), 2000.0)
    pts = {("p", "1"): np.array([-30.0, 2.0]), ("p", "2"): np.array([-36.0, -4.0])}
    fa, fb = feet_in(a, pts), feet_in(b, pts)
    fb[("p", "2")] = fb[("p", "1")] + 40.0  # the second box in view b is someone else's
    grass = players_on_grass([(a, fa), (b, fb)])
    assert set(grass) == {("p", "1")}
    assert grass[("p", "1")].views == 2
    assert np.allclose(grass[("p", "1")].point_m, [-30.0, 2.0], atol=1e-6)


def test_lines_join_the_fit_with_their_residuals() -> None:
    rng = np.random.default_rng(11)
    truth = camera_at(CENTRE, (-35.0, 2.0, 0.0), 2600.0)
    lines = visible_model_points(truth, W, H, rng, noise_px=1.0)
    assert lines
    pts = players(4, rng)
    fit = fit_camera_to_players(feet_in(truth, pts, 1.0, rng), as_grass(pts), lines, W, H, RIG)
    assert isinstance(fit, PlayerFit), fit
    assert set(fit.residuals_px) == set(lines)
    assert max(fit.residuals_px.values()) < 6.0
    assert ball_error(fit, truth) < 3.0


def heads_in(camera: Camera, grass: dict, noise_px: float = 0.0, rng: np.random.Generator | None = None) -> dict:
    keys = list(grass)
    uv, ok = camera.project(head_world(np.array([grass[k] for k in keys]), camera.C))
    assert ok.all()
    if noise_px:
        assert rng is not None
        uv = uv + rng.normal(0, noise_px, uv.shape)
    return {k: uv[i] for i, k in enumerate(keys)}


def test_head_point_is_the_top_centre_of_a_box_whose_top_and_sides_are_in_the_image() -> None:
    assert head_pixel((10, 20, 30, 80), W, H).tolist() == [20.0, 20.0]
    assert head_pixel((10, 0, 30, 80), W, H) is None  # head cut off
    assert head_pixel((10, 20, 30, H - 1), W, H).tolist() == [20.0, 20.0]  # feet cut off: the head is still seen
    assert head_pixel((0, 20, 30, 80), W, H) is None  # half of the player cut off: the centre moves
    up = head_world(np.array([[10.0, 0.0]]), np.array([-50.0, 0.0, -10.0]))[0]
    assert np.allclose(up, [10.0 + HEAD_OFFSET_M, 0.0, -HEAD_HEIGHT_M])  # beyond the player, away from the camera


def test_heads_pin_the_zoom_that_players_close_together_leave_loose() -> None:
    """Players standing close together fix the camera's direction but hardly its focal length: their boxes' heights
    (the head points) do. With 1.5 px of noise on every box point, the heads make the fit's own uncertainty smaller and
    keep the ball within a few pixels; a fit without heads is the feet-only fit."""
    with_heads, without = [], []
    for seed in range(8):
        rng = np.random.default_rng(300 + seed)
        truth = camera_at(CENTRE, (-35.0, 2.0, 0.0), 4000.0)
        pts = players(4, rng, spread=3.0)
        grass = as_grass(pts)
        feet = feet_in(truth, pts, 1.5, rng)
        heads = heads_in(truth, pts, 1.5, rng)
        settings = PlayerFitSettings(max_sigma_px=1e9)  # the uncertainties compared, not gated
        a = fit_camera_to_players(feet, grass, {}, W, H, RIG, settings, heads=heads)
        b = fit_camera_to_players(feet, grass, {}, W, H, RIG, settings)
        assert isinstance(a, PlayerFit) and isinstance(b, PlayerFit), (a, b)
        assert a.rig_index == b.rig_index == 1 and a.head_only == b.head_only == frozenset()  # every foot seen
        c = fit_camera_to_players(feet, grass, {}, W, H, RIG, settings, heads={})
        assert isinstance(c, PlayerFit) and np.array_equal(c.camera.K, b.camera.K) and c.sigma_px == b.sigma_px
        with_heads.append((a.sigma_px, ball_error(a, truth)))
        without.append((b.sigma_px, ball_error(b, truth)))
    assert np.median([s for s, _ in with_heads]) < 0.7 * np.median([s for s, _ in without])
    assert max(e for _, e in with_heads) < 6.0


def test_players_whose_feet_the_image_cuts_place_a_close_view_by_their_heads() -> None:
    """A close view shows players without their feet (every box cut by the bottom edge): no foot point, but their head
    points, the players' grass points from the well-lined views and a rig position fix the camera. 1 px of noise."""
    for seed in range(4):
        rng = np.random.default_rng(500 + seed)
        truth = camera_at(CENTRE, (-35.0, 2.0, -1.0), 3500.0)
        pts = players(6, rng, spread=6.0)
        grass = as_grass(pts)
        heads = heads_in(truth, pts, 1.0, rng)
        boxes = [("Player team left", k[1], (uv[0] - 20, uv[1], uv[0] + 20, H - 1)) for k, uv in heads.items()]
        assert all(foot_pixel(b, W, H) is None for _, _, b in boxes)
        seen = {("Player team left", i): head_pixel(b, W, H) for _, i, b in boxes}
        fit = fit_camera_to_players({}, grass, {}, W, H, RIG, heads=seen)
        assert isinstance(fit, PlayerFit), fit
        assert fit.rig_index == 1 and len(fit.players) == 6
        assert ball_error(fit, truth) < 6.0
        # each player's pixel is its head point, and the fit says so (the page draws it as a head, not a foot)
        assert fit.head_only == {k for k, _, _ in fit.players}
        assert all(np.allclose(uv, seen[k]) for k, uv, _ in fit.players)
        assert fit_camera_to_players({}, grass, {}, W, H, RIG) == PlayerRefusal("few_players",
                                                                               {"players": 0, "need": 3})


def test_players_at_a_rig_position_leave_out_lines_they_cannot_be_fitted_with() -> None:
    """A view whose few lines (at most 3 classes) are labelled wrong, and not merely mirrored (the goal area's main
    line named the penalty area's), cannot be fitted with its players, as labelled or mirrored: the players alone, at
    the rig position, give the camera (no line residuals: the lines are left out)."""
    for seed in range(3):
        rng = np.random.default_rng(20 + seed)
        truth = camera_at(CENTRE, (-35.0, 2.0, 0.0), 2600.0)
        lines = visible_model_points(truth, W, H, rng, classes=("Big rect. left main", "Small rect. left main"),
                                     noise_px=1.0)
        wrong = {"Big rect. left main": lines["Small rect. left main"],
                 "Small rect. left main": lines["Big rect. left main"]}
        pts = players(6, rng)
        feet = feet_in(truth, pts, 1.0, rng)
        fit = fit_camera_to_players(feet, as_grass(pts), wrong, W, H, RIG)
        assert isinstance(fit, PlayerFit), fit
        assert fit.rig_index == 1 and fit.residuals_px == {} and fit.line_rms_px is None and not fit.lines_mirrored
        assert ball_error(fit, truth) < 3.0
        right = fit_camera_to_players(feet, as_grass(pts), lines, W, H, RIG)
        assert isinstance(right, PlayerFit) and set(right.residuals_px) == set(lines)  # right lines stay in the fit
        assert not right.lines_mirrored
    # A view with 4 or more classes so labelled keeps its refusal: its lines alone say they are wrong.
    every = visible_model_points(truth, W, H, rng, noise_px=1.0)
    assert len(every) >= 4
    names = sorted(every)
    shuffled = {names[(i + 1) % len(names)]: every[c] for i, c in enumerate(names)}
    got = fit_camera_to_players(feet, as_grass(pts), shuffled, W, H, RIG)
    assert isinstance(got, PlayerRefusal) and got.code == "players_misfit"


def test_mirrored_lines_fit_the_players_camera_mirrored_and_say_so() -> None:
    """A view whose lines are labelled left for right (the pitch's 180-degree ambiguity, ``mirror_lines``) is fitted
    with its lines mirrored: the players' camera is the true one, its lines in the fit (each labelled class's distance
    to its mirror class's element), and the fit says the labels are mirrored; with 2 classes or with every class the
    view shows alike. Lines labelled right are never called mirrored."""
    rng = np.random.default_rng(31)
    truth = camera_at(CENTRE, (-35.0, 2.0, 0.0), 2600.0)
    pts = players(6, rng)
    feet = feet_in(truth, pts, 1.0, rng)
    few = visible_model_points(truth, W, H, rng, classes=("Big rect. left main", "Small rect. left main"),
                               noise_px=1.0)
    every = visible_model_points(truth, W, H, rng, noise_px=1.0)
    assert len(every) >= 4
    for lines in (few, every):
        labelled = mirror_lines(lines)  # the annotator's slip
        fit = fit_camera_to_players(feet, as_grass(pts), labelled, W, H, RIG)
        assert isinstance(fit, PlayerFit), fit
        assert fit.lines_mirrored and fit.rig_index == 1
        assert set(fit.residuals_px) == set(labelled) and max(fit.residuals_px.values()) < 5.0
        assert ball_error(fit, truth) < 3.0
        right = fit_camera_to_players(feet, as_grass(pts), lines, W, H, RIG)
        assert isinstance(right, PlayerFit) and not right.lines_mirrored and set(right.residuals_px) == set(lines)


def test_players_disagree_with_a_wrong_camera_not_with_the_true_one() -> None:
    rng = np.random.default_rng(41)
    truth = camera_at(CENTRE, (-35.0, 2.0, 0.0), 2600.0)
    pts = players(8, rng)
    grass = as_grass(pts)
    feet = feet_in(truth, pts, 1.0, rng)
    assert players_disagreement(truth, feet, grass, W, H) < 2.0
    off = camera_at(CENTRE, (-30.0, 6.0, 0.0), 2600.0)  # looks 6 m aside: its lines' wrong solution
    assert players_disagreement(off, feet, grass, W, H) > LINES_CONTRADICTED_SIGMA
    assert players_disagreement(truth, dict(list(feet.items())[:2]), grass, W, H) is None


def test_players_in_a_row_are_placed_by_their_heads_not_refused_as_collinear() -> None:
    """Players standing in one row on the grass have their foot points on one image line, which alone fixes no
    camera; their head points stand above that line, and with them the rig position's camera is found."""
    rng = np.random.default_rng(77)
    truth = camera_at(CENTRE, (-35.0, 2.0, 0.0), 2600.0)
    row = {("Player team left", str(i)): np.array([-42.0 + 3.5 * i, -3.0 + 1.5 * i]) for i in range(5)}
    grass = as_grass(row)
    feet = feet_in(truth, row, 0.3, rng)
    heads = heads_in(truth, row, 0.3, rng)
    alone = fit_camera_to_players(feet, grass, {}, W, H, RIG)
    assert isinstance(alone, PlayerRefusal) and alone.code == "collinear_players"
    fit = fit_camera_to_players(feet, grass, {}, W, H, RIG, heads=heads)
    assert isinstance(fit, PlayerFit), fit
    assert fit.rig_index == 1 and ball_error(fit, truth) < 3.0


def test_two_right_cameras_of_one_instant_agree_on_their_players_a_mirrored_one_does_not() -> None:
    """``pair_players_disagreement``: the main camera and a replay both right, their players' foot points a pixel
    noisy: a median within a few standard deviations; the replay's camera mirrored (what its mirrored lines calibrate
    to, ``mirror_camera``: it projects the mirrored world to the same pixels, so its ball ray is wrong while no
    residual of the ball's two rays shows it): far beyond :data:`LINES_CONTRADICTED_SIGMA`; a replay of another
    instant (every player 3 m on) too; with two shared players, no figure."""
    rng = np.random.default_rng(43)
    main = camera_at(np.array([0.0, 60.0, -14.0]), (-35.0, 0.0, 0.0), 1800.0)
    replay = camera_at(CENTRE, (-35.0, 2.0, 0.0), 2600.0)
    pts = players(8, rng)
    feet_main, feet_replay = feet_in(main, pts, 1.0, rng), feet_in(replay, pts, 1.0, rng)
    size = (W, H)
    agree = pair_players_disagreement(main, feet_main, size, replay, feet_replay, size)
    assert agree is not None and agree < 3.0
    mirrored = mirror_camera(replay)
    # the same image and boxes: only the lines were labelled left for right
    got = pair_players_disagreement(main, feet_main, size, mirrored, feet_replay, size)
    assert got is not None and got > LINES_CONTRADICTED_SIGMA
    later = {k: p + np.array([3.0, 0.0]) for k, p in pts.items()}
    desync = pair_players_disagreement(main, feet_main, size, replay, feet_in(replay, later, 1.0, rng), size)
    assert desync is not None and desync > LINES_CONTRADICTED_SIGMA
    two = dict(list(feet_replay.items())[:2])
    assert pair_players_disagreement(main, feet_main, size, replay, two, size) is None


def test_player_boxes_off_the_image_or_degenerate_never_reach_the_pair_comparison() -> None:
    """A dataset from outside is untrusted: boxes at 1e300 px, far outside the image, at the image's corner or upside
    down give no foot point (``feet_of``), so the pair comparison reads only the sound players and answers as without
    them, never raising."""
    from app.services.calibration.players import feet_of

    rng = np.random.default_rng(1)
    main = camera_at(np.array([0.0, 60.0, -14.0]), (-35.0, 0.0, 0.0), 1800.0)
    replay = camera_at(CENTRE, (-35.0, 2.0, 0.0), 2600.0)
    pts = players(6, rng)
    feet_main, feet_replay = feet_in(main, pts), feet_in(replay, pts)
    clean = pair_players_disagreement(main, feet_main, (W, H), replay, feet_replay, (W, H))
    assert clean is not None
    for box in ((1e300, 1e300, 1e300 + 1, 1e300 + 1), (-1e300, -1e300, 1e300, 1e300), (1e15, 5.0, 1e15 + 9, 40.0),
                (0.0, 0.0, 1.0, 1.0), (100.0, 300.0, 120.0, 200.0)):
        hostile = feet_of([("Player team left", f"x{i}", box) for i in range(6)], W, H)
        assert hostile == {}
        got = pair_players_disagreement(main, feet_main, (W, H), replay, {**feet_replay, **hostile}, (W, H))
        assert got == clean
