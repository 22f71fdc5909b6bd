"""The dataset formats an import reads, as data: each format's name, the reader that imports it, the options it
takes (``width``/``height`` for a SoccerNet-calibration set without images, ``from_lines``/``flip`` for an ISSIA
folder) and the games an input of it holds, read without reading the input whole: a format whose games can already
be stored takes the ``merge`` option (:data:`~app.services.transfer.merging.MERGE_MODES`), and an import of games
that exist is refused unless it names one (:func:`stored_games_refusal`). The import job
(:mod:`app.services.jobs.work`) runs a format by its name and the API refuses an option the format does not take,
without either branching on a format. The system kinds' policies name the formats that produce their systems
(:attr:`app.services.kinds.base.KindPolicy.import_formats`); ISSIA's reader lives with the ISSIA services, which
register it on import (:mod:`app.services.issia`) as they register the kind's hooks.
"""
from __future__ import annotations

from dataclasses import dataclass
from datetime import datetime
from pathlib import Path
from typing import Any, Callable, Mapping, Optional

import sqlalchemy as sa
from sqlalchemy.orm import Session

from app.core.config import Settings
from app.core.errors import DatasetError, InvalidInputError
from app.core.progress import Progress
from app.datasets.files import dataset_root
from app.datasets.sn_calibration import read_sn_calibration, sn_calibration_game
from app.datasets.soccernet_v3 import find_labels, game_key, read_soccernet_v3_game, soccernet_v3_labels
from app.datasets.soccernet_v3d import V3D_LABELS, read_soccernet_v3d
from app.db.models import Game
from app.services.transfer.archives import MAX_UPLOAD_SETTING
from app.services.transfer.caps import image_bytes, reading_limits
from app.services.transfer.importing import (
    ImportReport,
    import_sn_calibration,
    import_soccernet_v3,
    import_soccernet_v3d,
)
from app.services.transfer.merging import MERGE_MODES

#: ``run(session, path, settings, options, progress=, actor=, source_name=, merge=)`` -> the import's report (an
#: ``ImportReport``, or a report with ``as_result()`` giving the job's result, e.g. a detector's predictions').
ImportRun = Callable[..., Any]
#: A game's natural key: ``(league, season, match)``.
GameKey = tuple[str, str, str]


@dataclass(frozen=True)
class ImportFormat:
    """One dataset format: its name (``v3d import <name>``, the API's ``kind``), its reader, the names of the
    options it takes from a job's ``params`` (every other format-specific option is refused for it), the setting
    (its environment name, in MB) bounding an upload of it to ``POST /api/imports``
    (``app.services.transfer.archives.upload_limit``: never above ``V3D_MAX_UPLOAD_MB``, which bounds the route's
    body while it streams; a smaller one of a format's own is checked once the form is read, before the zip is
    unpacked), and for a format whose games can already be stored (it then takes ``merge``): ``games(path)``, the
    keys of the games an input holds (reading only names: its folders and label files), and ``read(path, options,
    settings)``, which reads and validates the whole input as its import does, storing nothing (raises
    ``DatasetError``)."""

    name: str
    run: ImportRun
    options: tuple[str, ...] = ()
    upload_limit: str = MAX_UPLOAD_SETTING
    games: Optional[Callable[[Path], list[GameKey]]] = None
    read: Optional[Callable[[Path, Mapping[str, Any], Settings], object]] = None
    #: What an input of the format holds, in a person's words (the refusal of an upload that is not one says it).
    layout: str = ""


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


def existing_games(session: Session, name: str, path: str | Path, *, before: Optional[datetime] = None) -> list[str]:
    """The games of the input ``path`` of format ``name`` that are stored already (created before ``before`` when
    given: the games an interrupted run of the same import stored are its own), as ``league/season/match``, sorted.

    Raises:
        ValueError: an unknown format. DatasetError: the input's games cannot be listed (as its reader says).
    """
    fmt = import_format(name)
    keys = sorted(set(fmt.games(Path(path)))) if fmt.games is not None else []
    found: list[str] = []
    for start in range(0, len(keys), 200):
        chunk = keys[start:start + 200]
        where: list[sa.ColumnElement[bool]] = [sa.tuple_(Game.league, Game.season, Game.match).in_(chunk)]
        if before is not None:
            where.append(Game.created_at < before)
        found += [f"{g.league}/{g.season}/{g.match}" for g in
                  session.execute(sa.select(Game.league, Game.season, Game.match).where(*where))]
    return sorted(found)


def stored_games_refusal(session: Session, name: str, path: str | Path, options: Mapping[str, Any],
                         settings: Settings, *, before: Optional[datetime] = None) -> Optional[tuple[str, list[str]]]:
    """Why an import of ``path`` (format ``name``, its ``options``) that names no merge is refused: its games stored
    already (:func:`existing_games`, ``before`` as there), once the input was read and found valid (an invalid input
    is refused for what is wrong in it first, naming the file and the field, as its import would); ``(message, the
    games)`` (:func:`merge_refusal`), or None when none of its games is stored.

    Raises:
        DatasetError: the input cannot be imported.
    """
    stored = existing_games(session, name, path, before=before)
    if not stored:
        return None
    fmt = import_format(name)
    session.rollback()  # no transaction held while the input is read
    if fmt.read is not None:
        fmt.read(Path(path), options, settings)
    return merge_refusal(stored), stored


#: How many stored games a refusal names (the rest counted).
NAMED_GAMES_MAX = 20


def merge_refusal(games: list[str]) -> str:
    """The refusal of an import without ``merge`` whose ``games`` are stored already: names them and the modes.

    >>> merge_refusal(["a/b/c"])[:56]
    'these games are stored already: a/b/c; nothing was impor'
    """
    named = ", ".join(games[:NAMED_GAMES_MAX]) + (f" and {len(games) - NAMED_GAMES_MAX} more"
                                                  if len(games) > NAMED_GAMES_MAX else "")
    modes = "; ".join(f"merge={mode}: {what}" for mode, what in MERGE_MODES.items())
    return f"these games are stored already: {named}; nothing was imported. Say how to merge them ({modes})"


def _v3_games(path: Path) -> list[GameKey]:
    return [game_key(labels.parent) for labels in soccernet_v3_labels(path)]


def _v3d_games(path: Path) -> list[GameKey]:
    return [game_key(labels.parent) for labels in find_labels(path, V3D_LABELS)]


def _calibration_games(path: Path) -> list[GameKey]:
    return [sn_calibration_game(path)]


def _v3_read(path: Path, options: Mapping[str, Any], settings: Settings) -> object:
    root = dataset_root(path)
    for labels in soccernet_v3_labels(path):  # one game at a time, dropped, as the import validates them
        read_soccernet_v3_game(labels, root, **reading_limits(settings))
    return None


def _v3d_read(path: Path, options: Mapping[str, Any], settings: Settings) -> object:
    return read_soccernet_v3d(path, settings.max_image_pixels, image_bytes(settings))


def _calibration_read(path: Path, options: Mapping[str, Any], settings: Settings) -> object:
    return read_sn_calibration(path, options.get("width"), options.get("height"), settings.max_image_pixels,
                               image_bytes(settings))


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


def _predictions(session: Session, path: str | Path, settings: Settings, options: Mapping[str, Any],
                 progress: Progress | None = None, **named: Any) -> Any:
    from app.services.transfer.predictions import import_predictions  # it recomputes systems: imported when run

    return import_predictions(session, path, settings, options.get("source"), progress=progress,
                              actor=named.get("actor"))


register_import_format(ImportFormat(
    "soccernet-v3", _v3, games=_v3_games, read=_v3_read,
    layout="a folder per game, <league>/<season>/<match>/, holding Labels-v3.json and Frames-v3.zip (its images; "
           "without it the labels alone are imported)"))
register_import_format(ImportFormat(
    "soccernet-v3d", _v3d, games=_v3d_games, read=_v3d_read,
    layout="a folder per game, <league>/<season>/<match>/, holding Labels-v3D.json"))
register_import_format(ImportFormat(
    "sn-calibration", _calibration, ("width", "height"), games=_calibration_games, read=_calibration_read,
    layout="a folder of SoccerNet-calibration frames: <frame>.json (its field lines' points) beside <frame>.jpg"))
# a ball detector's predictions (app.services.transfer.predictions): rows of their own on stored frames, no games
register_import_format(ImportFormat("predictions", _predictions, ("source",),
                                    upload_limit="V3D_MAX_PREDICTION_IMPORT_MB",
                                    layout="a CSV league,season,match,image,x1,y1,x2,y2,score, YOLO txt files or a "
                                           "COCO results JSON"))

#: How many of an upload's files a refusal names (the rest counted).
NAMED_FILES_MAX = 6


def check_upload_layout(name: str, folder: Path, upload: str) -> None:
    """Refuse an unpacked upload ``folder`` (the zip ``upload`` as sent) that is not of the format ``name``, as far as
    listing its games tells (the format's ``games``: names only, nothing read whole), in words that name no server
    folder: what is wrong, the files the zip holds, and the layout the format wants (:attr:`ImportFormat.layout`).
    A format without ``games`` is left to its import, which names the file and the field.

    Raises:
        InvalidInputError: (field ``file``) the upload holds no input of the format.
    """
    fmt = import_format(name)
    if fmt.games is None:
        return
    try:
        fmt.games(folder)
        return
    except DatasetError as exc:
        where = Path(exc.file)
        shown = upload if where == folder else f"{upload}!{where.relative_to(folder).as_posix()}" \
            if where.is_relative_to(folder) else upload
        problem = str(exc).split(": ", 1)[1] if ": " in str(exc) else str(exc)
    files = sorted(p.relative_to(folder).as_posix() for p in folder.rglob("*") if p.is_file())
    found = (f"it holds {len(files)} file{'' if len(files) == 1 else 's'}: "
             + ", ".join(files[:NAMED_FILES_MAX]) + (f" and {len(files) - NAMED_FILES_MAX} more"
                                                     if len(files) > NAMED_FILES_MAX else "")) if files else \
        "it holds no file"
    raise InvalidInputError(f"{shown}: {problem}; {found}. A {name} import wants {fmt.layout}", field="file")
