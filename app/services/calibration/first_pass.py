"""Calibration of an import's batches (``app.services.transfer.importing``): the first pass of every frame
from its lines alone, and the retry with the game's camera rig of the frames of SoccerNet-v3 games
that their lines alone refuse or calibrate below admission. A game new to the database needs
nothing stored (its rig comes from its own first pass), so it is calibrated whole, both passes, in
one task on the pool's processes, started ahead: the next batch's games calibrate while this
process stores the current batch. The same task then places the cameras its players place
(``players.place_in_game``) on those fresh results, so that the fits run in parallel too. Frames of
stored games are calibrated when their batch is stored (their rig reads the stored calibrations).
Reads the session, never writes it.
"""
from __future__ import annotations

from typing import Iterator, NamedTuple, Sequence

from sqlalchemy import select
from sqlalchemy.orm import Session

from app.core.config import Settings
from app.core.progress import Progress
from app.datasets.records import CalibrationFields, FrameRecord, GameRecord
from app.db.models import Frame, FrameRole, Game
from app.geometry.annotations import lines_from_json_lists
from app.geometry.calibration import CameraPrior
from app.services.calibration.calibrating import CalibrationJob, calibrate_lines, calibration_job, expected_side
from app.services.calibration.players import PlacementView, PlayerRow, place_in_game, view_of_fields
from app.services.calibration.pool import CalibrationPool, calibrate_many
from app.services.calibration.priors import dataset_prior, stored_camera_prior, wants_prior_retry, with_prior_refit
from app.services.calibration.rigs import game_rig, uses_rig, wants_rig_retry, with_rig_retry
from app.services.kinds import policy


class GameJob(NamedTuple):
    """The calibration of a game new to the database, both passes, as one task (:func:`calibrate_game`):
    per frame (in the game's order: systems, then their frames) its job (``calibrating.calibration_job``
    of the frame to be created), its role, and whether its system uses the game's rig
    (``rigs.uses_rig``); ``settings`` decide the retry and the rig. ``place``: the players place the cameras
    too (every frame of the game is here and every system uses the rig), from each frame's ``players`` and its
    system's index ``systems`` (the game's order)."""

    jobs: list[CalibrationJob]
    roles: list[FrameRole]
    rig_ok: list[bool]
    settings: Settings
    place: bool = False
    systems: Sequence[int] = ()
    players: Sequence[Sequence[PlayerRow]] = ()


class GameCalibration(NamedTuple):
    """What :func:`calibrate_game` gives per frame: the result from its lines alone (``first``), the one
    stored (``final``: ``rigs.with_rig_retry`` of the rig retry, or ``first``), and the rig pass's
    time (ms) of each retried frame, by index; ``placed``: the cameras the players placed on ``final``
    (:func:`place_game`) by index, None when the task did not place them."""

    first: list[CalibrationFields]
    final: list[CalibrationFields]
    rig_ms: dict[int, float]
    placed: dict[int, CalibrationFields] | None = None


def calibrate_game(job: GameJob) -> GameCalibration:
    """Calibrate a game new to the database: every frame from its lines, then the frames
    ``rigs.wants_rig_retry`` picks (of systems using the rig) with the game's rig estimated from
    those fresh results (``rigs.game_rig``: nothing of the game is stored), exactly as
    :func:`retry_with_game_rigs` does for a batch holding the game. Pure; runs in a worker process."""
    first = [calibrate_lines(*j) for j in job.jobs]
    final = list(first)
    rig_ms: dict[int, float] = {}
    retry = [i for i, f in enumerate(first) if job.rig_ok[i] and wants_rig_retry(f, job.settings)]
    if retry:
        rig = game_rig(None, None, job.settings, extra=first, extra_roles=job.roles)
        for i in retry if rig.positions else ():
            lines, width, height, side, _, main = job.jobs[i]
            fields = calibrate_lines(lines, width, height, side, rig, main)
            final[i] = with_rig_retry(first[i], fields)
            rig_ms[i] = fields.elapsed_ms or 0.0
    return GameCalibration(first, final, rig_ms, place_game(job, final) if job.place else None)


def place_game(job: GameJob, final: Sequence[CalibrationFields]) -> dict[int, CalibrationFields]:
    """The cameras the players place in a game whose every frame is in ``job`` (``players.place_in_game`` on its
    frames' ``final`` calibrations, what the import stores of them before it places the players' cameras itself),
    by frame index: the accepted fits only (a new game holds no camera the players placed before). Pure."""
    views: dict[int, list[tuple[int, PlacementView]]] = {}
    for i, (fields, (lines, width, height, *_), role) in enumerate(zip(final, job.jobs, job.roles, strict=True)):
        views.setdefault(job.systems[i], []).append(
            (i, view_of_fields(fields, lines, width, height, role is FrameRole.ACTION, job.players[i], job.settings)))
    systems = list(views.values())
    placed = place_in_game([[v for _, v in system] for system in systems])
    return {system[k][0]: got for system, got_of in zip(systems, placed, strict=True)
            for k, got in got_of.items() if isinstance(got, CalibrationFields)}


class FirstPassAhead(NamedTuple):
    """Calibrations of a batch's new games started before the batch is merged (:func:`start_first_pass`):
    per frame record (by ``id``), its job, its game's index in ``results`` and its index in that game;
    and the frame records of each game."""

    jobs: dict[int, tuple[CalibrationJob, int, int]]
    games: list[list[int]]
    results: Iterator[GameCalibration]


class BatchCalibration(NamedTuple):
    """:func:`first_pass` of a batch: per frame its result so far and its first pass's time (ms), the
    indices already retried with their game's rig (their ``results`` are final) and those retries'
    times (ms); the indices whose game's player cameras were placed ahead (``placed_ahead``) and those
    cameras (``placed``, by index: the accepted fits)."""

    results: list[CalibrationFields]
    first_ms: list[float | None]
    finished: set[int]
    rig_ms: dict[int, float]
    placed_ahead: set[int]
    placed: dict[int, CalibrationFields]


def new_frame_job(rec: FrameRecord) -> CalibrationJob:
    """The job ``calibrating.calibration_job`` gives a frame created from ``rec`` (its lines as imported)."""
    return (rec.lines, rec.width, rec.height, expected_side(rec.role), None, rec.role is FrameRole.ACTION)


def game_job(grec: GameRecord, settings: Settings) -> tuple[GameJob, list[FrameRecord]] | None:
    """The task of :func:`calibrate_game` for a game not stored yet: its frames to calibrate (those without an
    imported calibration, in the game's order) and their jobs; the players place the game's cameras in the task when
    it holds the whole game and every system uses the rig (else the rig or the views the placement reads would
    differ from what the import stores). None when no frame needs calibrating."""
    frames = [(srec, frec) for srec in grec.systems for frec in srec.frames if frec.calibration is None]
    if not frames:
        return None
    rig_ok = [policy(srec.kind).uses_rig for srec, _ in frames]
    place = all(rig_ok) and len(frames) == sum(len(srec.frames) for srec in grec.systems)
    system_of = {id(srec): k for k, srec in enumerate(grec.systems)}
    return GameJob(jobs=[new_frame_job(frec) for _, frec in frames], roles=[frec.role for _, frec in frames],
                   rig_ok=rig_ok, settings=settings, place=place,
                   systems=[system_of[id(srec)] for srec, _ in frames] if place else (),
                   players=[frec.players for _, frec in frames] if place else ()), [frec for _, frec in frames]


def start_first_pass(session: Session, records: list[GameRecord], pool: CalibrationPool, settings: Settings
                     ) -> FirstPassAhead | None:
    """Start the calibration of ``records``' games that are not stored yet (:func:`calibrate_game`, one
    task each, :func:`game_job`: every frame of such a game is calibrated from its imported lines, then
    retried with the game's rig, then the players place the cameras the lines cannot) on the pool's
    processes, and return at once, so that they calibrate while this process stores the previous batch.
    Games already stored are left to ``importing._store`` (most of their frames may need no calibration).
    None when the pool runs in this process. Reads only."""
    if pool.executor is None:
        return None
    jobs: dict[int, tuple[CalibrationJob, int, int]] = {}
    games: list[list[int]] = []
    tasks: list[GameJob] = []
    for grec in records:
        if session.scalar(select(Game.id).where(Game.league == grec.league, Game.season == grec.season,
                                                Game.match == grec.match)) is not None:
            continue
        got = game_job(grec, settings)
        if got is None:
            continue
        task, frecs = got
        for k, (frec, job) in enumerate(zip(frecs, task.jobs, strict=True)):
            jobs[id(frec)] = (job, len(tasks), k)
        games.append([id(frec) for frec in frecs])
        tasks.append(task)
    if not tasks:
        return None
    return FirstPassAhead(jobs, games, pool.map(calibrate_game, tasks))


def first_pass(frames: list[Frame], recs: list[FrameRecord], settings: Settings, progress: Progress | None,
               pool: CalibrationPool | None, ahead: FirstPassAhead | None) -> BatchCalibration:
    """The calibration of each frame from its lines alone, or, for the frames of a game calibrated
    ahead whose every job is the one started (always, for a game new to the database), its final
    result (both passes); the other frames are calibrated now."""
    jobs = [calibration_job(f) for f in frames]
    results: list[CalibrationFields | None] = [None] * len(jobs)
    first_ms: list[float | None] = [None] * len(jobs)
    finished: set[int] = set()
    rig_ms: dict[int, float] = {}
    placed_ahead: set[int] = set()
    placed: dict[int, CalibrationFields] = {}
    if ahead is not None:
        index = {id(rec): i for i, rec in enumerate(recs)}
        done = 0
        for game, calibrated in zip(ahead.games, ahead.results, strict=False):  # waits for each game in turn
            done += len(game)
            if progress:
                progress("calibrate", min(done, len(jobs)), len(jobs))
            mine = [index.get(key) for key in game]
            if any(i is None or ahead.jobs[key][0] != jobs[i] for i, key in zip(mine, game, strict=True)):
                continue  # a frame's job changed: the game is calibrated now, both passes
            for k, i in enumerate(mine):
                assert i is not None  # every frame of the game is one of ours: checked above
                results[i], first_ms[i] = calibrated.final[k], calibrated.first[k].elapsed_ms
                finished.add(i)
                if k in calibrated.rig_ms:
                    rig_ms[i] = calibrated.rig_ms[k]
                if calibrated.placed is not None:
                    placed_ahead.add(i)
                    if k in calibrated.placed:
                        placed[i] = calibrated.placed[k]
    rest = [i for i, r in enumerate(results) if r is None]
    done = len(jobs) - len(rest)
    step = (lambda stage, n, total: progress(stage, done + n, len(jobs))) if progress else None
    for i, fields in zip(rest, calibrate_many([jobs[i] for i in rest], settings.calibration_workers, step, pool=pool),
                         strict=True):
        results[i], first_ms[i] = fields, fields.elapsed_ms
    return BatchCalibration(results, first_ms, finished, rig_ms,  # type: ignore[arg-type]  # every result is set by now
                            placed_ahead, placed)


def retry_with_game_rigs(session: Session, frames: list[Frame], results: list[CalibrationFields],
                          settings: Settings, progress: Progress | None, pool: CalibrationPool | None = None,
                          finished: Sequence[int] | set[int] = ()) -> tuple[list[CalibrationFields], dict[int, float]]:
    """Recalibrate the frames of SoccerNet-v3 games refused or calibrated below admission
    (``rigs.wants_rig_retry``) with their game's camera rig, estimated from the game's stored
    calibrations (except the frames being recalibrated) and this import's fresh ones
    (``rigs.game_rig``). Writes nothing (the caller disables autoflush). Returns the final
    result per frame (``rigs.with_rig_retry``: the better fit by residual, a refusal carrying
    the rig's mirror flag) and the rig pass's time per retried frame index (ms). Frames in ``finished``
    (their game calibrated whole ahead, :func:`calibrate_game`) are left as they are."""
    done = set(finished)
    retry = [i for i, (f, r) in enumerate(zip(frames, results, strict=False))
             if i not in done and wants_rig_retry(r, settings) and uses_rig(f.system)]
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
    for i, fields in zip(retry, calibrate_many(jobs, settings.calibration_workers, progress, stage="rig", pool=pool),
                         strict=True):
        out[i] = with_rig_retry(out[i], fields)
        rig_ms[i] = fields.elapsed_ms or 0.0
    return out, rig_ms


def retry_with_dataset_prior(frames: list[Frame], results: list[CalibrationFields], settings: Settings,
                             progress: Progress | None, pool: CalibrationPool | None = None
                             ) -> tuple[list[CalibrationFields], dict[int, float], CameraPrior | None]:
    """Refit, with the learned camera prior of the batch's frames of systems without a rig
    (calibration datasets: frames from many stadiums; ``priors.dataset_prior`` from their fresh
    calibrations and field lines), those of them ``priors.wants_prior_retry`` picks: refused,
    every calibrated one when the prior has a radial term, else those with a camera position the
    lines leave open. A refit is kept when it calibrates; frames
    whose lines fix the camera as the confident ones do are left as they are (the JaC guard). When the
    batch is too small to learn from (an import of a few changed frames), each frame's game's stored
    prior (``priors.stored_camera_prior``) is used instead. Returns the final result per frame, the
    retry's time per retried frame index (ms) and the prior learned from this batch (None: none was).
    Writes nothing."""
    mine = [i for i, f in enumerate(frames) if not uses_rig(f.system)]
    learned = dataset_prior([results[i] for i in mine],
                            [(lines_from_json_lists(fl.lines) if (fl := frames[i].field_lines) is not None else {},
                              frames[i].width, frames[i].height) for i in mine])
    priors = {i: learned if learned is not None else stored_camera_prior(frames[i].system) for i in mine}
    retry = [i for i in mine if (prior := priors[i]) is not None and wants_prior_retry(results[i], prior)]
    out = list(results)
    ms: dict[int, float] = {}
    jobs = [calibration_job(frames[i], priors[i]) for i in retry]
    for i, fields in zip(retry, calibrate_many(jobs, settings.calibration_workers, progress, stage="prior", pool=pool),
                         strict=True):
        out[i] = with_prior_refit(out[i], fields)
        ms[i] = fields.elapsed_ms or 0.0
    return out, ms, learned
