"""Learning a dataset's camera prior (:class:`.priors.CameraPrior`) from its own calibrations.

The confident fits (position std at or below a quantile of the set's: :func:`.priors.confident_mask`) give the
anchors, grouped as the game rig groups camera centres (:func:`.rig.estimate_rig`), the roll's std and the lens's
radial term at the image corner; :mod:`.priors` says what each is and how a fit uses it. Learning sits above the
rig (which calibrates frames, which use the prior), the prior itself below the frame's fit: the calibration
package's imports form no circle.

World frame: SoccerNet (metres, centre spot origin, z down).
"""
from __future__ import annotations

from typing import Sequence

import numpy as np

from app.geometry.calibration.priors import CameraPrior, confident_mask
from app.geometry.calibration.rig import estimate_rig
from app.geometry.camera import Camera, pan_tilt_roll_from_rotation

#: Smallest anchor std, metres: a group of a few near-identical fits is not a camera known to
#: centimetres (calibrated centres of one camera scatter by tens of centimetres, :mod:`.rig`).
MIN_ANCHOR_STD_M = 0.25
#: Smallest roll std, degrees.
MIN_ROLL_STD_DEG = 0.1
#: Smallest std of the radial prior (relative distortion at the corner; a tenth of the real sets' median).
MIN_RADIAL_STD = 0.003
#: Fewest refitted confident fits a radial prior is learned from.
MIN_RADIAL_FITS = 10
#: Median distance to the centre of a 3D isotropic Gaussian, in stds (sqrt of chi-square(3)'s median).
_MEDIAN_RADIUS_3D = 1.5382


def _robust_std(values: np.ndarray) -> float:
    """1.4826 times the median absolute deviation from the median (a Gaussian's std)."""
    return 1.4826 * float(np.median(np.abs(values - np.median(values))))


def learn_camera_prior(cameras: Sequence[Camera], position_std_m: Sequence[float], *,
                       radial_corner: Sequence[float] | None = None,
                       confident_quantile: float = 0.5, radius_m: float = 1.5, min_frames: int = 2) -> CameraPrior:
    """Learn a :class:`CameraPrior` from a dataset's own calibrations.

    Args:
        cameras: calibrated cameras of the dataset (one per frame, SoccerNet world).
        position_std_m: per camera, the root-sum-square position std of its fit (m;
            :attr:`.uncertainty.CalibrationUncertainty.position_std_m`, ``inf`` allowed).
        radial_corner: per camera, its fit's relative radial distortion at the image corner with ``k1``
            free (:func:`.frame.radial_corner`; NaN where the refit failed); ``None``: no radial prior.
            Learned from the confident fits' values when there are :data:`MIN_RADIAL_FITS` or more.
        confident_quantile: fits whose position std is at or below this quantile of the finite ones
            feed the prior.
        radius_m, min_frames: grouping of the confident centres (:func:`.rig.estimate_rig`).

    Returns:
        The prior (without anchors when no group has ``min_frames`` confident fits; roll std from the
        confident fits, ``inf`` with fewer than 3).

    Raises:
        ValueError: lengths differ or ``confident_quantile`` is outside (0, 1].
    """
    if len(cameras) != len(position_std_m) or (radial_corner is not None and len(radial_corner) != len(cameras)):
        raise ValueError("learn_camera_prior: one position std (and radial term) per camera")
    if not 0.0 < confident_quantile <= 1.0:
        raise ValueError(f"confident_quantile must be in (0, 1], got {confident_quantile!r}")
    confident, cut = confident_mask(position_std_m, confident_quantile)
    if not np.any(confident):
        return CameraPrior(anchors_m=(), anchor_std_m=(), anchor_frames=(), roll_std_deg=float("inf"), confident_fits=0)
    chosen = [c for c, ok in zip(cameras, confident, strict=True) if ok]
    rig = estimate_rig(np.array([c.C for c in chosen]).reshape(-1, 3), radius_m=radius_m, min_frames=min_frames)
    rolls = np.array([pan_tilt_roll_from_rotation(c.R)[2] for c in chosen])
    roll_std = max(_robust_std(rolls), MIN_ROLL_STD_DEG) if len(rolls) >= 3 else float("inf")
    radial: dict = {}
    if radial_corner is not None:
        corner = np.asarray(radial_corner, dtype=float)[confident]
        corner = corner[np.isfinite(corner)]
        if len(corner) >= MIN_RADIAL_FITS:
            radial = {"radial_corner": float(np.median(corner)), "radial_fits": int(len(corner)),
                      "radial_corner_std": max(_robust_std(corner), MIN_RADIAL_STD)}
    return CameraPrior(
        anchors_m=tuple(p.centre_m for p in rig.positions),
        anchor_std_m=tuple(max(p.spread_m / _MEDIAN_RADIUS_3D, MIN_ANCHOR_STD_M) for p in rig.positions),
        anchor_frames=tuple(p.frames for p in rig.positions), roll_std_deg=roll_std, confident_fits=len(chosen),
        confident_std_m=cut, **radial)
