"""Camera calibration of a frame from its annotated field lines (and the game-level rig).

Public entry points: :func:`calibrate_frame` -> :class:`CalibrationResult`, with the optional
:class:`CalibrationPrior` and :class:`CalibrationSettings`.
"""
from app.geometry.calibration.frame import (
    JAC_GAMMAS,
    CalibrationPrior,
    CalibrationResult,
    CalibrationSettings,
    calibrate_frame,
    frame_jac,
    principal_point,
)

__all__ = [
    "JAC_GAMMAS", "CalibrationPrior", "CalibrationResult", "CalibrationSettings", "calibrate_frame",
    "frame_jac", "principal_point",
]
