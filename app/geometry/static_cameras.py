"""Static cameras of a sequence: calibrate a camera its field lines cannot, from the ball's trajectory.

A static camera (ISSIA) that sees few field lines (the centre circle and two side lines, say) can
be refused by :func:`app.geometry.calibration.calibrate_frame` or calibrated below admission
(JaC at the admission's gamma not above its threshold: :func:`app.geometry.jac.jac_admitted`). Its ball labels still
carry information: the other, admitted cameras give the ball's 3D position in many frames
(:mod:`app.geometry.trajectory`), and a camera that does not move is fixed by those 2D-3D correspondences (camera
resection: RANSAC over a grid of focal lengths, and the linear DLT of ``P`` split by RQ decomposition, Hartley and
Zisserman section 7.1, as starts of a robust refinement of focal length, rotation and centre on the reprojection error
with the principal point at the image centre). The camera's centre is then given to the line calibration as a prior
(:class:`~app.geometry.calibration.CalibrationPrior`), which fits focal length and rotation to the
lines; because focal length and distance trade off along the viewing direction, the centre is
then moved to where the lines and the ball agree best. The result is admitted only when its JaC at the admission's
gamma against the camera's own lines clears the same threshold, so the lines stay the judge.

World: SoccerNet metres, z down. Pure: numpy, scipy, OpenCV.
"""
from __future__ import annotations

import cv2
import numpy as np
from scipy.optimize import least_squares, minimize

from app.geometry.annotations import FieldLines
from app.geometry.calibration import CalibrationPrior, calibrate_frame
from app.geometry.camera import Camera
from app.geometry.jac import jac_admitted, jac_at_gammas

#: Focal lengths (as multiples of the image width) from which :func:`resect_from_ball` tries a RANSAC
#: resection with the focal length held: 0.4 (a wide angle) to 5 (a long lens), geometric steps of 10 %.
FOCAL_GRID_WIDTHS = np.geomspace(0.4, 5.0, 27)
#: RANSAC of each focal length: random sets of this many correspondences, this many times (with 30 %
#: wrong correspondences a set of 6 is all right with probability 0.12: 60 sets miss with probability 5e-4).
RANSAC_SAMPLE = 6
RANSAC_ITERATIONS = 60


def resect_from_ball(world_m: np.ndarray, image_px: np.ndarray, width: int, height: int, *,
                     inlier_px: float = 8.0) -> Camera | None:
    """A pinhole camera (square pixels, principal point ``((W - 1) / 2, (H - 1) / 2)``) from 2D-3D points,
    robust to wrong correspondences (a wrong label, a trajectory position off the ball).

    Starts: for each focal length of :data:`FOCAL_GRID_WIDTHS`, RANSAC resection with that focal length
    held (:func:`_pnp_start`, ``inlier_px``), and, when the points are not near
    one plane, the linear DLT of ``P`` split by RQ decomposition (Hartley and Zisserman section 7.1).
    Each start is refined (focal length, rotation, centre; Cauchy loss on the reprojection error, px;
    then again on the labels within ``inlier_px``); the camera with the most labels within ``inlier_px``
    wins (ties: the lower median error).

    Args:
        world_m: (N, 3) ball centres, world metres (SoccerNet, z down); N >= 8 and not all on one line.
        image_px: (N, 2) their labels in this camera, pixels.
        width, height: image size, px.
        inlier_px: labels further than this from the refined camera are left out (then refitted).

    Returns:
        The camera, or ``None`` when fewer than 8 points agree on one in front of them, above the grass.
    """
    X = np.asarray(world_m, float).reshape(-1, 3)
    u = np.asarray(image_px, float).reshape(-1, 2)
    ok = np.all(np.isfinite(X), 1) & np.all(np.isfinite(u), 1)
    X, u = X[ok], u[ok]
    if len(X) < 8:
        return None
    spread = np.linalg.svd(X - X.mean(0), compute_uv=False)
    if spread[1] < 0.5:  # metres: points on one line fix no camera
        return None
    pp = ((width - 1) / 2.0, (height - 1) / 2.0)
    found = [_pnp_start(X, u, f * width, pp, inlier_px) for f in FOCAL_GRID_WIDTHS]
    if spread[2] >= 0.05 * spread[0] and spread[2] >= 0.5:  # off one plane: the DLT fixes K and C together
        found.append(_dlt_start(X, u))
    starts = sorted((s for s in found if s is not None), key=lambda s: -s[0])[:3]  # the most inliers first

    def residual(q, idx):
        xc = (X[idx] - q[4:7]) @ cv2.Rodrigues(q[1:4])[0].T
        z = np.maximum(xc[:, 2], 1e-3)
        r = abs(q[0]) * xc[:, :2] / z[:, None] + np.array(pp) - u[idx]
        r[xc[:, 2] <= 1e-3] = 1e4
        return r.reshape(-1)

    best = None
    for _, q in starts:
        idx = np.arange(len(X))
        for _ in range(2):
            q = least_squares(residual, q, args=(idx,), loss="cauchy", f_scale=3.0, x_scale="jac").x
            err = np.linalg.norm(residual(q, np.arange(len(X))).reshape(-1, 2), axis=1)
            idx = np.nonzero(err < inlier_px)[0]
        if len(idx) < 8 or not q[6] < 0:  # too few agree, or a camera below the ground
            continue
        key = (len(idx), -float(np.median(err[idx])))
        if best is None or key > best[0]:
            best = (key, q)
    if best is None:
        return None
    q = best[1]
    f = abs(q[0])
    return Camera(K=np.array([[f, 0, pp[0]], [0, f, pp[1]], [0, 0, 1.0]]), R=cv2.Rodrigues(q[1:4])[0], C=q[4:7])


def _pnp_start(X: np.ndarray, u: np.ndarray, focal_px: float, pp: tuple[float, float], inlier_px: float,
               iterations: int = RANSAC_ITERATIONS) -> tuple[int, np.ndarray] | None:
    """(inliers, ``(f, rvec, C)``) of a RANSAC resection with focal length ``focal_px`` held, or ``None``:
    ``iterations`` random sets of :data:`RANSAC_SAMPLE` correspondences (a fixed seed: the same answer every
    time) each solved by ``cv2.solvePnP`` (SQPnP: planar sets too), scored by the labels within
    ``inlier_px`` of points in front of the camera, the best one solved again from its inliers."""
    K = np.array([[focal_px, 0, pp[0]], [0, focal_px, pp[1]], [0, 0, 1.0]])
    rng = np.random.default_rng(0)

    def inliers(rvec, tvec):
        xc = X @ cv2.Rodrigues(rvec)[0].T + tvec.reshape(3)
        z = xc[:, 2]
        with np.errstate(divide="ignore", invalid="ignore"):
            err = np.linalg.norm(focal_px * xc[:, :2] / z[:, None] + np.array(pp) - u, axis=1)
        return np.flatnonzero((z > 0) & (err < inlier_px))

    best = None
    for _ in range(iterations):
        pick = rng.choice(len(X), RANSAC_SAMPLE, replace=False)
        try:
            ok, rvec, tvec = cv2.solvePnP(X[pick], u[pick], K, None, flags=cv2.SOLVEPNP_SQPNP)
        except cv2.error:
            continue
        if ok:
            inl = inliers(rvec, tvec)
            if best is None or len(inl) > len(best):
                best = inl
    if best is None or len(best) < 8:
        return None
    ok, rvec, tvec = cv2.solvePnP(X[best], u[best], K, None, flags=cv2.SOLVEPNP_SQPNP)
    if not ok:
        return None
    R = cv2.Rodrigues(rvec)[0]
    return len(inliers(rvec, tvec)), np.concatenate([[focal_px], rvec.reshape(3), -R.T @ tvec.reshape(3)])


def _dlt_start(X: np.ndarray, u: np.ndarray) -> tuple[int, np.ndarray] | None:
    """(0, ``(f, rvec, C)``) from the normalised linear DLT of ``P`` (every point weighs), or ``None`` when it
    puts the points behind the camera."""
    # Hartley normalisation: centred points, mean distance sqrt(3) (3D) and sqrt(2) (2D)
    mX, mu = X.mean(0), u.mean(0)
    sX = np.sqrt(3) / np.mean(np.linalg.norm(X - mX, axis=1))
    su = np.sqrt(2) / np.mean(np.linalg.norm(u - mu, axis=1))
    TX = np.diag([sX, sX, sX, 1.0])
    TX[:3, 3] = -sX * mX
    Tu = np.diag([su, su, 1.0])
    Tu[:2, 2] = -su * mu
    Xh = np.hstack([X, np.ones((len(X), 1))])
    Xn, un = Xh @ TX.T, (np.hstack([u, np.ones((len(u), 1))]) @ Tu.T)[:, :2]
    A = np.zeros((2 * len(X), 12))
    A[0::2, 0:4], A[0::2, 8:12] = Xn, -un[:, :1] * Xn
    A[1::2, 4:8], A[1::2, 8:12] = Xn, -un[:, 1:] * Xn
    P = np.linalg.inv(Tu) @ np.linalg.svd(A)[2][-1].reshape(3, 4) @ TX
    if np.median(Xh @ P[2]) < 0:  # the DLT's sign ambiguity: the points must lie in front of the camera
        P = -P
    K, R = _rq(P[:, :3])
    C = -np.linalg.solve(P[:, :3], P[:, 3])
    f0 = 0.5 * (K[0, 0] + K[1, 1]) / K[2, 2]
    if not f0 > 0 or np.median((X - C) @ R[2]) < 0:
        return None
    return 0, np.concatenate([[f0], cv2.Rodrigues(R)[0].reshape(3), C])


def _rq(M: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """M = K R with K upper triangular with a positive diagonal and R a rotation (det +1) when det M > 0."""
    K, R = cv2.RQDecomp3x3(np.asarray(M, float))[1:3]
    D = np.diag(np.sign(np.diag(K)))
    K, R = K @ D, D @ R
    if np.linalg.det(R) < 0:
        R = -R
        K = -K
    return K, R


def calibrate_with_ball(lines: FieldLines | None, world_m: np.ndarray, image_px: np.ndarray, width: int, height: int,
                        *, admit_jac_gamma: float, admit_jac_min: float, search_m: float = 1.0,
                        max_evaluations: int = 150) -> tuple[Camera | None, float | None]:
    """Resect a static camera from ball correspondences (:func:`resect_from_ball`), then, with
    lines, re-fit focal length and rotation to them with the centre held fixed, moving the centre
    (Nelder-Mead, first steps ``search_m`` metres, at most ``max_evaluations`` calibrations) to where
    the fit agrees best with both (hypot of the RMS line residual and the median ball reprojection
    error, px); keep the
    candidate with the higher JaC at ``admit_jac_gamma`` (a fraction of the image diagonal) and admit it when
    that JaC is above ``admit_jac_min`` (:func:`app.geometry.jac.jac_admitted`; the service passes its settings').

    Returns:
        ``(camera, jac)``: ``camera`` is ``None`` when nothing is admitted; ``jac`` is the best
        JaC at ``admit_jac_gamma`` reached (``None`` without lines or without any candidate). Without lines the
        resected camera is returned unjudged.
    """
    X = np.asarray(world_m, float).reshape(-1, 3)
    u = np.asarray(image_px, float).reshape(-1, 2)
    cam = resect_from_ball(X, u, width, height)
    if cam is None:
        return None, None
    if not lines:
        return cam, None
    candidates = [cam]
    # ball points fix the centre well across the viewing direction, less well along it (focal length and
    # distance trade off): the centre moves (Nelder-Mead from the resected one) to where the line
    # calibration with that centre held fixed agrees best with both the lines and the ball
    def score(centre):
        if centre[2] >= 0:
            return 1e6, None
        prior = CalibrationPrior(centre_m=(float(centre[0]), float(centre[1]), float(centre[2])))
        res = calibrate_frame(lines, width, height, prior=prior, compute_jac=False)
        if res.camera is None:
            return 1e6, None
        assert res.rms_px is not None  # a fitted camera has its rms
        uv, front = res.camera.project(X)
        ball_px = float(np.median(np.linalg.norm(uv[front] - u[front], axis=1))) if front.any() else 1e6
        return float(np.hypot(res.rms_px, ball_px)), res.camera

    simplex = cam.C + np.vstack([np.zeros(3), np.eye(3) * search_m])
    opt = minimize(lambda c: score(c)[0], cam.C, method="Nelder-Mead",
                   options={"initial_simplex": simplex, "maxfev": max_evaluations, "xatol": 0.02, "fatol": 0.01})
    best = score(opt.x)[1]
    if best is not None:
        candidates.append(best)
    scored = [(jac_at_gammas(c, lines, width, height, (admit_jac_gamma,))[admit_jac_gamma], i, c)
              for i, c in enumerate(candidates)]
    jac, _, best = max(scored, key=lambda s: (s[0], s[1]))  # equal JaC: the camera fitted to the lines
    return (best if jac_admitted(jac, admit_jac_min) else None), float(jac)
