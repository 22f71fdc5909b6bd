"""What each kind of background job does (``app.services.jobs.runner`` runs them): ``import`` (a dataset
through ``app.services.transfer.importing`` or ``app.services.issia.sequences``), ``recompute`` (every system,
``recompute.recompute_all_systems``) and ``export`` (any export as a zip file,
``app.services.exports.files``: SoccerNet-v3D streamed while the database is read, the others written
as a tree and zipped).

Each is ``work(session, params, settings, progress, job_id) -> result`` (a JSON-able dict) and may be run
again from the start after a kill: imports are idempotent, a recompute gives the same rows, an export
rewrites its file (``<jobs dir>/exports/job-<id>-<format>.zip``, written as ``.part`` and renamed
when complete, removed ``Settings.export_keep_hours`` later).
"""
from __future__ import annotations

import contextlib
import re
import shutil
from contextvars import ContextVar
from pathlib import Path, PurePosixPath
from typing import Any

from sqlalchemy.engine import Engine
from sqlalchemy.orm import Session

from app.core.config import Settings, jobs_dir
from app.core.errors import ForbiddenError, InvalidInputError
from app.core.names import clean_title
from app.core.progress import Progress
from app.db.models import Job
from app.db.unit import write_unit
from app.services.backup.snapshot import BACKUPS, write_backup
from app.services.derivation.recompute import recompute_all_systems
from app.services.exports.files import EXPORTS, prune_exports, prune_stored_exports, write_export_zip
from app.services.exports.formats import NOTHING, RELEASE_EXPORTS, export_format
from app.services.jobs.summary import summary
from app.services.storage import storage_for
from app.services.storage.datasets import UPLOADS, DatasetFiles, rekey_frames
from app.services.storage.stores import Storage, StoredObject, checked_key
from app.services.transfer import data_root
from app.services.transfer.import_formats import import_format, stored_games_refusal

#: True while this process runs an import its operator named on this machine's command line (``v3d import``:
#: ``runner.run_job(..., command_line=True)``), the one import that may read a folder outside the data root (the
#: command is not confined). A job row anyone else queued (the API, an archive restored, a runner taking over a
#: stale job) reads only under the data root or from its own upload: the row's path is data, not the operator's word.
COMMAND_LINE = ContextVar("v3d_command_line_import", default=False)


def import_params(kind: str, path: str | Path, *, width: int | None = None, height: int | None = None,
                  from_lines: bool = False, flip: list[str] | None = None,
                  calibration_workers: int | None = None, upload: bool = False,
                  merge: str | None = None, source: str | None = None,
                  name: str | None = None, upload_key: str | None = None) -> dict[str, Any]:
    """The ``params`` of an import job (one shape for the API and the CLI, so that a command run again
    finds the job it started: ``jobs.find_resumable``). ``path`` is stored resolved; ``upload``: it is an
    unpacked upload of its own, removed when the dataset cannot be imported; ``merge``: how to merge games stored
    already (``app.services.transfer.merging.MERGE_MODES``), None: refuse them; ``source``: the name of a detector's
    predictions (kind ``predictions``); ``name``: an upload's file name as the browser sent it (its last path
    component, cleaned: ``app.core.names.clean_title``): what the job is titled by and its import named as, instead
    of the server's upload folder; ``upload_key``: the upload's folder in the store (``V3D_STORAGE_URL``), which
    the node running the job reads (:func:`run_import`)."""
    out = {"kind": kind, "path": str(Path(path).expanduser().resolve()), "width": width, "height": height,
           "from_lines": from_lines, "flip": list(flip or []), "calibration_workers": calibration_workers,
           "merge": merge}
    if source is not None:
        out["source"] = source
    if upload:
        out["upload"] = True
        # cleaned before anyone sees it (app.core.names.clean_title): no character that reorders, hides or escapes
        shown = clean_title(PurePosixPath(str(name or "").replace("\\", "/")).name)
        if shown:
            out["name"] = shown
        if upload_key is not None:
            out["upload_key"] = upload_key
    return out


def import_result(report: Any) -> dict[str, Any]:
    """The stored result of an import job: the counts of its ``ImportReport`` (or its own ``as_result()``), and
    ``summary``: them in words with the queue's links (``app.services.jobs.summary``)."""
    if hasattr(report, "as_result"):
        out = dict(report.as_result())
        out["summary"] = summary("import", out)
        return out
    keys = ("source", "games", "systems", "frames", "systems_new", "systems_changed", "calibrated", "refused",
            "rig_assisted", "player_assisted", "prior_fitted", "triangulated", "seconds", "systems_merged",
            "decisions_from_file", "decisions_reset")
    out = {k: getattr(report, k) for k in keys}
    out["refusal_reasons"] = dict(report.refusal_reasons)
    out["refusal_kinds"] = dict(report.refusal_kinds().most_common())
    out["skipped_systems"] = list(getattr(report, "skipped_systems", []))  # named, with why (the view cap)
    out["skipped_games"] = list(getattr(report, "skipped_games", []))  # named, with the entry refused and why
    out["frames_without_image"] = int(getattr(report, "frames_without_image", 0))
    out["players_dropped"] = int(getattr(report, "players_dropped", 0))  # beyond V3D_MAX_PLAYERS_PER_FRAME
    out["summary"] = summary("import", out)
    return out


def run_import(session: Session, params: dict[str, Any], settings: Settings, progress: Progress,
               job_id: int) -> dict[str, Any]:
    """Import ``params["path"]`` as ``params["kind"]`` (see :func:`import_params`). Without ``params["merge"]``, a
    valid input holding games stored before the job was queued is refused (``import_formats.stored_games_refusal``);
    the games an earlier run of the same job stored are merged as ``keep-newer`` (the run completes it).

    An upload is read from this node's copy of it (fetched from the store when another node received it:
    ``DatasetFiles.upload_folder``; removed again at the end when the store is remote); when the import ends, its
    frames name their images by the upload's key in the store, or by their path under the data root
    (``app.services.storage.datasets.rekey_frames``), so that every node finds them.

    Raises:
        DatasetError: the dataset cannot be imported (nothing of it stored; an upload's folder is removed).
        InvalidInputError: games stored already and no ``merge`` (field ``merge``; nothing stored).
        FileNotFoundError: the upload is no longer in the store.
    """
    files = DatasetFiles.from_settings(settings)
    params = confined_import(params, settings, files)
    key = params.get("upload_key")
    try:
        return _import_and_rekey(session, params, settings, progress, job_id, files)
    finally:
        if key and files.storage.local_path(str(key)) is None:  # this node's copy of an upload kept elsewhere
            remove_upload(params["path"], files)


def upload_folders(files: DatasetFiles) -> list[Path]:
    """The folders (resolved) an upload is unpacked into or read from: this node's ``<jobs dir>/uploads`` and a
    folder store's own ``uploads``."""
    out = [(files.scratch / UPLOADS).resolve()]
    own = files.storage.local_path(UPLOADS)
    if own is not None:
        out.append(own.resolve())
    return out


def is_upload_folder(path: str | Path, files: DatasetFiles) -> bool:
    """True when ``path`` is itself (no link) one upload's folder: a direct child of :func:`upload_folders`."""
    candidate = Path(path)
    if candidate.is_symlink():
        return False
    resolved = candidate.resolve()
    return any(resolved.parent == root for root in upload_folders(files))


def remove_upload(path: str | Path, files: DatasetFiles) -> bool:
    """Remove the upload folder ``path`` when it is one (:func:`is_upload_folder`), never any other folder (a job
    row's path is data: a restored or hand-made row naming a folder of the host must not delete it); whether it was
    removed."""
    if not is_upload_folder(path, files):
        return False
    shutil.rmtree(Path(path).resolve(), ignore_errors=True)
    return True


def confined_import(params: dict[str, Any], settings: Settings, files: DatasetFiles) -> dict[str, Any]:
    """``params`` with the path the import reads checked (and, for an upload kept in the store, found on this node):

    * ``upload_key``: ``uploads/<one name>``, read from this node's copy of it or the folder store's own folder;
    * ``upload`` without a key (a job of an older v3d): its path is one upload's folder (:func:`is_upload_folder`);
    * otherwise its path lies under the data root (``V3D_DATA_ROOT``), as the API's imports require, unless the
      operator typed it on this machine's command line (:data:`COMMAND_LINE`).

    Raises:
        ForbiddenError: anything else, named (field ``path`` or ``upload_key``); nothing read.
        FileNotFoundError: the upload is no longer in the store.
    """
    key = params.get("upload_key")
    if key:
        parts = str(key).split("/")
        if len(parts) != 2 or parts[0] != UPLOADS or parts[1] in ("", ".", ".."):
            raise ForbiddenError(f"upload_key: {str(key)[:200]!r} is not an upload's folder in the store "
                                 f"({UPLOADS}/<name>): nothing imported")
        return {**params, "path": str(files.upload_folder(str(key)).resolve())}  # as the import records it
    if params.get("upload"):
        if not is_upload_folder(params["path"], files):
            raise ForbiddenError("path: an upload's folder lies in the server's uploads folder and this job's does "
                                 "not: nothing imported")
        return params
    if COMMAND_LINE.get():
        return params
    try:
        return {**params, "path": str(data_root.confined_path(params["path"], settings.data_root))}
    except ForbiddenError:
        raise ForbiddenError("path: a queued import reads only under the data root (V3D_DATA_ROOT); this job's "
                             "path is not there: nothing imported (run `v3d import` on the machine to import "
                             "another folder)") from None


def _import_and_rekey(session: Session, params: dict[str, Any], settings: Settings, progress: Progress,
                      job_id: int, files: DatasetFiles) -> dict[str, Any]:
    """:func:`_import`, then the frames named by their key or path under the data root (:func:`_rekey`); an upload
    refused for its stored games removed (here and from the store)."""
    key = params.get("upload_key")
    try:
        result = _import(session, params, settings, progress, job_id)
    except InvalidInputError:
        if params.get("upload"):
            remove_upload(params["path"], files)
            if key:
                files.storage.delete_tree(str(key))
        raise
    except BaseException:
        # the games stored before the failure are named so that every node reads them; the import's own error is
        # the job's, whatever this meets
        with contextlib.suppress(Exception):
            _rekey(session, params, files)
        raise
    _rekey(session, params, files)
    return result


def _rekey(session: Session, params: dict[str, Any], files: DatasetFiles) -> None:
    """Frames of the import read from this node's folder named by their key in the store (an upload) or under the
    data root (every frame recorded under it, whichever import stored it), committed."""
    session.rollback()  # after the import's own transactions (or its failure): a transaction of its own
    if params.get("upload_key"):
        folder = Path(params["path"]).resolve()
    elif files.data_root is not None:
        folder = Path(files.data_root).expanduser().resolve()
    else:
        return
    # where an image lies is no version's concern (``app.db.scope.UNVERSIONED_COLUMNS``): no write lock either
    with write_unit(session, lock=False):
        rekey_frames(session, folder, files.reference(folder))


def shown_source(params: dict[str, Any], settings: Settings, job_id: int | None) -> str:
    """How an import job's ``params["path"]`` is shown to annotators and reviewers (no server path:
    ``app.services.transfer.data_root.dataset_name``; an upload as ``upload <job id>/...``)."""
    if params.get("upload") and job_id is not None:  # wherever its folder lies (the jobs folder may have moved since)
        title = clean_title(str(params.get("name") or ""))  # a job stored before titles were cleaned, too
        return f"{title} (upload {job_id})" if title else f"upload {job_id}"
    return data_root.dataset_name(params["path"], settings.data_root, jobs_dir(settings) / "uploads",
                        job_id if params.get("upload") else None)


def without_server_paths(job_id: int, params: dict[str, Any], result: dict[str, Any] | None, message: str | None,
                         settings: Settings) -> tuple[dict[str, Any], dict[str, Any] | None, str | None]:
    """An import job's params, result and message as annotators and reviewers see them: the imported
    path (and any file named inside it) by its shown name (:func:`shown_source`); other jobs unchanged."""
    if "path" not in params:
        return params, result, message
    path, name = str(params["path"]), shown_source(params, settings, job_id)
    params = {**params, "path": name}
    if "name" in params:  # an upload's file name as the browser sent it: shown cleaned, whenever it was stored
        params["name"] = clean_title(str(params["name"]))
    if result is not None and "source" in result:
        result = {**result, "source": name}
    if message:
        message = data_root.without_server_paths(message, path, name, server_folders(settings))
    return params, result, message


def server_folders(settings: Settings) -> dict[str, str]:
    """The server's folders a job message must not show to annotators and reviewers, each with what stands for it
    (``app.services.transfer.data_root.without_server_paths``): the uploads folder, the jobs folder, the data root
    and the temporary folder."""
    import tempfile

    folders = {str(jobs_dir(settings) / "uploads"): "upload", str(jobs_dir(settings)): "(jobs)"}
    if settings.data_root is not None:
        folders[str(settings.data_root)] = "(data root)"
    folders[tempfile.gettempdir()] = "(temporary folder)"
    return folders


def _import(session: Session, params: dict[str, Any], settings: Settings, progress: Progress,
            job_id: int | None = None) -> dict[str, Any]:
    if params.get("calibration_workers") is not None:
        settings = settings.model_copy(update={"calibration_workers": params["calibration_workers"]})
    fmt = import_format(params["kind"])
    actor = params.get("actor")  # who queued it (the import's audit entry); None: the local user (CLI)
    merge = params.get("merge")
    if merge is None:
        job = session.get(Job, job_id) if job_id is not None else None
        refusal = stored_games_refusal(session, fmt.name, params["path"], params, settings,
                                       before=job.created_at if job else None)
        session.rollback()  # the read's transaction ends before the import's long work
        if refusal is not None:
            raise InvalidInputError(refusal[0], field="merge")
    report = fmt.run(session, params["path"], settings, {o: params.get(o) for o in fmt.options}, progress=progress,
                     actor=actor, source_name=shown_source(params, settings, job_id), merge=merge or "keep-newer")
    return import_result(report)


def run_recompute(session: Session, params: dict[str, Any], settings: Settings, progress: Progress,
                  job_id: int) -> dict[str, Any]:
    """Recompute every system with the current settings (calibrations untouched)."""
    systems, triangulated = recompute_all_systems(session, settings, progress, actor=params.get("actor"))
    out: dict[str, Any] = {"systems": systems, "triangulated": triangulated}
    return {**out, "summary": summary("recompute", out)}


def export_path(settings: Settings, name: str) -> Path:
    """Where an export job writes its file ``name`` (``<jobs dir>/exports/<name>``; only the last part of ``name``)
    before it is stored (:func:`export_key`)."""
    return jobs_dir(settings) / "exports" / Path(name).name


def export_key(name: str) -> str:
    """The key of an export job's file ``name`` in the store (``exports/<name>``; only the last part of ``name``)."""
    return f"{EXPORTS}/{checked_key(PurePosixPath(name.replace(chr(92), '/')).name)}"


def export_params(fmt: str, include_all: bool = False, images: bool = True,
                  release: str | None = None) -> dict[str, Any]:
    """The ``params`` of an export job: ``format`` (a name of ``app.services.exports.formats``), ``all``,
    the options the format takes (SoccerNet-v3D's ``images``) and ``release`` (the release it exports instead of the
    database now), when given.

    Raises:
        InvalidInputError: an unknown format (field ``format``); ``all`` beside ``release`` (field ``all``); a
            release asked of a format not made from one (field ``release``).
    """
    try:
        export = export_format(fmt)
    except ValueError as exc:
        raise InvalidInputError(str(exc), field="format") from None
    out: dict[str, Any] = {"format": fmt, "all": bool(include_all)}
    if "images" in export.options:
        out["images"] = bool(images)
    if release is not None:
        if include_all:
            raise InvalidInputError("a release holds its accepted systems only: 'all' and 'release' exclude each "
                                    "other", field="all")
        if fmt not in RELEASE_EXPORTS:
            raise InvalidInputError(f"the {fmt} export is not made from a release yet; "
                                    f"{', '.join(RELEASE_EXPORTS)} is", field="release")
        out["release"] = release
    return out


def run_export(session: Session, params: dict[str, Any], settings: Settings, progress: Progress,
               job_id: int) -> dict[str, Any]:
    """Write the export ``params["format"]`` (default ``soccernet-v3d``; ``params["all"]``: every system, else
    the accepted ones; ``params["images"]``, SoccerNet-v3D only, default true: each game's ``Frames-v3.zip``)
    as a zip to the job's file ``job-<id>-<format>.zip`` (``files.write_export_zip``), kept in the store as
    ``exports/<file>`` (any node serves it), after removing export files older than ``Settings.export_keep_hours``
    (``files.prune_exports``, ``files.prune_stored_exports``); progress per game
    (SoccerNet-v3D) or per file zipped. Its download is named as the choice its options make
    (``ExportFormat.download_name``)."""
    fmt = str(params.get("format", "soccernet-v3d"))
    target = export_path(settings, f"job-{job_id}-{fmt}.zip")
    target.parent.mkdir(parents=True, exist_ok=True)
    prune_exports(target.parent, settings.export_keep_hours)
    storage = storage_for(settings)
    prune_stored_exports(storage, settings.export_keep_hours)
    report = write_export_zip(session, fmt, target, bool(params.get("all", False)), settings, progress,
                              images=bool(params.get("images", True)), release=params.get("release"))
    if report.get(NOTHING):  # the words say why; no empty zip is kept or offered
        target.unlink(missing_ok=True)
        return report
    key = export_key(target.name)
    if storage.local_path(key) != target:  # a store of its own: the file goes there (in parts), the scratch copy away
        storage.put_file(key, target)
        target.unlink(missing_ok=True)
    filename = export_format(fmt).download_name(params)
    return {**report, "file": target.name, "media_type": "application/zip", "filename": filename}


def backup_key(name: str) -> str:
    """The key of a backup job's archive ``name`` in the store (``backups/<name>``; only the last part of ``name``)."""
    return f"{BACKUPS}/{checked_key(PurePosixPath(name.replace(chr(92), '/')).name)}"


def run_backup(session: Session, params: dict[str, Any], settings: Settings, progress: Progress,
               job_id: int) -> dict[str, Any]:
    """Back up the deployment as ``v3d backup`` does (``app.services.backup.snapshot.write_backup``; ``params
    ["local_files"]``, default true: the files of datasets read from this machine's folders too) to the job's archive
    ``job-<id>-backup.zip``, kept in the store as ``backups/<file>`` (an admin downloads it: it holds password and
    token hashes); once it is complete, the store's archives beyond the ``V3D_BACKUPS_KEPT`` newest are removed
    (:func:`prune_backups`). Its result: the archive's file, size, tables, rows, files and the count of named files
    not found. Run again after a kill, it writes the archive again from a new snapshot."""
    bind = session.get_bind()
    engine = bind if isinstance(bind, Engine) else bind.engine
    session.rollback()  # the snapshot reads in a transaction of its own
    name = f"job-{job_id}-backup.zip"
    target = jobs_dir(settings) / BACKUPS / name
    report = write_backup(engine, settings, str(target), progress, local_files=bool(params.get("local_files", True)))
    storage = storage_for(settings)
    key = backup_key(name)
    if storage.local_path(key) != target:  # a store of its own: the archive goes there, the scratch copy away
        storage.put_file(key, target)
        target.unlink(missing_ok=True)
    prune_backups(storage, settings.backups_kept)  # only now that the new one is complete
    out = report.as_result()
    out.pop("destination")  # a path of the server's
    return {**out, "missing": len(report.missing), "file": name, "media_type": "application/zip",
            "filename": f"v3d-backup-{job_id}.zip"}


#: The name of a backup job's archive in the store's ``backups`` folder, its job's id captured.
_BACKUP_NAME = re.compile(r"job-(\d+)-backup\.zip")


def _stored_backups(storage: Storage) -> list[StoredObject]:
    """The backup jobs' archives of the store (``backups/job-<id>-backup.zip``), newest job first."""
    found = [(int(m.group(1)), o) for o in storage.list(BACKUPS)
             if (m := _BACKUP_NAME.fullmatch(o.key.removeprefix(f"{BACKUPS}/"))) is not None]
    return [o for _, o in sorted(found, key=lambda pair: (pair[0], pair[1].modified), reverse=True)]



def prune_backups(storage: Storage, kept: int) -> list[str]:
    """Remove the backup jobs' archives of ``storage`` beyond the ``kept`` newest (``V3D_BACKUPS_KEPT``); the keys
    removed (their jobs' downloads answer 404 then, as an export's past ``V3D_EXPORT_KEEP_HOURS``)."""
    old = [o.key for o in _stored_backups(storage)[kept:]]
    for key in old:
        storage.delete(key)
    return old


def backup_room_refusal(settings: Settings) -> str | None:
    """Why a new backup job cannot be written, in words, or None: the disk of the jobs folder (where the archive is
    written first) or of a folder store (where it is kept) has less free space than the last backup's archive took.
    A remote store is not measured from here."""
    storage = storage_for(settings)
    last = next(iter(_stored_backups(storage)), None)
    if last is None:
        return None
    folders = [jobs_dir(settings) / BACKUPS]
    own = storage.local_path(BACKUPS)
    if own is not None:
        folders.append(own)
    seen: set[int] = set()
    for folder in folders:
        existing = folder.resolve()
        while not existing.exists() and existing != existing.parent:
            existing = existing.parent
        device = existing.stat().st_dev
        if device in seen:
            continue
        seen.add(device)
        free = shutil.disk_usage(existing).free
        if free < last.size:
            return (f"the last backup's archive took {last.size / 2**20:,.1f} MB and the disk of {existing} has "
                    f"{free / 2**20:,.1f} MB free: no backup was queued. Free some space, or keep fewer archives "
                    f"(V3D_BACKUPS_KEPT, {settings.backups_kept} now)")
    return None


#: kind -> work (``app.services.jobs.runner.Work``).
WORK = {"import": run_import, "recompute": run_recompute, "export": run_export, "backup": run_backup}
#: kind -> the store key of a finished job's file (its ``result["file"]``), for the kinds that write one.
RESULT_FILES = {"export": export_key, "backup": backup_key}
