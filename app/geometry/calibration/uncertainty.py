"""How sure a calibration is: standard deviations of its camera parameters from the line fit.

First-order (Gauss-Newton) propagation of the line noise through the fit (Hartley and Zisserman,
section 5.2.3, result 5.11 "covariance of the estimated parameters"; Triggs et al., "Bundle
adjustment - a modern synthesis", section 9): with ``J`` the Jacobian of the fit's weighted pixel
residuals (:func:`.residuals.residuals`: every annotated point's distance to its model element)
with respect to the camera parameters ``x = [f, w (3), C (3) (, k1)]`` at the fitted camera, and
``sigma`` the line noise (px), ``Cov(x) = sigma^2 (J^T J)^+``. The line noise is the residuals' own
standard error ``sqrt(|r|^2 / (n - k))``, floored at :data:`MIN_LINE_NOISE_PX` (annotation clicks
are no better than about a pixel at 960x540, even when a frame's few points happen to fit exactly).
Pan, tilt and roll (SoccerNet's convention, :func:`app.geometry.camera.pan_tilt_roll_from_rotation`)
get their covariance through the numerical Jacobian of that conversion at the fitted rotation.

A parameter the lines leave under-determined (e.g. focal length against the distance along the
optical axis when only parallel lines are labelled) shows as a large standard deviation; an exactly
singular direction is reported as ``inf``. A camera whose centre was held fixed (the game's rig) has
position standard deviations 0: the fit did not estimate them.

World frame: SoccerNet (metres, centre spot origin, z down); image: pixels of the frame.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Mapping

import numpy as np

from app.geometry.annotations import FieldLines
from app.geometry.calibration.observations import build_observations
from app.geometry.calibration.residuals import CameraParametrisation, residuals, rotation_from_vector
from app.geometry.calibration.solver import PriorRows
from app.geometry.camera import Camera, pan_tilt_roll_from_rotation

#: Smallest line noise assumed, px (annotation clicks).
MIN_LINE_NOISE_PX = 1.0
#: Relative eigenvalue below which a direction of ``J^T J`` counts as undetermined (std ``inf``).
_RCOND = 1e-12
#: Forward-difference steps: focal (relative), rotation vector (rad), centre (m), k1.
_STEPS = (1e-6, 1e-7, 1e-5, 1e-6)


@dataclass(frozen=True)
class CalibrationUncertainty:
    """Standard deviations of a calibration's camera parameters.

    Attributes:
        position_m: (x, y, z) std of the camera centre, metres (world frame; 0 when the centre was
            held fixed).
        pan_deg, tilt_deg, roll_deg: std of SoccerNet's angles, degrees.
        focal_px: std of the focal length, pixels of the frame.
        line_noise_px: the line noise propagated (px).
        points: annotated points of the fit.
    """

    position_m: tuple[float, float, float]
    pan_deg: float
    tilt_deg: float
    roll_deg: float
    focal_px: float
    line_noise_px: float
    points: int

    def to_json(self) -> dict[str, Any]:
        """JSON form (``inf`` as ``None``): ``{"position_m": {"x", "y", "z"}, "pan_deg", "tilt_deg",
        "roll_deg", "focal_px", "line_noise_px", "points"}``."""
        def num(v: float) -> float | None:
            return float(v) if np.isfinite(v) else None
        x, y, z = self.position_m
        return {"position_m": {"x": num(x), "y": num(y), "z": num(z)}, "pan_deg": num(self.pan_deg),
                "tilt_deg": num(self.tilt_deg), "roll_deg": num(self.roll_deg), "focal_px": num(self.focal_px),
                "line_noise_px": num(self.line_noise_px), "points": int(self.points)}

    @classmethod
    def from_json(cls, data: Mapping[str, Any]) -> "CalibrationUncertainty":
        """Inverse of :meth:`to_json` (``None`` back to ``inf``). Raises KeyError/TypeError/ValueError
        on a malformed mapping."""
        def num(v: Any) -> float:
            return float("inf") if v is None else float(v)
        p = data["position_m"]
        return cls(position_m=(num(p["x"]), num(p["y"]), num(p["z"])), pan_deg=num(data["pan_deg"]),
                   tilt_deg=num(data["tilt_deg"]), roll_deg=num(data["roll_deg"]), focal_px=num(data["focal_px"]),
                   line_noise_px=num(data["line_noise_px"]), points=int(data["points"]))

    @property
    def position_std_m(self) -> float:
        """Root-sum-square of the position std (m): one number for weighting a view."""
        return float(np.sqrt(np.sum(np.square(self.position_m))))


def line_noise(residuals_px: np.ndarray, parameters: int) -> float:
    """The line noise of a fit (px): the standard error ``sqrt(|r|^2 / (n - k))`` of its ``n``
    line residuals ``residuals_px`` for ``parameters`` = ``k`` fitted parameters, floored at
    :data:`MIN_LINE_NOISE_PX`."""
    r = np.asarray(residuals_px, dtype=float)
    return max(float(np.sqrt(np.sum(r**2) / max(len(r) - parameters, 1))), MIN_LINE_NOISE_PX)


def parameter_covariance(jacobian: np.ndarray, sigma_px: float) -> tuple[np.ndarray, np.ndarray]:
    """Gauss-Newton covariance ``sigma^2 (J^T J)^+`` of a least-squares fit's parameters
    (Hartley and Zisserman, result 5.11).

    Args:
        jacobian: (n, k) Jacobian of the residuals (px) with respect to the parameters.
        sigma_px: residual noise, px.

    Returns:
        ``(cov, undetermined)``: (k, k) covariance in the parameters' units squared, and (k,) True for
        the parameters touched by a direction ``J`` does not determine (relative eigenvalue below
        1e-12; their variance is infinite, the covariance leaves that direction out). The columns are
        scaled to unit norm before inverting, so that focal (px) and rotation (rad) are comparable.
    """
    J = np.asarray(jacobian, dtype=float)
    k = J.shape[1]
    norms = np.linalg.norm(J, axis=0)
    norms[norms == 0] = 1.0
    Js = J / norms
    _, s, vt = np.linalg.svd(Js.T @ Js)
    inv_s = np.where(s > _RCOND * s[0], 1.0 / np.where(s > 0, s, 1.0), np.inf)
    # Directions with an infinite variance make every parameter they touch infinite.
    finite = np.isfinite(inv_s)
    cov_s = (vt[finite].T * inv_s[finite]) @ vt[finite]
    cov = sigma_px**2 * cov_s / np.outer(norms, norms)
    undetermined = np.zeros(k, dtype=bool)
    if not np.all(finite):
        undetermined = np.any(np.abs(vt[~finite]) > 1e-6, axis=0)
    return cov, undetermined


def _prior_residuals(prior: PriorRows, param: CameraParametrisation, x: np.ndarray) -> np.ndarray:
    """The rows :func:`.solver.robust_lm` appends for ``prior`` at the vector ``x`` (px)."""
    f, R, C, k1 = param.split(x)
    centre = np.zeros(3) if param.fixed_centre is not None else prior.whitening @ (C - prior.mean)
    radial = prior.k1_weight * (k1 / (f * f) - prior.k1_mean_px2) if param.fit_k1 else 0.0
    return np.concatenate([centre, [prior.roll_weight * np.arctan2(R[0, 2], R[1, 2]), radial]])


def _angles(R0: np.ndarray, w: np.ndarray) -> np.ndarray:
    return np.asarray(pan_tilt_roll_from_rotation(rotation_from_vector(w) @ R0), dtype=float)


def _wrap_deg(d: np.ndarray) -> np.ndarray:
    return (d + 180.0) % 360.0 - 180.0


def calibration_uncertainty(camera: Camera, lines: FieldLines, *, fixed_centre: bool = False,
                            line_noise_px: float | None = None,
                            prior: PriorRows | None = None) -> CalibrationUncertainty | None:
    """Standard deviations of ``camera``'s parameters given the annotated ``lines`` it was fitted to.

    Args:
        camera: the fitted camera (principal point fixed, square pixels, at most ``k1``), pixels.
        lines: :data:`~app.geometry.annotations.FieldLines` the fit used (leave out a class the fit
            ignored), same pixels.
        fixed_centre: the centre was held fixed (rig): only focal, rotation (and ``k1``) were fitted.
        line_noise_px: line noise to propagate; default the residuals' standard error, floored at
            :data:`MIN_LINE_NOISE_PX` (:func:`line_noise`).
        prior: the prior rows of a MAP fit (:attr:`.frame.CalibrationResult.centre_prior`): the
            covariance is then the posterior's, ``sigma^2 (J^T J + Jp^T Jp)^+`` with ``Jp`` the prior
            rows' Jacobian, so a centre the lines leave open gets the anchor's std rather than ``inf``.

    Returns:
        :class:`CalibrationUncertainty`, or ``None`` when the lines have no point with a model element.
    """
    obs = build_observations(lines)
    if obs.n_points == 0:
        return None
    k1 = float(camera.radial[0])
    fit_k1 = k1 != 0.0
    param = CameraParametrisation(principal_point=np.asarray(camera.K[:2, 2], dtype=float), R0=np.asarray(camera.R),
                                  fit_k1=fit_k1, fixed_centre=np.asarray(camera.C, float) if fixed_centre else None)
    f = float(camera.K[0, 0])
    x0 = param.vector(f, np.asarray(camera.C, float), k1)
    r0 = residuals(x0, obs, param)
    k = len(x0)
    steps = np.empty(k)
    steps[0] = _STEPS[0] * f
    steps[1:4] = _STEPS[1]
    if not fixed_centre:
        steps[4:7] = _STEPS[2]
    if fit_k1:
        steps[-1] = _STEPS[3]
    X = x0 + np.diag(steps)
    J = (residuals(X, obs, param) - r0) / steps[:, None]  # (k, n)
    J = J.T
    sigma = line_noise(r0, k) if line_noise_px is None else float(line_noise_px)
    if prior is not None:
        # The MAP fit's prior rows are residuals like the lines': their Jacobian joins the lines'.
        p0 = _prior_residuals(prior, param, x0)
        Jp = np.stack([(_prior_residuals(prior, param, X[j]) - p0) / steps[j] for j in range(k)], axis=1)
        J = np.vstack([J, Jp])
    return uncertainty_from_jacobian(param, J, sigma, int(obs.n_points))


def uncertainty_from_jacobian(param: CameraParametrisation, jacobian: np.ndarray, sigma_px: float,
                              points: int) -> CalibrationUncertainty:
    """:class:`CalibrationUncertainty` of a fit whose parameter vector is ``param``'s (``[f, w (3) (, C (3))
    (, k1)]``, the rotation vector at ``w = 0`` of ``param.R0``), from the (n, k) Jacobian of its pixel residuals
    (every row a residual in px: lines, foot points of players, prior rows) and the residual noise ``sigma_px``
    (Hartley and Zisserman, result 5.11, :func:`parameter_covariance`); ``points``: the observations fitted.
    The angles' std come through the numerical Jacobian of SoccerNet's (pan, tilt, roll) at ``w = 0``; a fixed
    centre (``param.fixed_centre``) has position std 0."""
    fixed_centre = param.fixed_centre is not None
    cov, undetermined = parameter_covariance(jacobian, sigma_px)
    var = np.where(undetermined, np.inf, np.diag(cov))
    # Angles: Jacobian of (pan, tilt, roll) with respect to the rotation vector at w = 0.
    a0 = _angles(param.R0, np.zeros(3))
    A = np.empty((3, 3))
    for j in range(3):
        w = np.zeros(3)
        w[j] = 1e-6
        A[:, j] = _wrap_deg(_angles(param.R0, w) - a0) / 1e-6
    cov_w = cov[1:4, 1:4]
    var_angles = np.diag(A @ cov_w @ A.T)
    if np.any(undetermined[1:4]):
        var_angles = np.where(np.any(np.abs(A[:, undetermined[1:4]]) > 1e-9, axis=1), np.inf, var_angles)
    position = (0.0, 0.0, 0.0) if fixed_centre else tuple(float(np.sqrt(max(v, 0.0))) for v in var[4:7])
    sd = np.sqrt(np.maximum(var_angles, 0.0))
    return CalibrationUncertainty(position_m=position, pan_deg=float(sd[0]), tilt_deg=float(sd[1]),  # type: ignore[arg-type]  # position holds three values (var[4:7])
                                  roll_deg=float(sd[2]), focal_px=float(np.sqrt(max(var[0], 0.0))),
                                  line_noise_px=float(sigma_px), points=int(points))
