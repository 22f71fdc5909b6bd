"""SoccerNet-v3D exports (``Labels-v3D.json`` per game and ``SNv3D.csv`` at the root, as
:mod:`app.services.transfer.exporting` writes them) -> validated records; no database.

Calibrations and field lines come from the JSON, ball labels from the CSV; the layout is SoccerNet-v3's
(:mod:`app.datasets.soccernet_v3`). Every problem raises :class:`~app.core.errors.DatasetError`
naming the file and the field.
"""
from __future__ import annotations

import ast
import csv
import json
from functools import partial
from pathlib import Path, PurePosixPath
from typing import Any, Mapping

from app.datasets.files import image_size_field, load_json_file, mapping
from app.datasets.records import FrameRecord, GameRecord, ImportedCalibration, SystemRecord
from app.datasets.soccernet_v3 import FrameImages, find_labels, game_key, v3_lines, v3_systems
from app.db.models import BallKind, CalibrationStatus, FrameRole, ReviewStatus, SystemKind
from app.geometry.camera import Camera
from app.geometry.jac import JAC_GAMMAS
from app.datasets.labels import LabelError, check_box, check_point
from app.core.errors import DatasetError
from app.datasets.records import CalibrationFields

V3D_LABELS = "Labels-v3D.json"
V3D_CSV = "SNv3D.csv"
#: The format's JaC keys (``Labels-v3D.json`` ``JaC`` object and ``SNv3D.csv`` columns), one per stored gamma.
JAC_KEYS: tuple[str, ...] = tuple(f"JaC@{g:g}" for g in JAC_GAMMAS)


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
            Camera.from_soccernet(mapping(cam, file, f"{where}.calibration"))
        except ValueError as exc:
            raise DatasetError(file, f"{where}.calibration", str(exc)) from None
    jac_in = item.get("JaC") or {}
    jac_in = mapping(jac_in, file, f"{where}.JaC")
    jac = []
    for g in JAC_KEYS:
        v = jac_in.get(g)
        if v is not None and (isinstance(v, bool) or not isinstance(v, (int, float)) or not 0 <= v <= 1):
            raise DatasetError(file, f"{where}.JaC.{g}", f"expected a number in [0, 1] or null, got {v!r}")
        jac.append(None if v is None else float(v))
    extra = mapping(item.get("v3d", {}), file, f"{where}.v3d")
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
    image = mapping(image, file, where)
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


def _v3d_frame(file: Path, section: str, name: str, item: Any, role: FrameRole, images: FrameImages, *,
               rows: Mapping[tuple[str, str, str, str], dict[str, Any]], csv_path: Path,
               game: tuple[str, str, str]) -> FrameRecord:
    """One frame of a ``Labels-v3D.json`` with its ``SNv3D.csv`` row (a :data:`FrameReader`)."""
    where = f"{section}[{name!r}]"
    item = mapping(item, file, where)
    width, height = image_size_field(item.get("imageMetadata"), file, f"{where}.imageMetadata")
    if item["imageMetadata"].get("imageType") == FrameRole.CAMERA.value:
        role = FrameRole.CAMERA
    entry = rows.get((*game, name))
    if entry is None:
        raise DatasetError(csv_path, None, f"no row for {'/'.join(game)} frame {name!r} of {file}")
    try:
        box, point, original = _v3d_ball(entry["row"], csv_path, entry["where"], width, height)
    except LabelError as exc:
        raise DatasetError(csv_path, f"{entry['where']} ({name})", str(exc)) from None
    extra = mapping(item.get("v3d", {}), file, f"{where}.v3d")
    original_lines = None
    if extra.get("original_lines") is not None:
        original_lines = v3_lines({"lines": extra["original_lines"]}, width, height, file, f"{where}.v3d.original")
    return FrameRecord(
        name=name, role=role, width=width, height=height, lines=v3_lines(item, width, height, file, where),
        ball_box=box, ball_point=point, calibration=_v3d_calibration(item, file, where),
        original_lines=original_lines, original_ball=original,
        **(images.locate(name) or _exported_image(extra.get("image"), file, f"{where}.v3d.image")),
    )


def read_soccernet_v3d(path: str | Path) -> list[GameRecord]:
    """Read and validate a SoccerNet-v3D tree: ``Labels-v3D.json`` per game and ``SNv3D.csv`` at the
    root (``path``), as :func:`app.services.transfer.exporting.export_soccernet_v3d` writes them.

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
    for labels in find_labels(root, V3D_LABELS):
        league, season, match = game_key(labels.parent)

        data = load_json_file(labels)
        reader = partial(_v3d_frame, rows=rows, csv_path=csv_path, game=(league, season, match))
        systems = v3_systems(labels, data, FrameImages(labels.parent), reader)
        meta = mapping(mapping(data, labels, "top level").get("GameMetadata", {}), labels, "GameMetadata")
        reviews = mapping(meta.get("v3d_reviews") or {}, labels, "GameMetadata.v3d_reviews")
        names = mapping(meta.get("v3d_systems") or {}, labels, "GameMetadata.v3d_systems")
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
