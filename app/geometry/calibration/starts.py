"""The starting cameras of a frame's calibration and their fits: ground homographies, fixed-centre rotations
at a known centre, look-at cameras from plausible broadcast positions; each start ranked by one compiled
evaluation and the best refined (:func:`~.solver.robust_lm`) within a budget of residual evaluations.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from app.geometry.annotations import image_diagonal
from app.geometry.calibration.held_out import distances_by_class
from app.geometry.calibration.initialisation import (
    camera_from_homography,
    fixed_centre_rotations,
    ground_homographies,
    labelled_target,
)
from app.geometry.calibration.observations import Observations
from app.geometry.calibration.residuals import (
    CameraParametrisation,
    ground_points_in_front,
    projection_matrix,
    residual_rows,
)
from app.geometry.calibration.result import CalibrationPrior, CalibrationSettings, principal_point
from app.geometry.calibration.solver import PriorRows, abs_percentile, robust_lm, soft_l1_cost
from app.geometry.camera import Camera, look_at_rotation

#: Plausible camera centres (world, metres, z down) tried, in this order, when the lines do not fix
#: a homography: main broadcast camera on either side, 18-yard cameras, high and low behind-goal
#: cameras. Only starting points; the refinement moves the centre freely.
START_CENTRES_M: tuple[tuple[float, float, float], ...] = (
    (0.0, 60.0, -20.0), (0.0, -60.0, -20.0),
    (-35.0, 45.0, -10.0), (35.0, 45.0, -10.0), (-35.0, -45.0, -10.0), (35.0, -45.0, -10.0),
    (-70.0, 0.0, -15.0), (70.0, 0.0, -15.0),
    (-58.0, 0.0, -2.0), (58.0, 0.0, -2.0),
)


@dataclass
class Candidate:
    """A camera fitted from one start: its parameter vector ``x`` under ``param``, robust cost (px^2), 90th
    percentile point distance ``p90`` (px), Jacobian at ``x``, the start it came from (``origin``, a label
    carried along) and whether the radial term was tried on it."""

    x: np.ndarray
    param: CameraParametrisation
    cost: float
    p90: float
    jacobian: np.ndarray
    origin: str
    k1_tried: bool = False


@dataclass
class Budget:
    """Residual evaluations left for one frame: bounds the worst-case time of a frame whose labels
    fit no camera, deterministically (the count does not depend on the machine's load)."""

    evaluations: int
    lookat_done: bool = False


def start_costs(xs: list[np.ndarray], params: list[CameraParametrisation], obs: Observations,
                 scale: float) -> list[float]:
    """Robust cost (px^2) of each start ``xs[i]`` under ``params[i]`` (all of one shape), in one
    compiled evaluation."""
    if not xs:
        return []
    return soft_l1_cost(residual_rows(np.array(xs), obs, params), scale).tolist()


def fit_start(x0: np.ndarray, obs: Observations, param: CameraParametrisation, scale: float, origin: str,
         budget: Budget, max_iter: int = 25, prior: PriorRows | None = None) -> Candidate | None:
    """Refine from ``x0`` (with the MAP ``prior`` rows, if any) and keep the result if it is a
    physical camera seeing its labels in front (a :class:`Candidate`, or None)."""
    if budget.evaluations <= 0:
        return None
    lower = np.full(len(x0), -np.inf)
    upper = np.full(len(x0), np.inf)
    lower[0], upper[0] = 10.0, 1e6
    if param.fixed_centre is None:
        upper[6] = -0.5  # above the ground (z points down); lower is a degenerate edge-on view
    try:
        sol = robust_lm(x0, obs, param, scale, lower=lower, upper=upper, max_iter=max_iter, tol=1e-5,
                        max_evaluations=budget.evaluations, prior=prior)
    except (ValueError, np.linalg.LinAlgError):
        budget.evaluations -= max_iter
        return None
    budget.evaluations -= sol.evaluations
    f, R, C, _ = param.split(sol.x)
    P = projection_matrix(f, param.principal_point, R, C)
    if not np.isfinite(sol.cost) or ground_points_in_front(P, obs) < 0.999:
        return None
    return Candidate(x=sol.x, param=param, cost=sol.cost, p90=abs_percentile(sol.residuals, 90),
                      jacobian=sol.jacobian, origin=origin)


def class_residuals(camera: Camera, obs: Observations) -> tuple[dict[str, float], float]:
    """Largest distance (px) of each class's points to its element, and the RMS over all points."""
    per_point = distances_by_class(camera, obs)
    out = {c: float(np.max(d)) for c, d in per_point.items()}
    allr = np.concatenate(list(per_point.values())) if per_point else np.zeros(0)
    return out, float(np.sqrt(np.mean(allr**2))) if len(allr) else 0.0


def search_starts(obs: Observations, width: int, height: int, prior: CalibrationPrior | None,
            settings: CalibrationSettings, budget: Budget, stage: str = "homography") -> Candidate | None:
    """Best camera from one family of starts.

    ``stage="homography"``: the closed-form cameras of the candidate ground homographies (the
    look-at starts too when there is none); ``stage="look-at"``: the look-at starts only;
    ``stage="anchors"``: look-at starts at the learned prior's anchors (``prior.camera_prior``). With a
    known centre (rig prior) only fixed-centre fits are made.
    """
    pp = principal_point(width, height)
    diag = image_diagonal(width, height)
    scale = settings.loss_scale_gamma * diag
    accept = settings.accept_gamma * diag
    best: Candidate | None = None

    def consider(c: Candidate | None) -> bool:
        nonlocal best
        if c is not None and (best is None or c.cost < best.cost):
            best = c
        return best is not None and best.p90 < accept

    target = labelled_target(obs)
    if prior is not None and prior.centre_m is not None:
        centre = np.asarray(prior.centre_m, dtype=float)
        starts = _fixed_centre_starts(obs, centre, pp, width, scale)
        for _, param, x0 in starts[:FIXED_CENTRE_REFINED]:
            if consider(fit_start(x0, obs, param, scale, "rig", budget)):
                break
        return best

    homography = homography_starts(obs, pp, scale) if stage == "homography" else []
    for _, name, param, x0 in homography[:2]:
        cand = fit_start(x0, obs, param, scale, name, budget)
        if consider(cand):
            return best
        if cand is not None and cand is best and obs.n_points >= settings.k1_min_points:
            # The lines may be curved by the lens: try the radial term before another start.
            best = with_k1(cand, obs, scale, settings, budget)
            if best.p90 < accept:
                return best

    if homography:
        # The lines fix a homography but its camera leaves some labels far off: a mislabelled line
        # is the likelier cause; the caller tries without each class before the look-at starts.
        return best

    # Look-at starts: a pan-tilt-zoom fit at each plausible centre (cheap, 4 parameters), then the
    # free refinement of the best two. The learned anchors (stage "anchors"): the best
    # ANCHOR_STARTS of them by the look-at start's robust cost.
    budget.lookat_done = True
    centres = [np.asarray(c, dtype=float) for c in START_CENTRES_M]
    if stage == "anchors":
        centres = [np.asarray(c, dtype=float) for c in prior.camera_prior.anchors_m]  # type: ignore[union-attr]  # the anchors stage runs only with a camera prior
    starts_ptz: list[tuple[str, CameraParametrisation, np.ndarray]] = []
    for c0 in centres:
        try:
            R0 = look_at_rotation(c0, target)
        except ValueError:
            continue
        fixed = CameraParametrisation(principal_point=pp, R0=R0, fixed_centre=c0)
        starts_ptz.append((f"start {tuple(c0.tolist())}", fixed, fixed.vector(1.5 * width, c0)))
    if stage == "anchors" and starts_ptz:
        costs = start_costs([x0 for _, _, x0 in starts_ptz], [q for _, q, _ in starts_ptz], obs, scale)
        starts_ptz = [starts_ptz[i] for i in np.argsort(costs, kind="stable")[:ANCHOR_STARTS]]
    ptz: list[Candidate] = []
    for name, fixed, x0 in starts_ptz:
        cand = fit_start(x0, obs, fixed, scale, name, budget, max_iter=8)
        if cand is not None:
            ptz.append(cand)
    ptz.sort(key=lambda c: c.cost)
    for cand in ptz[:2]:
        f1, R1, C1, _ = cand.param.split(cand.x)
        free = CameraParametrisation(principal_point=pp, R0=R1)
        if consider(fit_start(free.vector(float(f1), C1), obs, free, scale, cand.origin, budget)):
            break
    return best


#: Anchors of a learned prior refined as look-at starts (the best by the start's robust cost) when
#: no other start fits the labels.
ANCHOR_STARTS = 6


#: Focal length hypotheses (multiples of the image width) of a camera with a known centre: from a
#: wide view (0.5 W, about 90 degrees across) to a tight zoom (8 W, about 7 degrees), geometric steps.
FIXED_CENTRE_FOCALS_W: tuple[float, ...] = (0.5, 0.8, 1.25, 2.0, 3.2, 5.0, 8.0)


#: Fixed-centre starts refined (the best by robust cost at the start).
FIXED_CENTRE_REFINED = 3


def _fixed_centre_starts(obs: Observations, centre: np.ndarray, pp: np.ndarray, width: int, scale: float
                         ) -> list[tuple[float, CameraParametrisation, np.ndarray]]:
    """Starts of a fit with the centre held fixed, ranked by robust cost (``[(cost, parametrisation,
    x0)]``): for each focal hypothesis of
    :data:`FIXED_CENTRE_FOCALS_W`, the rotation that puts the labels' anchors where the labels show
    them (:func:`~.initialisation.fixed_centre_rotations`, a Wahba fit of image rays to world
    directions), and the rotation looking at the labelled part of the pitch."""
    focals = np.asarray(FIXED_CENTRE_FOCALS_W) * width
    rotations = list(fixed_centre_rotations(obs, centre, pp, focals))
    f_all = list(focals)
    try:
        look = look_at_rotation(centre, labelled_target(obs))
        rotations += [look] * len(focals)
        f_all += list(focals)
    except ValueError:
        pass
    params = [CameraParametrisation(principal_point=pp, R0=R0, fixed_centre=centre) for R0 in rotations]
    x0s = [param.vector(float(f0), centre) for param, f0 in zip(params, f_all, strict=True)]
    starts = list(zip(start_costs(x0s, params, obs, scale), params, x0s, strict=True))
    starts.sort(key=lambda t: t[0])
    return starts


def homography_starts(obs: Observations, pp: np.ndarray, scale: float
                       ) -> list[tuple[float, str, CameraParametrisation, np.ndarray]]:
    """Closed-form cameras of the candidate ground homographies, ranked by robust cost
    (``[(cost, name, parametrisation, x0)]``)."""
    inits: list[tuple[str, CameraParametrisation, np.ndarray]] = []
    for name, H in ground_homographies(obs, pp, float(2.0 * pp[0] + 1.0)):
        init = camera_from_homography(H, pp)
        if init is None:
            continue
        f0, R0, C0 = init
        param = CameraParametrisation(principal_point=pp, R0=R0)
        inits.append((name, param, param.vector(f0, C0)))
    costs = start_costs([x0 for _, _, x0 in inits], [param for _, param, _ in inits], obs, scale)
    starts = [(cost, name, param, x0) for cost, (name, param, x0) in zip(costs, inits, strict=True)]
    starts.sort(key=lambda t: t[0])
    return starts


def worst_residual(cand: Candidate | None, obs: Observations) -> float:
    """Largest class residual (px) of a candidate, infinity for none."""
    if cand is None:
        return float("inf")
    per_class = class_residuals(cand.param.camera(cand.x), obs)[0]
    return max(per_class.values()) if per_class else 0.0


def with_free_k1(best: Candidate) -> tuple[CameraParametrisation, float, np.ndarray, float]:
    """``best``'s parametrisation with ``k1`` free (its rotation as the reference, its centre fixed if
    it was), with its focal (px), centre (m) and ``k1``: what a refit with the radial term starts from."""
    f, R, C, k1 = best.param.split(best.x)
    param = CameraParametrisation(principal_point=best.param.principal_point, R0=R, fit_k1=True,
                                  fixed_centre=best.param.fixed_centre)
    return param, float(f), C, float(k1)


def with_k1(best: Candidate, obs: Observations, scale: float, settings: CalibrationSettings,
             budget: Budget) -> Candidate:
    """Add the radial coefficient when it lowers the robust cost by ``k1_min_gain`` or more (the
    better :class:`Candidate`)."""
    param, f, C, _ = with_free_k1(best)
    best.k1_tried = True
    cand = fit_start(param.vector(float(f), C, 0.0), obs, param, scale, best.origin + " +k1", budget)
    if cand is None or abs(cand.x[-1]) > settings.max_k1:
        return best
    if cand.cost < (1.0 - settings.k1_min_gain) * best.cost:
        cand.k1_tried = True
        return cand
    return best
