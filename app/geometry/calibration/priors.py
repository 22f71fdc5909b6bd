"""Learned calibration priors: where a dataset's cameras stand, so that a fit whose lines leave the
camera under-determined settles where the dataset's other cameras are.

Why: with few or nearly parallel lines the fit slides the camera along its optical axis and trades
distance for focal length (on failed held-out fits of the real sets the centre moved a median 3.7 m,
97 % of it along the axis, for a 3.5 % focal change). Broadcast cameras stand still during a game
(:mod:`.rig`), so the well-determined fits of a dataset cluster tightly where its cameras stand
(median distance between a confident fit's centre and its nearest neighbour: 0.29 m on the sn22 test
set, 0.24 m on wc14), and a Gaussian around those clusters is a prior the lines can be weighed against.

The prior (:class:`CameraPrior`), **learned** by :func:`.learning.learn_camera_prior` from v3d's own fits of
the data at hand, never from another calibration or synthetic truth (this module holds the prior and its rows
in a fit; learning it groups camera centres as the rig does, so it sits above :mod:`.rig`, in :mod:`.learning`):

* anchors: the groups of confident camera centres (fits whose position std, from
  :func:`.uncertainty.calibration_uncertainty`, is at or below a quantile of the set's), grouped as the
  game rig groups them (:func:`.rig.estimate_rig`), each with an isotropic std from its own spread;
* roll: broadcast heads are levelled; its std is the robust std (1.4826 MAD) of the confident fits'
  roll, floored at :data:`.learning.MIN_ROLL_STD_DEG`;
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


@dataclass(frozen=True)
class CameraPrior:
    """A dataset's learned camera prior (:func:`.learning.learn_camera_prior`).

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
            return cls(anchors_m=tuple(tuple(float(x) for x in a) for a in data["anchors_m"]),  # type: ignore[misc]  # CameraPrior checks each anchor's three values
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
    ``inf``, when none is finite). What :func:`.learning.learn_camera_prior` learns from, and what a caller
    computing per-fit inputs for it (the radial refits) needs to compute them for only."""
    std = np.asarray(position_std_m, dtype=float)
    finite = np.isfinite(std)
    if not np.any(finite):
        return np.zeros(len(std), dtype=bool), float("inf")
    cut = float(np.quantile(std[finite], quantile))
    return finite & (std <= cut), cut


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
