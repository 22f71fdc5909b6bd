"""Every export as one zip file, written by a background job (``app.services.jobs.work.run_export``) or a
request: the formats, the zip of an export tree, and how long the server keeps an export job's file.

The formats and how each is written are the registry's (:mod:`app.services.exports.formats`):
SoccerNet-v3D is streamed into the zip, the others (the tree exports) are written to a work folder, zipped with paths
relative to the tree's root (:func:`zip_tree`; folders, empty ones included, kept as entries: a YOLO split without
images still exists once unpacked) and the folder removed. No file of any export names a server folder: every export is
relocatable.

An export job's file is written in ``<jobs dir>/exports/`` (``app.core.config.jobs_dir``, beside the database or
under ``var/``) and kept in the store as ``exports/<file>`` (``V3D_STORAGE_URL``; by default the jobs folder itself,
so it stays where it was written); it is removed ``Settings.export_keep_hours`` after it was written
(:func:`prune_exports`, :func:`prune_stored_exports`, run whenever an export job starts and whenever a file is asked
for), or with its job.
"""
from __future__ import annotations

import os
import shutil
import time
import zipfile
from pathlib import Path
from typing import Any, Callable

from sqlalchemy.orm import Session

from app.core.config import Settings
from app.core.errors import InvalidInputError
from app.core.progress import Progress
from app.services.exports.formats import RELEASE_EXPORTS, export_format, export_names, tree_export_names
from app.services.storage.stores import Storage
from app.services.transfer.exporting import member_compression, zip_member

#: What ``POST /api/exports/{format}`` and the export jobs write (the registry's names, in its order).
EXPORT_FORMATS = export_names()
#: The store's folder of export jobs' files (``exports/job-<id>-<format>.zip``).
EXPORTS = "exports"


def zip_tree(root: Path, target: Path, progress: Progress | None = None) -> int:
    """Zip every file and folder under ``root`` into ``target`` with paths relative to ``root`` (POSIX; folders as
    entries, so that empty ones survive), ``progress("zip", files done, files)`` as it goes. Members in the order of
    their paths with the fixed time stamp and modes of ``exporting.zip_member`` (no file's time enters the zip: the
    same tree zips to the same bytes), data compressed already stored as it is (``exporting.member_compression``).
    Returns the zip's size in bytes."""
    entries = sorted(root.rglob("*"), key=lambda p: p.relative_to(root).as_posix())
    files = [p for p in entries if p.is_file()]
    done = 0
    with zipfile.ZipFile(target, "w", zipfile.ZIP_DEFLATED, allowZip64=True) as zf:
        for p in entries:
            rel = p.relative_to(root).as_posix()
            if p.is_dir():
                zf.writestr(zip_member(rel + "/", folder=True), b"")
                continue
            with p.open("rb") as src, zf.open(zip_member(rel, member_compression(rel)), "w", force_zip64=True) as dst:
                shutil.copyfileobj(src, dst, 1 << 20)
            done += 1
            if progress is not None:
                progress("zip", done, len(files))
    return target.stat().st_size


def write_tree(session: Session, fmt: str, out: Path, include_all: bool, settings: Settings) -> dict[str, Any]:
    """Write the export ``fmt`` (a tree format of the registry, not the streamed ``soccernet-v3d``) under ``out``;
    its counts (no path).

    Raises:
        ValueError: an unknown or streamed format.
        InvalidInputError: names that cannot be files (nothing written), as each export raises.
    """
    tree = export_format(fmt).tree
    if tree is None:
        raise ValueError(f"not a tree export: {fmt!r}; one of {', '.join(tree_export_names())}")
    return tree(session, out, include_all, settings)


def write_export_zip(session: Session, fmt: str, target: Path, include_all: bool, settings: Settings,
                     progress: Progress | None = None, images: bool = True,
                     release: str | None = None) -> dict[str, Any]:
    """The export ``fmt`` as the zip ``target`` (written as ``<target>.part`` and renamed when complete; a
    tree export's work folder ``<target>.work`` removed in every case); its counts, ``bytes`` and ``format``.
    ``images``: SoccerNet-v3D only (each game's ``Frames-v3.zip``). ``release``: the name of the release to export
    instead of the database now (``formats.RELEASE_EXPORTS``; the same release gives the same bytes).

    Raises:
        ValueError: an unknown format. InvalidInputError: a release asked of a format not made from one (field
            ``release``). NotFoundError: no release of that name. As each export raises otherwise.
    """
    export = export_format(fmt)
    part = target.with_name(target.name + ".part")
    work = target.with_name(target.name + ".work")
    report: dict[str, Any]
    try:
        if export.stream is not None:
            with open(part, "wb") as out:
                report = export.stream(session, out, include_all, {"images": images, "release": release},
                                       progress, settings)
        elif release is not None:
            if export.release_tree is None:
                raise InvalidInputError(f"the {fmt} export is not made from a release yet; "
                                        f"{', '.join(RELEASE_EXPORTS)} are", field="release")
            shutil.rmtree(work, ignore_errors=True)
            work.mkdir(parents=True)
            report = export.release_tree(session, work, release, settings)
            zip_tree(work, part, progress)
        else:
            shutil.rmtree(work, ignore_errors=True)
            work.mkdir(parents=True)
            if progress is not None:
                progress("export", 0, 0)
            report = write_tree(session, fmt, work, include_all, settings)
            zip_tree(work, part, progress)
        os.replace(part, target)
    finally:
        shutil.rmtree(work, ignore_errors=True)
        part.unlink(missing_ok=True)
    return {**report, "format": fmt, "bytes": target.stat().st_size}


def prune_stored_exports(storage: Storage, keep_hours: float, now: Callable[[], float] = time.time) -> list[str]:
    """Remove the export files of ``storage`` (under :data:`EXPORTS`) written more than ``keep_hours`` ago; the keys
    removed. A folder store's are pruned as :func:`prune_exports` prunes its folder (left-over work folders too)."""
    folder = storage.local_path(EXPORTS)
    if folder is not None:
        return [f"{EXPORTS}/{name}" for name in prune_exports(folder, keep_hours, now)]
    limit = now() - keep_hours * 3600.0
    old = [obj.key for obj in storage.list(EXPORTS) if obj.modified < limit]
    for key in old:
        storage.delete(key)
    return old


def prune_exports(folder: Path, keep_hours: float, now: Callable[[], float] = time.time) -> list[str]:
    """Remove the files (and left-over work folders) of ``folder`` last written more than ``keep_hours`` ago;
    the names removed. A missing folder is nothing to prune."""
    if not folder.is_dir():
        return []
    limit = now() - keep_hours * 3600.0
    removed = []
    for p in folder.iterdir():
        try:
            if p.lstat().st_mtime >= limit:
                continue
            if p.is_dir() and not p.is_symlink():
                shutil.rmtree(p, ignore_errors=True)
            else:
                p.unlink(missing_ok=True)
            removed.append(p.name)
        except FileNotFoundError:
            continue
    return removed
