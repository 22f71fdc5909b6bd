"""Calibration of an import's batches (``app.services.importing``): the first pass of every frame
from its lines alone, started ahead on the pool's processes for the games new to the database so
that it runs while the previous batch is stored, and the retry with the game's camera rig of the
frames of SoccerNet-v3 games that their lines alone refuse or calibrate below admission.
Reads the session, never writes it.
"""
from __future__ import annotations

from typing import Iterator, NamedTuple

from sqlalchemy import select
from sqlalchemy.orm import Session

from app.core.config import Settings
from app.db.models import Frame, FrameRole, Game
from app.datasets.records import FrameRecord, GameRecord
from app.services.calibrating import (
    CalibrationFields, CalibrationJob, CalibrationPool, calibrate_many, calibration_job, expected_side, game_rig, start_calibrating, uses_rig, wants_rig_retry, with_rig_retry,
)
from app.services.progress import Progress


class FirstPassAhead(NamedTuple):
    """First-pass calibrations of a batch started before the batch is merged (:func:`start_first_pass`):
    per frame record (by ``id``), its job and its index in ``results``."""

    jobs: dict[int, tuple[CalibrationJob, int]]
    results: Iterator[CalibrationFields]


def new_frame_job(rec: FrameRecord) -> CalibrationJob:
    """The job ``calibrating.calibration_job`` gives a frame created from ``rec`` (its lines as imported)."""
    return (rec.lines, rec.width, rec.height, expected_side(rec.role), None, rec.role is FrameRole.ACTION)


def start_first_pass(session: Session, records: list[GameRecord], pool: CalibrationPool) -> FirstPassAhead | None:
    """Start the first-pass calibration of the frames of ``records``' games that are not stored yet
    (every such frame is calibrated from its imported lines) on the pool's processes, and return at
    once, so that they calibrate while this process stores the previous batch. Games already stored
    are left to ``importing._store`` (most of their frames may need no calibration). Reads only."""
    jobs: dict[int, tuple[CalibrationJob, int]] = {}
    ordered: list[CalibrationJob] = []
    for grec in records:
        if session.scalar(select(Game.id).where(Game.league == grec.league, Game.season == grec.season,
                                                Game.match == grec.match)) is not None:
            continue
        for srec in grec.systems:
            for frec in srec.frames:
                if frec.calibration is None:
                    jobs[id(frec)] = (new_frame_job(frec), len(ordered))
                    ordered.append(jobs[id(frec)][0])
    results = start_calibrating(ordered, pool)
    return None if results is None else FirstPassAhead(jobs, results)


def first_pass(frames: list[Frame], recs: list[FrameRecord], settings: Settings, progress: Progress | None,
                pool: CalibrationPool | None, ahead: FirstPassAhead | None) -> list[CalibrationFields]:
    """The calibration of each frame from its lines alone: the result started ahead when its job is
    the one started (always, for a frame of a game new to the database), else calibrated now."""
    jobs = [calibration_job(f) for f in frames]
    results: list[CalibrationFields | None] = [None] * len(jobs)
    started: list[CalibrationFields] = []
    if ahead is not None:
        for fields in ahead.results:  # waits for each in turn
            started.append(fields)
            if progress:
                progress("calibrate", min(len(started), len(jobs)), len(jobs))
        for i, (job, rec) in enumerate(zip(jobs, recs)):
            hit = ahead.jobs.get(id(rec))
            if hit is not None and hit[0] == job:
                results[i] = started[hit[1]]
    rest = [i for i, r in enumerate(results) if r is None]
    done = len(jobs) - len(rest)
    step = (lambda stage, n, total: progress(stage, done + n, len(jobs))) if progress else None
    for i, fields in zip(rest, calibrate_many([jobs[i] for i in rest], settings.calibration_workers, step, pool=pool)):
        results[i] = fields
    return results  # type: ignore[return-value]


def retry_with_game_rigs(session: Session, frames: list[Frame], results: list[CalibrationFields],
                          settings: Settings, progress: Progress | None, pool: CalibrationPool | None = None
                          ) -> tuple[list[CalibrationFields], dict[int, float]]:
    """Recalibrate the frames of SoccerNet-v3 games refused or calibrated below admission
    (``calibrating.wants_rig_retry``) with their game's camera rig, estimated from the game's stored
    calibrations (except the frames being recalibrated) and this import's fresh ones
    (``calibrating.game_rig``). Writes nothing (the caller disables autoflush). Returns the final
    result per frame (``calibrating.with_rig_retry``: the better fit by residual, a refusal carrying
    the rig's mirror flag) and the rig pass's time per retried frame index (ms)."""
    retry = [i for i, (f, r) in enumerate(zip(frames, results)) if wants_rig_retry(r, settings) and uses_rig(f.system)]
    if not retry:
        return results, {}
    rigs = {}
    for game in {id(frames[i].system.game): frames[i].system.game for i in retry}.values():
        mine = [i for i, f in enumerate(frames) if f.system.game is game]
        rigs[id(game)] = game_rig(session, game.id, settings,
                                  exclude_frame_ids=[frames[i].id for i in mine if frames[i].id is not None],
                                  extra=[results[i] for i in mine], extra_roles=[frames[i].role for i in mine])
    retry = [i for i in retry if rigs[id(frames[i].system.game)].positions]
    jobs = [calibration_job(frames[i], rigs[id(frames[i].system.game)]) for i in retry]
    out = list(results)
    rig_ms: dict[int, float] = {}
    for i, fields in zip(retry, calibrate_many(jobs, settings.calibration_workers, progress, stage="rig", pool=pool)):
        out[i] = with_rig_retry(out[i], fields)
        rig_ms[i] = fields.elapsed_ms or 0.0
    return out, rig_ms
