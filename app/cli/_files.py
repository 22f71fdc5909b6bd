"""The JSON files of a folder (recursively) or a zip archive, as the offline commands (``v3d jac``,
``v3d calibrate``) read them: listed first, each read when it is used."""
from __future__ import annotations

import json
import zipfile
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable


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
