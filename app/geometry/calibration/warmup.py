"""Compiling the calibration's numba kernels ahead of use (an image build, a fresh checkout's set-up): by
calibrating a synthetic frame, so that every kernel the solver (:mod:`.solver`) runs for a frame's fit
(:mod:`.frame`) is compiled or loaded from numba's on-disk cache. Sits above both: the solver never imports its
callers.
"""
from __future__ import annotations

import numpy as np

from app.geometry.calibration.frame import calibrate_frame
from app.geometry.calibration.result import CalibrationPrior
from app.geometry.camera import Camera, look_at_rotation
from app.geometry.pitch import sample_pitch_polylines


def compile_kernels() -> None:
    """Compile every numba kernel of the calibration now (or load it from numba's on-disk cache):
    one calibration of a synthetic frame, free and with its centre known, with the radial term.
    For an image build or a warm-up; calibrating does it on first use anyway."""
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
