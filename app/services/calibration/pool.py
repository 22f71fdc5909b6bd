"""The one process pool of bulk calibration: imports (``app.services.transfer.importing``,
``app.services.calibration.first_pass``) and the offline ``v3d calibrate`` (:meth:`CalibrationPool.map`)
run their frames' calibrations through it; few jobs are calibrated in-process.
"""
from __future__ import annotations

import contextlib
import multiprocessing
import os
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass
from typing import Callable, Iterable, Iterator, Sequence, TypeVar

from app.core.progress import Progress
from app.datasets.records import CalibrationFields
from app.geometry.calibration.rig import CameraRig
from app.services.calibration.calibrating import CalibrationJob, calibrate_lines

_J = TypeVar("_J")


_R = TypeVar("_R")


#: Jobs below this count are calibrated in-process (a pool costs more than it saves).
_MIN_JOBS_FOR_POOL = 8


def _calibrate_job(job: CalibrationJob) -> CalibrationFields:
    return calibrate_lines(*job)


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
