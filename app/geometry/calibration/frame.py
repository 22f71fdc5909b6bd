"""Calibrate one frame from its annotated field lines.

Method (every step pure numpy):

1. Pair every annotated point with its model element (:mod:`.observations`).
2. Starting cameras (:mod:`.initialisation`): ground homographies from the straight ground lines
   (point-on-line DLT), completed where needed by correspondences derived from the labelled circles
   (poles of the lines, line-circle crossings and tangency points, each ambiguous pair tried both
   ways); each becomes a camera with the principal point fixed and square pixels, and the two with
   the smallest robust cost are refined. When no homography exists, cameras at plausible broadcast
   positions looking at the labelled part of the pitch, first refined with their centre held fixed
   (pan-tilt-zoom, 4 parameters), the two best then freed. With a known centre (the game's rig,
   :class:`CalibrationPrior`), rotations from a Wahba fit of the image rays of the anchors the
   labels fix to their world directions, for a series of focal lengths
   (:func:`~.initialisation.fixed_centre_rotations`), and the look-at rotation; the best three by
   robust cost are refined with the centre held fixed, and the fit is refused beyond
   ``accept_gamma`` RMS.
3. Robust Levenberg-Marquardt (:mod:`.solver`, soft-L1 loss) of focal length, rotation and centre
   on the pixel distance of every annotated point to its model line / circle / goal element
   (:mod:`.residuals`); goal posts and crossbars constrain the camera off the ground plane. One
   radial coefficient ``k1`` is added only when the pinhole fit leaves residuals above the loss
   scale and lowers the robust cost by 30 % or more.
4. When the winner leaves a class far from its element, every class is left out in turn (one
   mislabelled line, e.g. a left/right confusion, spoils a whole frame) and the look-at starts
   are tried; the class left out is flagged ``ignored_class:<class>``.
5. The candidate with the smallest robust cost wins (the labels' JaC is never used to choose: it is
   the evaluation). The result is refused, with a reason, when the labels cannot fix a camera
   (too few constraints, parallel or collinear labels) or no camera fits them within
   ``refuse_gamma`` of the diagonal. A budget of residual evaluations bounds the time per frame.
6. With a dataset's learned camera prior (``CalibrationPrior.camera_prior``, :mod:`.priors`): when no
   start fits the labels, the prior's anchors are look-at starts too; and a free fit less sure of
   its centre than the fits the prior was learned from is refined into a MAP fit (the prior's rows
   added to the robust line cost, :class:`~.solver.PriorRows`) at the anchors most consistent with
   it, kept when every class stays within ``refuse_gamma`` (flag ``"learned_prior"``). Before that, when the
   prior holds the set's lens (its radial distortion at the image corner), every fit is refined with ``k1`` free
   under the prior's row (flag ``"radial_prior"``): one frame's lines rarely fix the lens, and a pinhole
   fit puts the lines it did not see up to 10 px off near the border (:mod:`.priors`).

Every fit (``_fit``) is one compiled call (:func:`~.solver.robust_lm`), and every ranking of
starts one compiled evaluation of all of them (:func:`~.residuals.residual_rows`); what stays in
Python is the search below, which decides the order of the fits.

Over 400 lines on purpose: the search above is one algorithm whose steps share private candidates,
budgets and settings; split, its order (which decides the results) would be spread over modules.

Pixel convention: the principal point is fixed at ``((W - 1) / 2, (H - 1) / 2)``. Normalised
SoccerNet points become pixels as ``x (W - 1)`` (the official evaluator's conversion, see
:mod:`app.geometry.annotations`), which maps the normalised image centre 0.5 to ``(W - 1) / 2``; the
same convention is PnLCalib's. World frame: SoccerNet (metres, centre spot origin, z down).

Size (over 400 lines): the steps above and their fallbacks (class left out, rig centre, radial term) are
one decision procedure over shared candidate lists; the numerics live in the sibling modules.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field, replace
from typing import Any, Callable, Literal, Mapping, Sequence

import numpy as np

from app.geometry.annotations import AnnotationError, FieldLines, image_diagonal, mirror_lines
from app.geometry.calibration.initialisation import (
    camera_from_homography,
    fixed_centre_rotations,
    ground_homographies,
    labelled_target,
)
from app.geometry.calibration.held_out import distances_by_class
from app.geometry.calibration.observations import Observations, build_observations
from app.geometry.calibration.residuals import (
    CameraParametrisation,
    ground_points_in_front,
    projection_matrix,
    residual_rows,
)
from app.geometry.calibration.priors import CameraPrior, anchor_order, prior_rows
from app.geometry.calibration.solver import PriorRows, abs_percentile, robust_lm, soft_l1_cost
from app.geometry.calibration.uncertainty import line_noise, parameter_covariance
from app.geometry.camera import Camera, look_at_rotation
from app.geometry.jac import JAC_GAMMAS, jac_at_gammas
from app.geometry.pitch import MIN_LINE_CLASSES, MIRROR_CLASSES, PITCH_WIDTH_M

#: Flag of a calibration made with its centre fixed by a prior (a position of the game's camera rig).
RIG_FLAG = "rig_assisted"
#: Flag of a calibration fitted with a learned camera prior (a MAP fit, :mod:`.priors`).
PRIOR_FLAG = "learned_prior"
#: Flag of a calibration whose radial term was fitted under a learned radial prior (:mod:`.priors`).
RADIAL_PRIOR_FLAG = "radial_prior"
#: Largest relative radial distortion at the image corner, ``|k1| (h / f)^2`` with ``h`` the half
#: diagonal, accepted from a fit under the radial prior (the real sets' median is 0.04).
MAX_CORNER_DISTORTION = 0.2
#: Flag of a frame whose field-line labels are probably mirrored (camera-side prior here; the
#: multi-view verdict of ``app.geometry.mirror`` sets the same flag in the service).
MIRROR_FLAG = "probably_mirrored"

#: Plausible camera centres (world, metres, z down) tried, in this order, when the lines do not fix
#: a homography: main broadcast camera on either side, 18-yard cameras, high and low behind-goal
#: cameras. Only starting points; the refinement moves the centre freely.
START_CENTRES_M: tuple[tuple[float, float, float], ...] = (
    (0.0, 60.0, -20.0), (0.0, -60.0, -20.0),
    (-35.0, 45.0, -10.0), (35.0, 45.0, -10.0), (-35.0, -45.0, -10.0), (35.0, -45.0, -10.0),
    (-70.0, 0.0, -15.0), (70.0, 0.0, -15.0),
    (-58.0, 0.0, -2.0), (58.0, 0.0, -2.0),
)

Status = Literal["calibrated", "refused"]


@dataclass(frozen=True)
class CalibrationPrior:
    """Prior knowledge about the camera that filmed a frame (all optional).

    Attributes:
        expected_side: +1 when the camera is expected on the y > 0 side of the pitch (broadcast main
            cameras: 1,594 of 1,603 real cameras), -1 for y < 0, ``None`` for no expectation (replay
            cameras can stand anywhere). Used only to flag probably mirrored labels; never to fit.
        centre_m: (3,) known camera centre (world, metres), e.g. from the game's rig; the centre is
            then held fixed and only focal length and rotation are fitted.
        camera_prior: a dataset's learned :class:`~.priors.CameraPrior`: a free fit less sure of its
            centre than the prior's confident fits is refined into a MAP fit (lines and prior) at the
            anchors most consistent with it; the anchors are starts too when no other start fits
            (ignored with ``centre_m``).
    """

    expected_side: int | None = None
    centre_m: tuple[float, float, float] | None = None
    camera_prior: CameraPrior | None = None

    def __post_init__(self) -> None:
        if self.expected_side not in (None, 1, -1):
            raise ValueError(f"CalibrationPrior.expected_side must be +1, -1 or None, got {self.expected_side!r}")
        if self.centre_m is not None:
            c = np.asarray(self.centre_m, dtype=float)
            if c.shape != (3,) or not np.all(np.isfinite(c)):
                raise ValueError("CalibrationPrior.centre_m must be 3 finite numbers (world metres)")
            if c[2] >= 0:
                raise ValueError("CalibrationPrior.centre_m must be above the ground (z < 0, z points down)")


@dataclass(frozen=True)
class CalibrationSettings:
    """Tunable constants of :func:`calibrate_frame` (defaults are the service's).

    Attributes:
        min_constraints: fewest independent scalar constraints the labels must give (7 unknowns:
            focal length, 3 rotation, 3 centre; 4 with a known centre).
        loss_scale_gamma: soft-L1 loss scale as a fraction of the image diagonal.
        accept_gamma: a candidate whose 90th-percentile point distance is below this fraction of the
            diagonal ends the search early.
        refuse_gamma: refuse when a labelled class has a point farther than this fraction of the
            diagonal from its model element. With a known centre (rig prior) the RMS point distance
            must also stay within ``accept_gamma`` of the diagonal.
        k1_min_gain: relative drop of the robust cost that justifies the radial coefficient.
        k1_min_points: fewest labelled points for which the radial coefficient is tried.
        max_k1: largest accepted |k1|.
        max_evaluations: batched residual evaluations allowed per frame over all starts (one per
            Levenberg-Marquardt trial step); bounds the time spent on a frame whose labels fit no
            camera (a typical frame needs 20 to 40); the leave-one-class-out step gets half as many.
        leave_out_max_classes: classes left out in turn, the worst fitted first (all of them when no
            camera was found).
        prior_anchors: with a learned camera prior, MAP fits made (one per anchor, the most
            consistent with the lines first); the lowest MAP cost wins.
        prior_max_d2: an anchor is tried only when its squared Mahalanobis distance to the free fit
            (:func:`~.priors.anchor_order`) is at most this (chi-square, 3 degrees of freedom, 0.999).
        prior_max_evaluations: residual evaluations allowed to the MAP fits of a frame.
    """

    min_constraints: int = 7
    loss_scale_gamma: float = 0.002
    accept_gamma: float = 0.005
    refuse_gamma: float = 0.03
    k1_min_gain: float = 0.3
    k1_min_points: int = 12
    max_k1: float = 0.5
    max_evaluations: int = 140
    leave_out_max_classes: int = 7
    prior_anchors: int = 3
    prior_max_d2: float = 16.27
    prior_max_evaluations: int = 60


@dataclass(frozen=True)
class CalibrationResult:
    """Outcome of :func:`calibrate_frame`.

    Attributes:
        status: ``"calibrated"`` or ``"refused"``.
        camera: the camera (pixels of the frame, SoccerNet world) or ``None`` when refused.
        reason: why the frame was refused (``None`` when calibrated).
        jac: JaC at each gamma of :data:`JAC_GAMMAS` (keys ``"0.005"``, ``"0.01"``, ``"0.02"``), from
            :mod:`app.geometry.jac`; empty when refused or not computed.
        residuals_px: per labelled class, the largest distance (px) of its points to the model
            element under the returned camera (or the best rejected one), so a UI can point at
            the line that disagrees.
        flags: ``"probably_mirrored"`` (camera on the other side than ``prior.expected_side``, beyond
            the far side line: the labels are probably mirrored, :attr:`mirrored_lines` is the fix),
            ``"few_lines"`` (fewer labelled classes than :data:`app.geometry.pitch.MIN_LINE_CLASSES`), ``"radial_distortion"`` (``k1`` fitted),
            ``"ignored_class:<class>"`` (that class disagrees with every camera fitting the others;
            its residual stays in :attr:`residuals_px`), ``"rig_assisted"`` (centre fixed by a prior).
        rms_px: root mean square point distance, px.
        elapsed_ms: wall time of the call, milliseconds.
        mirrored_lines: when ``"probably_mirrored"`` is flagged, the mirrored labelling offered as
            the fix (:func:`app.geometry.annotations.mirror_lines`).
        centre_prior: the prior rows of a MAP fit (a centre prior: flag ``"learned_prior"``; the
            radial prior: flag ``"radial_prior"``), for :func:`~.uncertainty.calibration_uncertainty`'s
            posterior covariance; ``None`` otherwise.
    """

    status: Status
    camera: Camera | None
    reason: str | None
    jac: Mapping[str, float]
    residuals_px: Mapping[str, float]
    flags: tuple[str, ...]
    rms_px: float | None
    elapsed_ms: float
    mirrored_lines: FieldLines | None = field(default=None, repr=False)
    centre_prior: PriorRows | None = field(default=None, repr=False)

    @property
    def calibrated(self) -> bool:
        """True when a camera was returned."""
        return self.status == "calibrated"

    def to_json(self) -> dict[str, Any]:
        """JSON-ready summary (the camera in SoccerNet form)."""
        return {
            "status": self.status,
            "camera": self.camera.to_soccernet() if self.camera is not None else None,
            "reason": self.reason,
            "jac": dict(self.jac),
            "residuals_px": dict(self.residuals_px),
            "flags": list(self.flags),
            "rms_px": self.rms_px,
            "elapsed_ms": self.elapsed_ms,
        }


@dataclass
class _Candidate:
    x: np.ndarray
    param: CameraParametrisation
    cost: float
    p90: float
    jacobian: np.ndarray
    origin: str
    k1_tried: bool = False


def side_vote(camera: Camera, expected_side: int | None, margin_m: float = PITCH_WIDTH_M / 2.0) -> int:
    """The side prior on mirrored labels: +1 when the camera stands beyond the far side line from
    ``expected_side`` (labels probably mirrored), -1 beyond the near side line (as labelled), 0
    otherwise or without a side.

    One rule for :func:`calibrate_frame`'s ``probably_mirrored`` flag (a vote of +1) and for
    :func:`app.geometry.mirror.mirror_evidence`, which re-exports it.

    Args:
        camera: the calibrated camera (SoccerNet world, metres).
        expected_side: +1 (camera expected at y > 0), -1, or ``None``.
        margin_m: how far beyond the centre line along y (metres) the camera must stand to vote;
            default the half width, i.e. beyond a side line.

    >>> cam = Camera.from_parameters(focal_px=1000.0, principal_point=(960.0, 540.0), pan_deg=0.0,
    ...                              tilt_deg=80.0, roll_deg=0.0, position_m=[0.0, -50.0, -12.0])
    >>> side_vote(cam, 1), side_vote(cam, -1), side_vote(cam, None)
    (1, -1, 0)
    """
    if expected_side is None:
        return 0
    y = float(camera.C[1]) * expected_side
    return 1 if y < -margin_m else -1 if y > margin_m else 0


def principal_point(width: int, height: int) -> np.ndarray:
    """Principal point v3d's calibration fixes: ``((W - 1) / 2, (H - 1) / 2)`` px (module docstring)."""
    return np.array([(width - 1) / 2.0, (height - 1) / 2.0])


@dataclass
class _Budget:
    """Residual evaluations left for one frame: bounds the worst-case time of a frame whose labels
    fit no camera, deterministically (the count does not depend on the machine's load)."""

    evaluations: int
    lookat_done: bool = False


def _start_costs(xs: list[np.ndarray], params: list[CameraParametrisation], obs: Observations,
                 scale: float) -> list[float]:
    """Robust cost (px^2) of each start ``xs[i]`` under ``params[i]`` (all of one shape), in one
    compiled evaluation."""
    if not xs:
        return []
    return soft_l1_cost(residual_rows(np.array(xs), obs, params), scale).tolist()


def _fit(x0: np.ndarray, obs: Observations, param: CameraParametrisation, scale: float, origin: str,
         budget: _Budget, max_iter: int = 25, prior: PriorRows | None = None) -> _Candidate | None:
    """Refine from ``x0`` (with the MAP ``prior`` rows, if any) and keep the result if it is a
    physical camera seeing its labels in front (a :class:`_Candidate`, or None)."""
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
    return _Candidate(x=sol.x, param=param, cost=sol.cost, p90=abs_percentile(sol.residuals, 90),
                      jacobian=sol.jacobian, origin=origin)


def _class_residuals(camera: Camera, obs: Observations) -> tuple[dict[str, float], float]:
    """Largest distance (px) of each class's points to its element, and the RMS over all points."""
    per_point = distances_by_class(camera, obs)
    out = {c: float(np.max(d)) for c, d in per_point.items()}
    allr = np.concatenate(list(per_point.values())) if per_point else np.zeros(0)
    return out, float(np.sqrt(np.mean(allr**2))) if len(allr) else 0.0


def _refused(reason: str, t0: float, flags: tuple[str, ...] = (), residuals_px: Mapping[str, float] | None = None,
             rms: float | None = None) -> CalibrationResult:
    return CalibrationResult(status="refused", camera=None, reason=reason, jac={}, residuals_px=dict(residuals_px or {}),
                             flags=flags, rms_px=rms, elapsed_ms=(time.perf_counter() - t0) * 1e3)


def _validate(lines: Any, width: Any, height: Any) -> None:
    if not isinstance(width, (int, np.integer)) or not isinstance(height, (int, np.integer)) or width < 2 or height < 2:
        raise ValueError(f"width and height must be integers >= 2 (pixels), got {width!r} x {height!r}")
    if not isinstance(lines, Mapping):
        raise AnnotationError("lines must be a mapping of class -> list of (N, 2) pixel arrays")
    for cls, polys in lines.items():
        if cls not in MIRROR_CLASSES:
            raise AnnotationError(f"lines: unknown line class {cls!r}")
        if not isinstance(polys, (list, tuple)):
            raise AnnotationError(f"lines[{cls!r}] must be a list of (N, 2) pixel arrays")
        for i, p in enumerate(polys):
            try:
                a = np.asarray(p, dtype=float)
            except (TypeError, ValueError):
                raise AnnotationError(f"lines[{cls!r}][{i}] must be a finite (N, 2) pixel array of numbers") from None
            if a.ndim != 2 or a.shape[1] != 2 or not np.all(np.isfinite(a)):
                raise AnnotationError(f"lines[{cls!r}][{i}] must be a finite (N, 2) pixel array, got shape {a.shape}")


def _search(obs: Observations, width: int, height: int, prior: CalibrationPrior | None,
            settings: CalibrationSettings, budget: _Budget, stage: str = "homography") -> _Candidate | None:
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
    best: _Candidate | None = None

    def consider(c: _Candidate | None) -> bool:
        nonlocal best
        if c is not None and (best is None or c.cost < best.cost):
            best = c
        return best is not None and best.p90 < accept

    target = labelled_target(obs)
    if prior is not None and prior.centre_m is not None:
        centre = np.asarray(prior.centre_m, dtype=float)
        starts = _fixed_centre_starts(obs, centre, pp, width, scale)
        for _, param, x0 in starts[:FIXED_CENTRE_REFINED]:
            if consider(_fit(x0, obs, param, scale, "rig", budget)):
                break
        return best

    starts = _homography_starts(obs, pp, scale) if stage == "homography" else []
    for _, name, param, x0 in starts[:2]:
        cand = _fit(x0, obs, param, scale, name, budget)
        if consider(cand):
            return best
        if cand is not None and cand is best and obs.n_points >= settings.k1_min_points:
            # The lines may be curved by the lens: try the radial term before another start.
            best = _with_k1(cand, obs, scale, settings, budget)
            if best.p90 < accept:
                return best

    if starts:
        # The lines fix a homography but its camera leaves some labels far off: a mislabelled line
        # is the likelier cause; the caller tries without each class before the look-at starts.
        return best

    # Look-at starts: a pan-tilt-zoom fit at each plausible centre (cheap, 4 parameters), then the
    # free refinement of the best two. The learned anchors (stage "anchors"): the best
    # ANCHOR_STARTS of them by the look-at start's robust cost.
    budget.lookat_done = True
    centres = [np.asarray(c, dtype=float) for c in START_CENTRES_M]
    if stage == "anchors":
        centres = [np.asarray(c, dtype=float) for c in prior.camera_prior.anchors_m]  # type: ignore[union-attr]
    starts_ptz: list[tuple[str, CameraParametrisation, np.ndarray]] = []
    for c0 in centres:
        try:
            R0 = look_at_rotation(c0, target)
        except ValueError:
            continue
        fixed = CameraParametrisation(principal_point=pp, R0=R0, fixed_centre=c0)
        starts_ptz.append((f"start {tuple(c0.tolist())}", fixed, fixed.vector(1.5 * width, c0)))
    if stage == "anchors" and starts_ptz:
        costs = _start_costs([x0 for _, _, x0 in starts_ptz], [q for _, q, _ in starts_ptz], obs, scale)
        starts_ptz = [starts_ptz[i] for i in np.argsort(costs, kind="stable")[:ANCHOR_STARTS]]
    ptz: list[_Candidate] = []
    for name, fixed, x0 in starts_ptz:
        cand = _fit(x0, obs, fixed, scale, name, budget, max_iter=8)
        if cand is not None:
            ptz.append(cand)
    ptz.sort(key=lambda c: c.cost)
    for cand in ptz[:2]:
        f1, R1, C1, _ = cand.param.split(cand.x)
        free = CameraParametrisation(principal_point=pp, R0=R1)
        if consider(_fit(free.vector(float(f1), C1), obs, free, scale, cand.origin, budget)):
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
    x0s = [param.vector(float(f0), centre) for param, f0 in zip(params, f_all)]
    starts = list(zip(_start_costs(x0s, params, obs, scale), params, x0s))
    starts.sort(key=lambda t: t[0])
    return starts


def _homography_starts(obs: Observations, pp: np.ndarray, scale: float
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
    costs = _start_costs([x0 for _, _, x0 in inits], [param for _, param, _ in inits], obs, scale)
    starts = [(cost, name, param, x0) for cost, (name, param, x0) in zip(costs, inits)]
    starts.sort(key=lambda t: t[0])
    return starts


def _without_one_class(lines: FieldLines, obs: Observations, best: _Candidate | None, width: int, height: int,
                       settings: CalibrationSettings, budget: _Budget
                       ) -> tuple[str, _Candidate, Observations] | None:
    """Best camera that fits every labelled class but one (a mislabelled line): ``(class left out,
    candidate, its observations)``, or ``None``.

    Every class is left out in turn; the closed-form homography cameras of the remaining labels and
    the current best camera are ranked by robust cost, and the three best are refined. The winner
    is the refined camera whose worst remaining class is closest to its model.
    """
    pp = principal_point(width, height)
    scale = settings.loss_scale_gamma * image_diagonal(width, height)
    ranked: list[tuple[float, str, Observations, CameraParametrisation, np.ndarray]] = []
    for cls in _leave_out_order(obs, best, settings):
        reduced = _without_class_observations(lines, cls, settings)
        if reduced is None:
            continue
        starts = _homography_starts(reduced, pp, scale)
        if best is not None:
            starts.append((_start_costs([best.x], [best.param], reduced, scale)[0], "current", best.param, best.x))
        for cost, _, param, x0 in starts:
            ranked.append((cost / max(reduced.n_points, 1), cls, reduced, param, x0))
    ranked.sort(key=lambda t: t[0])
    winner: tuple[float, str, _Candidate, Observations] | None = None
    for _, cls, reduced, param, x0 in ranked[:3]:
        cand = _fit(x0, reduced, param, scale, f"without {cls!r}", budget)
        if cand is None:
            continue
        worst = max(_class_residuals(cand.param.camera(cand.x), reduced)[0].values())
        if winner is None or worst < winner[0]:
            winner = (worst, cls, cand, reduced)
    return None if winner is None else (winner[1], winner[2], winner[3])


def _leave_out_order(obs: Observations, ref: _Candidate | None, settings: CalibrationSettings) -> list[str]:
    """The classes to leave out in turn: with a camera ``ref``, the ``settings.leave_out_max_classes``
    it fits worst, worst first (the mislabelled class is almost always among them); else every class."""
    if ref is None:
        return list(obs.classes)
    per_class = _class_residuals(ref.param.camera(ref.x), obs)[0]
    return sorted(obs.classes, key=lambda c: -per_class[c])[:settings.leave_out_max_classes]


def _without_class_observations(lines: FieldLines, cls: str, settings: CalibrationSettings) -> Observations | None:
    """The observations of ``lines`` without class ``cls``, or None when the rest cannot fix a camera
    (fewer than ``settings.min_constraints`` constraints or three classes)."""
    reduced = build_observations({c: v for c, v in lines.items() if c != cls})
    if reduced.constraint_count() < settings.min_constraints or len(reduced.classes) < 3:
        return None
    return reduced


def _anchors_without_one_class(lines: FieldLines, obs: Observations, ref: _Candidate | None, width: int, height: int,
                               prior: CalibrationPrior, settings: CalibrationSettings, limit: float
                               ) -> tuple[str, _Candidate, Observations] | None:
    """The learned anchors as starts with each class left out in turn (a mislabelled line spoils the
    anchors' fits as it spoils the others; :func:`_without_one_class` has only the homography starts,
    which the remaining labels may not give): ``(class left out, candidate, its observations)`` for
    the first class whose removal lets a fit keep every other class within ``limit`` px, or None.
    Classes are tried worst fitted by ``ref`` first, at most ``settings.leave_out_max_classes``; one
    budget of ``2 settings.max_evaluations`` for all of them (only frames no other start fits pay it)."""
    budget = _Budget(2 * settings.max_evaluations)
    for cls in _leave_out_order(obs, ref, settings)[:settings.leave_out_max_classes]:
        reduced = _without_class_observations(lines, cls, settings)
        if reduced is None:
            continue
        if budget.evaluations <= 0:
            break
        cand = _search(reduced, width, height, prior, settings, budget, stage="anchors")
        if cand is not None and _worst(cand, reduced) <= limit:
            return cls, cand, reduced
    return None


def _worst(cand: _Candidate | None, obs: Observations) -> float:
    """Largest class residual (px) of a candidate, infinity for none."""
    if cand is None:
        return float("inf")
    per_class = _class_residuals(cand.param.camera(cand.x), obs)[0]
    return max(per_class.values()) if per_class else 0.0


def _with_free_k1(best: _Candidate) -> tuple[CameraParametrisation, float, np.ndarray, float]:
    """``best``'s parametrisation with ``k1`` free (its rotation as the reference, its centre fixed if
    it was), with its focal (px), centre (m) and ``k1``: what a refit with the radial term starts from."""
    f, R, C, k1 = best.param.split(best.x)
    param = CameraParametrisation(principal_point=best.param.principal_point, R0=R, fit_k1=True,
                                  fixed_centre=best.param.fixed_centre)
    return param, float(f), C, float(k1)


def _with_k1(best: _Candidate, obs: Observations, scale: float, settings: CalibrationSettings,
             budget: _Budget) -> _Candidate:
    """Add the radial coefficient when it lowers the robust cost by ``k1_min_gain`` or more (the
    better :class:`_Candidate`)."""
    param, f, C, _ = _with_free_k1(best)
    best.k1_tried = True
    cand = _fit(param.vector(float(f), C, 0.0), obs, param, scale, best.origin + " +k1", budget)
    if cand is None or abs(cand.x[-1]) > settings.max_k1:
        return best
    if cand.cost < (1.0 - settings.k1_min_gain) * best.cost:
        cand.k1_tried = True
        return cand
    return best


def _with_radial_prior(best: _Candidate, obs: Observations, camera_prior: CameraPrior, scale: float, limit: float,
                       half_diagonal: float, settings: CalibrationSettings) -> tuple[_Candidate, PriorRows | None]:
    """Refit ``best`` with ``k1`` free under the learned radial prior (:mod:`.priors`):
    ``(candidate, its prior rows)``, or ``(best, None)`` when the fit fails, leaves a class further
    from its element than ``limit`` px (or than ``best`` did) or bends the image corner by more than
    :data:`MAX_CORNER_DISTORTION`. The start is ``best``'s ``k1`` or the prior's ``c_0 (f / h)^2``."""
    param, f, C, k1 = _with_free_k1(best)
    sigma = line_noise(residual_rows(best.x, obs, [best.param]), len(best.x))
    rows = prior_rows(camera_prior, None, sigma, half_diagonal)
    start = k1 if k1 != 0.0 else camera_prior.radial_corner * (f / half_diagonal) ** 2
    cand = _fit(param.vector(f, C, start), obs, param, scale, best.origin + " +radial prior",
                _Budget(settings.prior_max_evaluations), prior=rows)
    if cand is None or abs(cand.x[-1]) * (half_diagonal / cand.x[0]) ** 2 > MAX_CORNER_DISTORTION:
        return best, None
    if _worst(cand, obs) > max(limit, _worst(best, obs)):
        return best, None
    cand.k1_tried = True
    return cand, rows


def radial_corner(camera: Camera, lines: FieldLines, width: int, height: int,
                  settings: CalibrationSettings | None = None) -> float:
    """The relative radial distortion at the image corner, ``k1 (h / f)^2`` (``h`` the half diagonal,
    px), of ``camera`` refitted to ``lines`` with ``k1`` free (focal, rotation, centre and ``k1``; no
    gain gate, no prior): the value a learned radial prior is learned from
    (:func:`.learning.learn_camera_prior`). The same lens gives the same value at any zoom and image size.

    Args:
        camera: a fit of ``lines`` (principal point fixed, square pixels). lines: the classes it
            used (:data:`~app.geometry.annotations.FieldLines`, pixels). width, height: image size, px.

    Returns:
        ``k1 (h / f)^2``, or NaN when the refit fails or its magnitude exceeds :data:`MAX_CORNER_DISTORTION`.
    """
    settings = settings or CalibrationSettings()
    obs = build_observations(lines)
    if obs.n_points < settings.k1_min_points:
        return float("nan")
    f = float(camera.K[0, 0])
    param = CameraParametrisation(principal_point=np.asarray(camera.K[:2, 2], dtype=float), R0=np.asarray(camera.R),
                                  fit_k1=True)
    cand = _fit(param.vector(f, np.asarray(camera.C, dtype=float), float(camera.radial[0])), obs, param,
                settings.loss_scale_gamma * image_diagonal(width, height), "radial", _Budget(settings.prior_max_evaluations))
    if cand is None:
        return float("nan")
    corner = float(cand.x[-1] * (image_diagonal(width, height) / 2.0 / cand.x[0]) ** 2)
    return corner if abs(corner) <= MAX_CORNER_DISTORTION else float("nan")


def _with_camera_prior(best: _Candidate, obs: Observations, camera_prior: CameraPrior, scale: float, limit: float,
                       half_diagonal: float, settings: CalibrationSettings) -> tuple[_Candidate, PriorRows | None]:
    """The MAP refinement of the free fit ``best`` with a learned prior (:mod:`.priors`):
    ``(candidate, its prior rows)``, or ``(best, None)`` when no anchor is consistent with the lines'
    estimate or no MAP fit keeps every class within ``limit`` px.

    The lines' covariance of the centre (Gauss-Newton, :func:`~.uncertainty.parameter_covariance`,
    line noise :func:`~.uncertainty.line_noise` of the free fit's line residuals) orders the anchors
    (:func:`~.priors.anchor_order`); a fit whose position std is at or below the prior's
    ``confident_std_m`` is left as it is; else up to ``settings.prior_anchors`` of those within
    ``settings.prior_max_d2`` are tried from ``best``, and the lowest MAP cost (lines and prior) wins.
    """
    if best.param.fixed_centre is not None or not camera_prior.anchors_m:
        return best, None
    r = residual_rows(best.x, obs, [best.param])
    sigma = line_noise(r, len(best.x))
    cov, undetermined = parameter_covariance(best.jacobian, sigma)
    cov_c = cov[4:7, 4:7] + np.diag(np.where(undetermined[4:7], 1e6, 0.0))
    if np.sqrt(np.trace(cov_c)) <= camera_prior.confident_std_m:
        return best, None  # the lines fix the centre as well as those the prior was learned from
    order, d2 = anchor_order(camera_prior, best.param.split(best.x)[2], cov_c)
    budget = _Budget(settings.prior_max_evaluations)
    winner: tuple[_Candidate, PriorRows] | None = None
    for a in order[d2 <= settings.prior_max_d2][:settings.prior_anchors]:
        rows = prior_rows(camera_prior, int(a), sigma, half_diagonal)
        cand = _fit(best.x, obs, best.param, scale, best.origin + " +prior", budget, prior=rows)
        if cand is not None and (winner is None or cand.cost < winner[0].cost):
            winner = (cand, rows)
    if winner is None or _worst(winner[0], obs) > limit:
        return best, None
    winner[0].k1_tried = best.k1_tried
    return winner


def calibrate_frame(
    lines: FieldLines,
    width: int,
    height: int,
    *,
    prior: CalibrationPrior | None = None,
    settings: CalibrationSettings | None = None,
    compute_jac: bool = True,
    jac_function: Callable[..., Mapping[float, float]] | None = None,
) -> CalibrationResult:
    """Calibrate a frame from its annotated field lines.

    Args:
        lines: :data:`~app.geometry.annotations.FieldLines`, pixels of this frame (continuous
            coordinates; SoccerNet-calibration points converted as ``x (W - 1)``).
        width, height: image size, pixels.
        prior: optional :class:`CalibrationPrior` (side of the pitch for the mirror flag, known centre).
        settings: :class:`CalibrationSettings`; defaults when ``None``.
        compute_jac: compute JaC at :data:`JAC_GAMMAS` for the returned camera.
        jac_function: replacement for :func:`app.geometry.jac.jac_at_gammas` (same signature).

    Returns:
        :class:`CalibrationResult`: a camera with principal point ``((W - 1) / 2, (H - 1) / 2)``,
        square pixels and at most the ``k1`` radial term, or a refusal with its reason. No exception
        escapes for well-formed input.

    Raises:
        ValueError: ``width``/``height`` are not integers >= 2.
        AnnotationError: ``lines`` is not a mapping of known line classes (SoccerNet spelling) ->
            list of finite (N, 2) arrays.
    """
    return _calibrate(lines, width, height, prior=prior, settings=settings, compute_jac=compute_jac,
                      jac_function=jac_function)


def calibrate_frames_together(jobs: list[tuple[FieldLines, int, int, CalibrationPrior | None]], *,
                              settings: CalibrationSettings | None = None, compute_jac: bool = True
                              ) -> list[CalibrationResult]:
    """:func:`calibrate_frame` of several frames; jobs whose ``lines`` are the same object share
    their observations (and what is computed once from them: the fixed-centre anchors, the compiled
    residuals' arrays), as a frame fitted at each position of its game's rig does. Every result is
    :func:`calibrate_frame`'s for that job; only ``elapsed_ms`` is the time of the whole call.

    Args:
        jobs: ``(lines, width, height, prior)`` per frame, as :func:`calibrate_frame`'s arguments.
        settings, compute_jac: as :func:`calibrate_frame`.

    Raises:
        as :func:`calibrate_frame`.
    """
    t0 = time.perf_counter()
    shared: dict[int, Observations] = {}
    results = []
    for lines, width, height, prior in jobs:
        _validate(lines, width, height)
        obs = shared.get(id(lines))
        if obs is None:
            obs = shared[id(lines)] = build_observations(lines)
        results.append(_calibrate(lines, width, height, prior=prior, settings=settings, compute_jac=compute_jac,
                                  observations=obs))
    elapsed = (time.perf_counter() - t0) * 1e3
    return [replace(r, elapsed_ms=elapsed) for r in results]


def _calibrate(
    lines: FieldLines,
    width: int,
    height: int,
    *,
    prior: CalibrationPrior | None = None,
    settings: CalibrationSettings | None = None,
    compute_jac: bool = True,
    jac_function: Callable[..., Mapping[float, float]] | None = None,
    observations: Observations | None = None,
) -> CalibrationResult:
    """:func:`calibrate_frame`; ``observations``: ``build_observations(lines)`` when the caller has
    it already."""
    t0 = time.perf_counter()
    _validate(lines, width, height)
    settings = settings or CalibrationSettings()
    diag = image_diagonal(width, height)
    obs = observations if observations is not None else build_observations(lines)
    fixed = prior is not None and prior.centre_m is not None
    need = 4 if fixed else settings.min_constraints
    n_constraints = obs.constraint_count()
    flags: list[str] = []
    if len(obs.classes) < MIN_LINE_CLASSES:
        flags.append("few_lines")
    if n_constraints < need:
        return _refused(f"fewer than {need} independent line constraints ({n_constraints}: "
                        f"{len(obs.classes)} usable line(s))", t0, tuple(flags))
    nx, ny = obs.ground_line_directions()
    if not obs.circle_classes and (nx == 0 or ny == 0) and len(obs.classes) - nx - ny == 0:
        return _refused("degenerate configuration: all labelled lines are parallel on the pitch and no "
                        "circle or goal fixes the view", t0, tuple(flags))
    pts = obs.all_points
    centred = pts - pts.mean(axis=0)
    normal = np.linalg.svd(centred, full_matrices=False)[2][-1]
    if np.max(np.abs(centred @ normal)) < settings.loss_scale_gamma * diag:
        return _refused("degenerate configuration: all labelled points are collinear in the image", t0, tuple(flags))
    try:
        budget = _Budget(settings.max_evaluations)
        best = _search(obs, width, height, prior, settings, budget)
        fit_obs = obs
        scale = settings.loss_scale_gamma * diag
        limit = settings.refuse_gamma * diag

        def polish(c: _Candidate | None, b: _Budget) -> _Candidate | None:
            if c is not None and not c.k1_tried and c.p90 > 0.5 * scale and obs.n_points >= settings.k1_min_points:
                return _with_k1(c, obs, scale, settings, b)
            return c

        best = polish(best, budget)
        if _worst(best, obs) > limit and not fixed:
            if len(obs.classes) >= 4:
                # One mislabelled line (left/right confusion, a wrong goal post) spoils a frame.
                alt = _without_one_class(lines, obs, best, width, height, settings,
                                         _Budget(settings.max_evaluations // 2))
                if alt is not None and _worst(alt[1], alt[2]) <= limit:
                    dropped, best, fit_obs = alt
                    flags.append(f"ignored_class:{dropped}")
            if fit_obs is obs and budget.evaluations > 0 and not budget.lookat_done:
                other = _search(obs, width, height, prior, settings, budget, stage="look-at")
                other = polish(other, budget)
                if other is not None and (best is None or other.cost < best.cost):
                    best = other
        centre_prior = None
        if (not fixed and prior is not None and prior.camera_prior is not None and prior.camera_prior.anchors_m
                and _worst(best, fit_obs) > limit):
            # No start fitted the labels: the learned camera positions are starts too.
            anchor_budget = _Budget(settings.max_evaluations)
            other = polish(_search(obs, width, height, prior, settings, anchor_budget, stage="anchors"), anchor_budget)
            if other is not None and _worst(other, obs) <= limit:
                best, fit_obs = other, obs
                flags[:] = [f for f in flags if not f.startswith("ignored_class:")]
            elif len(obs.classes) >= 4:
                alt = _anchors_without_one_class(lines, obs, other if other is not None else best, width, height,
                                                 prior, settings, limit)
                if alt is not None:
                    dropped, best, fit_obs = alt
                    flags[:] = [f for f in flags if not f.startswith("ignored_class:")] + [f"ignored_class:{dropped}"]
        radial_prior = None
        if best is not None and prior is not None and prior.camera_prior is not None and prior.camera_prior.has_radial:
            best, radial_prior = _with_radial_prior(best, fit_obs, prior.camera_prior, scale, limit, diag / 2.0,
                                                    settings)
        if best is not None and not fixed and prior is not None and prior.camera_prior is not None:
            best, centre_prior = _with_camera_prior(best, fit_obs, prior.camera_prior, scale, limit, diag / 2.0,
                                                     settings)
    except (np.linalg.LinAlgError, ValueError, FloatingPointError) as exc:  # numerical breakdown
        return _refused(f"solver failed: {exc}", t0, tuple(flags))
    if best is None:
        return _refused("no camera fits the labels (every start failed or put the pitch behind the camera)",
                        t0, tuple(flags))
    camera = best.param.camera(best.x)
    per_class, rms = _class_residuals(camera, obs)
    if fixed:
        flags.append(RIG_FLAG)
    if centre_prior is not None:
        flags.append(PRIOR_FLAG)
    if radial_prior is not None and best.param.fit_k1:
        flags.append(RADIAL_PRIOR_FLAG)
    if camera.radial[0] != 0.0:
        flags.append("radial_distortion")
    fitted = {c: per_class[c] for c in fit_obs.classes}
    worst = max(fitted.values()) if fitted else 0.0
    if worst > limit:
        bad = max(fitted, key=fitted.get)  # type: ignore[arg-type]
        return _refused(f"residual too high: {bad!r} is {worst:.1f} px from its model element "
                        f"(limit {limit:.1f} px)", t0, tuple(flags), per_class, rms)
    if fixed and rms > settings.accept_gamma * diag:
        # With the centre known only focal length and rotation are free and few lines are labelled:
        # the fit absorbs little, so labels it cannot bring within the tolerance of a good
        # single-frame fit (accept_gamma, the admission threshold's scale) disagree with the centre.
        return _refused(f"labels do not fit a camera at the known centre: {rms:.1f} px RMS "
                        f"(limit {settings.accept_gamma * diag:.1f} px)", t0, tuple(flags), per_class, rms)
    mirrored = None
    if prior is not None and side_vote(camera, prior.expected_side) == 1:
        flags.append(MIRROR_FLAG)
        mirrored = mirror_lines(lines)
    jac: dict[str, float] = {}
    if compute_jac:
        jac = frame_jac(camera, lines, width, height, jac_function)
    return CalibrationResult(status="calibrated", camera=camera, reason=None, jac=jac, residuals_px=per_class,
                             flags=tuple(flags), rms_px=rms, elapsed_ms=(time.perf_counter() - t0) * 1e3,
                             mirrored_lines=mirrored, centre_prior=centre_prior or radial_prior)


def lines_used(lines: FieldLines, flags: Sequence[str]) -> FieldLines:
    """The classes of ``lines`` a calibration with ``flags`` was fitted to: without those it flagged
    ``ignored_class:<class>`` (a new mapping; the arrays are shared)."""
    ignored = {f.split(":", 1)[1] for f in flags if f.startswith("ignored_class:")}
    return {c: v for c, v in lines.items() if c not in ignored}


def frame_jac(camera: Camera, lines: FieldLines, width: int, height: int,
              jac_function: Callable[..., Mapping[float, float]] | None = None) -> dict[str, float]:
    """JaC of ``camera`` against ``lines`` at :data:`JAC_GAMMAS`, keyed ``"0.005"``, ``"0.01"``, ``"0.02"``.

    Uses :func:`app.geometry.jac.jac_at_gammas` (the official evaluator's JaC) unless ``jac_function``
    with the same signature ``(camera, lines, width, height, gammas) -> {gamma: jac}`` is given.
    """
    values = (jac_function or jac_at_gammas)(camera, lines, width, height, JAC_GAMMAS)
    return {f"{g:g}": float(values[g]) for g in JAC_GAMMAS}
