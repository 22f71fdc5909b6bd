"""A ball detector's predictions, imported as a named source (``v3d import predictions FILE [--source NAME]``,
``POST /api/imports`` kind ``predictions``) and removed by source (``v3d predictions remove SOURCE``).

The file is a CSV with the header ``league,season,match,image,x1,y1,x2,y2,score`` (pixels of that image, continuous,
origin at the top-left corner; the image named as its kind names it, ``KindPolicy.image_name``: ``12_1.png``), one
row per detection, or a folder (an unpacked upload) holding exactly one such ``.csv``; or a detector's own output in
the layout of v3d's detector exports (:func:`prediction_input`): YOLO txt files (``class cx cy w h conf``,
normalised, one per image named by its exported stem, ``KindPolicy.view_stem``) or a COCO results JSON keyed by the
COCO export's image ids (``detector_export.coco_image_id``), both read by the monocular benchmark's readers
(``app.services.transfer.detector_files.load_predictions``).

A frame keeps at most ``V3D_MAX_PREDICTIONS_PER_FRAME`` predictions, all sources together (what the doubts' check of
detections considers per view; a detector run without non-maximum suppression writes thousands on one image): the
file is read as a stream keeping only the best of each frame by score (``app.geometry.metrics.BestDetections``: the
memory is bounded by the frames, never by the rows), and each frame then takes its best in the room the other sources'
predictions leave on it; the rest are counted in the report (``dropped``), never stored. An import never removes
another source's predictions.

The whole file is read and checked before anything is written, without the write lock: a malformed row (a missing
column, a value that is not a finite number, a score outside [0, 1], a box with no area or entirely outside its image)
is an error naming the file and its line (``DatasetError``), and nothing of the file is stored, the source's earlier
predictions included. Rows naming an image v3d does not hold are counted and named (the first
:data:`NAMED_UNKNOWN`), not an error; a box crossing its image's edge is clipped to the image. Importing a source
again replaces all its rows. The rows are then written a few hundred frames at a time (:func:`frames_per_batch`),
each batch its own short write transaction (it replaces the source's rows on its frames, bumps their systems'
versions and commits), so that another writer waits for one batch at most, never for the whole file (SQLite has one
write lock); a frame goes from the source's earlier predictions to its new ones in one transaction. An import
stopped while writing leaves the source partly replaced: import it again.

After the rows are stored, the systems they touch are recomputed (their doubts check the predictions,
``app.geometry.doubts.detections``) in the import's job, so that the CLI leaves the doubts stored when it exits.
"""
from __future__ import annotations

import csv
import io
import math
import re
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Hashable, Iterator, Sequence, cast

import sqlalchemy as sa
from sqlalchemy.orm import Session

from app.core.config import Settings
from app.core.errors import DatasetError, InvalidInputError
from app.core.names import check_name
from app.core.progress import Progress
from app.datasets.csv_cells import read_cell
from app.db.models import Frame, Game, Prediction, System
from app.db.session import end_reads
from app.db.unit import write_unit
from app.geometry.metrics import BestDetections
from app.services.audit.log import record_summary
from app.services.derivation.recompute import recompute_systems_by_id
from app.services.kinds import kind_of
from app.services.transfer.detector_files import load_predictions

#: The CSV's columns, in this order.
PREDICTION_COLUMNS = ("league", "season", "match", "image", "x1", "y1", "x2", "y2", "score")
#: Most prediction rows one write transaction holds (:func:`frames_per_batch`): a batch holds the write lock for a
#: few tens of milliseconds.
BATCH_ROWS = 5000
#: Most frames one write transaction replaces (its ``IN`` lists stay short).
BATCH_FRAMES = 500
#: Most images' keys the CSV reader keeps as read (rows repeat them; a file naming more reads the rest each time).
KEYS_KEPT = 10_000
#: How many unknown images a report names (the rest are counted).
NAMED_UNKNOWN = 20
#: A source's name: what ``--source`` takes (letters, digits, ``. _ -``; the file's stem by default).
SOURCE_PATTERN = re.compile(r"[A-Za-z0-9][A-Za-z0-9._-]{0,99}")


def frames_per_batch(per_frame: int) -> int:
    """Frames written per transaction when a frame keeps at most ``per_frame`` predictions: at most
    :data:`BATCH_ROWS` rows and :data:`BATCH_FRAMES` frames.

    >>> frames_per_batch(16), frames_per_batch(1000)
    (312, 5)
    """
    return max(1, min(BATCH_FRAMES, BATCH_ROWS // per_frame))


@dataclass
class PredictionReport:
    """What an import of predictions did: ``source`` (its name), ``rows`` read, ``stored`` predictions,
    ``replaced`` (the source's earlier rows removed), ``clipped`` boxes, ``unknown`` rows naming an image v3d does not
    hold and ``unknown_images`` (the first :data:`NAMED_UNKNOWN`, ``league/season/match/image``), ``dropped``
    predictions beyond ``cap`` (``V3D_MAX_PREDICTIONS_PER_FRAME``) on their frame, all sources together (the best by
    score are kept), ``frames`` and ``systems`` the file names, ``batches`` (write transactions), ``triangulated``
    systems after their recomputation, ``store_seconds`` of reading and storing the file, ``seconds`` of the whole
    import (the recomputation included)."""

    source: str
    cap: int = 0
    rows: int = 0
    stored: int = 0
    replaced: int = 0
    clipped: int = 0
    unknown: int = 0
    unknown_images: list[str] = field(default_factory=list)
    dropped: int = 0
    frames: int = 0
    systems: int = 0
    batches: int = 0
    triangulated: int = 0
    store_seconds: float = 0.0
    seconds: float = 0.0

    def as_result(self) -> dict[str, Any]:
        """The job's stored result (JSON)."""
        return {"kind": "predictions", "source": self.source, "rows": self.rows, "stored": self.stored,
                "replaced": self.replaced, "clipped": self.clipped, "unknown": self.unknown,
                "unknown_images": list(self.unknown_images), "dropped": self.dropped, "cap": self.cap,
                "frames": self.frames, "systems": self.systems, "batches": self.batches,
                "triangulated": self.triangulated, "store_seconds": round(self.store_seconds, 2),
                "seconds": round(self.seconds, 2)}


def check_source(name: str) -> str:
    """``name`` as a source's name (:data:`SOURCE_PATTERN`).

    Raises:
        InvalidInputError: another name (field ``source``).

    >>> check_source("yolo-sn-ball")
    'yolo-sn-ball'
    """
    check_name(name, "source", max_length=100, what="a source's name")  # the rule of every name people read
    if not isinstance(name, str) or not SOURCE_PATTERN.fullmatch(name):
        raise InvalidInputError("source must be 1-100 letters, digits, '.', '_' or '-', starting with a letter or "
                                "digit", field="source")
    return name


@dataclass(frozen=True)
class PredictionFormat:
    """One format of a detector's predictions that an import reads (:data:`PREDICTION_FORMATS`).

    Attributes:
        name: the format's word (``csv``, ``coco``, ``yolo``), as :func:`prediction_input` answers it.
        suffix: its files' extension, without the dot.
        whole_folder: the input is a folder of such files, named by the folder (the default source) and read without
            one file's size for the progress; else one file, named by its stem (a folder holds exactly one).
        detector_output: a detector's own output in the layout of v3d's detector exports, matched by exported stems
            and bounded per frame as it is read (:func:`_detector_rows`); else v3d's CSV, rows naming their images
            (:func:`_csv_rows`).
    """

    name: str
    suffix: str
    whole_folder: bool
    detector_output: bool


#: The prediction formats, in the order a folder is tried: one ``.csv`` file (whatever else it holds); else one COCO
#: results ``.json`` file; else, with neither, its YOLO ``.txt`` files. A single file is the format of its extension
#: among the single-file ones, else a CSV.
PREDICTION_FORMATS: dict[str, PredictionFormat] = {f.name: f for f in (
    PredictionFormat("csv", "csv", whole_folder=False, detector_output=False),
    PredictionFormat("coco", "json", whole_folder=False, detector_output=True),
    PredictionFormat("yolo", "txt", whole_folder=True, detector_output=True),
)}


def prediction_input(path: str | Path) -> tuple[str, Path]:
    """What an input holds and where: ``("csv", the CSV)`` for a ``.csv`` file or a folder (an unpacked upload) holding
    exactly one; ``("coco", the JSON)`` for a ``.json`` file or a folder holding one and no CSV (COCO results keyed by
    the COCO export's image ids); ``("yolo", the folder)`` for a folder of ``.txt`` files (YOLO ``class cx cy w h
    conf``, one file per image named by its exported stem, anywhere in the folder). The formats and their order are
    :data:`PREDICTION_FORMATS`'.

    Raises:
        DatasetError: no such file, or a folder holding none of these (or several CSV or JSON files).
    """
    path = Path(path)
    if path.is_dir():
        found = {f.suffix: sorted(p for p in path.rglob(f"*.{f.suffix}") if p.is_file() and not p.is_symlink())
                 for f in PREDICTION_FORMATS.values()}
        earlier: list[str] = []  # a folder holding files of a format tried before is not of a later one
        for fmt in PREDICTION_FORMATS.values():
            files = found[fmt.suffix]
            if not any(found[e] for e in earlier) and (len(files) >= 1 if fmt.whole_folder else len(files) == 1):
                return fmt.name, path if fmt.whole_folder else files[0]
            earlier.append(fmt.suffix)
        raise DatasetError(path, None, f"a predictions folder holds one .csv, one COCO results .json or YOLO .txt "
                                       f"files; found {len(found['csv'])} .csv and {len(found['json'])} .json")
    if not path.is_file():
        raise DatasetError(path, None, "no such file")
    single = [f for f in PREDICTION_FORMATS.values() if not f.whole_folder]
    return next((f.name for f in single if path.suffix.lower() == f".{f.suffix}"), single[0].name), path


@dataclass(frozen=True)
class PredictionRow:
    """One checked row: its ``line`` in the file, the image it names and its box ``(x1, y1, x2, y2)`` px, score."""

    line: int
    key: tuple[str, str, str, str]
    box: tuple[float, float, float, float]
    score: float


def read_prediction_rows(path: Path) -> Iterator[tuple[PredictionRow, int]]:
    """The rows of a predictions CSV, as a stream, each with the bytes of the file read so far (for progress).

    Raises:
        DatasetError: not UTF-8, a header other than :data:`PREDICTION_COLUMNS`, a row with another number of cells,
            a coordinate or score that is not a finite number, a score outside [0, 1], a box with no area (the message
            names the file and the line).
    """
    with open(path, "rb") as raw, io.TextIOWrapper(raw, encoding="utf-8-sig", newline="") as text:
        reader = csv.reader(text)
        try:
            header = next(reader, None)
            if header is None or tuple(c.strip() for c in header) != PREDICTION_COLUMNS:
                raise DatasetError(path, "line 1", f"the header must be {','.join(PREDICTION_COLUMNS)}, got "
                                                   f"{','.join(header or [])[:200]!r}")
            keys: dict[tuple[str, ...], tuple[str, ...]] = {}  # the images' keys as read, each once (rows repeat them)
            read = 0
            for cells in reader:
                line = reader.line_num
                if not cells:
                    continue
                if len(cells) != len(PREDICTION_COLUMNS):
                    raise DatasetError(path, f"line {line}", f"{len(cells)} cells, expected {len(PREDICTION_COLUMNS)} "
                                                              f"({','.join(PREDICTION_COLUMNS)})")
                try:
                    values = list(map(float, cells[4:]))
                except ValueError:
                    raise DatasetError(path, f"line {line} x1..score", "not numbers") from None
                if not all(map(math.isfinite, values)):
                    raise DatasetError(path, f"line {line} x1..score", "NaN or infinite value")
                x1, y1, x2, y2, score = values
                if not 0.0 <= score <= 1.0:
                    raise DatasetError(path, f"line {line} score", f"{score:g} is not in [0, 1]")
                if not (x2 > x1 and y2 > y1):
                    raise DatasetError(path, f"line {line} x1..y2", "the box has no area (needs x2 > x1 and y2 > y1)")
                cut = tuple(cells[:4])
                key = keys.get(cut)
                if key is None:
                    key = tuple(map(read_cell, cut))
                    if len(keys) < KEYS_KEPT:
                        keys[cut] = key
                if line % 1024 == 0:  # the bytes read so far, for progress: asked now and then (a system call)
                    read = raw.tell()
                yield PredictionRow(line, key, (x1, y1, x2, y2), score), read  # type: ignore[arg-type]  # four cells
        except UnicodeDecodeError as exc:
            raise DatasetError(path, None, f"not UTF-8 text ({exc.reason})") from None
        except csv.Error as exc:
            raise DatasetError(path, f"line {reader.line_num}", f"malformed CSV ({exc})") from None


Box = tuple[float, float, float, float]


def clip_box(box: Box, width: int, height: int) -> Box | None:
    """``box`` (px) clipped to a ``width`` x ``height`` image, or None when it lies entirely outside (no area left).

    >>> clip_box((-5.0, 10.0, 20.0, 30.0), 960, 540)
    (0.0, 10.0, 20.0, 30.0)
    >>> clip_box((970.0, 10.0, 990.0, 30.0), 960, 540) is None
    True
    """
    x1, y1 = max(box[0], 0.0), max(box[1], 0.0)
    x2, y2 = min(box[2], float(width)), min(box[3], float(height))
    if x2 <= x1 or y2 <= y1:
        return None
    return (x1, y1, x2, y2)


class _Frames:
    """Stored frames by ``(league, season, match, image)``, each game's read when a row first names it."""

    def __init__(self, session: Session) -> None:
        self.session = session
        self.games = {(g.league, g.season, g.match): g.id for g in session.execute(
            sa.select(Game.id, Game.league, Game.season, Game.match))}
        self.by_game: dict[int, dict[str, list[tuple[int, int, int, int]]]] = {}

    def find(self, key: tuple[str, str, str, str]) -> list[tuple[int, int, int, int]]:
        """``(frame id, system id, width, height)`` of each frame the row names (empty: unknown)."""
        gid = self.games.get(key[:3])
        if gid is None:
            return []
        frames = self.by_game.get(gid)
        if frames is None:
            frames = self.by_game[gid] = {}
            for f in self.session.scalars(sa.select(Frame).join(System).where(System.game_id == gid)):
                frames.setdefault(kind_of(f.system).image_name(f), []).append((f.id, f.system_id, f.width, f.height))
        return frames.get(key[3], [])


def import_predictions(session: Session, path: str | Path, settings: Settings, source: str | None = None,
                       progress: Progress | None = None, actor: str | None = None) -> PredictionReport:
    """Store the predictions of ``path`` (a CSV, YOLO files or COCO results, :func:`prediction_input`) as source
    ``source`` (default: the file's stem, a YOLO folder's name), replacing the source's earlier rows: at most
    ``settings.max_predictions_per_frame`` a frame, all sources together, the best by score. The file is read and
    checked whole first, without the write lock; then written in batches of :func:`frames_per_batch` frames, each its
    own write transaction; then the systems they touch are recomputed (their doubts). See the module docstring.
    ``progress("predictions", bytes read, file size)`` while reading, ``progress("store", frames written, frames)``.

    Raises:
        DatasetError: a malformed file or row (file and line named; nothing stored).
        InvalidInputError: a bad source name (field ``source``).
    """
    t0 = time.perf_counter()
    kind, found_path = prediction_input(path)
    fmt = PREDICTION_FORMATS[kind]
    cap = settings.max_predictions_per_frame
    report = PredictionReport(check_source(source or (Path(path).name if fmt.whole_folder else found_path.stem)), cap)
    size = found_path.stat().st_size if not fmt.whole_folder else 0
    best, system_of = _read_best(session, fmt, found_path, report, progress, size)
    earlier = _frames_of(session, report.source)
    end_reads(session)  # what was read is plain values now: the writes below take the lock batch by batch
    frames = sorted(set(system_of) | set(earlier))
    touched: set[int] = set()
    step = frames_per_batch(cap)
    for start in range(0, len(frames), step):
        chunk = frames[start:start + step]
        systems = {system_of[f] if f in system_of else earlier[f] for f in chunk}
        _write_batch(session, report, best, chunk, systems)
        touched |= systems
        if progress:
            progress("store", start + len(chunk), len(frames))
    with write_unit(session):
        record_summary(session, "import", {"kind": "predictions", "source": report.source, "stored": report.stored,
                                           "replaced": report.replaced, "unknown": report.unknown,
                                           "dropped": report.dropped, "cap": cap}, actor=actor)
    report.store_seconds = time.perf_counter() - t0
    session.expunge_all()
    report.triangulated = recompute_systems_by_id(session, sorted(touched), settings, progress,
                                                  {"reason": f"predictions {report.source}"}, actor)
    report.seconds = time.perf_counter() - t0
    return report


def _read_best(session: Session, fmt: PredictionFormat, path: Path, report: PredictionReport, progress: Progress | None,
               size: int) -> tuple[BestDetections, dict[int, int]]:
    """Read and check the whole input (in a read-only transaction: the stored frames it names), keeping the best
    ``report.cap`` predictions of each frame (keyed by frame id); counts ``rows``, ``unknown``, ``clipped``,
    ``dropped``, ``frames`` and ``systems`` in ``report``. Returns the kept predictions and each named frame's system.

    Raises:
        DatasetError: a malformed row, or a box entirely outside its image (nothing is written).
    """
    best = BestDetections(report.cap)
    system_of: dict[int, int] = {}
    detector = _CheckedBest(report.cap, path) if fmt.detector_output else None
    rows = _csv_rows(path, _Frames(session)) if detector is None else _detector_rows(session, path, detector)
    for row in rows:
        report.rows += 1
        if not row.frames:
            report.unknown += 1
            if len(report.unknown_images) < NAMED_UNKNOWN and row.name not in report.unknown_images:
                report.unknown_images.append(row.name)
            continue
        for fid, sid, w, h in row.frames:
            box = clip_box(row.box, w, h)
            if box is None:
                raise DatasetError(path, row.where,
                                   f"box {list(row.box)} lies entirely outside the {w}x{h} image {row.name!r}")
            report.clipped += box != row.box
            best.add(fid, box, row.score)
            system_of[fid] = sid
        if progress and size and report.rows % BATCH_ROWS == 0:
            progress("predictions", row.read, size)
    if progress and size:
        progress("predictions", size, size)
    if detector is not None:  # the detector readers keep the best of each image as they read: the rest were rows too
        report.rows += detector.dropped
        report.dropped += detector.dropped
    report.dropped += best.dropped
    report.frames, report.systems = len(system_of), len(set(system_of.values()))
    return best, system_of


def _write_batch(session: Session, report: PredictionReport, best: BestDetections, frames: list[int],
                 systems: set[int]) -> None:
    """One write transaction: bump the versions of ``systems`` (first: on PostgreSQL their row locks make a concurrent
    import of the same frames wait, so that the room counted below holds), replace the source's predictions on
    ``frames`` by its best in the room the other sources leave (``report.cap`` a frame), commit. Adds to ``report``'s
    ``stored``, ``replaced``, ``dropped`` and ``batches``."""
    with write_unit(session):
        _bump_versions(session, systems)
        report.replaced += _delete_source(session, report.source, frames)
        others = {fid: n for fid, n in session.execute(sa.select(Prediction.frame_id, sa.func.count())
                                                       .where(Prediction.frame_id.in_(frames))
                                                       .group_by(Prediction.frame_id))}
        batch: list[dict[str, Any]] = []
        for fid in frames:
            kept = best.best(fid)
            room = max(0, report.cap - others.get(fid, 0))
            report.dropped += max(0, len(kept) - room)
            batch.extend({"source": report.source, "frame_id": fid, "score": score, "x1": box[0], "y1": box[1],
                          "x2": box[2], "y2": box[3]} for box, score in kept[:room])
        if batch:
            session.execute(sa.insert(Prediction), batch)
    report.stored += len(batch)
    report.batches += 1


def _frames_of(session: Session, source: str) -> dict[int, int]:
    """The frames holding predictions of ``source``, each with its system."""
    return {fid: sid for fid, sid in session.execute(sa.select(Frame.id, Frame.system_id).where(
        Frame.id.in_(sa.select(Prediction.frame_id).where(Prediction.source == source))))}


def _bump_versions(session: Session, systems: set[int]) -> None:
    """Bump the version of each system whose predictions change, in the transaction that changes them: the doubts of an
    edit computed from the predictions as they were fail its compare (``app.db.scope``)."""
    ids = sorted(systems)
    for start in range(0, len(ids), 500):
        session.execute(sa.update(System).where(System.id.in_(ids[start:start + 500]))
                        .values(version=System.version + 1).execution_options(synchronize_session=False))


def _delete_source(session: Session, source: str, frames: list[int]) -> int:
    """Delete the source's rows on ``frames`` in the open transaction; returns how many."""
    result = session.execute(sa.delete(Prediction).where(Prediction.source == source, Prediction.frame_id.in_(frames)))
    return int(cast("sa.CursorResult[Any]", result).rowcount or 0)


class _CheckedBest(BestDetections):
    """:class:`BestDetections` of a detector's file (keyed by view stem) that refuses a score outside [0, 1] as it is
    read, kept or not: every detection of the file is checked."""

    def __init__(self, per_image: int, path: Path) -> None:
        super().__init__(per_image)
        self.path = path

    def add(self, image_id: Hashable, box: Sequence[float], score: float) -> None:
        """:meth:`BestDetections.add` of a checked score.

        Raises:
            DatasetError: a score outside [0, 1] (the view's stem named).
        """
        if not 0.0 <= float(score) <= 1.0:
            raise DatasetError(self.path, f"{image_id} score", f"{float(score):g} is not in [0, 1]")
        super().add(image_id, box, score)


@dataclass(frozen=True)
class _Resolved:
    """One prediction of an input with the stored frames it names (``(frame id, system id, width, height)``; empty:
    an image v3d does not hold, ``name`` saying which), ``where`` it is in its file (for errors) and the bytes of the
    file read so far (progress)."""

    where: str
    name: str
    frames: list[tuple[int, int, int, int]]
    box: Box
    score: float
    read: int = 0


def _csv_rows(path: Path, frames: _Frames) -> Iterator[_Resolved]:
    for row, read in read_prediction_rows(path):
        yield _Resolved(f"line {row.line} x1..y2", "/".join(row.key), frames.find(row.key), row.box, row.score, read)


@dataclass(frozen=True)
class _StemView:
    """A stored view as the detector readers match files to it: its exported stem and image size (px)."""

    stem: str
    width: int
    height: int
    frame_id: int
    system_id: int


def _detector_rows(session: Session, path: Path, keep: BestDetections) -> Iterator[_Resolved]:
    """The detections of YOLO txt files or a COCO results JSON (:func:`load_predictions`,
    the monocular benchmark's readers too: YOLO files matched by stem, COCO results by ``coco_image_id(stem)``, the ball
    class from ``data.yaml`` or 0, category 1), on every stored view named as the YOLO and COCO exports name it
    (``KindPolicy.view_stem``): the best ``keep.per_image`` of each view, chosen as the file is read
    (``keep.dropped`` counts the others); a YOLO file of an image v3d does not hold is named by its stem, COCO results
    of one are counted."""
    from sqlalchemy.orm import selectinload

    views = [_StemView(kind_of(f.system).view_stem(f.system.game, f), f.width, f.height, f.id, f.system_id)
             for f in session.scalars(sa.select(Frame).options(selectinload(Frame.system).selectinload(System.game)))]
    by_stem = {v.stem: v for v in views}
    dets, ignored = load_predictions(path, views, keep=keep)
    for stem, box, score in zip(dets.image_ids, dets.boxes, dets.scores, strict=True):
        v = by_stem[str(stem)]
        b = (float(box[0]), float(box[1]), float(box[2]), float(box[3]))
        yield _Resolved(f"{stem} box", str(stem), [(v.frame_id, v.system_id, v.width, v.height)], b, float(score))
    unknown = sorted({p.stem for p in path.rglob("*.txt") if p.stem not in by_stem}) if path.is_dir() else []
    named = iter(unknown)
    for _ in range(ignored):  # a YOLO file's stem, or a COCO result's (an image id v3d does not hold)
        last = unknown[-1] if unknown else "a COCO image id v3d does not hold"
        yield _Resolved("", next(named, last), [], (0.0, 0.0, 1.0, 1.0), 0.0)


def remove_predictions(session: Session, settings: Settings, source: str, actor: str | None = None) -> int:
    """Delete every prediction of ``source`` and recompute the systems they touched; returns how many were deleted
    (0: no such source). Written in batches of :data:`BATCH_FRAMES` frames, each its own short write transaction
    (the frame's predictions and its system's version together), as an import writes."""
    earlier = _frames_of(session, source)
    end_reads(session)
    frames, n = sorted(earlier), 0
    for start in range(0, len(frames), BATCH_FRAMES):
        chunk = frames[start:start + BATCH_FRAMES]
        with write_unit(session):
            _bump_versions(session, {earlier[f] for f in chunk})
            n += _delete_source(session, source, chunk)
    if n:
        with write_unit(session):
            record_summary(session, "import", {"kind": "predictions", "source": source, "removed": n}, actor=actor)
    recompute_systems_by_id(session, sorted(set(earlier.values())), settings, None,
                            {"reason": f"predictions {source} removed"}, actor)
    return n


def prediction_sources(session: Session) -> list[dict[str, Any]]:
    """Every stored source: ``{"source", "predictions", "frames", "imported_at"}`` (ISO 8601 UTC), by name."""
    rows = session.execute(sa.select(Prediction.source, sa.func.count(Prediction.id),
                                     sa.func.count(sa.distinct(Prediction.frame_id)),
                                     sa.func.max(Prediction.created_at))
                           .group_by(Prediction.source).order_by(Prediction.source))
    return [{"source": s, "predictions": int(n), "frames": int(f), "imported_at": t.isoformat() if t else None}
            for s, n, f, t in rows]
