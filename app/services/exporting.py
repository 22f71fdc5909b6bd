"""Export of reviewed labels as a SoccerNet-v3D tree (method.md section 9).

Written under ``out_dir``:

* per game ``<league>/<season>/<game>/Labels-v3D.json``: the SoccerNet-v3 layout (``GameMetadata``,
  ``actions``, ``replays``) with, per game, ``GameMetadata.reconstructions`` (actions whose system has
  more than one admitted frame) and, per frame, ``imageMetadata.calibrated_replays`` (actions: the
  admitted replays), ``calibration`` (SoccerNet camera JSON, section 2, or null) and
  ``JaC {"JaC@0.005", "JaC@0.01", "JaC@0.02"}``. v3d adds what a faithful re-import needs: the field
  lines (full precision, pixels), ``GameMetadata.v3d_reviews`` (system -> review status),
  ``GameMetadata.v3d_systems`` (action frame -> system name, where they differ) and per frame
  ``v3d {source, status, reason, flags, residuals_px, admitted, original_lines, image}`` (``image``:
  where the frame's pixels were, used by a re-import when the tree has no images of its own). Single-view
  systems are written as actions with ``imageType`` "camera".
* one ``SNv3D.csv`` at the root, one row per exported frame, with every column of section 9 (lists
  and dicts as JSON, boxes ``[x1, y1, x2, y2]`` in pixels, empty cells for missing values such as
  ``replay`` on actions) followed by v3d's columns ``ball_point``, ``original_ball_bbox``,
  ``original_ball_point`` and ``optimized_bbox``. ``set`` is train or test per game, from a stable
  hash of the game path (about 80 / 20).

Only accepted systems are exported unless ``include_all``. Floats are written with ``repr`` so that
:func:`app.services.importing.import_soccernet_v3d` reads back the same numbers.
"""
from __future__ import annotations

import csv
import hashlib
import io
import json
import tempfile
import zipfile
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Iterator

import sqlalchemy as sa
from sqlalchemy import Select, select
from sqlalchemy.orm import Session, selectinload

from app.db.models import Frame, FrameRole, Game, ReviewDecision, ReviewStatus, System
from app.services.errors import InvalidInputError

#: Columns of ``SNv3D.csv``: method.md section 9, then v3d's own.
CSV_COLUMNS = (
    "league", "season", "match", "main_action", "action", "replay", "img_w", "img_h", "is_ball", "ball_bbox",
    "calibration", "JaC@0.005", "JaC@0.01", "JaC@0.02", "ball_3D", "rep_error", "optimized_error", "optimized_d",
    "set", "ball_point", "original_ball_bbox", "original_ball_point", "optimized_bbox",
)
#: Share of games in the train split (the paper's split is about 80 / 20).
TRAIN_FRACTION = 0.8


@dataclass(frozen=True)
class ExportReport:
    """What an export wrote: counts and the files."""

    out_dir: Path
    games: int
    systems: int
    rows: int
    csv_path: Path
    label_files: tuple[Path, ...]


def split_of(game_path: str) -> str:
    """"train" or "test" for a game, from a stable hash of ``league/season/match`` (about 80 / 20).

    >>> split_of("england_epl/2014-2015/2015-02-21 - 18-00 Chelsea 1 - 1 Burnley") in ("train", "test")
    True
    """
    h = int.from_bytes(hashlib.sha256(game_path.encode("utf-8")).digest()[:8], "big")
    return "train" if (h % 10_000) < TRAIN_FRACTION * 10_000 else "test"


def _safe_component(value: str, what: str) -> str:
    if not value or value in (".", "..") or "/" in value or "\\" in value or "\0" in value:
        raise InvalidInputError(f"cannot be used as a folder name: {value!r}", field=what)
    return value


def _flat_lines(lines: dict[str, Any] | None) -> list[dict[str, Any]]:
    """``{class: [[[x, y], ...], ...]}`` -> SoccerNet-v3 ``[{class, points [x1, y1, ...]}]``, unrounded."""
    return [{"class": cls, "points": [float(v) for pt in poly for v in pt]}
            for cls, polys in (lines or {}).items() for poly in polys]


def _cell(value: Any) -> str:
    if value is None:
        return ""
    if isinstance(value, bool):
        return "True" if value else "False"
    if isinstance(value, (dict, list, tuple)):
        return json.dumps(value, separators=(", ", ": "))
    return repr(value) if isinstance(value, float) else str(value)


def _frame_json(frame: Frame, admitted_replays: list[str] | None) -> dict[str, Any]:
    cal = frame.calibration
    meta: dict[str, Any] = {"width": frame.width, "height": frame.height, "imageType": frame.role.value}
    if admitted_replays is not None:
        meta["calibrated_replays"] = admitted_replays
    fl = frame.field_lines
    return {
        "imageMetadata": meta,
        "lines": _flat_lines(fl.lines if fl else None),
        "calibration": cal.camera if cal is not None else None,
        "JaC": {"JaC@0.005": cal.jac_0005 if cal else None, "JaC@0.01": cal.jac_001 if cal else None,
                "JaC@0.02": cal.jac_002 if cal else None},
        "v3d": {
            "source": cal.source.value if cal else None, "status": cal.status.value if cal else None,
            "reason": cal.reason if cal else None, "flags": list(cal.flags) if cal else [],
            "residuals_px": dict(cal.residuals_px) if cal else {}, "admitted": bool(cal.admitted) if cal else False,
            "original_lines": _flat_lines(fl.original_lines) if fl else [],
            "image": {"zip": frame.image_zip, "member": frame.image_member, "path": frame.image_path},
        },
    }


def _csv_row(game: Game, system: System, frame: Frame, split: str) -> dict[str, str]:
    cal, label, opt, rep = frame.calibration, frame.ball_label, frame.optimised_box, frame.reprojection
    tri = system.triangulation
    is_action = frame.role is not FrameRole.REPLAY
    values: dict[str, Any] = {
        "league": game.league, "season": game.season, "match": game.match,
        "main_action": system.name if frame.role is FrameRole.REPLAY else frame.name,
        "action": is_action, "replay": None if is_action else frame.name,
        "img_w": frame.width, "img_h": frame.height, "is_ball": label is not None and label.kind is not None,
        "ball_bbox": label.box if label else None,
        "calibration": cal.camera if cal else None,
        "JaC@0.005": cal.jac_0005 if cal else None, "JaC@0.01": cal.jac_001 if cal else None,
        "JaC@0.02": cal.jac_002 if cal else None,
        "ball_3D": tri.ball3d if tri else None,
        "rep_error": rep.error_px if rep else None,
        "optimized_error": opt.error_m if opt else None, "optimized_d": opt.d_opt_px if opt else None,
        "set": split,
        "ball_point": label.point if label else None,
        "original_ball_bbox": label.original_box if label else None,
        "original_ball_point": label.original_point if label else None,
        "optimized_bbox": opt.box if opt else None,
    }
    return {k: _cell(values[k]) for k in CSV_COLUMNS}


def exported_systems(include_all: bool, *loads: Any) -> Select[tuple[System]]:
    """The query of the systems an export writes: accepted ones unless ``include_all``, in (league,
    season, match, id) order, with their game and the relationship ``loads`` given loaded. Every
    export (SoccerNet-v3D, YOLO, COCO) and the monocular benchmark's reference select by it."""
    query = (
        select(System).join(System.game).outerjoin(ReviewDecision, ReviewDecision.system_id == System.id)
        .options(selectinload(System.game), *loads)
        .order_by(Game.league, Game.season, Game.match, System.id)
    )
    return query if include_all else query.where(ReviewDecision.status == ReviewStatus.ACCEPTED)


#: Relationships an exported system needs loaded.
_EXPORT_LOADS = (
    selectinload(System.triangulation), selectinload(System.review),
    selectinload(System.frames).selectinload(Frame.calibration),
    selectinload(System.frames).selectinload(Frame.field_lines),
    selectinload(System.frames).selectinload(Frame.ball_label),
    selectinload(System.frames).selectinload(Frame.optimised_box),
    selectinload(System.frames).selectinload(Frame.reprojection),
)


@dataclass(frozen=True)
class ExportedGame:
    """One game of a SoccerNet-v3D export: its folder, its ``Labels-v3D.json`` document and its
    ``SNv3D.csv`` rows."""

    league: str
    season: str
    match: str
    doc: dict[str, Any]
    rows: list[dict[str, str]]
    systems: int

    @property
    def labels_path(self) -> str:
        """``league/season/match/Labels-v3D.json``, the file's place in the tree (POSIX separators)."""
        return f"{self.league}/{self.season}/{self.match}/Labels-v3D.json"

    def labels_json(self) -> bytes:
        """The ``Labels-v3D.json`` bytes (UTF-8, indented by one space)."""
        return json.dumps(self.doc, indent=1).encode("utf-8")


def iter_soccernet_v3d(session: Session, include_all: bool = False) -> Iterator[ExportedGame]:
    """The export game by game (see the module docstring), reading one game's systems at a time and
    releasing them before the next, so that memory stays bounded whatever the database's size.

    Raises:
        InvalidInputError: a league, season or match that cannot be a folder name; raised before the
            first game is yielded, so a writer writes nothing.
    """
    wanted = select(System.game_id).outerjoin(ReviewDecision, ReviewDecision.system_id == System.id)
    if not include_all:
        wanted = wanted.where(ReviewDecision.status == ReviewStatus.ACCEPTED)
    games = session.execute(
        select(Game.id, Game.league, Game.season, Game.match).where(Game.id.in_(wanted))
        .order_by(Game.league, Game.season, Game.match, Game.id)
    ).all()
    for gid, league, season, match in games:  # validate every folder name before writing anything
        for value, what in ((league, "league"), (season, "season"), (match, "match")):
            _safe_component(value, f"game {gid} {what}")
    for gid, league, season, match in games:
        systems = list(session.scalars(exported_systems(include_all, *_EXPORT_LOADS).where(System.game_id == gid)))
        yield _exported_game(systems[0].game, systems)
        session.expunge_all()


def _exported_game(game: Game, systems: list[System]) -> ExportedGame:
    split = split_of(game.path)
    actions: dict[str, Any] = {}
    replays: dict[str, Any] = {}
    reconstructions: list[str] = []
    rows: list[dict[str, str]] = []
    for system in systems:
        frames = list(system.frames)
        admitted = [f for f in frames if f.calibration is not None and f.calibration.admitted]
        if len(admitted) > 1:
            reconstructions.append(system.name)
        main = frames[0]
        others = frames[1:]
        main_json = _frame_json(main, [f.name for f in others if f in admitted])
        main_json["linked_replays"] = [f.name for f in others]
        actions[main.name] = main_json
        for f in others:
            rj = _frame_json(f, None)
            rj["linked_action"] = main.name
            replays[f.name] = rj
        rows.extend(_csv_row(game, system, f, split) for f in frames)
    doc = {
        "GameMetadata": {
            "UrlLocal": f"{game.path}/", "list_actions": list(actions), "list_replays": list(replays),
            "num_actions": len(actions), "num_replays": len(replays), "reconstructions": reconstructions,
            "v3d_reviews": {s.name: (s.review.status.value if s.review else ReviewStatus.PENDING.value)
                            for s in systems},
            "v3d_systems": {s.frames[0].name: s.name for s in systems if s.frames[0].name != s.name},
        },
        "actions": actions,
        "replays": replays,
    }
    return ExportedGame(game.league, game.season, game.match, doc, rows, len(systems))


def export_soccernet_v3d(session: Session, out_dir: str | Path, include_all: bool = False) -> ExportReport:
    """Write the SoccerNet-v3D tree of the database under ``out_dir`` (see the module docstring), game
    by game (:func:`iter_soccernet_v3d`), the CSV written as the games come.

    Args:
        session: database session (read only).
        out_dir: destination folder, created if missing; existing files of the same names are
            overwritten.
        include_all: export every system, not only the accepted ones.

    Returns:
        An :class:`ExportReport`.

    Raises:
        InvalidInputError: a league, season or match that cannot be a folder name (nothing written).
    """
    out = Path(out_dir)
    games = iter_soccernet_v3d(session, include_all)
    first = next(games, None)  # validates every folder name before anything is written
    out.mkdir(parents=True, exist_ok=True)
    csv_path = out / "SNv3D.csv"
    files: list[Path] = []
    n_games = n_systems = n_rows = 0
    with csv_path.open("w", newline="", encoding="utf-8") as fh:
        writer = csv.DictWriter(fh, fieldnames=CSV_COLUMNS)
        writer.writeheader()
        for exported in _chain(first, games):
            path = out / exported.labels_path
            path.parent.mkdir(parents=True, exist_ok=True)
            path.write_bytes(exported.labels_json())
            files.append(path)
            writer.writerows(exported.rows)
            n_games, n_systems, n_rows = n_games + 1, n_systems + exported.systems, n_rows + len(exported.rows)
    return ExportReport(out, n_games, n_systems, n_rows, csv_path, tuple(files))


def _chain(first: ExportedGame | None, rest: Iterator[ExportedGame]) -> Iterator[ExportedGame]:
    if first is not None:
        yield first
        yield from rest


class _ZipSink(io.RawIOBase):
    """A write-only, unseekable stream whose written bytes are taken out in pieces (:meth:`drain`), so
    that ``zipfile`` can write an archive while it is being sent."""

    def __init__(self) -> None:
        super().__init__()
        self._parts: list[bytes] = []
        self._pos = 0

    def writable(self) -> bool:
        return True

    def write(self, b: Any) -> int:
        data = bytes(b)
        self._parts.append(data)
        self._pos += len(data)
        return len(data)

    def tell(self) -> int:
        return self._pos

    def drain(self) -> bytes:
        data = b"".join(self._parts)
        self._parts.clear()
        return data


def export_size(session: Session, include_all: bool = False) -> tuple[int, int]:
    """``(systems, rows)`` an export would write (rows: one per frame of an exported system), counted
    without loading them."""
    chosen = select(System.id).outerjoin(ReviewDecision, ReviewDecision.system_id == System.id)
    if not include_all:
        chosen = chosen.where(ReviewDecision.status == ReviewStatus.ACCEPTED)
    ids = chosen.subquery()
    systems = session.scalar(select(sa.func.count()).select_from(ids)) or 0
    rows = session.scalar(select(sa.func.count(Frame.id)).where(Frame.system_id.in_(select(ids.c.id)))) or 0
    return int(systems), int(rows)


def stream_soccernet_v3d_zip(session: Session, include_all: bool = False) -> Iterator[bytes]:
    """The export as a zip archive, produced while the database is read: each game's
    ``Labels-v3D.json`` is compressed and handed on before the next game is read; ``SNv3D.csv`` is
    spooled (in memory up to 8 MB, then a temporary file) and written last. Memory stays bounded by one
    game and the spool. The archive is the same tree as :func:`export_soccernet_v3d` writes.

    Raises:
        InvalidInputError: as :func:`iter_soccernet_v3d`, before the first byte.
    """
    games = iter_soccernet_v3d(session, include_all)
    first = next(games, None)
    sink = _ZipSink()
    with tempfile.SpooledTemporaryFile(max_size=8 << 20, mode="w+", newline="", encoding="utf-8") as spool:
        writer = csv.DictWriter(spool, fieldnames=CSV_COLUMNS)
        writer.writeheader()
        with zipfile.ZipFile(sink, "w", compression=zipfile.ZIP_DEFLATED, compresslevel=1) as zf:
            for exported in _chain(first, games):
                zf.writestr(exported.labels_path, exported.labels_json())
                writer.writerows(exported.rows)
                yield sink.drain()
            spool.seek(0)
            with zf.open("SNv3D.csv", "w", force_zip64=True) as member:
                for chunk in iter(lambda: spool.read(1 << 20), ""):
                    member.write(chunk.encode("utf-8"))
                    yield sink.drain()
        yield sink.drain()
