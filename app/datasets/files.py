"""Reading the files of a dataset safely: JSON (UTF-8, errors naming the file), zip archives whose
entry names are checked before anything is read (an absolute name, a drive or a ``..`` component
refuses the archive), the ``*.json`` files of a folder or zip, image sizes. No database.

Every problem raises :class:`~app.core.errors.DatasetError` naming the file (``archive.zip!member``
inside zips) and the field, except :func:`json_files`, the lister of the offline commands, which raises
:class:`InputFileError`.
"""
from __future__ import annotations

import json
import math
import zipfile
from dataclasses import dataclass
from pathlib import Path, PurePosixPath
from typing import Any, Callable, Mapping

import numpy as np

from app.core.errors import DatasetError

#: Image files a frame may come with.
IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg")


def load_json_bytes(raw: bytes, where: str) -> Any:
    """``raw`` parsed as UTF-8 JSON; raises :class:`DatasetError` naming ``where`` (the file) otherwise."""
    try:
        return json.loads(raw.decode("utf-8"))
    except UnicodeDecodeError as exc:
        raise DatasetError(where, None, f"not UTF-8 text ({exc.reason} at byte {exc.start})") from None
    except json.JSONDecodeError as exc:
        raise DatasetError(where, None, f"invalid or truncated JSON: {exc.msg} at line {exc.lineno} "
                                        f"column {exc.colno}") from None


def load_json_file(path: Path) -> Any:
    """The JSON file ``path`` parsed; raises :class:`DatasetError` naming it when unreadable or invalid."""
    try:
        raw = path.read_bytes()
    except OSError as exc:
        raise DatasetError(path, None, f"cannot read: {exc.strerror}") from None
    return load_json_bytes(raw, str(path))


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


def safe_names(zf: zipfile.ZipFile, zip_path: Path) -> list[str]:
    """The archive's entry names; raises when one is absolute or has a ``..`` component
    (:func:`is_safe_member`, the rule the image route applies too)."""
    names = zf.namelist()
    for name in names:
        if name and not is_safe_member(name):
            raise DatasetError(zip_path, f"entry {name!r}", "unsafe entry name (absolute, drive or '..' "
                                                            "component); refusing the archive")
    return names


def open_zip(path: Path) -> zipfile.ZipFile:
    """The zip archive ``path``; raises :class:`DatasetError` naming it when it is not a readable zip."""
    try:
        return zipfile.ZipFile(path)
    except (zipfile.BadZipFile, OSError) as exc:
        raise DatasetError(path, None, f"not a readable zip archive ({exc})") from None


def mapping(value: Any, file: str | Path, where: str) -> Mapping[str, Any]:
    """``value`` when it is a JSON object; raises :class:`DatasetError` naming ``file`` and ``where`` otherwise."""
    if not isinstance(value, Mapping):
        raise DatasetError(file, where, f"expected a JSON object, got {type(value).__name__}")
    return value


def image_size_field(meta: Any, file: str | Path, where: str) -> tuple[int, int]:
    """``(width, height)`` in pixels of an ``imageMetadata`` object (integers > 1), else :class:`DatasetError`."""
    meta = mapping(meta, file, where)
    out = []
    for key in ("width", "height"):
        v = meta.get(key)
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) or v != int(v) or v <= 1:
            raise DatasetError(file, f"{where}.{key}", f"image {key} must be an integer > 1, got {v!r}")
        out.append(int(v))
    return out[0], out[1]


def decoded_image_size(raw: bytes, where: str) -> tuple[int, int]:
    """``(width, height)`` in pixels of an encoded image, by decoding it (OpenCV); raises
    :class:`DatasetError` naming ``where`` when it does not decode."""
    import cv2

    img = cv2.imdecode(np.frombuffer(raw, np.uint8), cv2.IMREAD_UNCHANGED)
    if img is None:
        raise DatasetError(where, None, "cannot decode the image to read its size")
    return int(img.shape[1]), int(img.shape[0])


# ----- the JSON files of a folder or zip (the offline commands' inputs and SoccerNet-calibration sets)
class InputFileError(Exception):
    """An input path or file of a command cannot be used; the message names the path or file."""


@dataclass(frozen=True)
class JsonFile:
    """One ``*.json`` file of a folder or zip."""

    label: str  # how to name the file in messages, e.g. "cams.zip:test/camera_1.json"
    name: str  # its path inside the folder or zip (POSIX)
    read: Callable[[], bytes]

    def load(self) -> Any:
        """The parsed JSON. Raises :class:`InputFileError` naming the file when it is not UTF-8 JSON."""
        try:
            return json.loads(self.read().decode("utf-8"))
        except (UnicodeDecodeError, json.JSONDecodeError) as exc:
            raise InputFileError(f"{self.label}: not readable JSON ({exc})") from exc


def json_files(path: Path, what: str) -> list[JsonFile]:
    """Every ``*.json`` file of a folder (recursively) or a zip (``__MACOSX/`` left out), sorted by path.

    Raises:
        InputFileError: ``path`` is missing, or neither a folder nor a zip archive (the message
            starts with ``what``, the argument's name).
    """
    if not path.exists():
        raise InputFileError(f"{what}: no such file or folder: {path}")
    if path.is_dir():
        return [JsonFile(str(p), p.relative_to(path).as_posix(), p.read_bytes)
                for p in sorted(path.rglob("*.json")) if p.is_file()]
    if zipfile.is_zipfile(path):
        archive = zipfile.ZipFile(path)
        names = sorted(n for n in archive.namelist()
                       if n.endswith(".json") and not n.endswith("/") and not n.startswith("__MACOSX/"))
        return [JsonFile(f"{path}:{n}", n, (lambda n=n: archive.read(n))) for n in names]
    raise InputFileError(f"{what}: {path} is neither a folder nor a zip archive")
