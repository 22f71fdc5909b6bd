"""Export of reviewed labels as a SoccerNet-v3D tree (method.md section 9).

Written under ``out_dir``:

* per game ``<league>/<season>/<game>/Labels-v3D.json``: the imported ``Labels-v3.json`` with every key kept
  (what the release carries and v3d does not edit is stored at import, ``games.release`` and ``frames.release``:
  ``GameMetadata`` with e.g. ``UrlYoutube``, each frame's ``imageMetadata``, every ``bboxes`` entry, the links;
  no source file is read) and v3d's work added (``app.datasets.soccernet_v3d.curated_entry``): each frame's
  ``lines`` and the "Ball" entry of its ``bboxes`` are the curated (current) ones, the imported ones kept
  under ``v3d.original_lines`` (where edited; null otherwise) and ``v3d.original_ball`` (the imported ball
  entry, or null). Per game ``GameMetadata.reconstructions`` (actions whose system has more than one admitted
  frame; ``list_actions``, ``list_replays`` and their counts are those written) and, per frame,
  ``imageMetadata.calibrated_replays`` (actions: the admitted replays), ``calibration`` (SoccerNet camera JSON,
  section 2, or null) and ``JaC {"JaC@0.005", "JaC@0.01", "JaC@0.02"}``. v3d adds what a faithful re-import
  needs: the field lines at full precision (pixels), ``GameMetadata.v3d_reviews`` (system -> review status),
  ``GameMetadata.v3d_systems`` (action frame -> system name, where they differ), ``GameMetadata.v3d_as_of``
  (the time of the game's newest change the file holds: its newest audit entry, or the ``v3d_as_of`` of the export
  it was imported from when later, ``games.as_of``, else its import; ISO 8601 UTC, the same for the same stored
  game, so two exports of it are byte for byte equal: a ``keep-newer`` merge of the file into a database keeps what
  was changed there after it, ``app.services.transfer.merging``) and per frame
  ``v3d {source, status, reason, flags, residuals_px, uncertainty, admitted, original_lines, original_ball}`` (no server
  path: a re-import finds images in the tree itself). Replays no action links are written as they came. Only
  SoccerNet-v3 systems are written (the kinds that take the ``soccernet-v3d`` export, ``app.services.kinds``):
  single SoccerNet-calibration frames leave as cameras (``app.services.transfer.cameras_export``), ISSIA
  sequences as ISSIA-3D (``app.services.issia.export``).
* per game ``<league>/<season>/<game>/Frames-v3.zip`` beside the labels (unless ``images=False``): the
  frames' images as the SoccerNet-v3 release packs them (members named by the frame, bytes as stored), so
  that the export re-imports with its images (:func:`write_frames_zip`).
* one ``SNv3D.csv`` at the root, one row per exported frame, with every column of section 9 (lists
  and dicts as JSON, boxes ``[x1, y1, x2, y2]`` in pixels, empty cells for missing values such as
  ``replay`` on actions) followed by v3d's columns ``ball_point``, ``original_ball_bbox``,
  ``original_ball_point`` and ``optimized_bbox``. ``set`` is train or test: the split a release gave the
  image (``v3d import split``) where there is one, else per game from a stable hash of the game path (about
  80 / 20).

Only accepted systems are exported unless ``include_all``. Floats are written in their shortest form
that reads back exactly (``repr``; ``orjson``), so that :func:`app.services.transfer.importing.import_soccernet_v3d`
reads back the same numbers.

Speed: the export reads each batch of games with one SQL query of plain rows (no ORM objects), takes
JSON columns as their stored text and embeds them as they are (``orjson.Fragment`` in the documents,
the text itself in CSV cells), and decodes only the field lines it must flatten and each frame's release: a
12,800-system export is CPU-bound at about 0.2 ms a frame (40 scale games: 0.7 s for 3,546 frames).
"""
from __future__ import annotations

import csv
import itertools
import zipfile
from dataclasses import dataclass
from pathlib import Path
from typing import Any, BinaryIO, Callable, Iterator

import orjson
import sqlalchemy as sa
from sqlalchemy import Select, select
from sqlalchemy.orm import Session, selectinload, undefer

from app.core.errors import InvalidInputError
from app.datasets.csv_cells import inert_row
from app.datasets.soccernet_v3 import V3_FRAMES_ZIP
from app.datasets.soccernet_v3d import JAC_KEYS, curated_entry
from app.db.models import (
    JAC_COLUMNS,
    AuditEntry,
    BallLabel,
    BallReprojection,
    Calibration,
    FieldLineAnnotation,
    Frame,
    FrameRole,
    Game,
    OptimisedBox,
    ReviewDecision,
    ReviewStatus,
    System,
    Triangulation,
)
from app.db.types import json_loads
from app.services.images.serving import frame_has_image, frame_image
from app.services.kinds import kinds_exported_by, split_of
from app.services.storage.datasets import DatasetFiles

#: Columns of ``SNv3D.csv``: method.md section 9, then v3d's own.
CSV_COLUMNS = (
    "league", "season", "match", "main_action", "action", "replay", "img_w", "img_h", "is_ball", "ball_bbox",
    "calibration", *JAC_KEYS, "ball_3D", "rep_error", "optimized_error", "optimized_d",
    "set", "ball_point", "original_ball_bbox", "original_ball_point", "optimized_bbox",
)

@dataclass(frozen=True)
class ExportReport:
    """What an export wrote: counts and the files."""

    out_dir: Path
    games: int
    systems: int
    rows: int
    csv_path: Path
    label_files: tuple[Path, ...]
    #: Images written into the games' ``Frames-v3.zip`` (0 with ``images=False``).
    images: int = 0


def safe_component(value: str, what: str) -> str:
    if not value or value in (".", "..") or "/" in value or "\\" in value or "\0" in value:
        raise InvalidInputError(f"cannot be used as a folder name: {value!r}", field=what)
    return value


def _cell(value: Any) -> str:
    if value is None:
        return ""
    if isinstance(value, bool):
        return "True" if value else "False"
    if isinstance(value, (dict, list, tuple)):
        return orjson.dumps(value).decode("utf-8")
    return repr(value) if isinstance(value, float) else str(value)


def _frame_json(row: Any, admitted_replays: list[str] | None) -> dict[str, Any]:
    """One frame's ``Labels-v3D.json`` entry from its export row (:func:`_frame_rows`): the release's entry
    with the curated lines and ball box (``app.datasets.soccernet_v3d.curated_entry``) and v3d's keys."""
    calibrated = row.cal_source is not None
    release = json_loads(row.release_json) if row.release_json else None
    lines = json_loads(row.lines_json) if row.lines_json else {}
    # Most frames were never edited: their original lines are the same text.
    edited = row.original_json is not None and row.original_json != row.lines_json
    ball_box = json_loads(row.ball_box) if _raw(row.ball_box) else None
    original_box = json_loads(row.original_box) if _raw(row.original_box) else None
    entry, original_ball, original_lines = curated_entry(
        release, lines, json_loads(row.original_json) if edited else None, ball_box, original_box)
    meta = entry.get("imageMetadata")
    meta = dict(meta) if isinstance(meta, dict) else {}
    meta.update(width=row.width, height=row.height)
    meta.setdefault("imageType", row.role.value)
    if admitted_replays is not None:
        meta["calibrated_replays"] = admitted_replays
    entry["imageMetadata"] = meta
    entry.update({
        "calibration": _camera(row),
        "JaC": {key: getattr(row, column) for key, column in zip(JAC_KEYS, JAC_COLUMNS.values(), strict=True)},
        "v3d": {
            "source": row.cal_source.value if calibrated else None,
            "status": row.cal_status.value if calibrated else None,
            "reason": row.reason, "flags": _fragment(row.flags_json, "[]") if calibrated else [],
            "residuals_px": _fragment(row.residuals_json, "{}") if calibrated else {},
            "uncertainty": _fragment(row.uncertainty_json, "null") if calibrated else None,
            "admitted": bool(row.admitted) if calibrated else False,
            "original_lines": original_lines,
            "original_ball": original_ball,
        },
    })
    return entry


def _fragment(json_text: str | None, empty: str) -> orjson.Fragment:
    """Stored JSON text embedded as it is in an ``orjson`` document (``empty`` for SQL NULL)."""
    return orjson.Fragment(json_text or empty)


def _camera(row: Any) -> orjson.Fragment | None:
    """The frame's SoccerNet camera as its stored JSON text, embedded as it is in the export (never
    decoded and encoded again: the camera is the largest value of a frame)."""
    return None if _raw(row.camera_json) == "" else orjson.Fragment(row.camera_json)


def _raw(json_text: str | None) -> str:
    """A CSV cell from stored JSON text: the text itself, empty for SQL NULL and JSON ``null``."""
    return "" if json_text is None or json_text == "null" else json_text


def _csv_row(game: Any, row: Any, split: str) -> list[str]:
    """One frame's ``SNv3D.csv`` row, the cells in :data:`CSV_COLUMNS` order (method.md section 9, then
    v3d's columns), from its export row. JSON cells are the stored JSON text, as it is; a cell a spreadsheet
    would run as a formula (a dataset's name starting with ``=``...) is escaped (``app.datasets.csv_cells``)."""
    is_action = row.role is not FrameRole.REPLAY
    return inert_row([
        game.league, game.season, game.match,
        row.name if is_action else row.system_name,  # main_action
        "True" if is_action else "False", "" if is_action else row.name,  # action, replay
        str(row.width), str(row.height),
        "True" if row.label_frame is not None and row.ball_kind is not None else "False",  # is_ball
        _raw(row.ball_box), _raw(row.camera_json),
        *(_cell(getattr(row, column)) for column in JAC_COLUMNS.values()),
        _raw(row.ball3d), _cell(row.rep_error_px), _cell(row.opt_error_m), _cell(row.opt_d_px),
        split,
        _raw(row.ball_point), _raw(row.original_box), _raw(row.original_point), _raw(row.opt_box),
    ])


#: Games read per query by :func:`iter_soccernet_v3d` (bounded memory, few round trips).
EXPORT_BATCH_GAMES = 25


def _confirmed(value: Any) -> Any:
    """``value`` (a current ball label's column) where a person placed the label, NULL where the label is a placement
    from a doubt's fix (a detector's prediction or the other views' ball) that no person has confirmed yet
    (``BallLabel.provenance`` set; JSON ``null`` counts as unset): an export holds only labels people placed, and
    nothing derived from such a label (the view's optimised box and reprojection error are read as NULL too)."""
    unconfirmed = sa.and_(BallLabel.provenance.is_not(None), sa.cast(BallLabel.provenance, sa.Text) != "null")
    return sa.case((unconfirmed, sa.null()), else_=value)


def _json_text(column: Any, label: str) -> Any:
    """``column`` (a JSON column) read as its JSON text, labelled ``label``: exported as it is stored,
    never decoded and encoded again."""
    return sa.cast(column, sa.Text).label(label)


def frame_row_select() -> Select[Any]:
    """The columns of an exported frame's row (frame, calibration, field lines, ball label, optimised box,
    reprojection, its system's id, name, 3D ball and review status; JSON columns as their stored text), joined from
    ``frames`` and ordered by game, system and position, without a ``WHERE``: :func:`_frame_rows` selects the
    exported games' frames, a release (``app.services.releases.content``) the accepted systems' frames."""
    S, F, C, L, B = System, Frame, Calibration, FieldLineAnnotation, BallLabel
    OB, R, T, D = OptimisedBox, BallReprojection, Triangulation, ReviewDecision
    return (
        select(
            S.game_id, S.id.label("system_id"), S.name.label("system_name"), _json_text(T.ball3d, "ball3d"),
            D.status.label("review_status"),
            F.id.label("frame_id"), F.name, F.role, F.width, F.height, F.split.label("frame_split"),
            C.source.label("cal_source"), C.status.label("cal_status"),
            _json_text(C.camera, "camera_json"), C.reason, _json_text(C.flags, "flags_json"),
            _json_text(C.residuals_px, "residuals_json"), _json_text(C.uncertainty, "uncertainty_json"), C.admitted,
            C.jac_0005, C.jac_001, C.jac_002,
            _json_text(L.lines, "lines_json"), _json_text(L.original_lines, "original_json"),
            B.frame_id.label("label_frame"), _confirmed(B.kind).label("ball_kind"),
            _confirmed(sa.cast(B.box, sa.Text)).label("ball_box"),
            _confirmed(sa.cast(B.point, sa.Text)).label("ball_point"), _json_text(B.original_box, "original_box"),
            _json_text(B.original_point, "original_point"),
            _confirmed(sa.cast(OB.box, sa.Text)).label("opt_box"), _confirmed(OB.d_opt_px).label("opt_d_px"),
            _confirmed(OB.error_m).label("opt_error_m"), _confirmed(R.error_px).label("rep_error_px"),
            _json_text(F.release, "release_json"),
        )
        .select_from(F).join(S, S.id == F.system_id)
        .outerjoin(T, T.system_id == S.id).outerjoin(D, D.system_id == S.id)
        .outerjoin(C, C.frame_id == F.id).outerjoin(L, L.frame_id == F.id).outerjoin(B, B.frame_id == F.id)
        .outerjoin(OB, OB.frame_id == F.id).outerjoin(R, R.frame_id == F.id)
        .order_by(S.game_id, S.id, F.position, F.id)
    )


def _frame_rows(session: Session, game_ids: list[int], include_all: bool) -> list[Any]:
    """Every exported frame of the games ``game_ids`` as one flat row (:func:`frame_row_select`), ordered by
    game, system and position: one SQL query read as plain rows, with none of the ORM's per-object
    cost (a SoccerNet-size export reads 35,000 frames)."""
    query = frame_row_select().where(System.game_id.in_(game_ids),
                                     System.kind.in_(kinds_exported_by("soccernet-v3d")))
    if not include_all:
        query = query.where(ReviewDecision.status == ReviewStatus.ACCEPTED)
    return list(session.execute(query))


def exported_systems(export: str, include_all: bool, *loads: Any) -> Select[System]:
    """The query of the systems ``export`` writes (a name of ``app.services.kinds.EXPORTS``; the kinds
    that take it, ``kinds_exported_by``): accepted ones unless ``include_all``, in (league, season,
    match, id) order, with their game and the relationship ``loads`` given loaded. The detector exports
    (YOLO, COCO) and the monocular benchmark's reference select by it."""
    query = (
        select(System).join(System.game).outerjoin(ReviewDecision, ReviewDecision.system_id == System.id)
        .where(System.kind.in_(kinds_exported_by(export)))
        .options(selectinload(System.game), *loads)
        .order_by(Game.league, Game.season, Game.match, System.id)
    )
    return query if include_all else query.where(ReviewDecision.status == ReviewStatus.ACCEPTED)


@dataclass(frozen=True)
class ExportedGame:
    """One game of a SoccerNet-v3D export: its folder, its ``Labels-v3D.json`` document and its
    ``SNv3D.csv`` rows."""

    league: str
    season: str
    match: str
    doc: dict[str, Any]
    rows: list[list[str]]
    systems: int
    #: (frame id, frame name) of every exported frame, in the document's order.
    frames: tuple[tuple[int, str], ...] = ()

    @property
    def labels_path(self) -> str:
        """``league/season/match/Labels-v3D.json``, the file's place in the tree (POSIX separators)."""
        return f"{self.league}/{self.season}/{self.match}/Labels-v3D.json"

    @property
    def frames_path(self) -> str:
        """``league/season/match/Frames-v3.zip``, where the game's images go (POSIX separators)."""
        return f"{self.league}/{self.season}/{self.match}/{V3_FRAMES_ZIP}"

    def labels_json(self) -> bytes:
        """The ``Labels-v3D.json`` bytes (UTF-8, one line, written by ``orjson``: floats in their shortest
        form that reads back exactly, as ``repr``)."""
        return orjson.dumps(self.doc)


def iter_soccernet_v3d(session: Session, include_all: bool = False,
                       progress: Callable[[str, int, int], None] | None = None) -> Iterator[ExportedGame]:
    """The export game by game (see the module docstring), reading one game's systems at a time and
    releasing them before the next, so that memory stays bounded whatever the database's size.
    ``progress("export", games done, games)`` is called after each game is handed on.

    Raises:
        InvalidInputError: a league, season or match that cannot be a folder name; raised before the
            first game is yielded, so a writer writes nothing.
    """
    wanted = (select(System.game_id).outerjoin(ReviewDecision, ReviewDecision.system_id == System.id)
              .where(System.kind.in_(kinds_exported_by("soccernet-v3d"))))
    if not include_all:
        wanted = wanted.where(ReviewDecision.status == ReviewStatus.ACCEPTED)
    games = list(session.scalars(
        select(Game).where(Game.id.in_(wanted)).options(undefer(Game.release))
        .order_by(Game.league, Game.season, Game.match, Game.id)
    ))
    for game in games:  # validate every folder name before writing anything
        for value, what in ((game.league, "league"), (game.season, "season"), (game.match, "match")):
            safe_component(value, f"game {game.id} {what}")
    by_id = {g.id: g for g in games}
    done = 0
    for first in range(0, len(games), EXPORT_BATCH_GAMES):
        batch = [g.id for g in games[first:first + EXPORT_BATCH_GAMES]]
        changed = changed_at(session, batch)  # read first: a change after it may be missing from the file
        rows = _frame_rows(session, batch, include_all)
        per_game: dict[int, list[Any]] = {gid: [] for gid in batch}
        for row in rows:
            per_game[row.game_id].append(row)
        del rows
        for gid in batch:
            game = by_id[gid]
            yield exported_game(game, per_game.pop(gid), game_as_of(game, changed.get(gid)))
            done += 1
            if progress:
                progress("export", done, len(games))


def changed_at(session: Session, game_ids: list[int]) -> dict[int, Any]:
    """Game id -> the time of its newest audit entry (its newest change: every edit, decision and merge of its
    systems is one), for the games that have one."""
    rows = session.execute(select(AuditEntry.game_id, sa.func.max(AuditEntry.at))
                           .where(AuditEntry.game_id.in_(game_ids)).group_by(AuditEntry.game_id))
    return {int(game_id): at for game_id, at in rows if game_id is not None}


def game_as_of(game: Game, newest_entry: Any) -> str:
    """The time of the game's newest change (ISO 8601, UTC): its newest audit entry or, when later, the time the
    SoccerNet-v3D export it was imported from held it as of (``Game.as_of``); its import's time when neither is
    known."""
    known = [t for t in (newest_entry, game.as_of) if t is not None]
    return (max(known) if known else game.created_at).isoformat()


def exported_game(game: Any, rows: list[Any], as_of: str) -> ExportedGame:
    """One game's ``Labels-v3D.json`` document and CSV rows from its frame rows (:func:`_frame_rows`), the game as
    of ``as_of`` (ISO 8601, UTC: its newest change the file holds)."""
    split = split_of(game.path)
    actions: dict[str, Any] = {}
    replays: dict[str, Any] = {}
    reconstructions: list[str] = []
    csv_rows: list[list[str]] = []
    reviews: dict[str, str] = {}
    renamed: dict[str, str] = {}
    systems = [list(g) for _, g in itertools.groupby(rows, key=lambda r: r.system_id)]
    for frames in systems:
        main, others = frames[0], frames[1:]
        name = main.system_name
        admitted = {f.name for f in frames if f.cal_source is not None and f.admitted}
        if len(admitted) > 1:
            reconstructions.append(name)
        main_json = _frame_json(main, [f.name for f in others if f.name in admitted])
        main_json["linked_replays"] = [f.name for f in others]
        actions[main.name] = main_json
        for f in others:
            rj = _frame_json(f, None)
            rj["linked_action"] = main.name
            replays[f.name] = rj
        csv_rows.extend(_csv_row(game, f, f.frame_split or split) for f in frames)
        reviews[name] = (main.review_status or ReviewStatus.PENDING).value
        if main.name != name:
            renamed[main.name] = name
    release = dict(game.release or {})
    unlinked = release.pop("replays", None)  # replays no action links, as they came
    if isinstance(unlinked, dict):
        replays.update((k, v) for k, v in unlinked.items() if k not in replays)
    meta = release.get("GameMetadata")
    doc = {
        **release,
        "GameMetadata": {
            **(meta if isinstance(meta, dict) else {}),
            "UrlLocal": meta["UrlLocal"] if isinstance(meta, dict) and "UrlLocal" in meta else f"{game.path}/",
            "list_actions": list(actions), "list_replays": list(replays),
            "num_actions": len(actions), "num_replays": len(replays), "reconstructions": reconstructions,
            "v3d_reviews": reviews,
            "v3d_systems": renamed,
            "v3d_as_of": as_of,
        },
        "actions": actions,
        "replays": replays,
    }
    return ExportedGame(game.league, game.season, game.match, doc, csv_rows, len(systems),
                        tuple((f.frame_id, f.name) for f in rows))


#: The time stamp of every member of an export's zips (the earliest a zip holds): no wall-clock time enters an
#: export, so the same content zips to the same bytes whenever it is written.
ZIP_DATE_TIME = (1980, 1, 1, 0, 0, 0)


def zip_member(name: str, compress_type: int = zipfile.ZIP_STORED, folder: bool = False) -> zipfile.ZipInfo:
    """The entry of an export's zip member ``name`` (POSIX path): the fixed :data:`ZIP_DATE_TIME`, mode 0644
    (0755 for a folder, ``name`` ending in ``/``), ``compress_type`` (``ZIP_DEFLATED`` members take zlib's default
    level unless the writer names one)."""
    info = zipfile.ZipInfo(name, date_time=ZIP_DATE_TIME)
    info.compress_type = compress_type
    info.external_attr = ((0o40755 << 16) | 0x10) if folder else (0o100644 << 16)
    return info


#: Endings of file names whose data is compressed already (gzip, zip, PNG, JPEG): a zip stores them as they are,
#: since deflating them again costs time and saves next to nothing.
_COMPRESSED_SUFFIXES = (".gz", ".zip", ".png", ".jpg", ".jpeg")


def member_compression(name: str) -> int:
    """How an export's zip holds the member ``name``: ``ZIP_STORED`` for data compressed already (its name ends in
    one of :data:`_COMPRESSED_SUFFIXES`, any case), else ``ZIP_DEFLATED``."""
    return zipfile.ZIP_STORED if name.lower().endswith(_COMPRESSED_SUFFIXES) else zipfile.ZIP_DEFLATED


#: Frames read per query by :func:`write_frames_zip` (below every database's bound on an ``IN`` list).
_FRAMES_PER_QUERY = 500


def write_frames_zip(session: Session, frames: tuple[tuple[int, str], ...], target: BinaryIO,
                     files: DatasetFiles | None = None) -> int:
    """Write the images of ``frames`` ((frame id, frame name) pairs) into a new zip on ``target`` as the
    SoccerNet-v3 ``Frames-v3.zip`` holds them: one member per frame, named by the frame, its bytes copied from
    the stored image as they are (PNG or JPEG, read through ``app.services.images.serving.frame_image``, which
    checks the header and that the file lies inside its dataset), stored without recompression. Frames
    without an image (their dataset shipped none) are left out. ``files``: where the images' references lead
    (default: the process's settings').

    Returns:
        The number of images written (0: the zip is empty).

    Raises:
        ImageUnavailable: a frame's image is gone or no longer the image imported.
    """
    written = 0
    ids = [frame_id for frame_id, _ in frames]
    loaded: dict[int, Frame] = {}
    for start in range(0, len(ids), _FRAMES_PER_QUERY):  # one query per chunk, not one per frame
        some = ids[start:start + _FRAMES_PER_QUERY]
        loaded.update((f.id, f) for f in session.scalars(select(Frame).where(Frame.id.in_(some))))
    with zipfile.ZipFile(target, "w", compression=zipfile.ZIP_STORED) as zf:
        for frame_id, name in frames:
            frame = loaded.get(frame_id)
            if frame is None or not frame_has_image(frame):
                continue
            with zf.open(zip_member(name), "w", force_zip64=True) as member:
                for chunk in frame_image(frame, files=files).chunks():
                    member.write(chunk)
            written += 1
    return written


def export_soccernet_v3d(session: Session, out_dir: str | Path, include_all: bool = False,
                         progress: Callable[[str, int, int], None] | None = None, images: bool = True,
                         dataset_files: DatasetFiles | None = None) -> ExportReport:
    """Write the SoccerNet-v3D tree of the database under ``out_dir`` (see the module docstring), game
    by game (:func:`iter_soccernet_v3d`), the CSV written as the games come.

    Args:
        session: database session (read only).
        out_dir: destination folder, created if missing; existing files of the same names are
            overwritten.
        include_all: export every system, not only the accepted ones.
        progress: ``progress("export", games done, games)`` after each game (:func:`iter_soccernet_v3d`).
        images: write each game's images as ``Frames-v3.zip`` beside its ``Labels-v3D.json``
            (:func:`write_frames_zip`; a game whose frames have no image gets none), so that the export
            re-imports with its images; False leaves them out.
        dataset_files: where the images' references lead (default: the process's settings).

    Returns:
        An :class:`ExportReport`.

    Raises:
        InvalidInputError: a league, season or match that cannot be a folder name (nothing written).
        ImageUnavailable: a frame's stored image is gone or changed since its import.
    """
    out = Path(out_dir)
    games = iter_soccernet_v3d(session, include_all, progress)
    first = next(games, None)  # validates every folder name before anything is written
    out.mkdir(parents=True, exist_ok=True)
    csv_path = out / "SNv3D.csv"
    files: list[Path] = []
    n_games = n_systems = n_rows = n_images = 0
    with csv_path.open("w", newline="", encoding="utf-8") as fh:
        writer = csv.writer(fh)
        writer.writerow(CSV_COLUMNS)
        for exported in chain_games(first, games):
            path = out / exported.labels_path
            path.parent.mkdir(parents=True, exist_ok=True)
            path.write_bytes(exported.labels_json())
            files.append(path)
            if images:
                n_images += _write_game_frames(session, exported, out / exported.frames_path,
                                               dataset_files)
            writer.writerows(exported.rows)
            n_games, n_systems, n_rows = n_games + 1, n_systems + exported.systems, n_rows + len(exported.rows)
    return ExportReport(out, n_games, n_systems, n_rows, csv_path, tuple(files), n_images)


def _write_game_frames(session: Session, exported: ExportedGame, path: Path, files: DatasetFiles | None) -> int:
    """The game's ``Frames-v3.zip`` at ``path`` (written as ``.part`` and renamed); none when no frame of it
    has an image. Returns the images written."""
    part = path.with_name(path.name + ".part")
    try:
        with part.open("wb") as fh:
            written = write_frames_zip(session, exported.frames, fh, files)
        if written:
            part.replace(path)
        else:
            part.unlink()
    except BaseException:
        part.unlink(missing_ok=True)
        raise
    return written


def chain_games(first: ExportedGame | None, rest: Iterator[ExportedGame]) -> Iterator[ExportedGame]:
    if first is not None:
        yield first
        yield from rest


def export_size(session: Session, include_all: bool = False) -> tuple[int, int]:
    """``(systems, rows)`` an export would write (rows: one per frame of an exported system), counted
    without loading them."""
    chosen = (select(System.id).outerjoin(ReviewDecision, ReviewDecision.system_id == System.id)
              .where(System.kind.in_(kinds_exported_by("soccernet-v3d"))))
    if not include_all:
        chosen = chosen.where(ReviewDecision.status == ReviewStatus.ACCEPTED)
    ids = chosen.subquery()
    systems = session.scalar(select(sa.func.count()).select_from(ids)) or 0
    rows = session.scalar(select(sa.func.count(Frame.id)).where(Frame.system_id.in_(select(ids.c.id)))) or 0
    return int(systems), int(rows)
