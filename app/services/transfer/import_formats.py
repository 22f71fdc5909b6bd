"""The dataset formats an import reads, as data: each format's name, the reader that imports it and the options it
takes (``width``/``height`` for a SoccerNet-calibration set without images, ``from_lines``/``flip`` for an ISSIA
folder). The import job (:mod:`app.services.jobs.work`) runs a format by its name and the API refuses an option the
format does not take, without either branching on a format. The system kinds' policies name the formats that
produce their systems (:attr:`app.services.kinds.base.KindPolicy.import_formats`); ISSIA's reader lives with the
ISSIA services, which register it on import (:mod:`app.services.issia`) as they register the kind's hooks.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable, Mapping

from sqlalchemy.orm import Session

from app.core.config import Settings
from app.services.jobs.progress import Progress
from app.services.transfer.archives import MAX_UPLOAD_SETTING
from app.services.transfer.importing import (
    ImportReport,
    import_sn_calibration,
    import_soccernet_v3,
    import_soccernet_v3d,
)

#: ``run(session, path, settings, options, progress=, actor=, source_name=)`` -> the import's report.
ImportRun = Callable[..., ImportReport]


@dataclass(frozen=True)
class ImportFormat:
    """One dataset format: its name (``v3d import <name>``, the API's ``kind``), its reader, the names of the
    options it takes from a job's ``params`` (every other format-specific option is refused for it), and the setting
    (its environment name, in MB) bounding an upload of it to ``POST /api/imports``
    (``app.services.transfer.archives.upload_limit``: never above ``V3D_MAX_UPLOAD_MB``, which bounds the route's
    body while it streams; a smaller one of a format's own is checked once the form is read, before the zip is
    unpacked)."""

    name: str
    run: ImportRun
    options: tuple[str, ...] = ()
    upload_limit: str = MAX_UPLOAD_SETTING


_FORMATS: dict[str, ImportFormat] = {}


def register_import_format(fmt: ImportFormat) -> None:
    """Make ``fmt`` importable by its name (called once per format when its module is imported)."""
    _FORMATS[fmt.name] = fmt


def import_format(name: str) -> ImportFormat:
    """The registered format ``name``.

    Raises:
        ValueError: no such format (or its services were not imported: ``app.services`` imports them all).
    """
    try:
        return _FORMATS[name]
    except KeyError:
        raise ValueError(f"unknown import kind {name!r}") from None


def registered_formats() -> Mapping[str, ImportFormat]:
    """Every registered format by name, in registration order."""
    return dict(_FORMATS)


def refused_options(name: str, given: Mapping[str, Any]) -> str | None:
    """Why ``given`` (option -> value; ``None``, ``False`` and empty mean "not given") does not suit format ``name``:
    a sentence naming the options another format takes and that format (e.g. "width and height apply to kind
    'sn-calibration' only"), or ``None`` when every given option is one ``name`` takes."""
    for other in _FORMATS.values():
        if other.name != name and any(given.get(o) not in (None, False, [], "") for o in other.options
                                      if o not in import_format(name).options):
            return f"{' and '.join(other.options)} apply to kind {other.name!r} only"
    return None


def _v3(session: Session, path: str | Path, settings: Settings, options: Mapping[str, Any],
        progress: Progress | None = None, **named: Any) -> ImportReport:
    return import_soccernet_v3(session, path, settings, progress=progress, **named)


def _v3d(session: Session, path: str | Path, settings: Settings, options: Mapping[str, Any],
         progress: Progress | None = None, **named: Any) -> ImportReport:
    return import_soccernet_v3d(session, path, settings, progress=progress, **named)


def _calibration(session: Session, path: str | Path, settings: Settings, options: Mapping[str, Any],
                 progress: Progress | None = None, **named: Any) -> ImportReport:
    return import_sn_calibration(session, path, settings, width=options.get("width"), height=options.get("height"),
                                 progress=progress, **named)


register_import_format(ImportFormat("soccernet-v3", _v3))
register_import_format(ImportFormat("soccernet-v3d", _v3d))
register_import_format(ImportFormat("sn-calibration", _calibration, ("width", "height")))
