"""What a frame's calibration tries beyond its best start: each class left out in turn (one mislabelled line
spoils a whole frame), a radial term ``k1`` when the pinhole fit leaves residuals, the dataset's learned lens
(radial prior) and its learned camera prior (a MAP fit at the prior's anchors).
"""
from __future__ import annotations

import numpy as np

from app.geometry.annotations import FieldLines, image_diagonal
from app.geometry.calibration.observations import Observations, build_observations
from app.geometry.calibration.priors import CameraPrior, anchor_order, prior_rows
from app.geometry.calibration.residuals import (
    CameraParametrisation,
    residual_rows,
)
from app.geometry.calibration.result import (
    MAX_CORNER_DISTORTION,
    CalibrationPrior,
    CalibrationSettings,
    principal_point,
)
from app.geometry.calibration.solver import PriorRows
from app.geometry.calibration.starts import (
    Budget,
    Candidate,
    class_residuals,
    fit_start,
    homography_starts,
    search_starts,
    start_costs,
    with_free_k1,
    worst_residual,
)
from app.geometry.calibration.uncertainty import line_noise, parameter_covariance
from app.geometry.camera import Camera


def without_one_class(lines: FieldLines, obs: Observations, best: Candidate | None, width: int, height: int,
                       settings: CalibrationSettings, budget: Budget
                       ) -> tuple[str, Candidate, Observations] | None:
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
        starts = homography_starts(reduced, pp, scale)
        if best is not None:
            starts.append((start_costs([best.x], [best.param], reduced, scale)[0], "current", best.param, best.x))
        for cost, _, param, x0 in starts:
            ranked.append((cost / max(reduced.n_points, 1), cls, reduced, param, x0))
    ranked.sort(key=lambda t: t[0])
    winner: tuple[float, str, Candidate, Observations] | None = None
    for _, cls, reduced, param, x0 in ranked[:3]:
        cand = fit_start(x0, reduced, param, scale, f"without {cls!r}", budget)
        if cand is None:
            continue
        worst = max(class_residuals(cand.param.camera(cand.x), reduced)[0].values())
        if winner is None or worst < winner[0]:
            winner = (worst, cls, cand, reduced)
    return None if winner is None else (winner[1], winner[2], winner[3])


def _leave_out_order(obs: Observations, ref: Candidate | None, settings: CalibrationSettings) -> list[str]:
    """The classes to leave out in turn: with a camera ``ref``, the ``settings.leave_out_max_classes``
    it fits worst, worst first (the mislabelled class is almost always among them); else every class."""
    if ref is None:
        return list(obs.classes)
    per_class = class_residuals(ref.param.camera(ref.x), obs)[0]
    return sorted(obs.classes, key=lambda c: -per_class[c])[:settings.leave_out_max_classes]


def _without_class_observations(lines: FieldLines, cls: str, settings: CalibrationSettings) -> Observations | None:
    """The observations of ``lines`` without class ``cls``, or None when the rest cannot fix a camera
    (fewer than ``settings.min_constraints`` constraints or three classes)."""
    reduced = build_observations({c: v for c, v in lines.items() if c != cls})
    if reduced.constraint_count() < settings.min_constraints or len(reduced.classes) < 3:
        return None
    return reduced


def anchors_without_one_class(lines: FieldLines, obs: Observations, ref: Candidate | None, width: int, height: int,
                               prior: CalibrationPrior, settings: CalibrationSettings, limit: float
                               ) -> tuple[str, Candidate, Observations] | None:
    """The learned anchors as starts with each class left out in turn (a mislabelled line spoils the
    anchors' fits as it spoils the others; :func:`without_one_class` has only the homography starts,
    which the remaining labels may not give): ``(class left out, candidate, its observations)`` for
    the first class whose removal lets a fit keep every other class within ``limit`` px, or None.
    Classes are tried worst fitted by ``ref`` first, at most ``settings.leave_out_max_classes``; one
    budget of ``2 settings.max_evaluations`` for all of them (only frames no other start fits pay it)."""
    budget = Budget(2 * settings.max_evaluations)
    for cls in _leave_out_order(obs, ref, settings)[:settings.leave_out_max_classes]:
        reduced = _without_class_observations(lines, cls, settings)
        if reduced is None:
            continue
        if budget.evaluations <= 0:
            break
        cand = search_starts(reduced, width, height, prior, settings, budget, stage="anchors")
        if cand is not None and worst_residual(cand, reduced) <= limit:
            return cls, cand, reduced
    return None






def with_radial_prior(best: Candidate, obs: Observations, camera_prior: CameraPrior, scale: float, limit: float,
                       half_diagonal: float, settings: CalibrationSettings) -> tuple[Candidate, PriorRows | None]:
    """Refit ``best`` with ``k1`` free under the learned radial prior (:mod:`.priors`):
    ``(candidate, its prior rows)``, or ``(best, None)`` when the fit fails, leaves a class further
    from its element than ``limit`` px (or than ``best`` did) or bends the image corner by more than
    :data:`MAX_CORNER_DISTORTION`. The start is ``best``'s ``k1`` or the prior's ``c_0 (f / h)^2``."""
    param, f, C, k1 = with_free_k1(best)
    sigma = line_noise(residual_rows(best.x, obs, [best.param]), len(best.x))
    rows = prior_rows(camera_prior, None, sigma, half_diagonal)
    start = k1 if k1 != 0.0 else camera_prior.radial_corner * (f / half_diagonal) ** 2
    cand = fit_start(param.vector(f, C, start), obs, param, scale, best.origin + " +radial prior",
                Budget(settings.prior_max_evaluations), prior=rows)
    if cand is None or abs(cand.x[-1]) * (half_diagonal / cand.x[0]) ** 2 > MAX_CORNER_DISTORTION:
        return best, None
    if worst_residual(cand, obs) > max(limit, worst_residual(best, obs)):
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
    cand = fit_start(param.vector(f, np.asarray(camera.C, dtype=float), float(camera.radial[0])), obs, param,
                settings.loss_scale_gamma * image_diagonal(width, height), "radial",
                     Budget(settings.prior_max_evaluations))
    if cand is None:
        return float("nan")
    corner = float(cand.x[-1] * (image_diagonal(width, height) / 2.0 / cand.x[0]) ** 2)
    return corner if abs(corner) <= MAX_CORNER_DISTORTION else float("nan")


def with_camera_prior(best: Candidate, obs: Observations, camera_prior: CameraPrior, scale: float, limit: float,
                       half_diagonal: float, settings: CalibrationSettings) -> tuple[Candidate, PriorRows | None]:
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
    budget = Budget(settings.prior_max_evaluations)
    winner: tuple[Candidate, PriorRows] | None = None
    for a in order[d2 <= settings.prior_max_d2][:settings.prior_anchors]:
        rows = prior_rows(camera_prior, int(a), sigma, half_diagonal)
        cand = fit_start(best.x, obs, best.param, scale, best.origin + " +prior", budget, prior=rows)
        if cand is not None and (winner is None or cand.cost < winner[0].cost):
            winner = (cand, rows)
    if winner is None or worst_residual(winner[0], obs) > limit:
        return best, None
    winner[0].k1_tried = best.k1_tried
    return winner
