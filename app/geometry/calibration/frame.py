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
   the evaluation). The result is refused, with a refusal code and its numbers (:class:`~.result.Refusal`), when the
   labels cannot fix a camera (too few constraints, parallel or collinear labels) or no camera fits them within
   ``refuse_gamma`` of the diagonal. A budget of residual evaluations bounds the time per frame.
6. With a dataset's learned camera prior (``CalibrationPrior.camera_prior``, :mod:`.priors`): when no
   start fits the labels, the prior's anchors are look-at starts too; and a free fit less sure of
   its centre than the fits the prior was learned from is refined into a MAP fit (the prior's rows
   added to the robust line cost, :class:`~.solver.PriorRows`) at the anchors most consistent with
   it, kept when every class stays within ``refuse_gamma`` (flag ``"learned_prior"``). Before that, when the
   prior holds the set's lens (its radial distortion at the image corner), every fit is refined with ``k1`` free
   under the prior's row (flag ``"radial_prior"``): one frame's lines rarely fix the lens, and a pinhole
   fit puts the lines it did not see up to 10 px off near the border (:mod:`.priors`).

Every fit (``fit_start``) is one compiled call (:func:`~.solver.robust_lm`), and every ranking of
starts one compiled evaluation of all of them (:func:`~.residuals.residual_rows`); what stays in
Python is the search, which decides the order of the fits: the starts and their ranking
(:mod:`.starts`), the fallbacks and lens terms (:mod:`.fallbacks`), and here the procedure that runs them
in order; what a calibration takes and answers is :mod:`.result`.

Pixel convention: the principal point is fixed at ``((W - 1) / 2, (H - 1) / 2)``. Normalised
SoccerNet points become pixels as ``x (W - 1)`` (the official evaluator's conversion, see
:mod:`app.geometry.annotations`), which maps the normalised image centre 0.5 to ``(W - 1) / 2``; the
same convention is PnLCalib's. World frame: SoccerNet (metres, centre spot origin, z down).
"""
from __future__ import annotations

import functools
import time
from dataclasses import replace
from typing import Any, Callable, Mapping, Sequence

import numpy as np

from app.geometry.annotations import AnnotationError, FieldLines, image_diagonal, mirror_lines
from app.geometry.calibration.fallbacks import (
    anchors_without_one_class,
    with_camera_prior,
    with_radial_prior,
    without_one_class,
)
from app.geometry.calibration.observations import Observations, build_observations
from app.geometry.calibration.result import (
    MIRROR_FLAG,
    PRIOR_FLAG,
    RADIAL_PRIOR_FLAG,
    RIG_FLAG,
    CalibrationPrior,
    CalibrationResult,
    CalibrationSettings,
    Refusal,
    side_vote,
)
from app.geometry.calibration.starts import Budget, Candidate, class_residuals, search_starts, with_k1, worst_residual
from app.geometry.camera import Camera
from app.geometry.jac import JAC_GAMMAS, jac_at_gammas
from app.geometry.pitch import MIN_LINE_CLASSES, MIRROR_CLASSES


def _refused(refusal: Refusal, t0: float, flags: tuple[str, ...] = (), residuals_px: Mapping[str, float] | None = None,
             rms: float | None = None) -> CalibrationResult:
    return CalibrationResult(status="refused", camera=None, refusal=refusal, jac={},
                             residuals_px=dict(residuals_px or {}),
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


#: ``polish(candidate, budget)``: the candidate with radial distortion tried where its residuals ask for it.
_Polish = Callable[[Candidate | None, Budget], Candidate | None]


def _polished(c: Candidate | None, b: Budget, obs: Observations, scale: float, settings: CalibrationSettings
              ) -> Candidate | None:
    """``c`` refitted with radial distortion (:func:`with_k1`, within budget ``b``) where it has not been tried, its
    90th-percentile residual is above half the loss scale ``scale`` (px) and the lines have enough points; else
    ``c``."""
    if c is not None and not c.k1_tried and c.p90 > 0.5 * scale and obs.n_points >= settings.k1_min_points:
        return with_k1(c, obs, scale, settings, b)
    return c


def _refusal_before_search(obs: Observations, settings: CalibrationSettings, diag: float, need: int) -> Refusal | None:
    """Why the lines cannot fix a camera, said before any start is tried: fewer constraints than ``need``, ground
    lines of one direction only (no circle), or every point on one line (within the loss scale, px, of ``diag`` the
    image diagonal); None when the search may start."""
    n_constraints = obs.constraint_count()
    if n_constraints < need:
        return Refusal("few_constraints", {"need": need, "constraints": n_constraints, "lines": len(obs.classes)})
    nx, ny = obs.ground_line_directions()
    if not obs.circle_classes and (nx == 0 or ny == 0) and len(obs.classes) - nx - ny == 0:
        return Refusal("parallel_lines")
    pts = obs.all_points
    centred = pts - pts.mean(axis=0)
    normal = np.linalg.svd(centred, full_matrices=False)[2][-1]
    if np.max(np.abs(centred @ normal)) < settings.loss_scale_gamma * diag:
        return Refusal("collinear_points")
    return None


def _second_tries(lines: FieldLines, obs: Observations, best: Candidate | None, width: int, height: int,
                  prior: CalibrationPrior | None, settings: CalibrationSettings, budget: Budget, limit: float,
                  polish: _Polish, flags: list[str]) -> tuple[Candidate | None, Observations]:
    """When the best start leaves a line beyond ``limit`` (px) and the centre is free: the fit without one line class
    (four classes or more; flagged ``ignored_class:<class>``), else the look-at starts with the budget left. The best
    candidate and the observations it was fitted to."""
    fit_obs = obs
    if len(obs.classes) >= 4:
        # One mislabelled line (left/right confusion, a wrong goal post) spoils a frame.
        alt = without_one_class(lines, obs, best, width, height, settings,
                                 Budget(settings.max_evaluations // 2))
        if alt is not None and worst_residual(alt[1], alt[2]) <= limit:
            dropped, best, fit_obs = alt
            flags.append(f"ignored_class:{dropped}")
    if fit_obs is obs and budget.evaluations > 0 and not budget.lookat_done:
        other = search_starts(obs, width, height, prior, settings, budget, stage="look-at")
        other = polish(other, budget)
        if other is not None and (best is None or other.cost < best.cost):
            best = other
    return best, fit_obs


def _anchor_tries(lines: FieldLines, obs: Observations, best: Candidate | None, fit_obs: Observations, width: int,
                  height: int, prior: CalibrationPrior, settings: CalibrationSettings, limit: float, polish: _Polish,
                  flags: list[str]) -> tuple[Candidate | None, Observations]:
    """The learned camera positions (``prior.camera_prior.anchors_m``) as starts, with every class, else without one
    (four classes or more; flags updated); the best candidate and the observations it was fitted to (unchanged when
    neither fits)."""
    anchor_budget = Budget(settings.max_evaluations)
    other = polish(search_starts(obs, width, height, prior, settings, anchor_budget, stage="anchors"),
                   anchor_budget)
    if other is not None and worst_residual(other, obs) <= limit:
        best, fit_obs = other, obs
        flags[:] = [f for f in flags if not f.startswith("ignored_class:")]
    elif len(obs.classes) >= 4:
        alt = anchors_without_one_class(lines, obs, other if other is not None else best, width, height,
                                         prior, settings, limit)
        if alt is not None:
            dropped, best, fit_obs = alt
            flags[:] = [f for f in flags if not f.startswith("ignored_class:")] + [f"ignored_class:{dropped}"]
    return best, fit_obs


def _refusal_after_fit(per_class: Mapping[str, float], rms: float, fit_obs: Observations, limit: float, fixed: bool,
                       centre_limit: float) -> Refusal | None:
    """Why the fitted camera is refused: a line it was fitted to beyond ``limit`` (px), or, with its centre fixed, an
    RMS beyond ``centre_limit`` (px); None when it stands."""
    fitted = {c: per_class[c] for c in fit_obs.classes}
    worst = max(fitted.values()) if fitted else 0.0
    if worst > limit:
        bad = max(fitted, key=fitted.get)  # type: ignore[arg-type]  # every key is in the dict: get never answers None
        return Refusal("residual_too_high", {"line": bad, "px": worst, "limit_px": limit})
    if fixed and rms > centre_limit:
        # With the centre known only focal length and rotation are free and few lines are labelled:
        # the fit absorbs little, so labels it cannot bring within the tolerance of a good
        # single-frame fit (accept_gamma, the admission threshold's scale) disagree with the centre.
        return Refusal("centre_misfit", {"rms_px": rms, "limit_px": centre_limit})
    return None


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
    flags: list[str] = []
    if len(obs.classes) < MIN_LINE_CLASSES:
        flags.append("few_lines")
    refusal = _refusal_before_search(obs, settings, diag, need)
    if refusal is not None:
        return _refused(refusal, t0, tuple(flags))
    try:
        budget = Budget(settings.max_evaluations)
        best = search_starts(obs, width, height, prior, settings, budget)
        fit_obs = obs
        scale = settings.loss_scale_gamma * diag
        limit = settings.refuse_gamma * diag
        polish: _Polish = functools.partial(_polished, obs=obs, scale=scale, settings=settings)
        best = polish(best, budget)
        if worst_residual(best, obs) > limit and not fixed:
            best, fit_obs = _second_tries(lines, obs, best, width, height, prior, settings, budget, limit, polish,
                                          flags)
        centre_prior = None
        if (not fixed and prior is not None and prior.camera_prior is not None and prior.camera_prior.anchors_m
                and worst_residual(best, fit_obs) > limit):
            # No start fitted the labels: the learned camera positions are starts too.
            best, fit_obs = _anchor_tries(lines, obs, best, fit_obs, width, height, prior, settings, limit, polish,
                                          flags)
        radial_prior = None
        if best is not None and prior is not None and prior.camera_prior is not None and prior.camera_prior.has_radial:
            best, radial_prior = with_radial_prior(best, fit_obs, prior.camera_prior, scale, limit, diag / 2.0,
                                                    settings)
        if best is not None and not fixed and prior is not None and prior.camera_prior is not None:
            best, centre_prior = with_camera_prior(best, fit_obs, prior.camera_prior, scale, limit, diag / 2.0,
                                                     settings)
    except (np.linalg.LinAlgError, ValueError, FloatingPointError) as exc:  # numerical breakdown
        return _refused(Refusal("solver_failed", {"error": str(exc)}), t0, tuple(flags))
    if best is None:
        return _refused(Refusal("no_camera_fits"), t0, tuple(flags))
    camera = best.param.camera(best.x)
    per_class, rms = class_residuals(camera, obs)
    if fixed:
        flags.append(RIG_FLAG)
    if centre_prior is not None:
        flags.append(PRIOR_FLAG)
    if radial_prior is not None and best.param.fit_k1:
        flags.append(RADIAL_PRIOR_FLAG)
    if camera.radial[0] != 0.0:
        flags.append("radial_distortion")
    refusal = _refusal_after_fit(per_class, rms, fit_obs, limit, fixed, settings.accept_gamma * diag)
    if refusal is not None:
        return _refused(refusal, t0, tuple(flags), per_class, rms)
    mirrored = None
    if prior is not None and side_vote(camera, prior.expected_side) == 1:
        flags.append(MIRROR_FLAG)
        mirrored = mirror_lines(lines)
    jac: dict[str, float] = {}
    if compute_jac:
        jac = frame_jac(camera, lines, width, height, jac_function)
    return CalibrationResult(status="calibrated", camera=camera, refusal=None, jac=jac, residuals_px=per_class,
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
