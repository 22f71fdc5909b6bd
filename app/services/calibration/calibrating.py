"""Calibration of stored frames: the pure ``calibrate_frame`` run on a frame's stored field lines, in this
process or in the one process pool of bulk work, its plain result (:class:`CalibrationFields`) and how it is
stored (:func:`apply_calibration`); admission (method.md section 4: calibrated with JaC at
``settings.admit_jac_gamma`` strictly above ``settings.admit_jac_min``); and the game rig.

Game rigs: broadcast cameras stay put during a game, so a frame of a SoccerNet-v3 game that its
lines alone cannot calibrate, or calibrate only below admission, is retried with its centre at one of
the game's camera positions (:func:`game_rig`, ``app.geometry.calibration.rig``), estimated from the
game's frames calibrated above the admission threshold; the rig's result is kept only when it fits
the labels better (:func:`with_rig_retry`, by residual). Calibration datasets (frames from many
stadiums) never use one.

The process pool (:func:`calibration_pool`) serves every bulk calibration: imports (``app.services.transfer.importing``,
``app.services.calibration.first_pass``) and the offline ``v3d calibrate`` (:meth:`CalibrationPool.map`).
"""
from __future__ import annotations

import contextlib
import dataclasses
import multiprocessing
import os
import time
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass
from typing import Any, Callable, Collection, Iterable, Iterator, Sequence, TypeVar

import numpy as np
import sqlalchemy as sa
from sqlalchemy import select
from sqlalchemy.orm import Session

from app.core.config import Settings
from app.db.models import JAC_COLUMNS, Calibration, CalibrationSource, CalibrationStatus, Frame, FrameRole, System
from app.db.types import json_safe, utcnow
from app.geometry.annotations import mirror_lines, FieldLines, lines_from_json_lists
from app.geometry.calibration import (
    CalibrationPrior, CameraPrior, calibrate_frame, calibration_uncertainty, learn_camera_prior, lines_used, radial_corner,
)
from app.geometry.calibration.result import MIRROR_FLAG, RIG_FLAG
from app.geometry.calibration.priors import confident_mask
from app.geometry.calibration.rig import CameraRig, calibrate_with_rig, estimate_rig
from app.geometry.calibration.solver import PriorRows
from app.geometry.camera import Camera
from app.geometry.jac import JAC_GAMMAS
from app.geometry.mirror import mirrored_fit_at_rig
from app.services.curation.doubt_words import with_sentence
from app.datasets.records import CalibrationFields
from app.services.jobs.progress import Progress
from app.services.kinds import kind_of

_J = TypeVar("_J")
_R = TypeVar("_R")

#: Calibration flag of a camera given by its dataset with no field lines to compute JaC on (an ISSIA
#: ``issia_calibration.json`` camera without ``issia_lines.json``): admitted as given.
GIVEN_CAMERA_FLAG = "given_camera"

#: Jobs below this count are calibrated in-process (a pool costs more than it saves).
_MIN_JOBS_FOR_POOL = 8


def expected_side(role: FrameRole) -> int | None:
    """Side of the pitch the camera of a frame is expected on: +1 (y > 0) for broadcast main cameras
    (actions and calibration-dataset frames, method.md section 3), None for replays (anywhere).
    Only used to flag probably mirrored labels (calibration's camera-side flag, and the side prior
    of ``app.geometry.mirror.mirror_evidence``)."""
    return None if role is FrameRole.REPLAY else 1


def calibrate_lines(lines_json: dict[str, Any], width: int, height: int, side: int | None = None,
                    rig: CameraRig | CameraPrior | None = None, main_camera: bool = False) -> CalibrationFields:
    """Calibrate one frame from its stored field lines (``{class: [[[x, y], ...], ...]}``, pixels).

    Pure: calls ``app.geometry.calibration.calibrate_frame`` (JaC at :data:`JAC_GAMMAS` included)
    with the prior ``expected_side=side``, or, given a game ``rig``, ``calibrate_with_rig`` (the
    centre fixed at one of the game's camera positions; ``main_camera``: the frame is an action,
    filmed by the main camera, whose position is preferred among equally fitting ones), and converts
    the result. A frame the rig cannot calibrate either is flagged :data:`MIRROR_FLAG` when its
    mirrored labels fit a rig position (``app.geometry.mirror.mirrored_fit_at_rig``; the result stays
    a refusal: labels are never changed silently). Given a dataset's learned ``CameraPrior`` in place
    of a rig (:func:`dataset_prior`), the free fit is made a MAP fit where the lines leave the centre
    open (``CalibrationPrior.camera_prior``). Safe to run in a worker process.
    """
    t0 = time.perf_counter()
    lines = lines_from_json_lists(lines_json)
    if isinstance(rig, CameraPrior):
        fields = _fields_from_result(calibrate_frame(lines, width, height, prior=CalibrationPrior(
            expected_side=side, camera_prior=rig)), lines)
        return dataclasses.replace(fields, elapsed_ms=(time.perf_counter() - t0) * 1e3)
    if rig is not None:
        fields = _fields_from_result(calibrate_with_rig(lines, width, height, rig, expected_side=side,
                                                        main_camera=main_camera), lines)
        if fields.status is CalibrationStatus.REFUSED:
            verdict = mirrored_fit_at_rig(lines, width, height, rig, expected_side=side)
            if verdict is not None:
                fields = dataclasses.replace(fields, flags=[*fields.flags, MIRROR_FLAG],
                                             mirror_evidence=json_safe(with_sentence(verdict.as_dict(), {})))
        return dataclasses.replace(fields, elapsed_ms=(time.perf_counter() - t0) * 1e3)
    prior = CalibrationPrior(expected_side=side) if side is not None else None
    fields = _fields_from_result(calibrate_frame(lines, width, height, prior=prior), lines)
    if fields.status is CalibrationStatus.REFUSED and side is not None:
        fields = _with_mirrored_refit(fields, lines, width, height, prior)
    return dataclasses.replace(fields, elapsed_ms=(time.perf_counter() - t0) * 1e3)


def _with_mirrored_refit(fields: CalibrationFields, lines: FieldLines, width: int, height: int,
                         prior: CalibrationPrior) -> CalibrationFields:
    """The mirrored re-fit of a main-camera frame its labels cannot calibrate (issue 18).

    Labels and their mirror fit mirrored cameras equally well (``app.geometry.mirror``), except where a prior
    breaks the symmetry: a main camera is expected on the near side (``expected_side``), so mirrored labels,
    which need the camera on the far side, can be refused outright. When the mirrored labelling
    (``app.geometry.annotations.mirror_lines``) calibrates under the same prior, the refusal is flagged
    :data:`MIRROR_FLAG` with evidence ``refit`` (the camera position and RMS of the mirrored fit, its JaC@0.5 %):
    a mirrored-labels doubt whose fix (mirroring the lines) gives that camera. The labels are not changed here.
    """
    mirrored = calibrate_frame(mirror_lines(lines), width, height, prior=prior)
    if str(getattr(mirrored.status, "value", mirrored.status)) != "calibrated" or mirrored.camera is None:
        return fields
    if MIRROR_FLAG in (mirrored.flags or ()):  # mirrored, it lands beyond the far side as well: no evidence
        return fields
    c = mirrored.camera.C
    evidence = {"verdict": MIRROR_FLAG, "margin": None, "camera_y_m": None, "side_vote": 0, "rig_distance_m": None,
                "rig_distance_mirrored_m": None, "rig_vote": 0, "pairs": [],
                "refit": {"position_m": [round(float(x), 2) for x in c],
                          "rms_px": None if mirrored.rms_px is None else round(float(mirrored.rms_px), 2),
                          "jac": None if not mirrored.jac else _opt_float(mirrored.jac.get(f"{JAC_GAMMAS[0]:g}")),
                          "source": "lines"}}
    return dataclasses.replace(fields, flags=[*fields.flags, MIRROR_FLAG],
                               mirror_evidence=json_safe(with_sentence(evidence, {})))


def _fields_from_result(result: Any, lines: FieldLines | None = None) -> CalibrationFields:
    """Plain fields of an ``app.geometry.calibration.CalibrationResult``; given the ``lines`` it was
    fitted to, with the camera's uncertainty (:func:`fit_uncertainty`)."""
    camera = result.camera
    status = CalibrationStatus(str(getattr(result.status, "value", result.status)))
    uncertainty = None
    if lines is not None and camera is not None and status is CalibrationStatus.CALIBRATED:
        uncertainty = fit_uncertainty(camera, lines, tuple(result.flags or ()), getattr(result, "centre_prior", None))
    jac = tuple(_opt_float(result.jac.get(f"{g:g}")) for g in JAC_GAMMAS) if result.jac else (None, None, None)
    return CalibrationFields(
        status=status,
        camera=json_safe(camera.to_soccernet()) if camera is not None and status is CalibrationStatus.CALIBRATED else None,
        jac=jac,  # type: ignore[arg-type]
        residuals_px=json_safe(dict(result.residuals_px or {})),
        flags=[str(f) for f in (result.flags or ())],
        reason=result.reason,
        elapsed_ms=float(result.elapsed_ms),
        rms_px=_opt_float(result.rms_px),
        uncertainty=uncertainty,
    )


def fit_uncertainty(camera: Camera, lines: FieldLines, flags: tuple[str, ...],
                    prior: PriorRows | None = None) -> dict[str, Any] | None:
    """JSON of ``app.geometry.calibration.calibration_uncertainty`` for a camera fitted to ``lines``:
    a class the fit ignored (flag ``ignored_class:<class>``) is left out, a rig-assisted fit
    (:data:`RIG_FLAG`) had its centre fixed, a MAP fit with a learned prior (``prior``: its
    ``CalibrationResult.centre_prior``) gets the posterior's std. None when it cannot be computed."""
    try:
        u = calibration_uncertainty(camera, lines_used(lines, flags), fixed_centre=RIG_FLAG in flags, prior=prior)
    except (np.linalg.LinAlgError, ValueError, FloatingPointError):
        return None
    return None if u is None else u.to_json()


def _opt_float(v: Any) -> float | None:
    return None if v is None else float(v)


#: ``(lines_json, width, height, side, rig, main_camera)``: the arguments of :func:`calibrate_lines`
#: (``rig``: a game's rig, or a dataset's learned prior).
CalibrationJob = tuple[dict[str, Any], int, int, "int | None", "CameraRig | CameraPrior | None", bool]


def _calibrate_job(job: CalibrationJob) -> CalibrationFields:
    return calibrate_lines(*job)


def calibration_job(frame: Frame, rig: CameraRig | CameraPrior | None = None,
                    lines: dict[str, Any] | None = None) -> CalibrationJob:
    """The job that calibrates ``frame`` from its current field lines, or from ``lines`` (JSON lists, px)
    in their place (with the game ``rig``, or a dataset's learned prior, if any).

    Raises:
        ValueError: the frame has no field lines and no ``lines`` are given.
    """
    if lines is None:
        if frame.field_lines is None:
            raise ValueError(f"frame {frame.id} ({frame.name!r}) has no field lines to calibrate from")
        lines = frame.field_lines.lines
    return (lines, frame.width, frame.height, expected_side(frame.role), rig, frame.role is FrameRole.ACTION)


@dataclass(frozen=True)
class CalibrationPool:
    """Processes for bulk calibration (:func:`calibration_pool`): ``executor`` None runs in this process."""

    workers: int
    executor: ProcessPoolExecutor | None

    def map(self, fn: Callable[[_J], _R], jobs: Iterable[_J], chunksize: int = 1) -> Iterator[_R]:
        """``fn`` over ``jobs``, results in order: on the pool's processes (``fn`` must be a module-level
        function, jobs and results picklable), or lazily in this process without an executor. Handed
        to the processes at once, so the caller may do other work before it reads the results."""
        if self.executor is None:
            return map(fn, jobs)
        return self.executor.map(fn, jobs, chunksize=chunksize)


@contextlib.contextmanager
def calibration_pool(workers: int = 0) -> Iterator[CalibrationPool]:
    """The process pool of bulk calibration, for the span of an import (its batches share it): in this
    process when ``workers`` (0 = all cores) is 1, else that many processes, shut down on exit.

    forkserver, not fork: the API runs imports from worker threads, and forking a threaded process can
    deadlock the child; workers import the geometry once and then take chunks of jobs."""
    n = workers or os.cpu_count() or 1
    if n <= 1:
        yield CalibrationPool(1, None)
        return
    executor = ProcessPoolExecutor(max_workers=n, mp_context=multiprocessing.get_context("forkserver"))
    try:
        yield CalibrationPool(n, executor)
    finally:
        executor.shutdown(wait=True, cancel_futures=True)


def calibrate_many(jobs: Sequence[CalibrationJob], workers: int = 0, progress: Progress | None = None,
                   stage: str = "calibrate", pool: CalibrationPool | None = None) -> list[CalibrationFields]:
    """Calibrate many frames, in parallel on ``workers`` processes (0 = all cores).

    Args:
        jobs: one :data:`CalibrationJob` per frame (see :func:`calibration_job`).
        workers: process count; 0 means ``os.cpu_count()``; 1, or fewer than a handful of jobs,
            runs in this process.
        progress: called with ``(stage, done, total)``.
        pool: a pool from :func:`calibration_pool` to run on (then ``workers`` is ignored); without
            one, a pool is made for this call.

    Returns:
        One :class:`CalibrationFields` per job, in order.
    """
    total = len(jobs)
    n = pool.workers if pool is not None else (workers or os.cpu_count() or 1)
    out: list[CalibrationFields] = []
    if n <= 1 or total < _MIN_JOBS_FOR_POOL:
        for job in jobs:
            out.append(_calibrate_job(job))
            if progress:
                progress(stage, len(out), total)
        return out
    chunk = _chunk_size(jobs, n)
    with contextlib.ExitStack() as stack:
        if pool is None:
            pool = stack.enter_context(calibration_pool(n))
        for fields in pool.map(_calibrate_job, jobs, chunksize=chunk):
            out.append(fields)
            if progress:
                progress(stage, len(out), total)
    return out


def _chunk_size(jobs: Sequence[CalibrationJob], workers: int) -> int:
    """Jobs per round trip to a worker: fewer round trips, but a chunk is the tail one worker may run
    alone at the end; rig retries (a full fit per rig position) get small chunks."""
    heavy = any(len(job) > 4 and isinstance(job[4], CameraRig) for job in jobs)
    return max(1, min(4 if heavy else 16, len(jobs) // (workers * 8)))


def apply_calibration(frame: Frame, fields: CalibrationFields, source: CalibrationSource) -> Calibration:
    """Write ``fields`` into the frame's calibration row (created if missing).

    ``admitted`` is reset to False: it is decided by :func:`recompute_system`.
    """
    cal = frame.calibration
    if cal is None:
        cal = Calibration(source=source, status=fields.status)
        frame.calibration = cal
    cal.source = source
    cal.status = fields.status
    cal.camera = fields.camera
    cal.jac_0005, cal.jac_001, cal.jac_002 = fields.jac
    cal.residuals_px = fields.residuals_px
    cal.flags = list(fields.flags)
    cal.reason = fields.reason
    cal.mirror_evidence = fields.mirror_evidence
    cal.uncertainty = fields.uncertainty
    cal.admitted = False
    cal.updated_at = utcnow()
    return cal


def admission_jac(calibration: Calibration, settings: Settings) -> float | None:
    """The calibration's JaC at ``settings.admit_jac_gamma``.

    Raises:
        ValueError: the gamma is not one of the stored :data:`JAC_GAMMAS`.
    """
    return getattr(calibration, JAC_COLUMNS[_gamma(settings)])


def is_admitted(calibration: Calibration | None, settings: Settings) -> bool:
    """True when the frame joins triangulation: calibrated with JaC@gamma > ``admit_jac_min``."""
    if calibration is None or calibration.status is not CalibrationStatus.CALIBRATED or calibration.camera is None:
        return False
    if GIVEN_CAMERA_FLAG in (calibration.flags or []):
        return True  # a static camera given by its dataset (ISSIA) without field lines to judge it
    jac = admission_jac(calibration, settings)
    return jac is not None and jac > settings.admit_jac_min


def game_rig(session: Session | None, game_id: int | None, settings: Settings, exclude_frame_ids: Collection[int] = (),
             extra: Iterable[CalibrationFields] = (), extra_roles: Sequence[FrameRole] | None = None,
             stored: Sequence[tuple[int, np.ndarray, bool]] | None = None) -> CameraRig:
    """The camera rig of a game (``app.geometry.calibration.rig.estimate_rig``), from the centres of
    its cameras that are calibrated with JaC@gamma > ``admit_jac_min`` and not rig-assisted themselves.
    Action frames mark the main camera's position (:attr:`RigPosition.main_frames`).

    Args:
        session: reads the stored calibrations; may be None when ``game_id`` is None.
        game_id: the game whose stored calibrations count (None: a game not stored yet).
        exclude_frame_ids: stored frames left out (the ones being recalibrated).
        extra: calibrations not stored yet that count too (an import's fresh results).
        extra_roles: the role of each of ``extra``'s frames (None: unknown, no main camera marked).
        stored: the game's stored rows as :func:`rig_rows` gives them, when the caller has read
            them already (then ``session`` is not queried).
    """
    extra = list(extra)
    roles: Sequence[FrameRole | None] = list(extra_roles) if extra_roles is not None else [None] * len(extra)
    if len(roles) != len(extra):
        raise ValueError(f"extra_roles must give one role per extra calibration ({len(extra)}), got {len(roles)}")
    gamma_index = JAC_GAMMAS.index(_gamma(settings))
    rows = [(np.asarray(f.camera["position_meters"], float), role is FrameRole.ACTION)  # type: ignore[index]
            for f, role in zip(extra, roles)
            if _feeds_rig(f.status, f.camera, f.flags, f.jac[gamma_index], settings)]
    if stored is None and game_id is not None and session is not None:
        stored = rig_rows(session, game_id, settings)
    if stored is not None:
        excluded = set(exclude_frame_ids)
        rows += [(c, main) for fid, c, main in stored if fid not in excluded]
    return estimate_rig(np.array([c for c, _ in rows]).reshape(-1, 3), main_camera=[m for _, m in rows])


def rig_centres(session: Session, game_id: int, settings: Settings) -> list[tuple[int, np.ndarray]]:
    """``(frame id, camera centre (3,), metres)`` of the stored calibrations of a game that feed its
    rig (:func:`game_rig`)."""
    return [(fid, c) for fid, c, _ in rig_rows(session, game_id, settings)]


def rig_rows(session: Session, game_id: int, settings: Settings) -> list[tuple[int, np.ndarray, bool]]:
    """``(frame id, camera centre (3,) metres, filmed by the main camera)`` of the calibrations feeding
    the game's rig: calibrated, JaC@gamma > ``admit_jac_min``, not rig-assisted. One query that reads
    only the centre out of each stored camera (the rig needs nothing else), so an edit does not decode
    every calibration of its game."""
    jac = getattr(Calibration, JAC_COLUMNS[_gamma(settings)])
    query = (select(Calibration.frame_id, Frame.role, Calibration.camera["position_meters"])
             .join(Frame, Frame.id == Calibration.frame_id)
             .join(System, System.id == Frame.system_id)
             .where(System.game_id == game_id, Calibration.status == CalibrationStatus.CALIBRATED,
                    Calibration.camera.is_not(None), jac > settings.admit_jac_min,
                    sa.cast(Calibration.flags, sa.Text).not_like(f'%"{RIG_FLAG}"%')))
    return [(fid, np.asarray(centre, float), role is FrameRole.ACTION) for fid, role, centre in session.execute(query)]


#: Fewest calibrated frames of an import's systems without a rig from which a dataset prior is learned
#: (half of them confident: a handful of anchors at least).
MIN_PRIOR_FRAMES = 40


def dataset_prior(results: Sequence[CalibrationFields],
                  lines: Sequence[tuple[FieldLines, int, int]] | None = None) -> CameraPrior | None:
    """The learned camera prior of a dataset (``app.geometry.calibration.learn_camera_prior``) from
    its frames' calibrations from their lines alone: the calibrated ones, not rig-assisted, with an
    uncertainty (camera and position std read from the fields). With ``lines`` (per result: its
    frame's field lines, width and height, px) the prior learns the radial term too, from the
    confident fits refitted with ``k1`` free (``radial_corner``; classes a fit ignored left out). None
    below :data:`MIN_PRIOR_FRAMES` such frames or when no anchor is found."""
    cams, stds, used = [], [], []
    for i, r in enumerate(results):
        if r.status is not CalibrationStatus.CALIBRATED or r.camera is None or r.uncertainty is None or RIG_FLAG in r.flags:
            continue
        p = r.uncertainty["position_m"]
        cams.append(Camera.from_soccernet(r.camera))
        stds.append(float(np.sqrt(sum(float("inf") if p[k] is None else float(p[k]) ** 2 for k in "xyz"))))
        used.append(i)
    if len(cams) < MIN_PRIOR_FRAMES:
        return None
    radial = None
    if lines is not None:
        confident, _ = confident_mask(stds)
        radial = []
        for cam, sure, i in zip(cams, confident, used):
            if not sure:
                radial.append(float("nan"))  # not among the confident fits the prior learns from
                continue
            field_lines, width, height = lines[i]
            radial.append(radial_corner(cam, lines_used(field_lines, results[i].flags), width, height))
    prior = learn_camera_prior(cams, stds, radial_corner=radial)
    return prior if prior.anchors_m else None


def stored_camera_prior(system: System) -> CameraPrior | None:
    """The learned camera prior stored on ``system``'s game (``games.camera_prior``: its calibration
    dataset's import learned it), or None: no game, a kind that uses rigs (:func:`uses_rig`: a game's
    cameras are its rig), nothing stored, or a stored value that is not a prior (then it is ignored)."""
    game = system.game
    if game is None or game.camera_prior is None or uses_rig(system):
        return None
    try:
        return CameraPrior.from_json(game.camera_prior)
    except ValueError:
        return None


def with_prior_refit(first: CalibrationFields, refit: CalibrationFields) -> CalibrationFields:
    """The calibration kept after a :func:`wants_prior_retry` refit: the refit when it calibrates (the MAP
    fit is the better estimate where the lines leave the centre open), the first fit otherwise."""
    return refit if refit.status is CalibrationStatus.CALIBRATED else first


def wants_prior_retry(fields: CalibrationFields, prior: CameraPrior) -> bool:
    """True when a frame's calibration from its lines alone is worth refitting with the dataset's
    learned ``prior``: refused, or calibrated while the prior has a radial term (every fit takes
    it: the lines of one frame rarely fix the lens), or calibrated with a camera-position std above the
    prior's confident ones' (``CameraPrior.confident_std_m``: the lines leave the centre open). Without
    a radial term, frames whose lines fix the camera as well as the confident ones are never refitted
    (their calibration stays as it is); refusals flagged :data:`MIRROR_FLAG` never are (the prior's
    anchors, on the labelled side, would fit mirrored labels with a wrong camera), nor rig-assisted
    fits."""
    if fields.status is CalibrationStatus.REFUSED:
        return MIRROR_FLAG not in fields.flags  # mirrored labels: a prior on this side would hide it
    if fields.uncertainty is None or RIG_FLAG in fields.flags:
        return False
    if prior.has_radial:
        return True
    p = fields.uncertainty["position_m"]
    if any(p[k] is None for k in "xyz"):
        return True
    return float(np.sqrt(sum(float(p[k]) ** 2 for k in "xyz"))) > prior.confident_std_m


def wants_rig_retry(fields: CalibrationFields, settings: Settings) -> bool:
    """True when a frame's calibration from its lines alone is worth retrying with the game's rig:
    refused, or calibrated without clearing admission (JaC@gamma <= ``admit_jac_min``: a free fit of
    few lines can settle metres from the camera's true position, where the rig's known centre fits
    the same labels better; :func:`with_rig_retry` keeps the better fit by residual)."""
    if fields.status is CalibrationStatus.REFUSED:
        return True
    jac = fields.jac[JAC_GAMMAS.index(_gamma(settings))]
    return jac is None or not jac > settings.admit_jac_min


def with_rig_retry(first: CalibrationFields, retried: CalibrationFields) -> CalibrationFields:
    """What is stored for a frame retried with the game's rig (:func:`wants_rig_retry`).

    * The rig calibrated it and the first pass refused it: the rig's calibration.
    * Both calibrated it: the one whose camera fits the labels better, by the RMS distance of every
      labelled point to its model element (the same definition for both, ``rms_px``; the first pass
      wins ties and when a residual is missing). The labels' JaC is never used to choose: it is
      what admission evaluates.
    * The rig refused it: the first result; a first refusal carries the rig's mirror flag and
      evidence when the mirrored labels fit a rig position (:func:`calibrate_lines`).
    """
    if retried.status is CalibrationStatus.CALIBRATED:
        if first.status is not CalibrationStatus.CALIBRATED:
            return retried
        if first.rms_px is not None and retried.rms_px is not None and retried.rms_px < first.rms_px:
            return retried
        return first
    if first.status is CalibrationStatus.REFUSED and MIRROR_FLAG in retried.flags:
        flags = first.flags if MIRROR_FLAG in first.flags else [*first.flags, MIRROR_FLAG]
        return dataclasses.replace(first, flags=flags, mirror_evidence=retried.mirror_evidence)
    return first


def _gamma(settings: Settings) -> float:
    if settings.admit_jac_gamma not in JAC_COLUMNS:
        raise ValueError(f"settings.admit_jac_gamma={settings.admit_jac_gamma!r} is not a stored JaC gamma; "
                         f"choose one of {list(JAC_GAMMAS)}")
    return settings.admit_jac_gamma


def _feeds_rig(status: CalibrationStatus, camera: dict[str, Any] | None, flags: Sequence[str] | None,
               jac: float | None, settings: Settings) -> bool:
    return (status is CalibrationStatus.CALIBRATED and camera is not None and RIG_FLAG not in (flags or ())
            and jac is not None and jac > settings.admit_jac_min)


def uses_rig(system: System) -> bool:
    """Whether game rigs apply to the system (its kind's ``uses_rig``: SoccerNet-v3 games, whose cameras
    are fixed during a game; never calibration datasets, whose frames come from many stadiums)."""
    return kind_of(system).uses_rig
