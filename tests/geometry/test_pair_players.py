"""The compiled pair comparison (``app.geometry.calibration.pair_players``, behind
``players.pair_players_disagreement``): a known answer, and the numpy functions' figures on synthetic pairs of every
kind the kernel branches on (lens distortion, a mirrored camera, players off the pitch or above the horizon, a
direction with too few players)."""
from __future__ import annotations

import numpy as np
import pytest

from app.geometry.calibration.grass import foot_world
from app.geometry.calibration.players import LINES_CONTRADICTED_SIGMA, pair_players_disagreement
from app.geometry.camera import Camera, look_at_rotation
from app.geometry.mirror import mirror_camera
from benchmarks.ball_players import numpy_pair_disagreement

W, H = 1920, 1080
PP = ((W - 1) / 2, (H - 1) / 2)


def camera(centre: np.ndarray, target: tuple[float, float, float], focal: float, radial: np.ndarray | None = None,
           tangential: np.ndarray | None = None, prism: np.ndarray | None = None) -> Camera:
    K = np.array([[focal, 0, PP[0]], [0, focal, PP[1]], [0, 0, 1.0]])
    return Camera(K=K, R=look_at_rotation(np.asarray(centre, float), np.asarray(target, float)),
                  C=np.asarray(centre, float), radial=np.zeros(6) if radial is None else radial,
                  tangential=np.zeros(2) if tangential is None else tangential,
                  thin_prism=np.zeros(4) if prism is None else prism)


def feet(cam: Camera, grass: np.ndarray, noise_px: float, rng: np.random.Generator) -> dict:
    """The foot pixels of players standing at ``grass`` (n, 2) m, as a box's bottom edge shows them."""
    uv, _ = cam.project(foot_world(grass, cam.C))
    uv = uv + rng.normal(0.0, noise_px, uv.shape)
    return {("Player team left", str(i)): uv[i] for i in range(len(uv))}


def test_two_exact_cameras_agree_to_rounding_and_two_players_give_no_figure() -> None:
    """Foot points projected without noise from where the players stand: each view puts the other's players exactly
    where its own feet are, so the figure is 0 (to rounding); a pixel of noise gives about a standard deviation."""
    rng = np.random.default_rng(3)
    a = camera(np.array([0.0, 60.0, -14.0]), (-35.0, 0.0, 0.0), 1800.0)
    b = camera(np.array([-70.0, 5.0, -18.0]), (-35.0, 2.0, 0.0), 2600.0)
    grass = np.array([-35.0, 0.0]) + rng.uniform(-12, 12, (7, 2))
    exact = pair_players_disagreement(a, feet(a, grass, 0.0, rng), (W, H), b, feet(b, grass, 0.0, rng), (W, H))
    assert exact is not None and exact < 1e-6
    noisy = pair_players_disagreement(a, feet(a, grass, 1.0, rng), (W, H), b, feet(b, grass, 1.0, rng), (W, H))
    assert noisy is not None and 0.1 < noisy < 3.0
    two = pair_players_disagreement(a, feet(a, grass[:2], 0.0, rng), (W, H), b, feet(b, grass[:2], 0.0, rng), (W, H))
    assert two is None


def pairs(rng: np.random.Generator) -> list[tuple]:
    """Random pairs of cameras and players: right, mirrored, distorted, some players off the pitch or above one
    camera's horizon, a foot pixel moved far."""
    out = []
    for i in range(60):
        a = camera(np.array([0.0, 60.0, -14.0]) + rng.normal(0, 4, 3), (-35.0, 0.0, 0.0), rng.uniform(900, 3000))
        lens = {} if i % 3 else {"radial": np.array([rng.normal(0, 0.1), rng.normal(0, 0.02), 0.001, 0.0, 0.01, 0.0]),
                                 "tangential": rng.normal(0, 1e-3, 2), "prism": rng.normal(0, 1e-3, 4)}
        b = camera(np.array([-70.0, 5.0, -18.0]) + rng.normal(0, 4, 3), (-35.0, 2.0, 0.0), rng.uniform(900, 3000),
                   **lens)
        grass = np.array([-35.0, 0.0]) + rng.uniform(-15, 15, (int(rng.integers(3, 14)), 2))
        if i % 5 == 2:
            grass[:2] += [60.0, 0.0]  # two players off the pitch where one camera puts them
        fa, fb = feet(a, grass, 1.5, rng), feet(b, grass, 1.5, rng)
        if i % 4 == 1:
            b = mirror_camera(b)  # the same image and boxes, the camera of its lines labelled left for right
        if i % 7 == 3:
            key = next(iter(fb))
            fb[key] = fb[key] + [0.0, -3000.0]  # above the horizon: the ray never meets the grass
        if i % 6 == 5:
            key = next(iter(fa))
            fa[key] = fa[key] + [400.0, 0.0]
        out.append((a, fa, (W, H), b, fb, (W, H)))
    return out


def test_the_compiled_comparison_gives_the_numpy_functions_figures() -> None:
    """Each figure equals the numpy functions' (``players_on_grass`` and ``players_disagreement`` each way) within
    1e-9 relative: the kernel follows their order of operations, only the small LAPACK inverses are written out (and
    finite differences of projections magnify their last bits); no pair on the other side of the threshold."""
    rng = np.random.default_rng(29)
    seen = {"none": 0, "agree": 0, "disagree": 0}
    for p in pairs(rng):
        with np.errstate(over="ignore", invalid="ignore"):  # numpy's undistortion of a pixel far off the lens
            ref = numpy_pair_disagreement(*p)
        got = pair_players_disagreement(*p)
        if ref is None:
            assert got is None
            seen["none"] += 1
            continue
        assert got == pytest.approx(ref, rel=1e-9, abs=1e-12)
        assert (got > LINES_CONTRADICTED_SIGMA) == (ref > LINES_CONTRADICTED_SIGMA)
        seen["agree" if ref <= LINES_CONTRADICTED_SIGMA else "disagree"] += 1
    assert seen["agree"] >= 10 and seen["disagree"] >= 10, seen
