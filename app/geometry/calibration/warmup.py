"""Compiling the calibration's numba kernels ahead of use (an image build, a fresh checkout's set-up): by
calibrating a synthetic frame, so that every kernel the solver (:mod:`.solver`) runs for a frame's fit
(:mod:`.frame`) is compiled or loaded from numba's on-disk cache, and by fitting a synthetic view to its players
(:mod:`.players`, whose least squares run compiled in :mod:`.player_problem`). Sits above them: the solvers never
import their callers.
"""
from __future__ import annotations

import numpy as np

from app.geometry.calibration.frame import calibrate_frame
from app.geometry.calibration.grass import foot_world, players_on_grass
from app.geometry.calibration.players import fit_camera_to_players, pair_players_disagreement
from app.geometry.calibration.result import CalibrationPrior
from app.geometry.camera import Camera, look_at_rotation
from app.geometry.pitch import sample_pitch_polylines


def compile_kernels() -> None:
    """Compile every numba kernel of the calibration now (or load it from numba's on-disk cache):
    one calibration of a synthetic frame, free and with its centre known, with the radial term.
    For an image build or a warm-up; calibrating does it on first use anyway. The players' fit and the players'
    comparison of two cameras (the 3D ball's check) are compiled with them."""
    centre = np.array([0.0, 62.0, -18.0])
    camera = Camera(K=np.array([[900.0, 0.0, 479.5], [0.0, 900.0, 269.5], [0.0, 0.0, 1.0]]),
                    R=look_at_rotation(centre, np.array([-20.0, -4.0, 0.0])), C=centre,
                    radial=np.array([0.05, 0.0, 0.0, 0.0, 0.0, 0.0]))
    lines = {}
    for cls, X in sample_pitch_polylines().items():
        uv, ok = camera.project(X)
        inside = ok & (uv[:, 0] >= 0) & (uv[:, 0] <= 959) & (uv[:, 1] >= 0) & (uv[:, 1] <= 539)
        if inside.sum() >= 4:
            lines[cls] = [uv[inside][:: max(1, int(inside.sum()) // 12)]]
    calibrate_frame(lines, 960, 540)
    calibrate_frame(lines, 960, 540, prior=CalibrationPrior(centre_m=(0.0, 62.0, -18.0)))
    _fit_players(camera)


def _fit_players(anchor: Camera) -> None:
    """One players' fit of a synthetic view (eight players seen by ``anchor`` and by a second view high behind the
    left goal), at a rig position and free: the kernels of :mod:`.player_problem` compiled or loaded."""
    grass = {("Player", str(i)): np.array([-30.0 + 3.0 * i, -10.0 + 2.5 * (i % 4)]) for i in range(8)}
    view = Camera(K=np.array([[1500.0, 0.0, 959.5], [0.0, 1500.0, 539.5], [0.0, 0.0, 1.0]]),
                  R=look_at_rotation(np.array([-70.0, 5.0, -18.0]), np.array([-20.0, -5.0, 0.0])),
                  C=np.array([-70.0, 5.0, -18.0]), radial=np.zeros(6))

    def feet(camera: Camera) -> dict[tuple[str, str], np.ndarray]:
        keys = list(grass)
        uv, _ = camera.project(foot_world(np.array([grass[k] for k in keys]), camera.C))
        return {k: uv[i] for i, k in enumerate(keys)}

    on_grass = players_on_grass([(anchor, feet(anchor))])
    fit_camera_to_players(feet(view), on_grass, {}, 1920, 1080, [tuple(view.C)])
    fit_camera_to_players(feet(view), on_grass, {}, 1920, 1080)
    # the ball's players check (:mod:`.pair_players`): compiled here too, or each calibration worker of a fresh
    # installation's first import compiles it at once
    pair_players_disagreement(anchor, feet(anchor), (960, 540), view, feet(view), (1920, 1080))
