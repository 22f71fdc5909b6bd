"""Bundle adjustment of a sequence's static cameras from their field lines and the ball's labels together.

Each static camera of a sequence (ISSIA) is calibrated once from its field lines
(:func:`app.geometry.calibration.calibrate_frame`). With one set of line annotations per camera, that
calibration's error is systematic: every frame shares it. The ball's labels in several cameras at once
(hundreds to thousands of frames) carry the cameras' relative geometry; the lines carry where the pitch
is (they fix the similarity, seven degrees of freedom, that the ball alone leaves free). The bundle
adjustment (Triggs et al., "Bundle adjustment - a modern synthesis", 2000) fits both at once:

* unknowns: per camera the calibration's own parameters (:class:`~app.geometry.calibration.residuals.
  CameraParametrisation`: focal length px, rotation vector, centre m, and SoccerNet's ``k1`` when the
  line fit has one; principal point held), and one 3D ball centre per frame (world metres);
* residuals, each divided by its noise level so that both kinds are in units of their standard deviation
  (the maximum-likelihood weighting of independent Gaussian errors):

  - the line residuals of each camera, exactly those the calibration minimises
    (:func:`app.geometry.calibration.residuals.residuals`: point-to-line and beyond-the-end distances,
    Sampson distance to circles, each class weighted as at most four points), over ``sigma_lines_px``:
    the RMS of the line calibrations' point distances, pooled over the cameras, with the degrees of
    freedom the fits used taken off (``sum d^2 / (n - 7 K)``);
  - the ball's reprojection residuals (x and y, px) of the labels given as inliers, over
    ``sigma_ball_px``: estimated from the data in two rounds (1.4826 times the median absolute residual,
    corrected for the 3 + the cameras' parameters per frame the fit absorbs), first at the start, then
    again at the first round's solution, from which the second round starts;

* loss: soft-L1 at :data:`LOSS_SCALE_SIGMA` standard deviations (a few pixels), so that a wrong label
  (1 % of them, hundreds of pixels off) or a mis-clicked line point pulls like a few correct ones;
* solver: ``scipy.optimize.least_squares`` (trust region reflective) with the Jacobian's sparsity given
  (``jac_sparsity``: a label's residuals depend on its camera and its frame's point only), so its finite
  differences group columns and its ``lsmr`` steps stay linear in the frames.

World: SoccerNet metres, origin at the centre spot, z down. Image: continuous pixels. Pure: numpy, scipy.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import numpy as np
from scipy.optimize import least_squares
from scipy.sparse import coo_matrix

from app.geometry.annotations import FieldLines
from app.geometry.calibration.observations import build_observations
from app.geometry.calibration.residuals import CameraParametrisation, residuals
from app.geometry.camera import Camera

#: Soft-L1 scale of every residual, in its standard deviations (about 2-3 px for 0.7-1 px of noise).
LOSS_SCALE_SIGMA = 3.0
#: Whitened residual given to a label whose point falls behind its camera (keeps the cost finite).
_BEHIND = 1e3
#: Parameters of one camera the line fit estimates (focal length, rotation, centre).
_CAMERA_DOF = 7


@dataclass(frozen=True)
class BundleResult:
    """Outcome of :func:`bundle_adjust`.

    Attributes:
        cameras: K refined cameras (``None`` where the input had none).
        points: (F, 3) refined ball centre per frame, world metres; NaN for frames not in the adjustment.
        sigma_lines_px: pooled line noise used as the lines' weight, px.
        sigma_ball_px: ball label noise used as the labels' weight (the second round's), px.
        ball_rms_px: (start, end) RMS of the ball residuals within :data:`LOSS_SCALE_SIGMA` sigmas, px.
        frames: number of frames in the adjustment; labels: number of ball labels.
        evaluations: residual evaluations of both rounds.
    """

    cameras: list[Camera | None]
    points: np.ndarray
    sigma_lines_px: float
    sigma_ball_px: float
    ball_rms_px: tuple[float, float]
    frames: int
    labels: int
    evaluations: int


def _distances(camera: Camera, obs) -> np.ndarray:
    """Unweighted point distances (N + M,) px of the lines ``obs`` under ``camera`` (undistorted with its k1)."""
    k1 = float(camera.radial[0]) if camera.radial is not None else 0.0
    param = CameraParametrisation(principal_point=camera.K[:2, 2].copy(), R0=camera.R, fit_k1=k1 != 0.0)
    x = param.vector(float(camera.K[0, 0]), camera.C, k1)
    r = residuals(x, obs, param)
    n = len(obs.seg_points)
    return np.concatenate([np.hypot(r[:n], r[n:2 * n]) / obs.seg_weight, r[2 * n:] / obs.circle_weight])


def bundle_adjust(cameras: Sequence[Camera | None], lines: Sequence[FieldLines | None], points_px: np.ndarray,
                  inliers: np.ndarray, start_m: np.ndarray, *, loss_scale_sigma: float = LOSS_SCALE_SIGMA,
                  max_nfev: int = 60) -> BundleResult:
    """Refine static cameras and per-frame ball centres from the cameras' field lines and the ball labels
    (module docstring).

    Args:
        cameras: K cameras (pixels of their annotation images; ``None``: not adjusted, its labels unused).
        lines: K field-line annotations (pixels) of those cameras, ``None`` or empty when a camera has none.
            The lines of all cameras together must fix the world frame (in practice: at least two cameras).
        points_px: (F, K, 2) ball labels, px; NaN where none.
        inliers: (F, K) bool, the labels to use (e.g. those a trajectory keeps); frames with fewer than two
            used labels are left out (one view does not constrain a camera).
        start_m: (F, 3) initial ball centres, world metres (e.g. the per-frame triangulation); frames with
            a non-finite start are left out.
        loss_scale_sigma: soft-L1 scale in standard deviations.
        max_nfev: most solver iterations per round.

    Returns:
        :class:`BundleResult`.

    Raises:
        ValueError: shapes that disagree, or fewer than two cameras with lines.
    """
    pts = np.asarray(points_px, float)
    F, K = pts.shape[:2]
    if pts.shape != (F, K, 2) or len(cameras) != K or len(lines) != K or np.shape(inliers) != (F, K) \
            or np.shape(start_m) != (F, 3):
        raise ValueError("bundle_adjust: points (F, K, 2), inliers (F, K), start (F, 3), K cameras and lines")
    active = [k for k in range(K) if cameras[k] is not None]
    obs = {k: build_observations(lines[k]) for k in active if lines[k]}
    obs = {k: o for k, o in obs.items() if o.n_points}
    if len(obs) < 2:
        raise ValueError("bundle_adjust: needs two or more adjusted cameras with field lines")
    use = np.asarray(inliers, bool) & np.all(np.isfinite(pts), axis=2)
    use[:, [k for k in range(K) if cameras[k] is None]] = False
    start = np.asarray(start_m, float)
    frames = np.flatnonzero((use.sum(axis=1) >= 2) & np.all(np.isfinite(start), axis=1))
    use = use[frames]
    lab_f, lab_k = np.nonzero(use)  # label rows: frame position in ``frames``, camera index
    uv = pts[frames[lab_f], lab_k]

    params = {}
    x0 = []
    for k in active:
        cam = cameras[k]
        k1 = float(cam.radial[0]) if cam.radial is not None else 0.0
        params[k] = CameraParametrisation(principal_point=cam.K[:2, 2].copy(), R0=cam.R, fit_k1=k1 != 0.0)
        x0.append(params[k].vector(float(cam.K[0, 0]), cam.C, k1))
    offsets = np.cumsum([0] + [params[k].size for k in active])
    n_cam = int(offsets[-1])
    slot = {k: (int(offsets[i]), int(offsets[i + 1])) for i, k in enumerate(active)}
    x0 = np.concatenate(x0 + [start[frames].reshape(-1)])

    # line noise, pooled: sum of squared distances over the points less the fits' degrees of freedom
    d = np.concatenate([_distances(cameras[k], o) for k, o in obs.items()])
    sigma_lines = float(np.sqrt(np.sum(d**2) / max(len(d) - _CAMERA_DOF * len(obs), 1)))

    line_rows = {k: len(residuals(x0[slice(*slot[k])], o, params[k])) for k, o in obs.items()}
    n_line = sum(line_rows.values())

    def unpack(x):
        return {k: params[k].camera(x[slice(*slot[k])]) for k in active}, x[n_cam:].reshape(-1, 3)

    def ball_residuals(x) -> np.ndarray:
        cams, X = unpack(x)
        r = np.empty((len(lab_f), 2))
        for k in active:
            sel = lab_k == k
            if sel.any():
                p, front = cams[k].project(X[lab_f[sel]])
                rk = p - uv[sel]
                rk[~front] = _BEHIND
                r[sel] = rk
        return r

    def fun(x, sigma_ball):
        parts = [residuals(x[slice(*slot[k])], o, params[k]) / sigma_lines for k, o in obs.items()]
        parts.append(ball_residuals(x).reshape(-1) / sigma_ball)
        return np.concatenate(parts)

    # sparsity: line rows of camera k -> its parameters; the two rows of a label -> its camera and its point
    rows, cols = [], []
    r0 = 0
    for k, n in line_rows.items():
        a, b = slot[k]
        rr, cc = np.meshgrid(np.arange(r0, r0 + n), np.arange(a, b), indexing="ij")
        rows.append(rr.ravel())
        cols.append(cc.ravel())
        r0 += n
    lab_rows = n_line + 2 * np.arange(len(lab_f))
    for i, k in enumerate(active):
        a, b = slot[k]
        sel = np.flatnonzero(lab_k == k)
        for dr in (0, 1):
            rr, cc = np.meshgrid(lab_rows[sel] + dr, np.arange(a, b), indexing="ij")
            rows.append(rr.ravel())
            cols.append(cc.ravel())
    for dr in (0, 1):
        for j in range(3):
            rows.append(lab_rows + dr)
            cols.append(n_cam + 3 * lab_f + j)
    rows, cols = np.concatenate(rows), np.concatenate(cols)
    sparsity = coo_matrix((np.ones(len(rows)), (rows, cols)), shape=(n_line + 2 * len(lab_f), len(x0))).tocsr()

    def sigma_of(x) -> float:
        r = ball_residuals(x).reshape(-1)
        dof = max(len(r) - 3 * len(frames) - n_cam, 1)
        return max(float(1.4826 * np.median(np.abs(r)) * np.sqrt(len(r) / dof)), 1e-3)

    def rms(x, sigma) -> float:
        r = np.linalg.norm(ball_residuals(x), axis=1)
        r = r[r <= loss_scale_sigma * sigma]
        return float(np.sqrt(np.mean(r**2))) if len(r) else float("nan")

    x, nfev = x0, 0
    sigma_ball = sigma_of(x0)
    rms0 = rms(x0, sigma_ball)
    for _ in range(2):
        sol = least_squares(fun, x, args=(sigma_ball,), jac_sparsity=sparsity, loss="soft_l1",
                            f_scale=loss_scale_sigma, x_scale="jac", method="trf", tr_solver="lsmr",
                            max_nfev=max_nfev)
        x, nfev = sol.x, nfev + sol.nfev
        sigma_ball = sigma_of(x)
    cams, X = unpack(x)
    out_pts = np.full((F, 3), np.nan)
    out_pts[frames] = X
    return BundleResult([cams.get(k) for k in range(K)], out_pts, sigma_lines, sigma_ball,
                        (rms0, rms(x, sigma_ball)), len(frames), len(lab_f), int(nfev))
