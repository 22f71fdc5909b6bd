"""Camera calibration of a frame from its annotated field lines (and the game-level rig).

Public entry points: :func:`calibrate_frame` -> :class:`CalibrationResult`, with the optional
:class:`CalibrationPrior` and :class:`CalibrationSettings`; the game-level rig:
:func:`estimate_rig` -> :class:`CameraRig`, and :func:`calibrate_with_rig`; a dataset's learned prior:
:func:`learn_camera_prior` -> :class:`CameraPrior` (given as ``CalibrationPrior(camera_prior=...)``), its
lens learned from :func:`radial_corner` of the dataset's fits.
"""
from app.geometry.calibration.fallbacks import radial_corner
from app.geometry.calibration.frame import JAC_GAMMAS, calibrate_frame, frame_jac, lines_used
from app.geometry.calibration.learning import learn_camera_prior
from app.geometry.calibration.priors import CameraPrior
from app.geometry.calibration.result import CalibrationPrior, CalibrationResult, CalibrationSettings, principal_point
from app.geometry.calibration.rig import CameraRig, RigPosition, calibrate_with_rig, estimate_rig
from app.geometry.calibration.uncertainty import CalibrationUncertainty, calibration_uncertainty

__all__ = [
    "JAC_GAMMAS", "CalibrationPrior", "CalibrationResult", "CalibrationSettings", "calibrate_frame",
    "frame_jac", "principal_point", "CameraRig", "RigPosition", "estimate_rig", "calibrate_with_rig",
    "CalibrationUncertainty", "calibration_uncertainty", "CameraPrior", "learn_camera_prior",
    "radial_corner", "lines_used",
]
