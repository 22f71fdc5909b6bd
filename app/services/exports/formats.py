"""The exports' registry: each format of the exports' data (:data:`app.services.kinds.exports.EXPORT_SPECS`: its
name, what it holds, the choices the UI offers and the names of their downloads, the kinds it writes) bound to the
functions that write it (:func:`bind_writers`, once per entry). Every list of exports reads this one: the export
job and its zip (:mod:`app.services.exports.files`, :mod:`app.services.jobs.work`), the ``POST /api/exports/{format}``
route's choices (``app.api.routes.exports``), the help of the ``v3d export`` commands (``app.cli``), the UI's
exports panel (``static/js/exportlist.js``, written from :func:`exports_js`:
``python -m app.services.exports.formats > static/js/exportlist.js``) and the docs (``docs/exports.md`` and
``docs/api.md`` name every format; ``tests/services/exports/test_export_formats.py`` checks all of these).

A format's ``name`` is the one word of every front end: ``v3d export <name>``, ``GET``/``POST /api/exports/<name>``
and an export job's ``params["format"]``. Which system kinds an export writes is the data's
(:func:`app.services.kinds.kinds_exported_by` reads it, as the kinds' policies do), not the writers'.
"""
from __future__ import annotations

import json
import re
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Any, BinaryIO, Callable, Literal, Mapping

from sqlalchemy.orm import Session

from app.core.config import Settings
from app.core.progress import Progress
from app.services.issia.export import export_issia3d
from app.services.kinds.exports import ExportChoice, export_spec
from app.services.releases.content import get_release
from app.services.releases.export import (
    ReleaseSource,
    export_release_cameras,
    export_release_detector,
    export_release_issia3d,
)
from app.services.storage.datasets import DatasetFiles
from app.services.transfer.cameras_export import export_cameras
from app.services.transfer.detector_export import export_detector
from app.services.transfer.export_zip import stream_soccernet_v3d_zip
from app.services.transfer.exporting import export_size

#: ``write(session, out, include_all, settings)``: the export written as a tree under the folder ``out`` (created);
#: answers its counts (JSON-able, no server path).
TreeWriter = Callable[[Session, Path, bool, Settings], dict[str, Any]]
#: ``release_tree(session, out, release name, settings)``: the export of a release written as a tree under ``out``;
#: its counts.
ReleaseTreeWriter = Callable[[Session, Path, str, Settings], dict[str, Any]]
#: ``stream(session, out, include_all, options, progress, settings)``: the export written as a zip into the open binary
#: file ``out`` while the database is read; answers its counts.
ZipStreamer = Callable[[Session, BinaryIO, bool, Mapping[str, Any], "Progress | None", Settings], dict[str, Any]]


@dataclass(frozen=True)
class ExportFormat:
    """One export format: its entry of the exports' data and its writers (made by :func:`bind_writers`).

    Attributes:
        name: ``v3d export <name>``, ``/api/exports/<name>``, the job's ``params["format"]``.
        describes: what the export writes, in a sentence or two (the command's help, the docs' table).
        choices: the UI's buttons for it, the first one the default (its options are the job's defaults).
        tree: writes it as a folder tree, zipped afterwards (``files.zip_tree``); None when streamed.
        stream: writes it straight into a zip; None for a tree export. Exactly one of the two is set.
        release_tree: writes a release's export as a tree (a streamed format takes ``options["release"]``); None
            when the format is not made from a release.
    """

    name: str
    describes: str
    choices: tuple[ExportChoice, ...]
    tree: TreeWriter | None = None
    stream: ZipStreamer | None = None
    release_tree: ReleaseTreeWriter | None = None

    @property
    def options(self) -> tuple[str, ...]:
        """The names of the options its choices set (``("images",)`` for SoccerNet-v3D; none for the others)."""
        return tuple(dict.fromkeys(k for c in self.choices for k in c.options))

    def download_name(self, options: Mapping[str, Any]) -> str:
        """The file name of a download of this format asked with ``options`` (an option not given takes the
        first choice's value): the name of the choice those options make, and, for a release's export
        (``options["release"]``), the release's name before the extension, as each asset of a release page names
        its release (``soccernet-v3d-v1.1.zip``): two releases' files never share a name."""
        defaults = self.choices[0].options
        name = next((c.download_name for c in self.choices
                     if all(options.get(k, defaults.get(k)) == v for k, v in c.options.items())),
                    self.choices[0].download_name)
        release = options.get("release")
        if not release:
            return name
        stem, dot, ext = name.rpartition(".")
        return f"{stem}-{_FILE_UNSAFE.sub('_', str(release))}{dot}{ext}" if dot else f"{name}-{release}"


#: What a release's name may not bring into a file name (a path's separators, quotes, spaces): each such run is "_".
_FILE_UNSAFE = re.compile(r"[^A-Za-z0-9._+-]+")

_FORMATS: dict[str, ExportFormat] = {}


def register_export_format(fmt: ExportFormat) -> None:
    """Make ``fmt`` exportable by its name (once per format, below; the order is the UI's).

    Raises:
        ValueError: the format sets both or neither of ``tree`` and ``stream``, or a choice's id is taken.
    """
    if (fmt.tree is None) == (fmt.stream is None):
        raise ValueError(f"export {fmt.name!r}: exactly one of tree and stream")
    taken = {c.id for f in _FORMATS.values() if f.name != fmt.name for c in f.choices}
    if taken & {c.id for c in fmt.choices}:
        raise ValueError(f"export {fmt.name!r}: a choice id is taken: {sorted(taken & {c.id for c in fmt.choices})}")
    _FORMATS[fmt.name] = fmt


def bind_writers(name: str, *, tree: TreeWriter | None = None, stream: ZipStreamer | None = None,
                 release_tree: ReleaseTreeWriter | None = None) -> None:
    """Register the export format ``name`` of the exports' data (:func:`app.services.kinds.exports.export_spec`)
    with the functions that write it (as :class:`ExportFormat`'s); once per entry of the data.

    Raises:
        ValueError: ``name`` has no entry in the data, its writers are bound already, or
            :func:`register_export_format`'s errors.
    """
    spec = export_spec(name)
    if name in _FORMATS:
        raise ValueError(f"export {name!r}: its writers are bound already")
    register_export_format(ExportFormat(spec.name, spec.describes, spec.choices, tree=tree, stream=stream,
                                        release_tree=release_tree))


def export_format(name: str) -> ExportFormat:
    """The registered format ``name``.

    Raises:
        ValueError: no such format.
    """
    try:
        return _FORMATS[name]
    except KeyError:
        raise ValueError(f"unknown export {name!r}; one of {', '.join(_FORMATS)}") from None


def export_names() -> tuple[str, ...]:
    """Every registered format's name, in the UI's order."""
    return tuple(_FORMATS)


def tree_export_names() -> tuple[str, ...]:
    """The names of the formats written as a tree and zipped (every one but the streamed ones)."""
    return tuple(n for n, f in _FORMATS.items() if f.tree is not None)


def exports_js() -> str:
    """The ES module ``static/js/exportlist.js``: every choice of every format, in order, as the exports panel
    offers them (``{id, label, format, body, title}``: ``body`` is the job's options, ``title`` the tooltip)."""
    entries = [{"id": c.id, "label": c.label, "format": f.name, "body": dict(c.options), "title": c.holds}
               for f in _FORMATS.values() for c in f.choices]
    return JS_TEMPLATE.replace("__EXPORTS__", json.dumps(entries, indent=1, ensure_ascii=False))


JS_TEMPLATE = """\
// The exports the exports panel offers: one entry per button, in order ({id, label, format, body, title}).
// WRITTEN FROM app/services/exports/formats.py
// (python -m app.services.exports.formats > static/js/exportlist.js);
// tests/services/exports/test_export_formats.py checks that the two agree. Do not edit the list here.

export const EXPORTS = /*EXPORTS*/__EXPORTS__/*END*/;
"""


def _soccernet_v3d(session: Session, out: BinaryIO, include_all: bool, options: Mapping[str, Any],
                   progress: Progress | None, settings: Settings) -> dict[str, Any]:
    files = DatasetFiles.from_settings(settings)
    name = options.get("release")
    if name:  # the release's documents, not the database now
        release = get_release(session, str(name))
        for chunk in stream_soccernet_v3d_zip(session, False, progress, images=bool(options.get("images", True)),
                                              source=ReleaseSource(session, release), files=files):
            out.write(chunk)
        return {"systems": release.systems, "views": release.views, "release": release.name, "hash": release.hash}
    systems, rows = export_size(session, include_all)
    for chunk in stream_soccernet_v3d_zip(session, include_all, progress, images=bool(options.get("images", True)),
                                          files=files):
        out.write(chunk)
    return {"systems": systems, "rows": rows}


def _release_cameras(session: Session, out: Path, name: str, settings: Settings) -> dict[str, Any]:
    release = get_release(session, name)
    report = export_release_cameras(session, release, out).as_dict()
    return {**report, "release": release.name, "hash": release.hash}


#: The key of an export's counts that says, in words, why it holds nothing: the job then keeps no file (an empty zip
#: offered for download reads as an export that failed to write).
NOTHING = "nothing"


def _issia_3d(session: Session, out: Path, include_all: bool, settings: Settings) -> dict[str, Any]:
    r = export_issia3d(session, out, include_all=include_all)
    report: dict[str, Any] = {"sequences": r.sequences, "rows": r.rows, "calibrations": r.calibrations}
    if not r.sequences:
        report[NOTHING] = ("nothing to export: no ISSIA sequence is stored" if include_all else
                           "nothing to export: no accepted frame of an ISSIA sequence")
    return report


def _cameras(session: Session, out: Path, include_all: bool, settings: Settings) -> dict[str, Any]:
    return export_cameras(session, out, include_all=include_all).as_dict()


def _release_issia3d(session: Session, out: Path, name: str, settings: Settings) -> dict[str, Any]:
    release = get_release(session, name)
    r = export_release_issia3d(session, release, out)
    report: dict[str, Any] = {"sequences": r.sequences, "rows": r.rows, "calibrations": r.calibrations,
                              "release": release.name, "hash": release.hash}
    if not r.sequences:
        report[NOTHING] = f"nothing to export: release {release.name} holds no frame of an ISSIA sequence"
    return report


def _release_detector(fmt: Literal["yolo", "coco"]) -> ReleaseTreeWriter:
    def write(session: Session, out: Path, name: str, settings: Settings) -> dict[str, Any]:
        release = get_release(session, name)  # its boxes chosen with the settings it recorded, not these
        report = export_release_detector(session, release, fmt, out, DatasetFiles.from_settings(settings)).as_dict()
        report.pop("out_dir", None)  # a server folder: no export names one
        return {**report, "release": release.name, "hash": release.hash}
    return write


def _detector(fmt: Literal["yolo", "coco"]) -> TreeWriter:
    def write(session: Session, out: Path, include_all: bool, settings: Settings) -> dict[str, Any]:
        report = export_detector(session, fmt, out, include_all, settings.ball_diameter_m,
                                 settings.export_ball_box, files=DatasetFiles.from_settings(settings)).as_dict()
        report.pop("out_dir", None)  # a server folder: no export names one
        return report
    return write


#: The writers of every format of the exports' data, in its order (the UI's).
bind_writers("soccernet-v3d", stream=_soccernet_v3d)
bind_writers("issia-3d", tree=_issia_3d, release_tree=_release_issia3d)
bind_writers("cameras", tree=_cameras, release_tree=_release_cameras)
bind_writers("yolo", tree=_detector("yolo"), release_tree=_release_detector("yolo"))
bind_writers("coco", tree=_detector("coco"), release_tree=_release_detector("coco"))


#: The formats an export job writes from a release (``{"release": name}``); the others answer 422 naming
#: ``release`` until they read a release's documents too.
RELEASE_EXPORTS = tuple(n for n, f in _FORMATS.items() if f.stream is not None or f.release_tree is not None)


if __name__ == "__main__":
    sys.stdout.write(exports_js())
