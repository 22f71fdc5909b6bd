"""Reading and validation of dataset files into plain records (no database): SoccerNet-v3 trees,
SoccerNet-calibration folders or zips, SoccerNet-v3D exports. Private to ``app.services.importing``.

Every problem raises :class:`~app.services.errors.DatasetError` naming the file (``archive.zip!member``
inside zips) and the field. Images are located, never extracted: a record holds the zip path and
member name or a file path. Zip entry names are checked before anything else is read: an absolute
name, a drive or a ``..`` component refuses the archive.
"""
from __future__ import annotations

import ast
import csv
import json
import math
import zipfile
from dataclasses import dataclass
from functools import partial
from pathlib import Path, PurePosixPath
from typing import Any, Callable, Iterator, Mapping

import numpy as np

from app.db.models import BallKind, CalibrationStatus, FrameRole, ReviewStatus, SystemKind
from app.geometry.annotations import (
    AnnotationError, from_soccernet_calibration, from_soccernet_v3, lines_to_json_lists,
)
from app.geometry.camera import Camera
from app.services._labels import LabelError, check_box, check_point
from app.services.errors import DatasetError
from app.services.recompute import CalibrationFields

V3_LABELS = "Labels-v3.json"
V3_FRAMES_ZIP = "Frames-v3.zip"
V3D_LABELS = "Labels-v3D.json"
V3D_CSV = "SNv3D.csv"
#: League given to games made from a SoccerNet-calibration folder or zip.
SN_CALIBRATION_LEAGUE = "sn-calibration"
_IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg")
_SN_CALIBRATION_SKIP = {"match_info.json", "per_match_info.json"}


# ----- records: validated input, nothing stored yet ----------------------------------------------
@dataclass(frozen=True)
class ImportedCalibration:
    """A calibration read from a SoccerNet-v3D export (stored with source "imported")."""

    fields: CalibrationFields


@dataclass(frozen=True)
class FrameRecord:
    """One validated frame: size, image source, field lines (JSON lists, pixels), ball label."""

    name: str
    role: FrameRole
    width: int
    height: int
    lines: dict[str, Any]
    ball_box: list[float] | None = None
    ball_point: list[float] | None = None
    image_zip: str | None = None
    image_member: str | None = None
    image_path: str | None = None
    calibration: ImportedCalibration | None = None
    #: Exports carry the imported originals too (``None``: the current values are the originals).
    original_lines: dict[str, Any] | None = None
    original_ball: tuple[BallKind | None, list[float] | None, list[float] | None] | None = None


@dataclass(frozen=True)
class SystemRecord:
    """One system: its name, kind and frames (the action first)."""

    name: str
    kind: SystemKind
    frames: list[FrameRecord]
    review: ReviewStatus | None = None


@dataclass(frozen=True)
class GameRecord:
    """One game and its systems."""

    league: str
    season: str
    match: str
    source_path: str
    systems: list[SystemRecord]


# ----- small readers ------------------------------------------------------------------------------
def _load_json_bytes(raw: bytes, where: str) -> Any:
    try:
        return json.loads(raw.decode("utf-8"))
    except UnicodeDecodeError as exc:
        raise DatasetError(where, None, f"not UTF-8 text ({exc.reason} at byte {exc.start})") from None
    except json.JSONDecodeError as exc:
        raise DatasetError(where, None, f"invalid or truncated JSON: {exc.msg} at line {exc.lineno} "
                                        f"column {exc.colno}") from None


def _load_json_file(path: Path) -> Any:
    try:
        raw = path.read_bytes()
    except OSError as exc:
        raise DatasetError(path, None, f"cannot read: {exc.strerror}") from None
    return _load_json_bytes(raw, str(path))


def is_safe_member(name: str) -> bool:
    """True for a relative archive member name without ``..``, drive or backslash tricks.

    >>> is_safe_member("12_1.png"), is_safe_member("frames/12.png")
    (True, True)
    >>> is_safe_member("../secret.png"), is_safe_member("/etc/passwd"), is_safe_member("a\\\\..\\\\b")
    (False, False, False)
    """
    posix = name.replace("\\", "/")
    parts = PurePosixPath(posix).parts
    return bool(parts) and not posix.startswith("/") and ".." not in parts and ":" not in parts[0]


def _safe_names(zf: zipfile.ZipFile, zip_path: Path) -> list[str]:
    """The archive's entry names; raises when one is absolute or has a ``..`` component
    (:func:`is_safe_member`, the rule the image route applies too)."""
    names = zf.namelist()
    for name in names:
        if name and not is_safe_member(name):
            raise DatasetError(zip_path, f"entry {name!r}", "unsafe entry name (absolute, drive or '..' "
                                                            "component); refusing the archive")
    return names


def _open_zip(path: Path) -> zipfile.ZipFile:
    try:
        return zipfile.ZipFile(path)
    except (zipfile.BadZipFile, OSError) as exc:
        raise DatasetError(path, None, f"not a readable zip archive ({exc})") from None


def _mapping(value: Any, file: str | Path, where: str) -> Mapping[str, Any]:
    if not isinstance(value, Mapping):
        raise DatasetError(file, where, f"expected a JSON object, got {type(value).__name__}")
    return value


def _size(meta: Any, file: str | Path, where: str) -> tuple[int, int]:
    meta = _mapping(meta, file, where)
    out = []
    for key in ("width", "height"):
        v = meta.get(key)
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) or v != int(v) or v <= 1:
            raise DatasetError(file, f"{where}.{key}", f"image {key} must be an integer > 1, got {v!r}")
        out.append(int(v))
    return out[0], out[1]


def _v3_lines(item: Mapping[str, Any], width: int, height: int, file: str | Path, where: str) -> dict[str, Any]:
    lines = item.get("lines", [])
    if not isinstance(lines, list):
        raise DatasetError(file, f"{where}.lines", "expected a list of {class, points}")
    try:
        return lines_to_json_lists(from_soccernet_v3(lines, width, height))
    except AnnotationError as exc:
        raise DatasetError(file, f"{where}.{exc}", "invalid field line") from None


def _v3_ball(item: Mapping[str, Any], width: int, height: int, file: str | Path, where: str) -> list[float] | None:
    boxes = item.get("bboxes", [])
    if not isinstance(boxes, list):
        raise DatasetError(file, f"{where}.bboxes", "expected a list of boxes")
    for i, b in enumerate(boxes):
        if isinstance(b, Mapping) and b.get("class") == "Ball":
            pts = b.get("points")
            if not isinstance(pts, Mapping):
                raise DatasetError(file, f"{where}.bboxes[{i}].points", "expected {x1, y1, x2, y2}")
            try:
                return check_box([pts.get(k) for k in ("x1", "y1", "x2", "y2")], width, height)
            except LabelError as exc:
                raise DatasetError(file, f"{where}.bboxes[{i}] (Ball)", str(exc)) from None
    return None


class _Images:
    """Where a game's frame images are: ``Frames-v3.zip`` (members), a folder, or nowhere."""

    def __init__(self, game_dir: Path) -> None:
        self.zip_path: Path | None = None
        self.members: set[str] = set()
        self.folders: list[Path] = []
        zp = game_dir / V3_FRAMES_ZIP
        if zp.is_file():
            with _open_zip(zp) as zf:
                self.members = set(_safe_names(zf, zp))
            self.zip_path = zp.resolve()
        for folder in (game_dir / "Frames-v3", game_dir):
            if folder.is_dir():
                self.folders.append(folder.resolve())

    def locate(self, name: str) -> dict[str, str | None]:
        if self.zip_path is not None and name in self.members:
            return {"image_zip": str(self.zip_path), "image_member": name}
        if "/" not in name and "\\" not in name and ".." not in name:
            for folder in self.folders:
                if (folder / name).is_file():
                    return {"image_path": str(folder / name)}
        return {}


def _game_key(game_dir: Path) -> tuple[str, str, str]:
    parts = game_dir.resolve().parts
    if len(parts) < 4:
        raise DatasetError(game_dir, None, "a game folder must sit at <league>/<season>/<game>")
    return parts[-3], parts[-2], parts[-1]


def _find(root: Path, filename: str) -> list[Path]:
    if not root.exists():
        raise DatasetError(root, None, "no such file or folder")
    if root.is_file():
        if root.name != filename:
            raise DatasetError(root, None, f"expected a folder or a {filename} file")
        return [root]
    found = sorted(root.rglob(filename))
    if not found:
        raise DatasetError(root, None, f"no {filename} found under this folder")
    return found


# ----- SoccerNet-v3 -------------------------------------------------------------------------------
def _v3_frame(file: Path, section: str, name: str, item: Any, role: FrameRole, images: _Images) -> FrameRecord:
    where = f"{section}[{name!r}]"
    item = _mapping(item, file, where)
    width, height = _size(item.get("imageMetadata"), file, f"{where}.imageMetadata")
    return FrameRecord(
        name=name, role=role, width=width, height=height,
        lines=_v3_lines(item, width, height, file, where),
        ball_box=_v3_ball(item, width, height, file, where),
        **images.locate(name),
    )


FrameReader = Callable[[Path, str, str, Any, FrameRole, "_Images"], FrameRecord]


def _v3_systems(file: Path, data: Any, images: _Images, frame_reader: FrameReader = _v3_frame) -> list[SystemRecord]:
    """Systems of a SoccerNet-v3(D) labels document: each action and its ``linked_replays``, each
    frame read by ``frame_reader(file, section, name, item, role, images)``."""
    data = _mapping(data, file, "top level")
    actions = _mapping(data.get("actions"), file, "actions")
    replays = _mapping(data.get("replays", {}), file, "replays")
    systems = []
    for aname, action in actions.items():
        action = _mapping(action, file, f"actions[{aname!r}]")
        frames = [frame_reader(file, "actions", aname, action, FrameRole.ACTION, images)]
        linked = action.get("linked_replays", [])
        if not isinstance(linked, list):
            raise DatasetError(file, f"actions[{aname!r}].linked_replays", "expected a list of replay names")
        for rname in linked:
            if not isinstance(rname, str) or rname not in replays:
                raise DatasetError(file, f"actions[{aname!r}].linked_replays",
                                   f"replay {rname!r} is not in 'replays'")
            frames.append(frame_reader(file, "replays", rname, replays[rname], FrameRole.REPLAY, images))
        names = [f.name for f in frames]
        if len(set(names)) != len(names):
            raise DatasetError(file, f"actions[{aname!r}].linked_replays", f"repeated frame names {names}")
        systems.append(SystemRecord(name=aname, kind=SystemKind.SOCCERNET_V3, frames=frames))
    return systems


def read_soccernet_v3(path: str | Path) -> list[GameRecord]:
    """Read and validate a SoccerNet-v3 tree (``<league>/<season>/<game>/Labels-v3.json``).

    ``path`` may be the tree's root, any folder inside it, or one ``Labels-v3.json``. A system is an
    action and its ``linked_replays``; the ball is the box of class "Ball". Images come from
    ``Frames-v3.zip`` beside the labels (members, never extracted) or a folder of frames
    (``Frames-v3/`` or the game folder itself).

    Raises:
        DatasetError: naming the file and field (truncated JSON, unknown line class, NaN or
            out-of-image ball box, unsafe zip entry, unknown linked replay, bad image size, ...).
    """
    games = []
    for labels in _find(Path(path), V3_LABELS):
        league, season, match = _game_key(labels.parent)
        systems = _v3_systems(labels, _load_json_file(labels), _Images(labels.parent))
        games.append(GameRecord(league, season, match, str(labels.parent.resolve()), systems))
    return games


# ----- SoccerNet-calibration ----------------------------------------------------------------------
def _image_size(raw: bytes, where: str) -> tuple[int, int]:
    import cv2

    img = cv2.imdecode(np.frombuffer(raw, np.uint8), cv2.IMREAD_UNCHANGED)
    if img is None:
        raise DatasetError(where, None, "cannot decode the image to read its size")
    return int(img.shape[1]), int(img.shape[0])


def read_sn_calibration(path: str | Path, width: int | None = None, height: int | None = None) -> GameRecord:
    """Read and validate a SoccerNet-calibration folder or zip of per-frame JSON (normalised points).

    Every ``<stem>.json`` (``match_info.json`` excepted) is one frame and one single-view system
    named ``<stem>``. Image size: ``width`` and ``height`` when given, else read from the image
    ``<stem>.jpg``/``.png`` beside the JSON (in the folder or the zip), which also becomes the
    frame's image source. Normalised points become pixels as ``x (W - 1), y (H - 1)``.

    The game is ``sn-calibration / <parent folder name> / <folder or zip stem>``.

    Raises:
        DatasetError: naming the file (``archive.zip!member`` inside zips) and the field.
    """
    root = Path(path)
    if (width is None) != (height is None):
        raise DatasetError(root, "--width/--height", "give both or neither")
    if width is not None and (width <= 1 or height <= 1):  # type: ignore[operator]
        raise DatasetError(root, "--width/--height", f"must be > 1, got {width}x{height}")
    systems = []
    for stem, where, raw, image in _sn_calibration_entries(root):
        data = _load_json_bytes(raw, where)
        if width is not None:
            w, h, img_src = int(width), int(height), image[1] if image else {}  # type: ignore[arg-type]
        elif image is not None:
            (w, h), img_src = _image_size(image[0](), image[2]), image[1]
        else:
            raise DatasetError(where, None, "image size unknown: pass --width and --height or put the image "
                                            f"{stem}.jpg beside it")
        try:
            lines = lines_to_json_lists(from_soccernet_calibration(data, w, h))
        except AnnotationError as exc:
            raise DatasetError(where, str(exc), "invalid field line") from None
        frame = FrameRecord(name=f"{stem}.json", role=FrameRole.CAMERA, width=w, height=h, lines=lines, **img_src)
        systems.append(SystemRecord(name=stem, kind=SystemKind.SINGLE_VIEW, frames=[frame]))
    if not systems:
        raise DatasetError(root, None, "no per-frame .json files found")
    resolved = root.resolve()
    match = resolved.stem if resolved.is_file() else resolved.name
    return GameRecord(SN_CALIBRATION_LEAGUE, resolved.parent.name, match, str(resolved), systems)


def _natural(name: str) -> tuple:
    stem = PurePosixPath(name).stem
    return (0, int(stem), name) if stem.isdigit() else (1, 0, name)


def _sn_calibration_entries(root: Path) -> Iterator[tuple[str, str, bytes, Any]]:
    """(stem, where, json bytes, (image bytes loader, image source, where) | None) per frame."""
    if not root.exists():
        raise DatasetError(root, None, "no such file or folder")
    if root.is_file():
        with _open_zip(root) as zf:
            names = _safe_names(zf, root)
            by_stem = {PurePosixPath(n).with_suffix("").as_posix(): n for n in names
                       if n.lower().endswith(_IMAGE_SUFFIXES)}
            jsons = [n for n in names if n.endswith(".json") and PurePosixPath(n).name not in _SN_CALIBRATION_SKIP
                     and not PurePosixPath(n).name.startswith("camera_")]
            for n in sorted(jsons, key=_natural):
                key = PurePosixPath(n).with_suffix("").as_posix()
                img = by_stem.get(key)
                image = None
                if img is not None:
                    image = ((lambda m=img: zf.read(m)), {"image_zip": str(root.resolve()), "image_member": img},
                             f"{root}!{img}")
                yield PurePosixPath(n).stem, f"{root}!{n}", zf.read(n), image
        return
    jsons = [p for p in root.glob("*.json") if p.name not in _SN_CALIBRATION_SKIP and not p.name.startswith("camera_")]
    for p in sorted(jsons, key=lambda q: _natural(q.name)):
        image = None
        for suffix in _IMAGE_SUFFIXES:
            img = p.with_suffix(suffix)
            if img.is_file():
                image = ((lambda q=img: q.read_bytes()), {"image_path": str(img.resolve())}, str(img))
                break
        yield p.stem, str(p), p.read_bytes(), image


# ----- SoccerNet-v3D (what app.services.exporting writes) -----------------------------------------
def _cell_json(value: str | None, file: Path, where: str) -> Any:
    """A CSV cell holding JSON (or a Python literal); empty, "nan" and "None" mean absent."""
    if value is None:
        return None
    text = value.strip()
    if text in ("", "nan", "NaN", "None", "null"):
        return None
    try:
        return json.loads(text)
    except json.JSONDecodeError:
        try:
            return ast.literal_eval(text)
        except (ValueError, SyntaxError):
            raise DatasetError(file, where, f"cannot parse {text[:60]!r}") from None


def _cell_bool(value: str | None, file: Path, where: str) -> bool:
    text = (value or "").strip().lower()
    if text in ("true", "1", "yes"):
        return True
    if text in ("false", "0", "no", ""):
        return False
    raise DatasetError(file, where, f"expected a boolean, got {value!r}")


def _read_v3d_csv(csv_path: Path) -> dict[tuple[str, str, str, str], dict[str, Any]]:
    """Rows of ``SNv3D.csv`` keyed by (league, season, match, frame name)."""
    try:
        text = csv_path.read_text(encoding="utf-8")
    except OSError as exc:
        raise DatasetError(csv_path, None, f"cannot read: {exc.strerror}") from None
    reader = csv.DictReader(text.splitlines())
    required = {"league", "season", "match", "main_action", "action", "replay", "is_ball", "ball_bbox"}
    missing = required - set(reader.fieldnames or ())
    if missing:
        raise DatasetError(csv_path, "header", f"missing column(s) {sorted(missing)}")
    rows = {}
    for i, row in enumerate(reader, start=2):
        where = f"line {i}"
        is_action = _cell_bool(row["action"], csv_path, f"{where}.action")
        name = row["main_action"] if is_action else row["replay"]
        if not name:
            raise DatasetError(csv_path, f"{where}.{'main_action' if is_action else 'replay'}", "empty frame name")
        rows[(row["league"], row["season"], row["match"], name)] = {"row": row, "where": where}
    return rows


def _v3d_calibration(item: Mapping[str, Any], file: Path, where: str) -> ImportedCalibration:
    cam = item.get("calibration")
    if cam is not None:
        try:
            Camera.from_soccernet(_mapping(cam, file, f"{where}.calibration"))
        except ValueError as exc:
            raise DatasetError(file, f"{where}.calibration", str(exc)) from None
    jac_in = item.get("JaC") or {}
    jac_in = _mapping(jac_in, file, f"{where}.JaC")
    jac = []
    for g in ("JaC@0.005", "JaC@0.01", "JaC@0.02"):
        v = jac_in.get(g)
        if v is not None and (isinstance(v, bool) or not isinstance(v, (int, float)) or not 0 <= v <= 1):
            raise DatasetError(file, f"{where}.JaC.{g}", f"expected a number in [0, 1] or null, got {v!r}")
        jac.append(None if v is None else float(v))
    extra = _mapping(item.get("v3d", {}), file, f"{where}.v3d")
    status = CalibrationStatus.CALIBRATED if cam is not None else CalibrationStatus.REFUSED
    reason = extra.get("reason") if cam is None else None
    return ImportedCalibration(CalibrationFields(
        status=status, camera=dict(cam) if cam is not None else None, jac=tuple(jac),  # type: ignore[arg-type]
        residuals_px=dict(extra.get("residuals_px") or {}), flags=list(extra.get("flags") or []),
        reason=reason if cam is None else None,
    ))


def _exported_image(image: Any, file: Path, where: str) -> dict[str, str]:
    """The image source an export recorded for a frame, when that file still exists."""
    if not image:
        return {}
    image = _mapping(image, file, where)
    zip_path, member, path = image.get("zip"), image.get("member"), image.get("path")
    if isinstance(zip_path, str) and isinstance(member, str):
        parts = PurePosixPath(member.replace("\\", "/")).parts
        if member.startswith(("/", "\\")) or ".." in parts:
            raise DatasetError(file, f"{where}.member", f"unsafe zip member name {member!r}")
        return {"image_zip": zip_path, "image_member": member} if Path(zip_path).is_file() else {}
    if isinstance(path, str) and Path(path).is_file():
        return {"image_path": path}
    return {}


def _v3d_ball(row: Mapping[str, str], csv_path: Path, where: str, width: int, height: int) -> tuple[
        list[float] | None, list[float] | None, tuple[BallKind | None, list[float] | None, list[float] | None] | None]:
    """(box, point, original) of one ``SNv3D.csv`` row; original is None when the columns are absent."""
    box = point = original = None
    if _cell_bool(row.get("is_ball"), csv_path, f"{where}.is_ball"):
        raw_box = _cell_json(row.get("ball_bbox"), csv_path, f"{where}.ball_bbox")
        raw_point = _cell_json(row.get("ball_point"), csv_path, f"{where}.ball_point")
        if raw_box is not None:
            box = check_box(raw_box, width, height)
        elif raw_point is not None:
            point = check_point(raw_point, width, height)
        else:
            raise DatasetError(csv_path, f"{where}.ball_bbox", "is_ball is true but no box or point")
    if "original_ball_bbox" in row or "original_ball_point" in row:
        ob = _cell_json(row.get("original_ball_bbox"), csv_path, f"{where}.original_ball_bbox")
        op = _cell_json(row.get("original_ball_point"), csv_path, f"{where}.original_ball_point")
        ob = check_box(ob, width, height) if ob is not None else None
        op = check_point(op, width, height) if op is not None else None
        original = (BallKind.BOX if ob is not None else BallKind.POINT if op is not None else None, ob, op)
    return box, point, original


def _v3d_frame(file: Path, section: str, name: str, item: Any, role: FrameRole, images: _Images, *,
               rows: Mapping[tuple[str, str, str, str], dict[str, Any]], csv_path: Path,
               game: tuple[str, str, str]) -> FrameRecord:
    """One frame of a ``Labels-v3D.json`` with its ``SNv3D.csv`` row (a :data:`FrameReader`)."""
    where = f"{section}[{name!r}]"
    item = _mapping(item, file, where)
    width, height = _size(item.get("imageMetadata"), file, f"{where}.imageMetadata")
    if item["imageMetadata"].get("imageType") == FrameRole.CAMERA.value:
        role = FrameRole.CAMERA
    entry = rows.get((*game, name))
    if entry is None:
        raise DatasetError(csv_path, None, f"no row for {'/'.join(game)} frame {name!r} of {file}")
    try:
        box, point, original = _v3d_ball(entry["row"], csv_path, entry["where"], width, height)
    except LabelError as exc:
        raise DatasetError(csv_path, f"{entry['where']} ({name})", str(exc)) from None
    extra = _mapping(item.get("v3d", {}), file, f"{where}.v3d")
    original_lines = None
    if extra.get("original_lines") is not None:
        original_lines = _v3_lines({"lines": extra["original_lines"]}, width, height, file, f"{where}.v3d.original")
    return FrameRecord(
        name=name, role=role, width=width, height=height, lines=_v3_lines(item, width, height, file, where),
        ball_box=box, ball_point=point, calibration=_v3d_calibration(item, file, where),
        original_lines=original_lines, original_ball=original,
        **(images.locate(name) or _exported_image(extra.get("image"), file, f"{where}.v3d.image")),
    )


def read_soccernet_v3d(path: str | Path) -> list[GameRecord]:
    """Read and validate a SoccerNet-v3D tree: ``Labels-v3D.json`` per game and ``SNv3D.csv`` at the
    root (``path``), as :func:`app.services.exporting.export_soccernet_v3d` writes them.

    Calibrations (camera, JaC) come from the JSON and are kept as they are; field lines from the
    JSON; ball labels from the CSV (``ball_bbox``; ``ball_point`` for point labels). Images are found
    as for SoccerNet-v3 (``Frames-v3.zip`` or a folder beside the labels).

    Raises:
        DatasetError: naming the file and field; also when the CSV lacks a row for a frame.
    """
    root = Path(path)
    if not root.is_dir():
        raise DatasetError(root, None, "expected the folder holding SNv3D.csv")
    csv_path = root / V3D_CSV
    if not csv_path.is_file():
        raise DatasetError(csv_path, None, "missing: a SoccerNet-v3D tree has SNv3D.csv at its root")
    rows = _read_v3d_csv(csv_path)
    games = []
    for labels in _find(root, V3D_LABELS):
        league, season, match = _game_key(labels.parent)

        data = _load_json_file(labels)
        reader = partial(_v3d_frame, rows=rows, csv_path=csv_path, game=(league, season, match))
        systems = _v3_systems(labels, data, _Images(labels.parent), reader)
        meta = _mapping(_mapping(data, labels, "top level").get("GameMetadata", {}), labels, "GameMetadata")
        reviews = _mapping(meta.get("v3d_reviews") or {}, labels, "GameMetadata.v3d_reviews")
        names = _mapping(meta.get("v3d_systems") or {}, labels, "GameMetadata.v3d_systems")
        out = []
        for s in systems:
            kind = SystemKind.SINGLE_VIEW if s.frames[0].role is FrameRole.CAMERA else SystemKind.SOCCERNET_V3
            name = names.get(s.name, s.name)
            if not isinstance(name, str) or not name:
                raise DatasetError(labels, f"GameMetadata.v3d_systems[{s.name!r}]", f"expected a name, got {name!r}")
            status = reviews.get(name)
            try:
                review = ReviewStatus(status) if status is not None else None
            except ValueError:
                raise DatasetError(labels, f"GameMetadata.v3d_reviews[{name!r}]", f"unknown status {status!r}") from None
            out.append(SystemRecord(name, kind, s.frames, review))
        games.append(GameRecord(league, season, match, str(labels.parent.resolve()), out))
    return games
