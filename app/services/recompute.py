"""Recomputation of everything derived from annotations: calibration, admission, triangulation,
reprojections and optimised boxes.

Chain (docs/architecture.md): a frame's field lines -> its calibration (:func:`recompute_frame`) ->
its system's admission and triangulation -> reprojections and optimised boxes of the system's frames
(:func:`recompute_system`). These functions only change the session; the caller commits, so an edit
and its recomputation land in one transaction (``app.services.editing``).

Admission (method.md section 4): a frame joins triangulation when it is calibrated and its JaC at
``settings.admit_jac_gamma`` is strictly above ``settings.admit_jac_min``.

Derived rows:

* ``Triangulation`` (+ ``TriangulationPair`` per pair of admitted labelled views), always present
  after recomputation, with the status of ``app.geometry.triangulation.triangulate_ball``;
* ``BallReprojection`` for every frame with a camera when the system has a 3D ball (the error is
  against the frame's label, None without one);
* ``OptimisedBox`` (paper Eq. min_diametre; drawn by ``settings.optimised_box_method``) for every admitted frame with a label
  when the system has a 3D ball and the ball lies in front of the camera along the labelled ray;
* ``Doubt`` rows and the system's doubt counts (``app.services.doubts.update_doubts``, last).

A view a reviewer excluded (``ReviewDecision.excluded``) keeps its calibration and labels but takes no
part in the triangulation.

Bulk calibration (:func:`calibrate_many`) runs the pure ``calibrate_frame`` in a process pool and
returns plain :class:`CalibrationFields`; the main process writes them (:func:`apply_calibration`).

Mirrored labels (``app.geometry.mirror``): after admission, every calibrated frame of the system is
judged from its camera's side, the game's rig and its ball ray against the other views; the verdict
sets the flag :data:`MIRROR_FLAG` and ``Calibration.mirror_evidence``. The flag replaces
``calibrate_frame``'s camera-side flag for calibrated frames, which it reproduces for a frame with no
other evidence (a single frame, a view without a ball). Labels are never changed here.

Game rigs: broadcast cameras stay put during a game, so a frame of a SoccerNet-v3 game that its
lines alone cannot calibrate, or calibrate only below admission, is retried with its centre at one of
the game's camera positions (:func:`game_rig`, ``app.geometry.calibration.rig``), estimated from the
game's frames calibrated above the admission threshold; the rig's result is kept only when it fits
the labels better (:func:`with_rig_retry`, by residual). Calibration datasets (frames from many
stadiums) never use one.
"""
from __future__ import annotations

import contextlib
import dataclasses
import multiprocessing
import os
import time
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass, field
from typing import Any, Callable, Collection, Iterable, Iterator, Sequence

import numpy as np
import sqlalchemy as sa
from sqlalchemy import select
from sqlalchemy.orm import Session, selectinload

from app.core.config import Settings
from app.db.models import (
    BallReprojection, Calibration, CalibrationSource, CalibrationStatus, Frame, FrameRole, OptimisedBox, ReviewStatus,
    System, SystemKind, Triangulation, TriangulationPair, TriangulationStatus,
)
from app.db.session import begin_write
from app.db.types import json_safe, utcnow
from app.geometry.annotations import lines_from_json_lists
from app.geometry.ball import optimise_box
from app.geometry.calibration import CalibrationPrior, calibrate_frame
from app.geometry.calibration.frame import MIRROR_FLAG, RIG_FLAG
from app.geometry.calibration.rig import CameraRig, calibrate_with_rig, estimate_rig
from app.geometry.camera import Camera
from app.geometry.mirror import MirrorSettings, MirrorView, mirror_evidence, mirrored_fit_at_rig
from app.geometry.triangulation import BallObservation, error_above_tau, triangulate_ball
from app.services.audit import record_summary
from app.services.doubts import is_excluded, update_doubts

#: The three JaC gammas stored per calibration (fractions of the image diagonal, method.md s4).
JAC_GAMMAS: tuple[float, float, float] = (0.005, 0.01, 0.02)
_JAC_COLUMNS = {0.005: "jac_0005", 0.01: "jac_001", 0.02: "jac_002"}


#: Version of what :func:`recompute_system` derives (rows and the queue's figures); raise it when that
#: changes, so that stored systems are recomputed before they are served (:func:`refresh_stale_systems`).
DERIVED_VERSION = 1
#: Calibration flag of a camera given by its dataset with no field lines to compute JaC on (an ISSIA
#: ``issia_calibration.json`` camera without ``issia_lines.json``): admitted as given.
GIVEN_CAMERA_FLAG = "given_camera"

#: Jobs below this count are calibrated in-process (a pool costs more than it saves).
_MIN_JOBS_FOR_POOL = 8

#: ``progress(stage, done, total)``: called as work advances (the CLI draws a tqdm bar from it).
Progress = Callable[[str, int, int], None]


@dataclass(frozen=True)
class CalibrationFields:
    """What is stored of a calibration: plain values, picklable across processes.

    Attributes:
        status: calibrated or refused.
        camera: SoccerNet camera JSON (method.md section 2) at the frame's resolution, or None.
        jac: JaC at the gammas of :data:`JAC_GAMMAS` (None where not computed).
        residuals_px: class -> residual in pixels.
        flags: warnings raised by calibration (e.g. probable mirrored labels).
        reason: why calibration was refused (None when calibrated).
        elapsed_ms: wall time of the calibration, rig positions and mirrored-labels check included
            (not stored; import reports use it).
        rms_px: RMS distance (px) of every labelled point to its model element under the camera, or
            under the best rejected one (not stored): how a rig retry is compared with the first
            result (:func:`with_rig_retry`).
        mirror_evidence: for a frame refused even with the game's rig whose mirrored labels fit a
            rig position (``app.geometry.mirror.mirrored_fit_at_rig``), that evidence (JSON); the
            flag :data:`MIRROR_FLAG` is then in ``flags``. Calibrated frames get theirs from
            :func:`recompute_system`.
    """

    status: CalibrationStatus
    camera: dict[str, Any] | None
    jac: tuple[float | None, float | None, float | None]
    residuals_px: dict[str, Any] = field(default_factory=dict)
    flags: list[str] = field(default_factory=list)
    reason: str | None = None
    elapsed_ms: float | None = None
    mirror_evidence: dict[str, Any] | None = None
    rms_px: float | None = None


def expected_side(role: FrameRole) -> int | None:
    """Side of the pitch the camera of a frame is expected on: +1 (y > 0) for broadcast main cameras
    (actions and calibration-dataset frames, method.md section 3), None for replays (anywhere).
    Only used to flag probably mirrored labels (calibration's camera-side flag, and the side prior
    of ``app.geometry.mirror.mirror_evidence``)."""
    return None if role is FrameRole.REPLAY else 1


def calibrate_lines(lines_json: dict[str, Any], width: int, height: int, side: int | None = None,
                    rig: CameraRig | None = None, main_camera: bool = False) -> CalibrationFields:
    """Calibrate one frame from its stored field lines (``{class: [[[x, y], ...], ...]}``, pixels).

    Pure: calls ``app.geometry.calibration.calibrate_frame`` (JaC at :data:`JAC_GAMMAS` included)
    with the prior ``expected_side=side``, or, given a game ``rig``, ``calibrate_with_rig`` (the
    centre fixed at one of the game's camera positions; ``main_camera``: the frame is an action,
    filmed by the main camera, whose position is preferred among equally fitting ones), and converts
    the result. A frame the rig cannot calibrate either is flagged :data:`MIRROR_FLAG` when its
    mirrored labels fit a rig position (``app.geometry.mirror.mirrored_fit_at_rig``; the result stays
    a refusal: labels are never changed silently). Safe to run in a worker process.
    """
    t0 = time.perf_counter()
    lines = lines_from_json_lists(lines_json)
    if rig is not None:
        fields = _fields_from_result(calibrate_with_rig(lines, width, height, rig, expected_side=side,
                                                        main_camera=main_camera))
        if fields.status is CalibrationStatus.REFUSED:
            verdict = mirrored_fit_at_rig(lines, width, height, rig, expected_side=side)
            if verdict is not None:
                fields = dataclasses.replace(fields, flags=[*fields.flags, MIRROR_FLAG],
                                             mirror_evidence=json_safe(verdict.as_dict()))
        return dataclasses.replace(fields, elapsed_ms=(time.perf_counter() - t0) * 1e3)
    prior = CalibrationPrior(expected_side=side) if side is not None else None
    return _fields_from_result(calibrate_frame(lines, width, height, prior=prior))


def _fields_from_result(result: Any) -> CalibrationFields:
    """Plain fields of an ``app.geometry.calibration.CalibrationResult``."""
    camera = result.camera
    status = CalibrationStatus(str(getattr(result.status, "value", result.status)))
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
    )


def _opt_float(v: Any) -> float | None:
    return None if v is None else float(v)


#: ``(lines_json, width, height, side, rig, main_camera)``: the arguments of :func:`calibrate_lines`.
CalibrationJob = tuple[dict[str, Any], int, int, "int | None", "CameraRig | None", bool]


def _calibrate_job(job: CalibrationJob) -> CalibrationFields:
    return calibrate_lines(*job)


def calibration_job(frame: Frame, rig: CameraRig | None = None) -> CalibrationJob:
    """The job that calibrates ``frame`` from its current field lines (with the game ``rig``, if any)."""
    if frame.field_lines is None:
        raise ValueError(f"frame {frame.id} ({frame.name!r}) has no field lines to calibrate from")
    return (frame.field_lines.lines, frame.width, frame.height, expected_side(frame.role), rig,
            frame.role is FrameRole.ACTION)


@dataclass(frozen=True)
class CalibrationPool:
    """Processes for bulk calibration (:func:`calibration_pool`): ``executor`` None runs in this process."""

    workers: int
    executor: ProcessPoolExecutor | None


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
        assert pool.executor is not None
        for fields in pool.executor.map(_calibrate_job, jobs, chunksize=chunk):
            out.append(fields)
            if progress:
                progress(stage, len(out), total)
    return out


def start_calibrating(jobs: Sequence[CalibrationJob], pool: CalibrationPool) -> Iterator[CalibrationFields] | None:
    """Hand ``jobs`` to the pool's processes now and return at once: the returned iterator yields one
    :class:`CalibrationFields` per job, in order, waiting for each (so the caller can do other work
    meanwhile, e.g. store the previous batch of an import). None when the pool runs in this process
    or there are too few jobs (then calibrate them with :func:`calibrate_many` when needed)."""
    if pool.executor is None or len(jobs) < _MIN_JOBS_FOR_POOL:
        return None
    return pool.executor.map(_calibrate_job, jobs, chunksize=_chunk_size(jobs, pool.workers))


def _chunk_size(jobs: Sequence[CalibrationJob], workers: int) -> int:
    """Jobs per round trip to a worker: fewer round trips, but a chunk is the tail one worker may run
    alone at the end; rig retries (a full fit per rig position) get small chunks."""
    heavy = any(len(job) > 4 and job[4] is not None for job in jobs)
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
    cal.admitted = False
    cal.updated_at = utcnow()
    return cal


def admission_jac(calibration: Calibration, settings: Settings) -> float | None:
    """The calibration's JaC at ``settings.admit_jac_gamma``.

    Raises:
        ValueError: the gamma is not one of the stored :data:`JAC_GAMMAS`.
    """
    return getattr(calibration, _JAC_COLUMNS[_gamma(settings)])


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
    jac = getattr(Calibration, _JAC_COLUMNS[_gamma(settings)])
    query = (select(Calibration.frame_id, Frame.role, Calibration.camera["position_meters"])
             .join(Frame, Frame.id == Calibration.frame_id)
             .join(System, System.id == Frame.system_id)
             .where(System.game_id == game_id, Calibration.status == CalibrationStatus.CALIBRATED,
                    Calibration.camera.is_not(None), jac > settings.admit_jac_min,
                    sa.cast(Calibration.flags, sa.Text).not_like(f'%"{RIG_FLAG}"%')))
    return [(fid, np.asarray(centre, float), role is FrameRole.ACTION) for fid, role, centre in session.execute(query)]


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
    if settings.admit_jac_gamma not in _JAC_COLUMNS:
        raise ValueError(f"settings.admit_jac_gamma={settings.admit_jac_gamma!r} is not a stored JaC gamma; "
                         f"choose one of {list(JAC_GAMMAS)}")
    return settings.admit_jac_gamma


def _feeds_rig(status: CalibrationStatus, camera: dict[str, Any] | None, flags: Sequence[str] | None,
               jac: float | None, settings: Settings) -> bool:
    return (status is CalibrationStatus.CALIBRATED and camera is not None and RIG_FLAG not in (flags or ())
            and jac is not None and jac > settings.admit_jac_min)


def uses_rig(system: System) -> bool:
    """Game rigs apply to SoccerNet-v3 games (cameras fixed during a game), never to calibration
    datasets, whose frames come from many stadiums."""
    return system.kind is SystemKind.SOCCERNET_V3


def recompute_frame(session: Session, frame: Frame, settings: Settings) -> Triangulation:
    """Recalibrate ``frame`` from its current field lines, then recompute its system.

    A frame of a SoccerNet-v3 game that its lines alone cannot calibrate, or calibrate only below
    admission (:func:`wants_rig_retry`), is retried with the game's rig (:func:`game_rig`, the other
    frames' camera positions; :func:`with_rig_retry` keeps the better fit). The calibration's source
    becomes "computed". The caller flushes or commits.

    Raises:
        ValueError: the frame has no field lines, or the settings' admission gamma is not stored.
    """
    fields = calibrate_lines(*calibration_job(frame))
    rig_sources = None
    if wants_rig_retry(fields, settings) and uses_rig(frame.system) and frame.system.game_id is not None:
        # read once: the retry's rig and the system's mirror evidence both use the game's stored
        # cameras, and the evidence leaves this system's frames out, so this frame's new row is moot
        stored = rig_rows(session, frame.system.game_id, settings)
        rig_sources = [(fid, c) for fid, c, _ in stored]
        rig = game_rig(session, frame.system.game_id, settings, exclude_frame_ids=[frame.id], stored=stored)
        if rig.positions:
            fields = with_rig_retry(fields, calibrate_lines(*calibration_job(frame, rig)))
    apply_calibration(frame, fields, CalibrationSource.COMPUTED)
    return recompute_system(session, frame.system, settings, rig_sources)


def recompute_system(session: Session, system: System, settings: Settings,
                     rig_sources: Sequence[tuple[int, np.ndarray]] | None = None) -> Triangulation:
    """Admission, mirror evidence, triangulation, reprojections and optimised boxes of one system,
    from its current calibrations and ball labels (see the module docstring). Replaces the previous
    derived rows in the session; the caller flushes or commits. The system's frames must have ids
    (be flushed).

    Args:
        rig_sources: ``(frame id, camera centre)`` feeding the game's rig (:func:`rig_centres`), to spare
            a query per system in bulk; read from the session when None.

    Returns:
        The system's :class:`Triangulation` row.
    """
    frames = list(system.frames)
    cameras: dict[int, Camera] = {}
    observations: list[BallObservation] = []
    for f in frames:
        cal = f.calibration
        if cal is not None:
            cal.admitted = is_admitted(cal, settings)
            if cal.status is CalibrationStatus.CALIBRATED and cal.camera is not None:
                cameras[f.id] = Camera.from_soccernet(cal.camera)
        centre = _label_centre(f)
        if cal is not None and cal.admitted and centre is not None and not is_excluded(f):
            observations.append(BallObservation(view_id=f.id, camera=cameras[f.id], point_px=centre,
                                                image_width=f.width))
    if system.kind is not SystemKind.ISSIA:  # static cameras on every side: the broadcast priors do not hold
        _update_mirror_flags(session, system, cameras, settings, rig_sources)
    if system.kind is SystemKind.ISSIA:  # the labels the sequence's trajectory keeps, that agree
        from app.services.issia_trajectory import consensus_observations
        observations = consensus_observations(system, observations, settings)
    result = triangulate_ball(observations, tau_px=settings.triangulation_tau_px, rule=settings.pair_error_rule,
                              min_baseline_m=settings.min_baseline_m, min_parallax_deg=settings.min_parallax_deg)

    tri = system.triangulation
    if tri is None:
        tri = Triangulation(system=system, status=TriangulationStatus(result.status), tau_px=result.tau_px,
                            rule=result.rule, min_baseline_m=result.min_baseline_m)
        session.add(tri)
    tri.status = TriangulationStatus(result.status)
    tri.ball3d = None if result.point is None else [float(v) for v in result.point]
    tri.tau_px, tri.rule, tri.min_baseline_m = result.tau_px, result.rule, result.min_baseline_m
    tri.computed_at = utcnow()
    tri.pairs.clear()
    for p in result.pairs:
        tri.pairs.append(TriangulationPair(
            frame_a_id=p.view_a, frame_b_id=p.view_b,
            point=None if p.point is None else [float(v) for v in p.point],
            error_px=json_safe(p.error), parallax_deg=json_safe(p.parallax_deg), baseline_m=float(p.baseline_m),
            kept=bool(p.kept), reason=p.reason,
        ))

    ball = None if result.point is None else np.asarray(result.point, dtype=float)
    for f in frames:
        _update_reprojection(f, cameras.get(f.id), ball)
        admitted = f.calibration is not None and f.calibration.admitted
        _update_optimised_box(f, cameras.get(f.id) if admitted else None, ball, settings)
    update_doubts(system, settings, cameras)
    update_summary(system, tri)
    system.derived_version = DERIVED_VERSION
    return tri


def update_summary(system: System, tri: Triangulation) -> None:
    """Store the review queue's figures of ``system`` (``System.views_total`` ... ``views_above_tau``,
    model docstring) from its current frames and triangulation: aggregates over the **admitted** views,
    ``views_flagged`` over every view, ``views_above_tau`` by ``app.geometry.triangulation.error_above_tau``."""
    frames = list(system.frames)
    cals = [f.calibration for f in frames]
    admitted = [f for f in frames if f.calibration is not None and f.calibration.admitted]
    system.review_status = system.review.status if system.review is not None else ReviewStatus.PENDING
    system.views_total = len(frames)
    system.views_calibrated = sum(c is not None and c.status is CalibrationStatus.CALIBRATED for c in cals)
    system.views_admitted = len(admitted)
    system.views_labelled = sum(f.ball_label is not None and f.ball_label.kind is not None for f in frames)
    jacs = [f.calibration.jac_0005 for f in admitted if f.calibration.jac_0005 is not None]
    system.lowest_jac = min(jacs) if jacs else None
    labelled = [f for f in admitted if f.ball_label is not None and f.ball_label.kind is not None
                and f.reprojection is not None and f.reprojection.error_px is not None]
    system.worst_error_px = max((f.reprojection.error_px for f in labelled), default=None)
    system.views_flagged = sum(c is not None and MIRROR_FLAG in (c.flags or []) for c in cals)
    system.views_above_tau = sum(error_above_tau(f.reprojection.error_px, f.width, tri.tau_px, tri.rule)
                                 for f in labelled)


def refresh_stale_systems(session: Session, settings: Settings, progress: Progress | None = None) -> int:
    """Recompute (calibrations untouched) every system stored by an older version of the derived rows
    (``System.derived_version < DERIVED_VERSION``, e.g. after a schema upgrade) and commit; returns how
    many. Serving or reporting a database calls it first, so stored doubts and queue figures are current.
    Systems are recomputed and committed :data:`_REFRESH_BATCH` at a time (a crash leaves the rest stale,
    to be refreshed next time), each in a write transaction (``app.db.session.begin_write``), so a
    server running meanwhile never sees half a batch and its edits wait their turn. The recompute is one audit entry (action "recompute", by the local
    user), written with the last batch."""
    ids = list(session.scalars(select(System.id).where(System.derived_version < DERIVED_VERSION).order_by(System.id)))
    _recompute_in_batches(session, ids, settings, progress, {"reason": "stored by an older version",
                                                             "derived_version": DERIVED_VERSION})
    return len(ids)


def recompute_all_systems(session: Session, settings: Settings, progress: Progress | None = None,
                          actor: str | None = None) -> tuple[int, int]:
    """The full recompute: every system recomputed with the current settings (calibrations untouched:
    admission, triangulation, reprojections, optimised boxes, mirror flags, doubts and queue figures),
    committed :data:`_REFRESH_BATCH` systems at a time with ``progress("recompute", done, total)``
    after each commit. Idempotent: run again after a crash, it gives the same rows. One audit entry
    (action "recompute", by ``actor``; None: the local user), written with the last batch.

    Returns:
        ``(systems recomputed, systems triangulated)``.
    """
    ids = list(session.scalars(select(System.id).order_by(System.id)))
    return len(ids), _recompute_in_batches(session, ids, settings, progress, {"reason": "full recompute"}, actor)


def _recompute_in_batches(session: Session, ids: list[int], settings: Settings, progress: Progress | None,
                          audit_after: dict[str, Any], actor: str | None = None) -> int:
    """Recompute the systems ``ids``, committing and releasing :data:`_REFRESH_BATCH` at a time (bounded
    memory), each batch in a write transaction (``app.db.session.begin_write``, so a server running
    meanwhile never sees half a batch and its edits wait their turn), the audit entry ("recompute",
    ``audit_after`` with the counts) written with the last batch; returns how many were triangulated."""
    triangulated = 0
    for start in range(0, len(ids), _REFRESH_BATCH):
        begin_write(session)  # each batch read and written under the write lock (SQLite: BEGIN IMMEDIATE)
        batch = session.scalars(select(System).where(System.id.in_(ids[start:start + _REFRESH_BATCH]))).all()
        triangulated += recompute_systems(session, batch, settings)
        if start + _REFRESH_BATCH >= len(ids):
            record_summary(session, "recompute", {"systems": len(ids), **audit_after}, actor=actor)
        session.commit()
        session.expunge_all()
        if progress:
            progress("recompute", min(start + _REFRESH_BATCH, len(ids)), len(ids))
    return triangulated


def mirror_settings(settings: Settings) -> MirrorSettings:
    """The mirror evidence's settings: the triangulation's tau and pair-error rule, the rest default."""
    return MirrorSettings(tau_px=settings.triangulation_tau_px, rule=settings.pair_error_rule)


def _update_mirror_flags(session: Session, system: System, cameras: dict[int, Camera], settings: Settings,
                         rig_sources: Sequence[tuple[int, np.ndarray]] | None) -> None:
    """Judge every calibrated frame of the system (``app.geometry.mirror.mirror_evidence``: ball rays
    of every calibrated, labelled frame, side prior, the game's rig estimated without this system's
    frames) and set :data:`MIRROR_FLAG` and ``mirror_evidence`` on its calibration. Refused frames
    keep what their rig retry found (:func:`with_rig_retry`).

    Rays of frames below the admission threshold count too: JaC is the same for labels and their
    mirror, so admission says nothing about mirroring, and a rough camera cannot bring two rays
    within tau by chance (it gives no agreement, hence no evidence). Counting them flagged more of
    the dev set's injected mirrored views with no false flag either way; today's figures are in the
    docstring of ``benchmarks/mirror_flags.py`` (73 of 92 flagged)."""
    frames = [f for f in system.frames if f.id in cameras]
    if not frames:
        return
    positions = None
    if uses_rig(system) and system.game_id is not None:
        sources = rig_sources if rig_sources is not None else rig_centres(session, system.game_id, settings)
        mine = {f.id for f in system.frames}
        rig = estimate_rig(np.array([c for fid, c in sources if fid not in mine]).reshape(-1, 3))
        positions = np.array([p.centre_m for p in rig.positions]).reshape(-1, 3)
    views = [MirrorView(view_id=f.id, camera=cameras[f.id], ball_px=_label_centre(f), image_width=f.width,
                        expected_side=expected_side(f.role), rays=True, name=f.name)
             for f in frames]
    verdicts = mirror_evidence(views, positions, mirror_settings(settings))
    for f in frames:
        cal, verdict = f.calibration, verdicts[f.id]
        flags = [x for x in (cal.flags or []) if x != MIRROR_FLAG]
        cal.flags = [*flags, MIRROR_FLAG] if verdict.flagged else flags
        cal.mirror_evidence = json_safe(verdict.as_dict())


def _label_centre(frame: Frame) -> np.ndarray | None:
    """(2,) labelled ball centre in pixels, or None without a current label."""
    centre = frame.ball_label.centre if frame.ball_label is not None else None
    return None if centre is None else np.asarray(centre, dtype=float)


def _update_reprojection(frame: Frame, camera: Camera | None, ball: np.ndarray | None) -> None:
    uv = None
    if camera is not None and ball is not None:
        proj, in_front = camera.project(ball.reshape(1, 3))
        uv = proj[0] if in_front[0] else None
    if uv is None:
        frame.reprojection = None
        return
    centre = _label_centre(frame)
    error = None if centre is None else float(np.linalg.norm(uv - centre))
    rep = frame.reprojection or BallReprojection(point=[0.0, 0.0])
    rep.point, rep.error_px = [float(uv[0]), float(uv[1])], error
    frame.reprojection = rep


def _update_optimised_box(frame: Frame, camera: Camera | None, ball: np.ndarray | None, settings: Settings) -> None:
    opt = None
    centre = _label_centre(frame)
    if camera is not None and ball is not None and centre is not None:
        r = optimise_box(camera, centre, ball, settings.ball_diameter_m, method=settings.optimised_box_method)
        opt = r if r.status == "ok" else None
    if opt is None:
        frame.optimised_box = None
        return
    row = frame.optimised_box or OptimisedBox(box=[], d_opt_px=0.0, error_m=0.0)
    row.box, row.d_opt_px, row.error_m = [float(v) for v in opt.box], float(opt.d_px), float(opt.error_m)
    frame.optimised_box = row


#: Everything :func:`recompute_system` reads or replaces, loaded up front for many systems.
_RECOMPUTE_LOADS = (
    selectinload(System.triangulation).selectinload(Triangulation.pairs),
    selectinload(System.doubts), selectinload(System.review),
    selectinload(System.frames).options(
        selectinload(Frame.calibration), selectinload(Frame.ball_label), selectinload(Frame.reprojection),
        selectinload(Frame.optimised_box), selectinload(Frame.review), selectinload(Frame.field_lines),
    ),
)
_LOAD_CHUNK = 500
#: Systems recomputed per transaction by :func:`refresh_stale_systems`.
_REFRESH_BATCH = 500


def preload_systems(session: Session, systems: Sequence[System]) -> None:
    """Flush, then load the frames, calibrations, labels and derived rows of ``systems`` in a few
    ``selectin`` queries (instead of one lazy load per attribute and frame)."""
    session.flush()
    ids = [s.id for s in systems]
    for start in range(0, len(ids), _LOAD_CHUNK):
        session.scalars(select(System).where(System.id.in_(ids[start:start + _LOAD_CHUNK]))
                        .options(*_RECOMPUTE_LOADS)).all()


def recompute_systems(session: Session, systems: Iterable[System], settings: Settings,
                      progress: Progress | None = None, *, preloaded: bool = False) -> int:
    """:func:`recompute_system` for each system, then one flush; returns how many were triangulated.

    The systems' frames and derived rows are loaded in a few ``selectin`` queries first
    (:func:`preload_systems`; skipped when ``preloaded``: the caller did it), so that recomputing
    thousands of systems does not issue one lazy load per attribute.
    """
    systems = list(systems)
    if preloaded:
        session.flush()
    else:
        preload_systems(session, systems)
    sources = {gid: rig_centres(session, gid, settings)
               for gid in {s.game_id for s in systems if uses_rig(s) and s.game_id is not None}}
    n = 0
    for i, s in enumerate(systems, 1):
        if recompute_system(session, s, settings, sources.get(s.game_id)).status is TriangulationStatus.TRIANGULATED:
            n += 1
        if progress:
            progress("triangulate", i, len(systems))
    session.flush()
    return n
