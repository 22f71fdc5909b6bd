"""ISSIA-3D in the service: the sequences' import, trajectory, re-fit and export.

Importing this package registers the ISSIA kind's hooks (``app.services.kinds.issia.register_hooks``): the kind's
policy delegates its trajectory work to these modules without importing them; and the ``issia`` import format
(``app.services.transfer.import_formats``), which the import job runs by name. ``app.services`` imports this package
first, so every use of a service finds them registered.
"""
from pathlib import Path
from typing import Any, Mapping

from app.datasets.issia import CALIBRATION_FILE, LINES_FILE, POINTS_FILE, RELEASED_POINTS_FILE, read_issia
from app.services.issia.sequences import LEAGUE, SEASON, import_issia, refined_with_ball, refit_after_edit
from app.services.issia.trajectory import consensus_observations, merge_doubts
from app.services.kinds.issia import IssiaHooks, register_hooks
from app.services.transfer.import_formats import ImportFormat, register_import_format

register_hooks(IssiaHooks(consensus_observations=consensus_observations, merge_doubts=merge_doubts,
                          refined_with_ball=refined_with_ball, refit_after_edit=refit_after_edit))


def _import(session: Any, path: Any, settings: Any, options: Mapping[str, Any], progress: Any = None,
            **named: Any) -> Any:
    return import_issia(session, path, settings, from_lines=bool(options.get("from_lines")),
                        flipped_cameras=options.get("flip") or [], progress=progress, **named)


def _games(path: Path) -> list[tuple[str, str, str]]:
    return [(LEAGUE, SEASON, path.resolve().name)]  # one game per folder, named by it (``import_issia``)


def _read(path: Path, options: Mapping[str, Any], settings: Any) -> object:
    return read_issia(path, flipped_cameras=options.get("flip") or [], max_pixels=settings.max_image_pixels)


register_import_format(ImportFormat(
    "issia", _import, ("from_lines", "flip"), games=_games, read=_read,
    layout=f"one sequence's folder: {CALIBRATION_FILE} or {LINES_FILE} (the six cameras), {POINTS_FILE} or "
           f"{RELEASED_POINTS_FILE} (the ball points), optionally videos/cam<k>.mp4 or frames/cam<k>/"))
