"""SoccerNet-calibration sets (a folder or zip of per-frame JSON with normalised field-line points,
images beside them) -> validated records; no database. One lister of the set's files
(:func:`app.datasets.files.json_files`) serves the import and the offline commands (``v3d calibrate``).
"""
from __future__ import annotations

import zipfile
from pathlib import Path, PurePosixPath
from typing import Any, Iterator

from app.core.errors import DatasetError
from app.datasets.files import (
    IMAGE_SUFFIXES,
    MAX_IMAGE_BYTES,
    MAX_IMAGE_PIXELS,
    InputFileError,
    dataset_relative,
    dataset_root,
    file_image_header,
    inside_dataset,
    json_files,
    load_json_bytes,
    member_image_header,
    open_zip,
    safe_names,
)
from app.datasets.records import FrameRecord, GameRecord, SystemRecord
from app.db.models import FrameRole, SystemKind
from app.geometry.annotations import AnnotationError, from_soccernet_calibration, lines_to_json_lists

#: League given to games made from a SoccerNet-calibration folder or zip.
SN_CALIBRATION_LEAGUE = "sn-calibration"
#: The summary ``v3d calibrate`` writes beside its cameras.
CALIBRATION_SUMMARY = "calibration_summary.json"
#: Files of a set that are not frames: the set's own metadata and ``v3d calibrate``'s summary.
NOT_FRAMES = frozenset({"match_info.json", "per_match_info.json", CALIBRATION_SUMMARY})


def is_frame_file(name: str) -> bool:
    """True for a frame's annotation JSON (POSIX path inside the set), False for metadata, summaries
    and camera predictions (``camera_*.json``)."""
    base = PurePosixPath(name).name
    return base.endswith(".json") and base not in NOT_FRAMES and not base.startswith("camera_")


def frame_entries(root: Path, max_pixels: int = MAX_IMAGE_PIXELS,
                  max_bytes: int = MAX_IMAGE_BYTES) -> Iterator[tuple[str, str, bytes, Any]]:
    """``(frame name, where, JSON bytes, image)`` per frame file of a SoccerNet-calibration folder or
    zip, sub-folders included, in natural order of their paths (``where`` names the file,
    ``archive.zip!member`` in zips). A frame is named by its file's stem, as ``v3d jac`` pairs
    annotations with cameras; ``image`` is ``(reader of its header, image source fields, where)`` of
    the ``.jpg``/``.png`` of the same path, or None (the reader checks the type and the pixel limit,
    :func:`app.datasets.files.image_header`, and answers an ``ImageHeader``). The import and ``v3d calibrate`` both read
    sets through this function.

    Raises:
        DatasetError: ``root`` is missing or neither a folder nor a zip; an unsafe zip entry name;
            two frame files of one stem (in different sub-folders); a frame or image file resolving
            outside the set's folder (:func:`app.datasets.files.inside_dataset`).
    """
    if not root.exists():
        raise DatasetError(root, None, "no such file or folder")
    if not root.is_dir() and not zipfile.is_zipfile(root):
        raise DatasetError(root, None, "neither a folder nor a zip archive")
    try:
        files = [f for f in json_files(root, str(root)) if is_frame_file(f.name)]
    except InputFileError as exc:  # a JSON member too large to parse
        raise DatasetError(root, None, str(exc).removeprefix(f"{root}:")) from None
    keys = [PurePosixPath(f.name).with_suffix("") for f in files]
    if root.is_dir():
        top = dataset_root(root)
        for f in files:
            inside_dataset(top, root / f.name, "frame file")
        yield from _named(root, files, keys, _images(root, None, max_pixels, max_bytes))
        return
    with open_zip(root) as zf:
        yield from _named(root, files, keys, _images(root, zf, max_pixels, max_bytes))


def _named(root: Path, files: list[Any], keys: list[PurePosixPath], images: dict[str, Any]
           ) -> Iterator[tuple[str, str, bytes, Any]]:
    """The entries of :func:`frame_entries` from the set's frame files and their paths without suffix."""
    seen: set[str] = set()
    for f, key in sorted(zip(files, keys, strict=True), key=lambda fk: _natural(fk[0].name)):
        name = key.name
        where = f.label if root.is_dir() else f"{root}!{f.name}"
        if name in seen:
            raise DatasetError(where, None, f"two frames named {name!r}")
        seen.add(name)
        yield name, where, f.read(), images.get(key.as_posix())


def _images(root: Path, zf: zipfile.ZipFile | None, max_pixels: int, max_bytes: int) -> dict[str, Any]:
    """Path without suffix -> (loader, image source fields, where) of the images of the set (the
    folder ``root``, or the open archive ``zf`` of ``root``, whose entry names are checked first); an
    image file that resolves outside the set's folder (a link leading out) refuses the set."""
    out: dict[str, Any] = {}
    top = dataset_root(root)
    if zf is None:
        for p in sorted(root.rglob("*")):
            if p.suffix.lower() in IMAGE_SUFFIXES and p.is_file():
                rel = p.relative_to(root).with_suffix("").as_posix()
                source = {"image_root": str(top), "image_path": dataset_relative(top, p, "image")}
                out.setdefault(rel, ((lambda q=p: file_image_header(q, q, max_pixels, max_bytes)), source, str(p)))
        return out
    source_zip = {"image_root": str(top), "image_zip": dataset_relative(top, root, "path")}
    for n in safe_names(zf, root):
        if n.lower().endswith(IMAGE_SUFFIXES):
            key = PurePosixPath(n).with_suffix("").as_posix()
            out.setdefault(key, ((lambda m=n: member_image_header(zf, m, f"{root}!{m}", max_pixels,
                                                                    max_bytes)),
                                 {**source_zip, "image_member": n}, f"{root}!{n}"))
    return out


def _natural(name: str) -> tuple:
    stem = PurePosixPath(name).stem
    parent = PurePosixPath(name).parent.as_posix()
    return (parent, 0, int(stem), name) if stem.isdigit() else (parent, 1, 0, name)


def read_sn_calibration(path: str | Path, width: int | None = None, height: int | None = None,
                        max_pixels: int = MAX_IMAGE_PIXELS, max_image_bytes: int = MAX_IMAGE_BYTES) -> GameRecord:
    """Read and validate a SoccerNet-calibration folder or zip of per-frame JSON (normalised points).

    Every ``<stem>.json`` of the folder or zip, sub-folders included (:func:`frame_entries`;
    metadata, summaries and ``camera_*.json`` excepted), is one frame and one single-view system
    named ``<stem>``. Image size: ``width`` and ``height`` when given, else read from the image
    ``<stem>.jpg``/``.png`` beside the JSON (in the folder or the zip), which also becomes the
    frame's image source; every such image is checked from its header (PNG or JPEG, at most
    ``max_pixels`` pixels and ``max_image_bytes`` bytes) whether or not the size is given. Normalised points become
    pixels as ``x (W - 1), y (H - 1)``.

    The game is ``sn-calibration / <parent folder name> / <folder or zip stem>``.

    A folder holding ``cameras.json`` (v3d's cameras export, ``app.services.transfer.cameras_export``) is read as that
    export: each image size's ``<W>x<H>/ground_truth.zip`` (``<split>/<name>.json``) at the size its index names, one
    system per view named ``<name>`` (:func:`_cameras_export_systems`), so the export imports again as downloaded.

    Raises:
        DatasetError: naming the file (``archive.zip!member`` inside zips) and the field.
    """
    root = Path(path)
    if (width is None) != (height is None):
        raise DatasetError(root, "--width/--height", "give both or neither")
    if width is not None and (width <= 1 or height <= 1):  # type: ignore[operator]  # height is given when width is (checked above)
        raise DatasetError(root, "--width/--height", f"must be > 1, got {width}x{height}")
    systems = []
    if root.is_dir() and (root / CAMERAS_INDEX).is_file() and width is None:
        systems = list(_cameras_export_systems(root))
    for stem, where, raw, image in frame_entries(root, max_pixels, max_image_bytes) if not systems else ():
        data = load_json_bytes(raw, where)
        header = image[0]() if image is not None else None
        img_src = {**image[1], "image_type": header.type} if image is not None and header is not None else {}
        if width is not None:
            w, h = int(width), int(height)  # type: ignore[arg-type]  # height is given when width is (checked above)
        elif header is not None:
            w, h = header.width, header.height
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
    return GameRecord(*sn_calibration_game(root), str(root.resolve()), systems)


#: The index of v3d's cameras export (``app.services.transfer.cameras_export.INDEX``).
CAMERAS_INDEX = "cameras.json"


def _cameras_export_systems(root: Path) -> Iterator[SystemRecord]:
    """The views of v3d's cameras export at ``root`` as single-view systems: per set of ``cameras.json``
    (``{"sets": [{"width", "height", "ground_truth", ...}]}``), the members ``<split>/<name>.json`` of its
    ``ground_truth.zip`` (field lines, normalised) at the set's size, named ``<name>``; every file read resolves
    inside ``root``.

    Raises:
        DatasetError: an index that is not one, a set without a size or zip, a zip leading out of ``root``, a name
            twice, field lines that do not parse (naming the file and field).
    """
    top = dataset_root(root)
    index_path = inside_dataset(top, root / CAMERAS_INDEX, "cameras")
    index = load_json_bytes(index_path.read_bytes(), str(index_path))
    sets = index.get("sets") if isinstance(index, dict) else None
    if not isinstance(sets, list):
        raise DatasetError(index_path, "sets", "expected {\"sets\": [...]} (v3d's cameras export)")
    seen: set[str] = set()
    for i, entry in enumerate(sets):
        try:
            w, h, zip_name = int(entry["width"]), int(entry["height"]), str(entry["ground_truth"])
        except (TypeError, KeyError, ValueError) as exc:
            raise DatasetError(index_path, f"sets[{i}]", f"expected width, height and ground_truth: {exc}") from None
        if w <= 1 or h <= 1:
            raise DatasetError(index_path, f"sets[{i}]", f"image size must be > 1, got {w}x{h}")
        zpath = inside_dataset(top, root / zip_name, f"sets[{i}].ground_truth")
        for _, where, raw, _image in frame_entries(zpath):
            name = PurePosixPath(where.rsplit("!", 1)[-1]).stem
            if name in seen:
                raise DatasetError(where, None, f"two views named {name!r}")
            seen.add(name)
            try:
                lines = lines_to_json_lists(from_soccernet_calibration(load_json_bytes(raw, where), w, h))
            except AnnotationError as exc:
                raise DatasetError(where, str(exc), "invalid field line") from None
            frame = FrameRecord(name=f"{name}.json", role=FrameRole.CAMERA, width=w, height=h, lines=lines)
            yield SystemRecord(name=name, kind=SystemKind.SINGLE_VIEW, frames=[frame])


def sn_calibration_game(path: str | Path) -> tuple[str, str, str]:
    """``(league, season, match)`` of the game a SoccerNet-calibration folder or zip becomes:
    ``sn-calibration / <parent folder name> / <folder or zip stem>`` (nothing is read)."""
    resolved = Path(path).resolve()
    return SN_CALIBRATION_LEAGUE, resolved.parent.name, resolved.stem if resolved.is_file() else resolved.name
