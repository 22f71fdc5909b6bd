"""SoccerNet-v3D exports (``Labels-v3D.json`` per game and ``SNv3D.csv`` at the root, as
:mod:`app.services.transfer.exporting` writes them) -> validated records; no database.

Calibrations and field lines come from the JSON, ball labels from the CSV; the layout is SoccerNet-v3's
(:mod:`app.datasets.soccernet_v3`). Every problem raises :class:`~app.core.errors.DatasetError`
naming the file and the field.

A ``Labels-v3D.json`` is the imported ``Labels-v3.json`` with v3d's work added: each frame's entry keeps every
key of the release, its ``lines`` and the "Ball" entry of its ``bboxes`` are the curated (current) ones, and
v3d's keys (:data:`V3D_FRAME_KEYS`, :data:`V3D_IMAGE_KEYS`, :data:`V3D_GAME_KEYS`) hold the rest, the imported
ball entry and field lines under ``v3d.original_ball`` / ``v3d.original_lines`` where they were edited.
:func:`curated_entry` makes an entry from what is stored and :func:`released_entry` gives the release back.
"""
from __future__ import annotations

import ast
import csv
import json
from datetime import datetime, timezone
from functools import partial
from pathlib import Path
from typing import Any, Mapping

from app.core.errors import DatasetError, EntryError
from app.datasets.csv_cells import read_cell
from app.datasets.files import (
    MAX_IMAGE_BYTES,
    MAX_IMAGE_PIXELS,
    dataset_root,
    file_image_header,
    image_size_field,
    inside_dataset,
    is_safe_member,
    json_problem,
    load_json_file,
    mapping,
    member_image_header,
    open_zip,
    safe_names,
)
from app.datasets.labels import LabelError, check_box, check_point
from app.datasets.records import CalibrationFields, FrameRecord, GameRecord, ImportedCalibration, SystemRecord
from app.datasets.soccernet_v3 import (
    BALL_CLASS,
    LINE_ORDER_KEY,
    FrameImages,
    ball_index,
    find_labels,
    flat_lines,
    game_key,
    game_release,
    ordered_lines,
    release_entry,
    v3_lines,
    v3_players,
    v3_systems,
)
from app.db.models import BallKind, CalibrationStatus, FrameRole, ReviewStatus, SystemKind
from app.geometry.calibration.uncertainty import CalibrationUncertainty
from app.geometry.camera import Camera
from app.geometry.jac import JAC_GAMMAS

V3D_LABELS = "Labels-v3D.json"
V3D_CSV = "SNv3D.csv"
#: The format's JaC keys (``Labels-v3D.json`` ``JaC`` object and ``SNv3D.csv`` columns), one per stored gamma.
JAC_KEYS: tuple[str, ...] = tuple(f"JaC@{g:g}" for g in JAC_GAMMAS)
#: Keys v3d adds to a frame's entry, to its ``imageMetadata`` and to ``GameMetadata``: the rest is the release's.
V3D_FRAME_KEYS = ("calibration", "JaC", "v3d")
V3D_IMAGE_KEYS = ("calibrated_replays",)
V3D_GAME_KEYS = ("reconstructions", "v3d_reviews", "v3d_systems", "v3d_as_of")
_BOX_KEYS = ("x1", "y1", "x2", "y2")


def ball_entry(box: list[float], like: Mapping[str, Any] | None = None) -> dict[str, Any]:
    """A ``bboxes`` entry of the ball with ``points`` ``{x1, y1, x2, y2}`` = ``box`` (pixels), its other keys those
    of ``like`` (default: class "Ball", ID null, as SoccerNet-v3 writes a ball).

    >>> ball_entry([1.0, 2.0, 3.0, 4.0])
    {'class': 'Ball', 'ID': None, 'points': {'x1': 1.0, 'y1': 2.0, 'x2': 3.0, 'y2': 4.0}}
    """
    return {**(like or {"class": BALL_CLASS, "ID": None}), "points": dict(zip(_BOX_KEYS, box, strict=False))}


def _with_ball(bboxes: list[Any], entry: Mapping[str, Any] | None) -> list[Any]:
    """``bboxes`` with its first "Ball" entry replaced by ``entry`` (removed when None); ``entry`` put first
    when there is no ball entry."""
    out = list(bboxes)
    i = ball_index(out)
    if entry is None:
        if i is not None:
            del out[i]
    elif i is None:
        out.insert(0, dict(entry))
    else:
        out[i] = dict(entry)
    return out


def curated_entry(release: Mapping[str, Any] | None, lines: Mapping[str, Any],
                  original_lines: Mapping[str, Any] | None, ball_box: list[float] | None,
                  original_box: list[float] | None) -> tuple[dict[str, Any], dict[str, Any] | None, Any]:
    """A frame's ``Labels-v3D.json`` entry before v3d's own keys: the release's entry (``frames.release``, every
    key; ``{}`` without one) with the curated field lines and ball box.

    Args:
        release: the frame's entry as imported (``app.datasets.soccernet_v3.release_entry``), or None.
        lines: the current field lines as stored (``{class: [[[x, y], ...], ...]}``, pixels).
        original_lines: the imported ones, as stored, when the lines were edited; None when not (the entry then
            carries the lines as they came, in their order).
        ball_box: the current ball box ``[x1, y1, x2, y2]`` px, None without one (a removed label or a point):
            the "Ball" entry of ``bboxes`` is set to it (its points as imported while they equal it), removed
            when None, added first when the release had none.
        original_box: the imported ball box, used when the release has no ball entry.

    Returns:
        ``(entry, original ball entry or None, original lines or None when unedited)``, the last two for
        ``v3d.original_ball`` / ``v3d.original_lines`` (SoccerNet-v3 ``[{class, points}]``).
    """
    entry = dict(release or {})
    as_imported = entry.pop("lines", None)
    order = entry.pop(LINE_ORDER_KEY, None)

    def imported(stored: Mapping[str, Any]) -> Any:
        return as_imported if as_imported is not None else ordered_lines(stored, order)

    if original_lines is None:
        entry["lines"], kept_lines = imported(lines), None
    else:
        entry["lines"], kept_lines = flat_lines(lines), imported(original_lines)
    bboxes = entry.get("bboxes")
    bboxes = list(bboxes) if isinstance(bboxes, list) else []
    i = ball_index(bboxes)
    original = bboxes[i] if i is not None else (ball_entry(original_box) if original_box is not None else None)
    if ball_box is None:
        bboxes = _with_ball(bboxes, None)
    elif i is None or [bboxes[i].get("points", {}).get(k) for k in _BOX_KEYS] != list(ball_box):
        bboxes = _with_ball(bboxes, ball_entry(ball_box, bboxes[i] if i is not None else None))
    entry["bboxes"] = bboxes
    return entry, original, kept_lines


def released_entry(item: Mapping[str, Any], extra: Mapping[str, Any], original_box: list[float] | None,
                   lines: Mapping[str, Any], file: Path, where: str) -> dict[str, Any]:
    """The release's entry of a frame (``FrameRecord.release``) from its ``Labels-v3D.json`` entry ``item``: v3d's
    keys removed, the imported ball entry (``v3d.original_ball``; from ``original_box`` in exports without it) in
    place of the curated one, the imported field lines (``v3d.original_lines`` where edited) kept only when the
    stored ``lines`` (the imported ones, pixels) do not give them back (:func:`release_entry`).

    Raises:
        DatasetError: ``v3d.original_ball`` is neither null nor a "Ball" entry with points, or its points are not
            the CSV's ``original_ball_bbox`` (``original_box``).
    """
    entry = {k: v for k, v in item.items() if k not in V3D_FRAME_KEYS}
    meta = entry.get("imageMetadata")
    if isinstance(meta, Mapping):
        entry["imageMetadata"] = {k: v for k, v in meta.items() if k not in V3D_IMAGE_KEYS}
    if "original_ball" in extra:
        original = extra["original_ball"]
        field = f"{where}.v3d.original_ball"
        if original is not None and not (isinstance(original, Mapping) and original.get("class") == BALL_CLASS
                                         and isinstance(original.get("points"), Mapping)):
            raise DatasetError(file, field, "expected null or a bboxes entry of class 'Ball' with its points")
        points = None if original is None else [original["points"].get(k) for k in _BOX_KEYS]
        if points is not None and original_box is not None and points != list(original_box):
            raise DatasetError(file, field,
                               f"points {points} are not the CSV's original_ball_bbox {list(original_box)}")
    else:
        original = ball_entry(original_box) if original_box is not None else None
    if isinstance(entry.get("bboxes"), list) or original is not None:
        bboxes = entry.get("bboxes")
        entry["bboxes"] = _with_ball(bboxes if isinstance(bboxes, list) else [], original)
    if extra.get("original_lines") is not None:
        entry["lines"] = extra["original_lines"]
    return release_entry(entry, lines)


def _cell_json(value: str | None, file: Path, where: str) -> Any:
    """A CSV cell holding JSON (or a Python literal); empty, "nan" and "None" mean absent."""
    if value is None:
        return None
    text = value.strip()
    if text in ("", "nan", "NaN", "None", "null"):
        return None
    try:
        return json.loads(text)
    except ValueError:  # JSONDecodeError, or an integer too long: a Python literal, or refused below
        pass
    except RecursionError:
        raise DatasetError(file, where, f"cannot parse {text[:60]!r}: {json_problem(RecursionError())}") from None
    try:
        return ast.literal_eval(text)
    except (ValueError, SyntaxError, RecursionError, MemoryError) as exc:
        said = json_problem(exc) if isinstance(exc, (ValueError, RecursionError)) else None
        raise DatasetError(file, where, f"cannot parse {text[:60]!r}" + (f": {said}" if said else "")) from None


def _cell_bool(value: str | None, file: Path, where: str) -> bool:
    text = (value or "").strip().lower()
    if text in ("true", "1", "yes"):
        return True
    if text in ("false", "0", "no", ""):
        return False
    raise DatasetError(file, where, f"expected a boolean, got {value!r}")


def _read_v3d_csv(csv_path: Path) -> dict[tuple[str, str, str, str], dict[str, Any]]:
    """Rows of ``SNv3D.csv`` keyed by (league, season, match, frame name), each cell as v3d's export was given it
    (``app.datasets.csv_cells.read_cell``: the escape of a formula-like cell undone)."""
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
    for i, raw in enumerate(reader, start=2):
        row = {k: read_cell(v) if isinstance(v, str) else v for k, v in raw.items()}
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
    uncertainty = extra.get("uncertainty")  # the line fit's standard deviations (what the triangulation weighs)
    if uncertainty is not None:
        try:
            CalibrationUncertainty.from_json(mapping(uncertainty, file, f"{where}.v3d.uncertainty"))
        except (KeyError, TypeError, ValueError) as exc:
            raise DatasetError(file, f"{where}.v3d.uncertainty", f"malformed standard deviations ({exc})") from None
    return ImportedCalibration(CalibrationFields(
        status=status, camera=dict(cam) if cam is not None else None, jac=tuple(jac),  # type: ignore[arg-type]  # one JaC per JAC_KEYS, three
        residuals_px=dict(extra.get("residuals_px") or {}), flags=list(extra.get("flags") or []),
        reason=reason if cam is None else None,
        uncertainty=dict(uncertainty) if cam is not None and uncertainty else None,
    ))


def _exported_image(image: Any, file: Path, where: str, images: FrameImages) -> dict[str, str]:
    """The image source recorded in a frame's ``v3d.image`` (``zip`` + ``member`` or ``path``, relative
    to the game's folder), when that file exists; it must resolve inside the dataset's folder ``root``.

    Raises:
        DatasetError: an unsafe member name, or a zip or path leading out of the dataset (an absolute
            path such as ``/etc/passwd``, ``..``, a link), naming the field.
    """
    if not image:
        return {}
    root = images.root
    image = mapping(image, file, where)
    zip_path, member, path = image.get("zip"), image.get("member"), image.get("path")
    if isinstance(zip_path, str) and isinstance(member, str):
        if not is_safe_member(member):
            raise DatasetError(file, f"{where}.member", f"unsafe zip member name {member!r}")
        resolved = inside_dataset(root, file.parent / zip_path, f"{where}.zip")
        if not resolved.is_file():
            return {}
        with open_zip(resolved) as zf:
            if member not in safe_names(zf, resolved):
                return {}
            header = member_image_header(zf, member, f"{zip_path}!{member}", images.max_pixels,
                                         images.max_bytes)
        return {"image_root": str(root), "image_zip": resolved.relative_to(root).as_posix(),
                "image_member": member, "image_type": header.type}
    if isinstance(path, str):
        resolved = inside_dataset(root, file.parent / path, f"{where}.path")
        if not resolved.is_file():
            return {}
        header = file_image_header(resolved, path, images.max_pixels, images.max_bytes)
        return {"image_root": str(root), "image_path": resolved.relative_to(root).as_posix(), "image_type": header.type}
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
        raise EntryError(csv_path, f"{entry['where']} ({name})", str(exc)) from None
    extra = mapping(item.get("v3d") or {}, file, f"{where}.v3d")
    lines = v3_lines(item, width, height, file, where)
    original_lines = None
    if extra.get("original_lines") is not None:
        original_lines = v3_lines({"lines": extra["original_lines"]}, width, height, file, f"{where}.v3d.original")
    # checked even when the tree holds the frame itself: a reference leading out refuses the dataset
    exported = _exported_image(extra.get("image"), file, f"{where}.v3d.image", images)
    original_box = (original[1] if original is not None else box)
    release = released_entry(item, extra, original_box, original_lines if original_lines is not None else lines,
                             file, where)
    return FrameRecord(
        name=name, role=role, width=width, height=height, lines=lines,
        ball_box=box, ball_point=point, calibration=_v3d_calibration(item, file, where),
        original_lines=original_lines, original_ball=original, release=release, players=v3_players(item)[0],
        **(images.locate(name) or exported),
    )


def read_soccernet_v3d(path: str | Path, max_pixels: int = MAX_IMAGE_PIXELS,
                       max_image_bytes: int = MAX_IMAGE_BYTES) -> list[GameRecord]:
    """Read and validate a SoccerNet-v3D tree: ``Labels-v3D.json`` per game and ``SNv3D.csv`` at the
    root (``path``), as :func:`app.services.transfer.exporting.export_soccernet_v3d` writes them.

    Calibrations (camera, JaC) come from the JSON and are kept as they are; field lines from the
    JSON; ball labels from the CSV (``ball_bbox``; ``ball_point`` for point labels). Images are found
    as for SoccerNet-v3 (``Frames-v3.zip`` or a folder beside the labels), else where a frame's
    ``v3d.image`` says, relative to its game's folder. Every file read resolves inside ``path``
    (:func:`app.datasets.files.inside_dataset`); each image is a PNG or JPEG of at most ``max_pixels``
    pixels, read from its header.

    Raises:
        DatasetError: naming the file and field; also when the CSV lacks a row for a frame.
    """
    root = Path(path)
    if not root.is_dir():
        raise DatasetError(root, None, "expected the folder holding SNv3D.csv")
    top = dataset_root(root)
    csv_path = root / V3D_CSV
    if not csv_path.is_file():
        raise DatasetError(csv_path, None, "missing: a SoccerNet-v3D tree has SNv3D.csv at its root")
    rows = _read_v3d_csv(inside_dataset(top, csv_path, V3D_CSV))
    games = []
    for labels in find_labels(root, V3D_LABELS):
        league, season, match = game_key(labels.parent)

        data = load_json_file(inside_dataset(top, labels, V3D_LABELS))
        reader = partial(_v3d_frame, rows=rows, csv_path=csv_path, game=(league, season, match))
        with FrameImages(labels.parent, top, max_pixels, max_image_bytes) as images:
            systems = v3_systems(labels, data, images, reader)
        meta = mapping(mapping(data, labels, "top level").get("GameMetadata", {}), labels, "GameMetadata")
        release = game_release(data, systems)
        if "GameMetadata" in release:
            release["GameMetadata"] = {k: v for k, v in release["GameMetadata"].items() if k not in V3D_GAME_KEYS}
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
                raise DatasetError(labels, f"GameMetadata.v3d_reviews[{name!r}]",
                                   f"unknown status {status!r}") from None
            out.append(SystemRecord(name, kind, s.frames, review))
        games.append(GameRecord(league, season, match, str(labels.parent.resolve()), out, release,
                                as_of(meta.get("v3d_as_of"), labels)))
    return games


def as_of(value: Any, file: Path) -> datetime | None:
    """The time of the game's newest change the export holds (``GameMetadata.v3d_as_of``, ISO 8601 with its offset,
    as the export writes it) as a UTC time; None when absent.

    Raises:
        DatasetError: naming the field, for anything else (a time without its offset included).
    """
    if value is None:
        return None
    try:
        when = datetime.fromisoformat(value) if isinstance(value, str) and len(value) <= 64 else None
    except ValueError:
        when = None
    if when is None or when.tzinfo is None:
        raise DatasetError(file, "GameMetadata.v3d_as_of",
                           f"expected an ISO 8601 time with its offset, got {str(value)[:40]!r}")
    return when.astimezone(timezone.utc)
