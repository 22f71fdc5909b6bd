"""Import of SoccerNet-v3 trees, SoccerNet-calibration folders or zips, and SoccerNet-v3D exports.

Every importer works in two phases so that bad input stores nothing:

1. **read and validate** the whole input into plain records (``app.datasets``:
   :func:`read_soccernet_v3`, :func:`read_sn_calibration`, :func:`read_soccernet_v3d`); any problem
   raises :class:`~app.core.errors.DatasetError` naming the file and the field. A SoccerNet-v3
   tree is validated game by game and its records dropped, but the first batch's, kept for its storing; each
   other batch is read again when it is stored, so memory holds two batches of records, not the whole tree (and an
   input of one batch, most uploads, is read once). A game read alone whose labels hold an
   entry the shared label check refuses (:class:`~app.core.errors.EntryError`: a ball box beyond its image's
   plausible range, NaN, ...) is left out and named in the report (``skipped_games``: file, entry, why); the other
   games import;
2. **write** the records in transactions of whole games (``Settings.import_batch_frames`` frames or so
   each, so that memory stays bounded at SoccerNet size): games, systems and frames are matched by
   their natural keys (league/season/match, system name, frame name), so importing the same input
   twice gives the same rows, and an import cut short (a crash, a kill) leaves whole games stored and
   is completed by running it again. A re-import refreshes the imported originals and merges the
   current values and decisions of the stored games by its merge mode (``app.services.transfer.merging``:
   ``keep-newer`` keeps what a person changed after what the file holds; one audit entry per system it
   changes). In each batch the frames whose lines are new or changed are calibrated in the import's
   process pool before the batch's first write, then the batch is written, its touched systems
   recomputed (``app.services.derivation.recompute``) and committed, or rolled back. Another writer that commits
   while a batch calibrates (an edit, a page's presence claim, a login) never fails it: on SQLite such a batch cannot
   write any more, and runs again once holding the write lock from its start (``app.db.unit.computed_then_written``),
   the other writers waiting for it then. The pool does not
   wait meanwhile: the first pass of the next batch's new games is calibrating
   (``app.services.calibration.first_pass``) while this process stores the current batch.

What a release carries that v3d does not edit (``GameMetadata``, each frame's ``imageMetadata`` and every
``bboxes`` entry up to ``V3D_MAX_PLAYERS_PER_FRAME`` player boxes, the links) is stored as it came
(``games.release``, ``frames.release``) and refreshed by a re-import; the exports write it back without reading the
source files.

Images are never extracted: a frame stores the dataset's folder and, relative to it, the zip path and
member name (or a file path); the readers refuse a file that resolves outside the imported folder.
Each committed batch of an import is one audit entry (``app.services.audit.log.record_summary``, action
"import": the counts so far, ``batch`` of ``batches``; the last one holds the import's totals), written in the
batch's own transaction; a frame whose labels or lines it changes gets a new edit version (ETag).
"""
from __future__ import annotations

import contextlib
import copy
import gc
import threading
import time
from collections import Counter
from dataclasses import dataclass, field
from functools import partial
from pathlib import Path
from typing import Callable, Iterator

from sqlalchemy.orm import Session

from app.core.config import Settings
from app.core.errors import EntryError
from app.core.progress import Progress
from app.datasets.files import dataset_root
from app.datasets.records import CalibrationFields, GameRecord
from app.datasets.sn_calibration import read_sn_calibration
from app.datasets.soccernet_v3 import read_soccernet_v3, read_soccernet_v3_game, soccernet_v3_labels
from app.datasets.soccernet_v3d import read_soccernet_v3d
from app.db import scope
from app.db.models import (
    CalibrationSource,
    CalibrationStatus,
    Frame,
    System,
    TriangulationStatus,
)
from app.db.session import refresh_statistics
from app.db.types import utcnow
from app.db.unit import computed_then_written
from app.geometry.calibration.result import PLAYERS_FLAG, PRIOR_FLAG, RADIAL_PRIOR_FLAG, RIG_FLAG
from app.services.audit.log import record_summary
from app.services.calibration.calibrating import apply_calibration
from app.services.calibration.first_pass import (
    BatchCalibration,
    FirstPassAhead,
    first_pass,
    retry_with_dataset_prior,
    retry_with_game_rigs,
    start_first_pass,
)
from app.services.calibration.players import (
    place_cameras_by_players,
    store_players,
    systems_with_mirrored_anchors,
)
from app.services.calibration.pool import CalibrationPool, calibration_pool
from app.services.calibration.rigs import uses_rig
from app.services.derivation.loading import load_view_players
from app.services.derivation.recompute import (
    calibrate_frame_lines,
    preload_systems,
    recompute_systems,
)
from app.services.transfer.caps import image_bytes, read_within_caps, reading_limits, within_player_cap, within_view_cap
from app.services.transfer.storing import MergedBatch, merge_batch
from app.services.wording.words import WORDS

__all__ = [
    "ImportReport", "audit_counts", "import_soccernet_v3", "import_sn_calibration", "import_soccernet_v3d",
    "read_soccernet_v3", "read_sn_calibration", "read_soccernet_v3d",
]


@dataclass
class ImportReport:
    """What an import did.

    Attributes:
        source: the path imported.
        source_name: how annotators and reviewers see it (no server path:
            ``app.services.transfer.data_root.dataset_name``; default: its last component).
        games, systems, frames: how many the input holds.
        systems_new, systems_changed: systems created, and existing systems whose input changed.
        calibrated, refused: outcome of the calibrations run (or imported) by this import.
        rig_assisted: frames of SoccerNet-v3 games refused from their lines alone, or calibrated
            below admission, whose stored calibration is their game's camera rig's (counted in
            ``calibrated``).
        player_assisted: frames whose stored calibration the players placed (``calibration.players``: the views
            the lines cannot calibrate, fitted to the players they share with their system's well-lined views).
        prior_fitted: frames of calibration datasets whose stored calibration is a MAP fit with the
            dataset's learned camera prior (flag ``learned_prior``: its centre, or ``radial_prior``: its
            lens; counted in ``calibrated``).
        refusal_reasons: refusal code (``WORDS["refusal"]``) -> count among ``refused``.
        triangulated: recomputed systems that got a 3D ball.
        read_seconds, calibration_seconds, store_seconds: wall time of reading and validating the
            input, of the calibration step, and of writing, recomputing and committing;
            seconds: of the whole import.
        calibration_ms: calibration time of each calibrated frame (ms, in its worker): its
            ``calibrate_frame`` call plus, for a frame retried with its game's rig, the rig pass.
    """

    source: str
    source_name: str = ""
    games: int = 0
    systems: int = 0
    frames: int = 0
    systems_new: int = 0
    systems_changed: int = 0
    calibrated: int = 0
    refused: int = 0
    rig_assisted: int = 0
    player_assisted: int = 0
    prior_fitted: int = 0
    refusal_reasons: Counter = field(default_factory=Counter)
    triangulated: int = 0
    read_seconds: float = 0.0
    calibration_seconds: float = 0.0
    store_seconds: float = 0.0
    seconds: float = 0.0
    calibration_ms: list[float] = field(default_factory=list)
    #: Systems of the input left out, each ``"<league>/<season>/<match>/<system>: <why>"`` (more views than
    #: ``V3D_MAX_VIEWS_PER_SYSTEM``); the rest of the dataset imports. Counted in ``systems``.
    skipped_systems: list[str] = field(default_factory=list)
    #: Games of the input left out, each ``"<labels file, relative to the dataset>: <entry>: <why>"`` (an entry the
    #: shared label check refuses); the other games import. Not counted in ``games``.
    skipped_games: list[str] = field(default_factory=list)
    #: The merge into stored games (``app.services.transfer.merging``): stored systems it changed (one audit entry
    #: each), systems whose decision it took from the file (said in their decision's comment and entry), and systems
    #: whose decisions it set back to pending because it changed their labels.
    systems_merged: int = 0
    decisions_from_file: int = 0
    decisions_reset: int = 0
    #: Frames of the input that come without an image (a labels-only dataset: every frame), counted in ``frames``.
    frames_without_image: int = 0
    #: Player boxes of the input beyond ``V3D_MAX_PLAYERS_PER_FRAME`` a frame, not stored
    #: (:func:`app.services.transfer.caps.within_player_cap`).
    players_dropped: int = 0

    def refusal_kinds(self) -> Counter:
        """``refusal_reasons`` in words: each refusal code's meaning (``WORDS["refusal"]``, the review pages'
        table) -> count.

        >>> ImportReport("x", refusal_reasons=Counter({"residual_too_high": 3})).refusal_kinds()
        Counter({'one labelled line stays too far from its pitch line under every camera': 3})
        """
        return Counter({WORDS["refusal"].get(code, {}).get("means", code): n
                        for code, n in self.refusal_reasons.items()})


# ----- writing ------------------------------------------------------------------------------------
def _store(session: Session, records: list[GameRecord], settings: Settings, report: ImportReport,
           progress: Progress | None, pool: CalibrationPool | None = None, ahead: FirstPassAhead | None = None,
           after_calibration: Callable[[], None] | None = None, *, mode: str = "keep-newer",
           actor: str | None = None) -> None:
    """Upsert ``records`` into the session (no autoflush), calibrate the frames whose lines are new or
    changed in a process pool (then the refused ones of SoccerNet-v3 games with their game's rig)
    while nothing is written yet, so that a long import does not hold SQLite's write lock; then
    flush, store the calibrations and recompute the touched systems.

    Stored systems are merged by ``mode`` (``app.services.transfer.merging``): each one changed gets its audit entry
    (by ``actor``) in the batch's transaction. ``ahead``: first-pass calibrations started before the merge
    (``import_calibration.start_first_pass``); a frame whose job is the one started takes its result.
    ``after_calibration`` is called once every calibration of the batch is done (the caller starts the next batch's
    first pass then)."""
    now = utcnow()
    merged = merge_batch(session, records, settings, progress, now, mode=mode,
                         source=report.source_name or Path(report.source).name, actor=actor)
    report.decisions_from_file += merged.decisions_from_file
    report.decisions_reset += merged.decisions_reset
    report.systems_new += merged.systems_new
    report.systems_changed += merged.systems_changed
    results, first = _calibrate_batch(session, merged, settings, report, progress, pool, ahead, after_calibration)
    _write_batch(session, merged, results, first, settings, report, progress)


def _calibrate_batch(session: Session, merged: MergedBatch, settings: Settings, report: ImportReport,
                     progress: Progress | None, pool: CalibrationPool | None, ahead: FirstPassAhead | None,
                     after_calibration: Callable[[], None] | None) -> tuple[list[CalibrationFields], BatchCalibration]:
    """Calibrate the batch's frames to calibrate, before anything is written: the first pass, then the refused ones of
    games with a rig with their game's rig, then with the dataset's learned prior (kept on the games); one result per
    frame, timed into ``report``, and the first pass itself (the cameras its pool tasks placed by players)."""
    to_calibrate = merged.to_calibrate
    t0 = time.perf_counter()
    batch = first_pass(to_calibrate, merged.to_calibrate_recs, settings, progress, pool, ahead)
    first_ms, rig_ms = batch.first_ms, dict(batch.rig_ms)
    with session.no_autoflush:
        results, retried_ms = retry_with_game_rigs(session, to_calibrate, batch.results, settings, progress, pool,
                                                   batch.finished)
    rig_ms.update(retried_ms)
    results, prior_ms, learned_prior = retry_with_dataset_prior(to_calibrate, results, settings, progress, pool)
    if learned_prior is not None:  # kept for every later recalibration of these datasets' frames
        for game in {id(f.system.game): f.system.game for f in to_calibrate if not uses_rig(f.system)}.values():
            game.camera_prior = learned_prior.to_json()
            scope.game_changed(game)  # its frames' recalibrations read the prior (``scope``)
    for i, ms in prior_ms.items():
        rig_ms[i] = rig_ms.get(i, 0.0) + ms
    if after_calibration is not None:
        after_calibration()
    report.calibration_ms = [ms + rig_ms.get(i, 0.0) for i, ms in enumerate(first_ms) if ms is not None]
    report.calibration_seconds = time.perf_counter() - t0
    report.rig_assisted += sum(RIG_FLAG in r.flags for r in results)
    report.prior_fitted += sum(PRIOR_FLAG in r.flags or RADIAL_PRIOR_FLAG in r.flags for r in results)
    return results, batch


def _write_batch(session: Session, merged: MergedBatch, results: list[CalibrationFields], first: BatchCalibration,
                 settings: Settings, report: ImportReport, progress: Progress | None) -> None:
    """The batch's writes: the calibrations (computed, then imported), the player boxes and the cameras they place,
    the counts of calibrated and refused views, the recomputation of the touched systems and the merges' audit."""
    to_calibrate, imported, touched = merged.to_calibrate, merged.imported, merged.touched
    # The first write of the import. Systems new in this batch hold every row a recomputation reads
    # already (their relationships were set when they were created): only stored ones are loaded.
    preload_systems(session, [s for s in touched if s.id is not None], settings)
    for frame, fields in zip(to_calibrate, results, strict=True):  # one result per frame
        apply_calibration(frame, fields, CalibrationSource.COMPUTED)
    for frame, fields in imported:
        apply_calibration(frame, fields, CalibrationSource.IMPORTED)
    store_players(session, merged.new_players)
    # written past the ORM, so read back in one query: the ball judged by evidence compares each pair's players, and
    # a lazy load per view would flush the session every time
    load_view_players(session, [f for f, _, _ in merged.new_players])
    # The games new to the database had their players place their cameras in the pool, with their calibration;
    # the other systems' are placed here, on what was just stored.
    for i, fields in first.placed.items():
        apply_calibration(to_calibrate[i], fields, CalibrationSource.COMPUTED)
    report.player_assisted += len(first.placed)
    ahead_frames = {id(to_calibrate[i]) for i in first.placed_ahead}
    players = {id(f): rows for f, rows, _ in merged.new_players}

    def relined(f: Frame) -> CalibrationFields:
        return calibrate_frame_lines(session, f, settings, refine=False).fields

    report.player_assisted += place_cameras_by_players(
        [s for s in touched if not s.frames or any(id(f) not in ahead_frames for f in s.frames)], settings,
        players, relined=relined)
    report.triangulated += recompute_systems(session, touched, settings, progress, preloaded=True)
    # The recomputation's mirror verdicts (every view's ball ray against the others') flag anchors the first pass
    # could not judge: a mirrored anchor puts its players on the wrong side of the pitch, so the systems holding one
    # have their weak views placed again without it, and are recomputed once more.
    again = systems_with_mirrored_anchors(touched, settings)
    if again:
        placed_before = sum(_by_players(f) for s in again for f in s.frames)
        ball_before = sum(_triangulated(s) for s in again)
        place_cameras_by_players(again, settings, players, relined=relined)
        report.player_assisted += sum(_by_players(f) for s in again for f in s.frames) - placed_before
        report.triangulated += recompute_systems(session, again, settings, preloaded=True) - ball_before
    for frame, fields in [*zip(to_calibrate, results, strict=True), *imported]:
        placed = frame.calibration is not None and frame.calibration.status is CalibrationStatus.CALIBRATED
        if fields.status is CalibrationStatus.CALIBRATED or placed:  # the players may place a camera lines refused
            report.calibrated += 1
        else:
            report.refused += 1
            report.refusal_reasons[fields.refusal or "unspecified"] += 1
    report.systems_merged += sum(merge.record(session) for merge in merged.merges)


def _store_audited(session: Session, records: list[GameRecord], settings: Settings, report: ImportReport,
                   progress: Progress | None, pool: CalibrationPool, ahead: list[FirstPassAhead | None],
                   after_calibration: Callable[[], None], *, merge: str, actor: str | None,
                   audit: dict[str, int]) -> None:
    """:func:`_store` of one batch (with ``ahead``'s calibrations, taken by the first call only) and its audit
    entry: every committed batch is audited in its own transaction, so that a crash after it leaves the entry of what
    was stored (the counts so far and ``audit``, the batch's number; the last one carries the totals)."""
    _store(session, records, settings, report, progress, pool, ahead.pop() if ahead else None, after_calibration,
           mode=merge, actor=actor)
    record_summary(session, "import", {**audit_counts(report), **audit}, actor=actor)


def _put_back(report: ImportReport, before: ImportReport) -> None:
    """``report``'s counts as they were ``before`` a batch's try that was rolled back."""
    vars(report).update(vars(copy.deepcopy(before)))


def _by_players(frame: Frame) -> bool:
    return frame.calibration is not None and PLAYERS_FLAG in (frame.calibration.flags or [])


def _triangulated(system: System) -> bool:
    return system.triangulation is not None and system.triangulation.status is TriangulationStatus.TRIANGULATED


#: One game of an import's input: reads (and validates) it when called, as often as needed.
GameReader = Callable[[], GameRecord]


def _held(records: list[GameRecord]) -> list[GameReader]:
    """Readers of games already in memory (inputs read whole: a calibration set, a v3D export)."""
    def reader(rec: GameRecord) -> GameReader:
        return lambda: rec

    return [reader(rec) for rec in records]


def _batches(frames_per_game: list[int], max_frames: int) -> Iterator[list[int]]:
    """Indices of whole games, in order, grouped so that a group holds at most ``max_frames`` frames
    (a larger game forms a group alone)."""
    batch: list[int] = []
    n = 0
    for g, frames in enumerate(frames_per_game):
        if batch and n + frames > max_frames:
            yield batch
            batch, n = [], 0
        batch.append(g)
        n += frames
    if batch:
        yield batch


def audit_counts(report: ImportReport) -> dict[str, object]:
    """The counts an import's audit entry keeps (``after``)."""
    return {"source": report.source, "source_name": report.source_name or Path(report.source).name,
            "games": report.games, "systems": report.systems, "frames": report.frames,
            "systems_new": report.systems_new, "systems_changed": report.systems_changed,
            "calibrated": report.calibrated, "refused": report.refused, "triangulated": report.triangulated}


def _dataset_name(file: str | Path, path: str | Path) -> str:
    """``file`` as the dataset names it: relative to the imported folder (``path``, or the folder of a file given),
    never a server path (the report reaches every role through the job's result)."""
    root = dataset_root(path)
    try:
        return Path(file).resolve().relative_to(root).as_posix()
    except ValueError:
        return Path(file).name


def _read_all(path: str | Path, settings: Settings, progress: Progress | None, games: Callable[[], list[GameReader]],
              source_name: str | None, t0: float
              ) -> tuple[ImportReport, list[GameReader], list[int], list[GameRecord]]:
    """The validation of an import, before anything is written: every game read once (``progress("read", ...)``), a
    game with a refused entry left out and named; the report so far, a reader of each game kept (within the view
    cap), its number of frames, and the records of the first batch's games (as :func:`_batches` groups them), kept
    as read so that the batch is not read again (a labels file of 120,000 boxes costs its parse once); the other
    games are dropped once read, so that memory holds one batch of records meanwhile."""
    report = ImportReport(source=str(path), source_name=source_name or Path(path).name)
    frames_per_game: list[int] = []
    readers: list[GameReader] = []
    first: list[GameRecord] = []
    first_frames, first_full = 0, False
    listed = list(games())
    for n_read, read in enumerate(listed):  # validation: raises before anything is written
        if progress:  # "reading": the first stage a job shows, from its first second
            progress("read", n_read, len(listed))
        try:
            rec = read()
        except EntryError as exc:  # one entry of this game's labels refused: the game is left out, named
            report.skipped_games.append(f"{_dataset_name(exc.file, path)}: {exc.field}: {exc.problem}")
            continue
        report.systems += len(rec.systems)
        rec, dropped = within_player_cap(within_view_cap(rec, settings, report.skipped_systems), settings)
        report.players_dropped += dropped
        frames = sum(len(s.frames) for s in rec.systems)
        frames_per_game.append(frames)
        report.frames_without_image += sum(1 for s in rec.systems for f in s.frames
                                           if not (f.image_zip or f.image_path))
        readers.append(partial(read_within_caps, read, settings))
        first_full = first_full or bool(first) and first_frames + frames > settings.import_batch_frames
        if not first_full:  # :func:`_batches`' rule: the first batch goes on while its frames fit
            first.append(rec)
            first_frames += frames
        del rec
    report.read_seconds = time.perf_counter() - t0
    report.games = len(readers)
    report.frames = sum(frames_per_game)
    return report, readers, frames_per_game, first


#: The full collections' threshold while an import stores its batches (:func:`_full_collections_by_batch`): in effect
#: never reached, the import collects once per batch itself.
_NO_AUTOMATIC_FULL_COLLECTION = 1 << 30


class _Collector:
    """The imports storing batches in this process now (``running``, under ``lock``) and the collector's thresholds
    before the first of them (``thresholds``), which the last one puts back."""

    lock = threading.Lock()
    running = 0
    thresholds: tuple[int, int, int] = gc.get_threshold()


@contextlib.contextmanager
def _full_collections_by_batch() -> Iterator[None]:
    """For the span of an import's batches, the garbage collector's full collections come once per batch, from the
    import itself (``gc.collect()`` once a batch is committed and released), not whenever the objects that survived
    young collections grew by a quarter: a batch's rows, records and ORM states (millions of objects) are held for the
    whole batch, and the automatic full collections traversed them again and again (a cProfile-free count on 40 games
    of ``soccernet-v3-scale``: 23-27 full collections, 5-6 s of the import's main process's 15 s CPU). Young
    collections run as before, and what a batch leaves (cycles of ORM objects, released with the session's identity
    map) is collected when it ends, as a full collection would have done during the next one. The thresholds are put
    back when the last import of the process (imports may run in threads of a server) ends. Changes no result."""
    with _Collector.lock:
        if _Collector.running == 0:
            _Collector.thresholds = young, middle, _ = gc.get_threshold()
            gc.set_threshold(young, middle, _NO_AUTOMATIC_FULL_COLLECTION)
        _Collector.running += 1
    try:
        yield
    finally:
        with _Collector.lock:
            _Collector.running -= 1
            if _Collector.running == 0:
                gc.set_threshold(*_Collector.thresholds)


def _run(session: Session, path: str | Path, settings: Settings, progress: Progress | None,
         games: Callable[[], list[GameReader]], actor: str | None = None,
         source_name: str | None = None, merge: str = "keep-newer") -> ImportReport:
    """Read and validate everything (nothing is stored when the input is bad), then store it in
    batches of whole games (``settings.import_batch_frames`` frames or so: a crash leaves whole games
    stored or not at all), each calibrated, recomputed and committed before the next is stored; the
    calibration processes serve every batch. ``games`` lists the input's games as readers: the
    validation reads each once and drops it (but the first batch's games, stored as it read them), and each
    other batch is read again when its calibration starts, so memory holds two batches of records, not the whole
    input (an input file changed meanwhile can still fail the import then, after whole games were stored; running it
    again completes it). With more than one batch ``progress`` reports the stage "games" (games stored /
    total) instead of the inner stages of each batch. Each batch writes its audit entry (by ``actor``,
    None: the local user) in its own transaction, with one entry per stored system it merged by ``merge``
    (``app.services.transfer.merging``). Before all that, ``progress("read", games read, games)`` while the input is
    read and validated. While the batches are stored the garbage is collected once per batch
    (:func:`_full_collections_by_batch`)."""
    t0 = time.perf_counter()
    report, readers, frames_per_game, first = _read_all(path, settings, progress, games, source_name, t0)
    batches = [[readers[i] for i in group] for group in _batches(frames_per_game, settings.import_batch_frames)]
    total_batches, batch_number = len(batches), 1
    calibration_ms: list[float] = []
    calibration_seconds = 0.0
    done = 0
    with calibration_pool(settings.calibration_workers) as pool, _full_collections_by_batch():
        if batches:  # the first batch as the validation read it (the same games: ``_read_all``)
            group = batches.pop(0)
            loaded = first if len(first) == len(group) else [read() for read in group]
            del first, group
        else:
            loaded = None
        ahead = start_first_pass(session, loaded, pool, settings) if loaded else None
        # the next batch and its calibration once ``start_next`` started them (reset for every batch)
        following: list[list[GameRecord] | None] = [None]
        started: list[FirstPassAhead | None] = [None]

        def start_next() -> None:  # the next batch calibrates while this one is stored (once, whatever the tries)
            if batches and following[0] is None:
                following[0] = records = [read() for read in batches.pop(0)]
                started[0] = start_first_pass(session, records, pool, settings)

        while loaded is not None:
            batch, last = loaded, not batches
            following[0], started[0] = None, None
            # a second try (the first met another writer, ``computed_then_written``) calibrates again, nothing ahead
            store = partial(_store_audited, session, batch, settings, report,
                            progress if last and done == 0 else None, pool, [ahead], start_next, merge=merge,
                            actor=actor, audit={"batch": batch_number, "batches": total_batches,
                                                "batch_games": len(batch)})
            computed_then_written(session, store, partial(_put_back, report, copy.deepcopy(report)))
            ahead, loaded = started[0], following[0]
            if loaded is None and batches:  # not started ahead
                loaded = [read() for read in batches.pop(0)]
            batch_number += 1
            session.expunge_all()
            gc.collect()  # what the batch leaves, once (``_full_collections_by_batch``)
            calibration_ms += report.calibration_ms
            calibration_seconds += report.calibration_seconds
            done += len(batch)
            if progress and (not last or done > len(batch)):  # more than one batch
                progress("games", done, report.games)
            del batch
    refresh_statistics(session)  # the edits that follow are planned on the imported rows
    report.calibration_ms, report.calibration_seconds = calibration_ms, calibration_seconds
    report.seconds = time.perf_counter() - t0
    report.store_seconds = report.seconds - report.read_seconds - report.calibration_seconds
    return report


def import_soccernet_v3(session: Session, path: str | Path, settings: Settings,
                        progress: Progress | None = None, *, actor: str | None = None,
                        source_name: str | None = None, merge: str = "keep-newer") -> ImportReport:
    """Import a SoccerNet-v3 tree (see :func:`read_soccernet_v3`), calibrate its frames (process pool
    over ``calibrate_frame``), triangulate its systems, and commit game batch by game batch.

    Idempotent: a second import of the same tree changes nothing. ``progress(stage, done, total)``
    is called for the stages "merge" (records matched to rows), "calibrate", "rig" (frames retried
    with their game's camera rig, when there are any), "prior" (frames of calibration datasets refitted
    with the dataset's learned camera prior, when there are any) and "triangulate".

    ``actor`` is the import's audit entry's (None: the local user); ``source_name`` how it names the
    input to non-admins (default: the path's last component); ``merge`` how it merges games already stored
    (``app.services.transfer.merging.MERGE_MODES``).

    Raises:
        DatasetError: invalid input (nothing is stored).
    """
    return _run(session, path, settings, progress,
                lambda: [partial(read_soccernet_v3_game, labels, dataset_root(path), **reading_limits(settings))
                         for labels in soccernet_v3_labels(path)], actor, source_name, merge)


def import_sn_calibration(session: Session, path: str | Path, settings: Settings, width: int | None = None,
                          height: int | None = None, progress: Progress | None = None, *,
                          actor: str | None = None, source_name: str | None = None,
                          merge: str = "keep-newer") -> ImportReport:
    """Import a SoccerNet-calibration folder or zip (see :func:`read_sn_calibration`): each frame
    becomes a single-view system, calibrated in a process pool, reviewed for its calibration.

    ``actor``, ``source_name``, ``merge``: as :func:`import_soccernet_v3`.

    Raises:
        DatasetError: invalid input (nothing is stored).
    """
    return _run(session, path, settings, progress,
                lambda: _held([read_sn_calibration(path, width, height, settings.max_image_pixels,
                                                   image_bytes(settings))]),
                actor, source_name, merge)


def import_soccernet_v3d(session: Session, path: str | Path, settings: Settings,
                         progress: Progress | None = None, *, actor: str | None = None,
                         source_name: str | None = None, merge: str = "keep-newer") -> ImportReport:
    """Import a SoccerNet-v3D tree (see :func:`read_soccernet_v3d`). Calibrations are stored with
    source "imported" and not recomputed; admission, triangulation and optimised boxes are
    recomputed from them and from the ball labels of ``SNv3D.csv``.

    ``actor``, ``source_name``, ``merge``: as :func:`import_soccernet_v3` (``keep-newer`` compares the stored
    changes with the time of the newest change the export holds, ``GameMetadata.v3d_as_of``).

    Raises:
        DatasetError: invalid input (nothing is stored).
    """
    return _run(session, path, settings, progress, lambda: _held(read_soccernet_v3d(path, settings.max_image_pixels,
                                                                                      image_bytes(settings))),
                actor, source_name, merge)
