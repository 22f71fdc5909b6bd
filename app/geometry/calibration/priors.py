"""Learned calibration priors: where a dataset's cameras stand, so that a fit whose lines leave the
camera under-determined settles where the dataset's other cameras are (issue 17).

Why: with few or nearly parallel lines the fit slides the camera along its optical axis and trades
distance for focal length (on failed held-out fits of the real sets the centre moved a median 3.7 m,
97 % of it along the axis, for a 3.5 % focal change). Broadcast cameras stand still during a game
(:mod:`.rig`), so the well-determined fits of a dataset cluster tightly where its cameras stand
(median distance between a confident fit's centre and its nearest neighbour: 0.29 m on the sn22 test
set, 0.24 m on wc14), and a Gaussian around those clusters is a prior the lines can be weighed against.

The prior (:class:`CameraPrior`), **learned** by :func:`learn_camera_prior` from v3d's own fits of the
data at hand, never from another calibration or synthetic truth:

* anchors: the groups of confident camera centres (fits whose position std, from
  :func:`.uncertainty.calibration_uncertainty`, is at or below a quantile of the set's), grouped as the
  game rig groups them (:func:`.rig.estimate_rig`), each with an isotropic std from its own spread;
* roll: broadcast heads are levelled; its std is the robust std (1.4826 MAD) of the confident fits'
  roll, floored at :data:`MIN_ROLL_STD_DEG`;
* the lens: the radial term as the relative distortion at the image corner, ``c = k1 (h / f)^2``
  (``h`` the half diagonal, px; the same number at any image size), whose median and robust std the
  confident fits refitted with ``k1`` free (:func:`.frame.radial_corner`) give. A set's frames share it
  whatever the zoom (real sets, 960x540: medians 0.033 sn22 and 0.042 wc14, i.e. ``k1 / f^2`` near
  1.1-1.4e-7 px^-2 at every focal length while ``k1`` grows from 0.3 at 1,400 px to 1.0 at 3,600 px),
  yet a frame's lines rarely fix it: without it a fit puts a line it did not see up to 10 px off near
  the image border (the held-out-class measure, :mod:`.held_out`).

The radial prior refines every fit (:func:`.frame.calibrate_frame` with
``CalibrationPrior(camera_prior=...)``, ``k1`` free under the prior's row). The centre's MAP fit is made only
for fits less sure of their centre than the confident ones (:attr:`CameraPrior.confident_std_m`), adds
the prior as residual rows (:class:`.solver.PriorRows`) to the lines' robust cost. The anchor is the one
most consistent with the lines' own estimate (:func:`anchor_order`: Mahalanobis distance under the
fit's covariance plus the anchor's); the prior's weight against the lines is the Gaussian one, so it
shrinks as the lines constrain more: the posterior shift is ``S_fit (S_fit + S_anchor)^-1`` of the
offset, nothing when the lines fix the centre far better than the anchor does.

World frame: SoccerNet (metres, centre spot origin, z down); image: pixels of the frame.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import numpy as np

from app.geometry.calibration.solver import PriorRows
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


@dataclass(frozen=True)
class CameraPrior:
    """A dataset's learned camera prior (:func:`learn_camera_prior`).

    Attributes:
        anchors_m: (K, 3) anchor centres, world metres (z down), most supported first.
        anchor_std_m: (K,) isotropic std of each anchor, metres.
        anchor_frames: (K,) confident fits behind each anchor.
        roll_std_deg: std of the roll prior (zero mean), degrees; ``inf`` for none.
        confident_fits: fits the prior was learned from.
        confident_std_m: the position std (m, root-sum-square) at or below which a fit counted as
            confident. A fit whose lines fix its centre that well is left as the lines have it (the
            MAP fit is made only above it): the prior was learned from such fits, and it must not
            move them (the JaC guard); ``inf`` when nothing was learned.
        radial_corner: median relative radial distortion at the image corner, ``k1 (h / f)^2`` (``h`` the
            half diagonal), of the confident fits refitted with ``k1`` free. radial_corner_std: its robust
            std; ``inf`` for no radial prior.
        radial_fits: refitted fits the radial prior was learned from.
    """

    anchors_m: tuple[tuple[float, float, float], ...]
    anchor_std_m: tuple[float, ...]
    anchor_frames: tuple[int, ...]
    roll_std_deg: float
    confident_fits: int
    confident_std_m: float = float("inf")
    radial_corner: float = 0.0
    radial_corner_std: float = float("inf")
    radial_fits: int = 0

    @property
    def has_radial(self) -> bool:
        """Whether the prior holds a radial term (a finite ``radial_corner_std``)."""
        return bool(np.isfinite(self.radial_corner_std))

    def __post_init__(self) -> None:
        if len(self.anchor_std_m) != len(self.anchors_m) or len(self.anchor_frames) != len(self.anchors_m):
            raise ValueError("CameraPrior: one std and one frame count per anchor")
        if any(not s > 0 for s in self.anchor_std_m) or not self.roll_std_deg > 0 or not self.radial_corner_std > 0:
            raise ValueError("CameraPrior: stds must be positive")
        if not np.isfinite(self.radial_corner):
            raise ValueError("CameraPrior: radial_corner must be finite")

    def to_json(self) -> dict:
        """The prior as JSON (what ``games.camera_prior`` stores): lists of floats; an infinite std or
        cut as null."""
        def fin(v: float) -> float | None:
            return float(v) if np.isfinite(v) else None

        return {"anchors_m": [[float(x) for x in a] for a in self.anchors_m],
                "anchor_std_m": [float(s) for s in self.anchor_std_m],
                "anchor_frames": [int(n) for n in self.anchor_frames],
                "roll_std_deg": fin(self.roll_std_deg), "confident_fits": int(self.confident_fits),
                "confident_std_m": fin(self.confident_std_m), "radial_corner": float(self.radial_corner),
                "radial_corner_std": fin(self.radial_corner_std), "radial_fits": int(self.radial_fits)}

    @classmethod
    def from_json(cls, data: dict) -> "CameraPrior":
        """The prior :meth:`to_json` wrote (a prior stored before the radial term has none).

        Raises:
            ValueError: missing keys, or values :class:`CameraPrior` refuses.
        """
        try:
            return cls(anchors_m=tuple(tuple(float(x) for x in a) for a in data["anchors_m"]),
                       anchor_std_m=tuple(float(s) for s in data["anchor_std_m"]),
                       anchor_frames=tuple(int(n) for n in data["anchor_frames"]),
                       roll_std_deg=float("inf") if data["roll_std_deg"] is None else float(data["roll_std_deg"]),
                       confident_fits=int(data["confident_fits"]),
                       confident_std_m=float("inf") if data["confident_std_m"] is None
                       else float(data["confident_std_m"]),
                       radial_corner=float(data.get("radial_corner", 0.0)),
                       radial_corner_std=float("inf") if data.get("radial_corner_std") is None
                       else float(data["radial_corner_std"]),
                       radial_fits=int(data.get("radial_fits", 0)))
        except (KeyError, TypeError) as exc:
            raise ValueError(f"not a stored CameraPrior: {exc}") from exc


def confident_mask(position_std_m: Sequence[float], quantile: float = 0.5) -> tuple[np.ndarray, float]:
    """Which fits count as confident: ``(mask (N,), cut)`` with ``cut`` the ``quantile`` of the finite
    position stds (m) and the mask true where a std is finite and at or below it (all false, cut
    ``inf``, when none is finite). What :func:`learn_camera_prior` learns from, and what a caller
    computing per-fit inputs for it (the radial refits) needs to compute them for only."""
    std = np.asarray(position_std_m, dtype=float)
    finite = np.isfinite(std)
    if not np.any(finite):
        return np.zeros(len(std), dtype=bool), float("inf")
    cut = float(np.quantile(std[finite], quantile))
    return finite & (std <= cut), cut


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
    from app.geometry.calibration.rig import estimate_rig  # rig imports frame, which imports this module

    if len(cameras) != len(position_std_m) or (radial_corner is not None and len(radial_corner) != len(cameras)):
        raise ValueError("learn_camera_prior: one position std (and radial term) per camera")
    if not 0.0 < confident_quantile <= 1.0:
        raise ValueError(f"confident_quantile must be in (0, 1], got {confident_quantile!r}")
    confident, cut = confident_mask(position_std_m, confident_quantile)
    if not np.any(confident):
        return CameraPrior(anchors_m=(), anchor_std_m=(), anchor_frames=(), roll_std_deg=float("inf"), confident_fits=0)
    chosen = [c for c, ok in zip(cameras, confident) if ok]
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


def anchor_order(prior: CameraPrior, centre_m: np.ndarray, centre_cov_m2: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The prior's anchors ordered by consistency with a fit's centre.

    Args:
        prior: the :class:`CameraPrior`.
        centre_m: (3,) the fit's centre, metres. centre_cov_m2: (3, 3) its covariance from the lines
            (m^2; may be near singular along an undetermined direction).

    Returns:
        ``(indices, d2)``: anchor indices, most consistent first, and their squared Mahalanobis
        distances ``(C - a)^T (S_fit + s_a^2 I)^-1 (C - a)`` (chi-square with 3 degrees of freedom
        when the fit and the anchor agree).
    """
    A = np.asarray(prior.anchors_m, dtype=float).reshape(-1, 3)
    if len(A) == 0:
        return np.zeros(0, dtype=int), np.zeros(0)
    s2 = np.square(np.asarray(prior.anchor_std_m, dtype=float))
    cov = np.asarray(centre_cov_m2, dtype=float)[None] + s2[:, None, None] * np.eye(3)[None]
    d = A - np.asarray(centre_m, dtype=float)[None]
    d2 = np.einsum("ki,ki->k", d, np.linalg.solve(cov, d[..., None])[..., 0])
    order = np.argsort(d2, kind="stable")
    return order, d2[order]


def prior_rows(prior: CameraPrior, anchor: int | None, line_noise_px: float, half_diagonal_px: float) -> PriorRows:
    """The MAP residual rows (:class:`.solver.PriorRows`) of anchor ``anchor`` (``None``: no centre
    prior), the roll prior and the radial prior against lines of noise ``line_noise_px`` (px), for an
    image of half diagonal ``half_diagonal_px`` (``h``): ``whitening = sigma / s_a I`` (px per metre),
    ``roll_weight = sigma / s_roll`` (px per radian; 0 without a roll prior), the radial prior in pixel
    units, ``kappa_0 = c_0 / h^2`` (px^-2) and ``k1_weight = sigma h^2 / s_c`` (px^3; 0 without one)."""
    roll = 0.0 if not np.isfinite(prior.roll_std_deg) else line_noise_px / np.radians(prior.roll_std_deg)
    h2 = float(half_diagonal_px) ** 2
    radial = line_noise_px * h2 / prior.radial_corner_std if prior.has_radial else 0.0
    if anchor is None:
        mean, whitening = np.zeros(3), np.zeros((3, 3))
    else:
        mean = np.asarray(prior.anchors_m[anchor], dtype=float)
        whitening = (line_noise_px / float(prior.anchor_std_m[anchor])) * np.eye(3)
    return PriorRows(mean=mean, whitening=whitening, roll_weight=float(roll),
                     k1_mean_px2=float(prior.radial_corner / h2), k1_weight=float(radial))
