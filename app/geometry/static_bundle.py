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
  (the maximum-likelihood weighting of independent Gaussian errors; not a tuned ratio):

  - the line residuals of each camera, exactly those the calibration minimises
    (:func:`app.geometry.calibration.residuals.residuals`: point-to-line and beyond-the-end distances,
    Sampson distance to circles, each class weighted as at most four points), over ``sigma_lines_px``;
  - the ball's reprojection residuals (x and y, px) of the labels given as inliers, over ``sigma_ball_px``;

  both noise levels are estimated from the data (``sqrt(sum r^2 / (n - p))`` over the residuals within
  :data:`TRIM_SIGMA` times a median-based guess, ``p`` the parameters the fit absorbs: 7 per camera for the
  lines, 3 per frame and the cameras' for the ball), first at the start, then again at each round's
  solution, from which the next round starts, until neither moves by more than :data:`SIGMA_SETTLED` (at
  most ``max_rounds``);

* loss: soft-L1 at :data:`LOSS_SCALE_SIGMA` standard deviations (a few pixels), so that a wrong label
  (1 % of them, hundreds of pixels off) or a mis-clicked line point pulls like a few correct ones;
* solver: Levenberg-Marquardt on the robust cost (IRLS, as the calibration's own solver), each step's
  points eliminated by the Schur complement (the Jacobian is sparse: a label's residuals depend on its
  camera and its frame's point only, a line's on its camera), so a step costs a reduced system of the
  cameras' parameters and a 3 x 3 block per frame: linear in the frames (:func:`_schur_lm`).
  ``scipy.optimize.least_squares`` with ``jac_sparsity`` and ``lsmr`` steps was tried first: from a start
  0.3 m off it stopped after 400 evaluations still 0.1-0.6 m off (12 s), where this converges.

World: SoccerNet metres, origin at the centre spot, z down. Image: continuous pixels. Pure: numpy, scipy.
"""
from __future__ import annotations

import functools
from dataclasses import dataclass
from typing import Sequence

import numpy as np

from app.geometry.annotations import FieldLines
from app.geometry.calibration.observations import build_observations
from app.geometry.calibration.residuals import CameraParametrisation, residuals
from app.geometry.calibration.solver import soft_l1_cost
from app.geometry.camera import Camera

#: Soft-L1 scale of every residual, in its standard deviations (about 2-3 px for 0.7-1 px of noise).
LOSS_SCALE_SIGMA = 3.0
#: Whitened residual given to a label whose point falls behind its camera (keeps the cost finite).
_BEHIND = 1e3
#: Residuals beyond this many times the first guess of the noise are left out of its estimate.
TRIM_SIGMA = 5.0
#: Rounds stop when neither noise level moved by more than this fraction.
SIGMA_SETTLED = 0.05
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
        evaluations: residual evaluations (full-evaluation equivalents, Jacobians included) of all rounds.
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


def _parametrise(cameras: Sequence[Camera | None], active: list[int], start: np.ndarray
                 ) -> tuple[dict[int, CameraParametrisation], dict[int, tuple[int, int]], int, dict[int, np.ndarray]]:
    """The adjusted cameras' parametrisation (focal length, centre, rotation about their own, k1 where they have
    one), their slots in the solver's vector, its number of camera parameters, and each camera's start vector (a
    slice of the whole start: the cameras', then ``start``, the (N, 3) ball centres)."""
    params = {}
    x0_parts = []
    for k in active:
        cam = cameras[k]
        assert cam is not None  # active: the cameras that are set
        k1 = float(cam.radial[0]) if cam.radial is not None else 0.0
        params[k] = CameraParametrisation(principal_point=cam.K[:2, 2].copy(), R0=cam.R, fit_k1=k1 != 0.0)
        x0_parts.append(params[k].vector(float(cam.K[0, 0]), cam.C, k1))
    offsets = np.cumsum([0] + [params[k].size for k in active])
    n_cam = int(offsets[-1])
    slot = {k: (int(offsets[i]), int(offsets[i + 1])) for i, k in enumerate(active)}
    x0 = np.concatenate(x0_parts + [start.reshape(-1)])
    return params, slot, n_cam, {k: x0[slice(*slot[k])] for k in active}


def _noise_sigma(r: np.ndarray, dof: int) -> float:
    """The residuals' standard deviation, px: ``sqrt(sum r^2 / (n - dof))`` over those within
    :data:`TRIM_SIGMA` times a first, robust guess (1.4826 median |r|), ``dof`` the parameters the fit
    absorbs (unbiased for least squares; the guess alone is not, as a frame seen twice keeps 1 of its 4)."""
    guess = 1.4826 * float(np.median(np.abs(r))) * np.sqrt(len(r) / max(len(r) - dof, 1))
    kept = r[np.abs(r) <= TRIM_SIGMA * guess]
    return max(float(np.sqrt(np.sum(kept**2) / max(len(kept) - dof, 1))), 1e-3)


@dataclass(frozen=True)
class _Residuals:
    """The bundle's residuals, whitened: each camera's field lines and the ball labels' reprojections, over the
    selected labels (``lab_f``: frame position of each label; ``by_cam``: each camera's label rows; ``uv``: (labels,
    2) px)."""

    params: dict[int, CameraParametrisation]
    obs: dict
    uv: np.ndarray
    lab_f: np.ndarray
    by_cam: dict[int, np.ndarray]
    n_frames: int
    n_cam: int

    def line_res(self, k, xk, sigma_lines):
        return residuals(xk, self.obs[k], self.params[k]) / sigma_lines if k in self.obs else np.zeros(0)

    def ball_res(self, k, xk, X, sigma_ball):
        """(labels of camera k, 2) whitened reprojection residuals of the points ``X`` (one per label)."""
        p, front = self.params[k].camera(xk).project(X)
        r = (p - self.uv[self.by_cam[k]]) / sigma_ball
        r[~front] = _BEHIND
        return r

    def all_ball(self, xs, X, sigma_ball) -> np.ndarray:
        r = np.empty((len(self.lab_f), 2))
        for k in self.by_cam:
            if len(self.by_cam[k]):
                r[self.by_cam[k]] = self.ball_res(k, xs[k], X[self.lab_f[self.by_cam[k]]], sigma_ball)
        return r

    def sigmas(self, xs, X) -> tuple[float, float]:
        d = np.concatenate([_distances(self.params[k].camera(xs[k]), o) for k, o in self.obs.items()])
        return (_noise_sigma(d, _CAMERA_DOF * len(self.obs)),
                _noise_sigma(self.all_ball(xs, X, 1.0).reshape(-1), 3 * self.n_frames + self.n_cam))

    def rms(self, xs, X, sigma, loss_scale_sigma) -> float:
        r = np.linalg.norm(self.all_ball(xs, X, 1.0), axis=1)
        r = r[r <= loss_scale_sigma * sigma]
        return float(np.sqrt(np.mean(r**2))) if len(r) else float("nan")


def bundle_adjust(cameras: Sequence[Camera | None], lines: Sequence[FieldLines | None], points_px: np.ndarray,
                  inliers: np.ndarray, start_m: np.ndarray, *, loss_scale_sigma: float = LOSS_SCALE_SIGMA,
                  max_iterations: int = 50, max_rounds: int = 4) -> BundleResult:
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
        max_iterations: most Levenberg-Marquardt linearisations per round.
        max_rounds: most rounds (each re-estimates both noise levels at the last solution and solves again).

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
    obs = {k: build_observations(labelled) for k in active if (labelled := lines[k])}
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

    params, slot, n_cam, cam_x = _parametrise(cameras, active, start[frames])
    X0 = start[frames].copy()
    res = _Residuals(params, obs, uv, lab_f, {k: np.flatnonzero(lab_k == k) for k in active}, len(frames), n_cam)
    by_cam = res.by_cam
    line_res, ball_res, sigmas, rms = res.line_res, res.ball_res, res.sigmas, res.rms

    xs, X, nfev = cam_x, X0, 0
    sigma_lines, sigma_ball = sigmas(xs, X)
    rms0 = rms(xs, X, sigma_ball, loss_scale_sigma)
    for _ in range(max_rounds):
        xs, X, n = _schur_lm(xs, X, active, slot, n_cam, lab_f, by_cam, len(frames),
                             functools.partial(line_res, sigma_lines=sigma_lines),
                             functools.partial(ball_res, sigma_ball=sigma_ball), loss_scale_sigma, max_iterations)
        nfev += n
        new = sigmas(xs, X)
        settled = all(abs(a / b - 1) < SIGMA_SETTLED for a, b in zip(new, (sigma_lines, sigma_ball), strict=True))
        sigma_lines, sigma_ball = new
        if settled:
            break
    cams = {k: params[k].camera(xs[k]) for k in active}
    out_pts = np.full((F, 3), np.nan)
    out_pts[frames] = X
    return BundleResult([cams.get(k) for k in range(K)], out_pts, sigma_lines, sigma_ball,
                        (rms0, rms(xs, X, sigma_ball, loss_scale_sigma)), len(frames), len(lab_f), int(nfev))


def _schur_lm(xs: dict, X: np.ndarray, active: list[int], slot: dict, n_cam: int, lab_f: np.ndarray,
              by_cam: dict, n_frames: int, line_res, ball_res, scale: float, max_iterations: int,
              rel_step: float = 1e-6, tol: float = 1e-7) -> tuple[dict, np.ndarray, int]:
    """Minimise the soft-L1 cost (``scale``) of the whitened line and ball residuals over the cameras'
    parameter vectors ``xs`` (camera index -> vector) and the points ``X`` (frames, 3), from there.

    Levenberg-Marquardt in the IRLS form of the robust loss (as :func:`app.geometry.calibration.solver.
    robust_lm`), with the points eliminated from each damped step by the Schur complement (Triggs et al.,
    section 6.1; Hartley and Zisserman, appendix A6.3): the reduced camera system is ``n_cam`` square, each
    frame's point a 3 x 3 block, so a step is linear in the frames. The Jacobian is made of forward
    differences, each camera parameter moving only that camera's residuals and each point coordinate (all
    points at once) only its labels'. Returns the solution and the residual evaluations made (each a full
    evaluation's worth)."""
    n_lab = len(lab_f)

    def evaluate(xs, X):
        rl = {k: line_res(k, xs[k]) for k in active}
        rb = np.zeros((n_lab, 2))
        for k in active:
            if len(by_cam[k]):
                rb[by_cam[k]] = ball_res(k, xs[k], X[lab_f[by_cam[k]]])
        return rl, rb

    def cost_of(rl, rb) -> float:
        return float(soft_l1_cost(np.concatenate([*rl.values(), rb.reshape(-1)]), scale))

    rl, rb = evaluate(xs, X)
    cost, nfev, lam = cost_of(rl, rb), 1, 1e-3
    for _ in range(max_iterations):
        # Jacobian blocks: lines and labels of camera k by its parameters; labels by their point
        Jl, Jb = {}, {}
        for k in active:
            xk, idx = xs[k], by_cam[k]
            Jl[k] = np.empty((len(rl[k]), len(xk)))
            Jb[k] = np.empty((len(idx), 2, len(xk)))
            for j in range(len(xk)):
                probe = xk.copy()
                h = rel_step * max(1.0, abs(xk[j]))
                probe[j] += h
                Jl[k][:, j] = (line_res(k, probe) - rl[k]) / h
                if len(idx):
                    Jb[k][:, :, j] = (ball_res(k, probe, X[lab_f[idx]]) - rb[idx]) / h
        nfev += n_cam // max(len(active), 1)
        Jp = np.empty((n_lab, 2, 3))
        for j in range(3):
            h = rel_step * np.maximum(1.0, np.abs(X[:, j]))
            probe = X.copy()
            probe[:, j] += h
            for k in active:
                idx = by_cam[k]
                if len(idx):
                    Jp[idx, :, j] = (ball_res(k, xs[k], probe[lab_f[idx]]) - rb[idx]) / h[lab_f[idx], None]
        nfev += 3
        # normal equations of the IRLS step (weights rho'(s) of soft-L1)
        U, g_c = np.zeros((n_cam, n_cam)), np.zeros(n_cam)
        V, g_p = np.zeros((n_frames, 3, 3)), np.zeros((n_frames, 3))
        W = np.zeros((n_frames, n_cam, 3))
        wb = 1.0 / np.sqrt(1.0 + (rb / scale) ** 2)
        for k in active:
            a, b = slot[k]
            wl = 1.0 / np.sqrt(1.0 + (rl[k] / scale) ** 2)
            U[a:b, a:b] += Jl[k].T @ (wl[:, None] * Jl[k])
            g_c[a:b] += Jl[k].T @ (wl * rl[k])
            idx = by_cam[k]
            if len(idx):
                wJ = wb[idx][:, :, None] * Jb[k]
                U[a:b, a:b] += np.einsum("lri,lrj->ij", Jb[k], wJ)
                g_c[a:b] += np.einsum("lri,lr->i", wJ, rb[idx])
                W[lab_f[idx], a:b, :] = np.einsum("lri,lrj->lij", wJ, Jp[idx])  # one label per camera and frame
        wJp = wb[:, :, None] * Jp
        np.add.at(V, lab_f, np.einsum("lri,lrj->lij", Jp, wJp))
        np.add.at(g_p, lab_f, np.einsum("lri,lr->li", wJp, rb))
        dU, dV = np.maximum(np.diag(U), 1e-12), np.maximum(np.einsum("fii->fi", V), 1e-12)
        improved, gain = False, 0.0
        while lam < 1e10:
            Vd = V + lam * dV[:, :, None] * np.eye(3)
            Vinv = np.linalg.inv(Vd)
            T = np.einsum("fai,fij->faj", W, Vinv)
            S = (U + lam * np.diag(dU)
                 - T.transpose(1, 0, 2).reshape(n_cam, -1) @ W.transpose(1, 0, 2).reshape(n_cam, -1).T)
            rhs = g_c - np.einsum("faj,fj->a", T, g_p)
            try:
                dc = np.linalg.solve(S, rhs)
            except np.linalg.LinAlgError:
                lam *= 10.0
                continue
            dp = np.einsum("fij,fj->fi", Vinv, g_p - np.einsum("fai,a->fi", W, dc))
            xs_new = {k: xs[k] - dc[slot[k][0]:slot[k][1]] for k in active}
            X_new = X - dp
            rl_new, rb_new = evaluate(xs_new, X_new)
            nfev += 1
            cost_new = cost_of(rl_new, rb_new)
            if np.isfinite(cost_new) and cost_new < cost:
                gain = (cost - cost_new) / max(cost, 1e-300)
                xs, X, rl, rb, cost = xs_new, X_new, rl_new, rb_new, cost_new
                lam = max(lam / 5.0, 1e-9)
                improved = True
                break
            lam *= 5.0
        if not improved or gain < tol:
            break
    return xs, X, nfev
