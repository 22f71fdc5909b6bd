"""app.geometry.static_bundle.bundle_adjust: six static cameras (an ISSIA-like rig: three behind each touch line)
refined from their field lines and the ball's labels, on a synthetic scene of known truth: perturbed starting
cameras and points, wrong labels among the inliers it is given."""
from __future__ import annotations

import cv2
import numpy as np
import pytest

from app.geometry.camera import Camera, look_at_rotation
from app.geometry.pitch import sample_pitch_polylines
from app.geometry.static_bundle import bundle_adjust
from app.geometry.trajectory import triangulate_frame
from app.geometry.triangulation import BallObservation

W, H = 1920, 1080
#: (centre, look-at target, focal px) of each camera, world metres (z down), like the ISSIA rig.
RIG = [((-35.4, 54.0, -6.1), (-36.0, 10.0, 0.0), 2640.0), ((-35.7, -53.6, -7.7), (-36.0, -10.0, 0.0), 2690.0),
       ((-1.8, 54.8, -7.6), (0.0, 8.0, 0.0), 2610.0), ((-1.1, -52.7, -6.0), (0.0, -8.0, 0.0), 2560.0),
       ((34.7, 52.7, -6.2), (36.0, 10.0, 0.0), 2460.0), ((36.9, -53.1, -6.9), (36.0, -10.0, 0.0), 2460.0)]


def _rig() -> list[Camera]:
    out = []
    for C, target, f in RIG:
        C = np.array(C)
        K = np.array([[f, 0, (W - 1) / 2], [0, f, (H - 1) / 2], [0, 0, 1.0]])
        out.append(Camera(K=K, R=look_at_rotation(C, np.array(target)), C=C))
    return out


def _lines(cam: Camera, rng) -> dict[str, list[np.ndarray]]:
    """The pitch lines the camera sees, about 6 points per class, 1 px of noise per axis."""
    lines = {}
    for cls, X in sample_pitch_polylines().items():
        uv, ok = cam.project(X)
        inside = ok & (uv[:, 0] >= 0) & (uv[:, 0] < W) & (uv[:, 1] >= 0) & (uv[:, 1] < H)
        if inside.sum() >= 4:
            pts = uv[inside][:: max(1, int(inside.sum()) // 6)]
            lines[cls] = [pts + rng.normal(0, 1.0, pts.shape)]
    return lines


def _perturbed(cam: Camera, rng) -> Camera:
    """The camera with its centre moved by 0.3 m, its focal length by 1 % and its rotation by 0.1 degree."""
    d = rng.normal(size=3)
    w = rng.normal(size=3)
    w *= np.radians(0.15) / np.linalg.norm(w)
    K = cam.K.copy()
    K[0, 0] = K[1, 1] = cam.K[0, 0] * (1 + 0.005 * rng.choice([-1, 1]))
    return Camera(K=K, R=cv2.Rodrigues(w)[0] @ cam.R, C=cam.C + 0.15 * d / np.linalg.norm(d))


def _angle_deg(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.degrees(np.arccos(np.clip((np.trace(a @ b.T) - 1) / 2, -1, 1))))


@pytest.mark.parametrize("seed", [3, 5])
def test_bundle_recovers_the_rig_from_lines_and_ball(seed):
    """800 random ball positions (on the grass to 8 m high), labels with 0.7 px noise where the ball is in the
    image (70 % of those), 2 % of the labels wrong (200 px or more off) and all given as inliers; lines with
    1 px noise, about 6 points a class; starting cameras 0.15 m / 0.5 % / 0.15 degree off, the points
    triangulated with them. Recovered: every centre within 0.1 m and on average within 6 cm, focal length
    within 0.25 %, rotation within 0.07 degree (started from the truth, seed 3 ends 0.09 m / 0.2 % / 0.034
    degree off: what this scene's lines fix), the points within 8 cm (median; 0.7 px at 50 m is 1.3 cm across a ray,
    more along it) and closer than the start's by 40 %, the label noise estimated within
    20 % (seeds 3, 5 here; 11 checked by hand)."""
    rng = np.random.default_rng(seed)
    truth = _rig()
    lines = [_lines(c, rng) for c in truth]
    assert all(len(ln) >= 4 for ln in lines)
    F = 800
    X = np.column_stack([rng.uniform(-50, 50, F), rng.uniform(-25, 25, F), -rng.uniform(0.11, 8.0, F)])
    pts = np.full((F, 6, 2), np.nan)
    for k, cam in enumerate(truth):
        uv, front = cam.project(X)
        seen = front & (uv[:, 0] >= 0) & (uv[:, 0] < W) & (uv[:, 1] >= 0) & (uv[:, 1] < H) & (rng.random(F) < 0.7)
        pts[seen, k] = uv[seen] + rng.normal(0, 0.7, (int(seen.sum()), 2))
    labelled = np.argwhere(np.isfinite(pts[..., 0]))
    wrong = labelled[rng.choice(len(labelled), int(0.02 * len(labelled)), replace=False)]
    for f, k in wrong:
        while True:
            p = rng.uniform([0, 0], [W, H])
            if np.linalg.norm(p - pts[f, k]) >= 200:
                pts[f, k] = p
                break
    start = [_perturbed(c, rng) for c in truth]
    # the starting points as a sequence gives them: each frame triangulated with the starting cameras
    X0 = np.full_like(X, np.nan)
    for f in range(F):
        obs = [BallObservation(k, start[k], pts[f, k], W) for k in range(6) if np.isfinite(pts[f, k, 0])]
        tri = triangulate_frame(obs, tau_px=20.0, rule="max_scaled_1920", min_baseline_m=1.0, min_parallax_deg=0.0)
        if tri.point is not None:
            X0[f] = tri.point
    res = bundle_adjust(start, lines, pts, np.isfinite(pts[..., 0]), X0)
    assert res.frames > 300 and res.labels > 800
    errors = []
    for got, cam, s in zip(res.cameras, truth, start, strict=False):
        assert np.linalg.norm(s.C - cam.C) > 0.149  # the start was off
        errors.append(np.linalg.norm(got.C - cam.C))
        assert errors[-1] < 0.1
        assert abs(got.K[0, 0] / cam.K[0, 0] - 1) < 0.0025
        assert _angle_deg(got.R, cam.R) < 0.07
        np.testing.assert_allclose(got.K[:2, 2], cam.K[:2, 2])  # principal point held
    assert np.mean(errors) < 0.06
    used = np.isfinite(res.points).all(axis=1)
    err_points = np.median(np.linalg.norm(res.points[used] - X[used], axis=1))
    assert err_points < 0.08 and err_points < 0.6 * np.median(np.linalg.norm(X0[used] - X[used], axis=1))
    assert 0.8 * 0.7 < res.sigma_ball_px < 1.2 * 0.7
    assert res.ball_rms_px[1] < 0.2 * res.ball_rms_px[0]


def test_bundle_needs_lines_of_two_cameras():
    cams = _rig()
    pts = np.full((10, 6, 2), np.nan)
    with pytest.raises(ValueError, match="two or more"):
        bundle_adjust(cams, [None] * 6, pts, np.ones((10, 6), bool), np.zeros((10, 3)))
