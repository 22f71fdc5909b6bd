"""``v3d backup``: one consistent snapshot of a deployment, online, into one archive (``app.services.backup.archive``).

Every table is read in **one read transaction** (PostgreSQL: ``REPEATABLE READ, READ ONLY``, ``pg_dump``'s MVCC
snapshot; SQLite: one deferred transaction, whose WAL snapshot is fixed at its first read), so the audit, the
versions and the derived rows agree with each other while edits go on: an edit committed after the snapshot began is
wholly absent, one committed before wholly present. The same transaction names the store's objects the snapshot refers
to (frames' images and archives, kept uploads, export results), which are copied after the tables: a stored object is
written once under its key and never changed in place, so the copy is the snapshot's.

The archive is written beside its destination under a temporary name (``.NAME.part``) and renamed only when complete
(an ``s3://`` destination is uploaded only when complete: S3 shows an object once its upload ends), so a backup killed
or failing midway leaves nothing that looks like a backup. The archive holds every password and token hash and the
session key: it and its ``.part`` are mode 0600 from their first byte whatever the umask
(``archive.open_secret``), a destination that is a symbolic link is refused, and a ``.part`` a killed backup left is
named by the next backup beside it.
"""
from __future__ import annotations

import contextlib
import os
import secrets
import time
import warnings
from dataclasses import dataclass, field
from datetime import datetime, timezone
from pathlib import Path
from typing import Any, Iterator, Optional

import orjson
import sqlalchemy as sa
from sqlalchemy.engine import Engine

from app.core.config import Settings, jobs_dir
from app.core.progress import Progress
from app.db.session import RESTORING_TABLE
from app.services.backup.archive import ArchiveWriter, LocalRoot, Manifest, TableEntry, replace_into, s3_location
from app.services.backup.rows import column_kind, encoder, read_column
from app.services.storage import storage_for
from app.services.storage.datasets import IN_DATA_ROOT, STORED, DatasetFiles, OutsideDataset
from app.services.storage.stores import Storage, join_key

#: Rows fetched and written at a time.
BATCH_ROWS = 5000
#: Tables that are no part of a deployment's data: Alembic's own (the revision goes in the manifest) and a restore's
#: mark.
SKIPPED_TABLES = frozenset({"alembic_version", RESTORING_TABLE})
#: The store's folder of backups the API's job writes (never backed up themselves).
BACKUPS = "backups"
#: The suffix of an archive being written (``.NAME.part`` beside it), renamed to its name when complete.
PART = ".part"


@dataclass
class BackupReport:
    """What a backup wrote: ``destination``, its ``size`` (bytes), ``tables``, ``rows`` and ``objects`` (store
    objects and local files) written, ``missing`` (objects the snapshot names that were not found), ``seconds``, and
    ``stale_parts``: the unfinished ``.part`` files found beside the destination when it began (:func:`stale_parts`)."""

    destination: str
    size: int
    tables: int
    rows: int
    objects: int
    missing: list[str]
    seconds: float
    schema_revision: str
    stale_parts: list[str] = field(default_factory=list)

    def as_result(self) -> dict[str, Any]:
        """The report as a job's result (JSON)."""
        return {k: getattr(self, k) for k in ("destination", "size", "tables", "rows", "objects", "missing",
                                              "seconds", "schema_revision")}


def v3d_version() -> str:
    """The installed v3d's version (its package metadata)."""
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version("v3d")
    except PackageNotFoundError:
        return "unknown"


def write_backup(engine: Engine, settings: Settings, destination: str, progress: Optional[Progress] = None,
                 local_files: bool = True) -> BackupReport:
    """Back up the database of ``engine`` and the objects of the store (``settings``) it names to ``destination``: a
    file path, or ``s3://BUCKET/KEY`` through the store's credentials (boto3's standard variables). See the module
    docstring. ``local_files``: copy the files of datasets read from this machine's folders (a command-line import's,
    the demo's); without, the manifest lists their folders and a restore names those its machine lacks.

    Raises:
        ValueError: a destination that is a folder, or an ``s3://`` one without a bucket or key.
        app.services.storage.stores.StorageError, OSError: the store or the file system failed (no archive left).
    """
    started = time.monotonic()
    target, upload = _destination(destination, settings)
    part = target.with_name(f".{target.name}{PART}")
    part.parent.mkdir(parents=True, exist_ok=True)
    stale = stale_parts(part.parent)
    storage = storage_for(settings)
    files = DatasetFiles(storage, settings.data_root, jobs_dir(settings))
    manifest = Manifest(v3d_version=v3d_version(), schema_revision="", engine=engine.dialect.name,
                        backup_id=f"{datetime.now(timezone.utc):%Y%m%dT%H%M%SZ}-{secrets.token_hex(3)}",
                        created_at=datetime.now(timezone.utc).isoformat())
    writer = ArchiveWriter(part, manifest)
    try:
        with _snapshot(engine) as conn:
            manifest.schema_revision = _revision(conn)
            tables = _tables(conn)
            named = _named_objects(conn, tables, storage)
            rows = _write_tables(conn, tables, writer, progress)
        missing = _write_objects(named, writer, storage, files, local_files, progress)
        writer.close()
    except BaseException:
        writer.abort()
        part.unlink(missing_ok=True)
        raise
    size = part.stat().st_size
    try:
        if upload is not None:
            bucket_store, key = upload
            bucket_store.put_file(key, part)
            part.unlink()
        else:
            replace_into(part, target)
    except BaseException:
        part.unlink(missing_ok=True)
        raise
    return BackupReport(destination=destination, size=size, tables=len(manifest.tables), rows=rows,
                        objects=len(manifest.objects) + sum(r.files for r in manifest.local_roots),
                        missing=missing, seconds=round(time.monotonic() - started, 3),
                        schema_revision=manifest.schema_revision, stale_parts=stale)


def stale_parts(folder: Path) -> list[str]:
    """The ``.NAME.part`` files in ``folder`` before a backup starts writing its own: each one a backup that did not
    finish (killed, or still running) left, holding a copy of the secrets it had written so far. They are named, not
    removed (one may be another backup's, running now); the backup's own name, if among them, is written over."""
    try:
        return sorted(str(p) for p in folder.glob(f".*{PART}") if p.is_file())
    except OSError:
        return []


def _destination(destination: str, settings: Settings) -> tuple[Path, Optional[tuple[Storage, str]]]:
    """The local file the archive is written to, and (an ``s3://`` destination) the bucket's store and key it is
    uploaded to when complete."""
    s3 = s3_location(destination, "destination")
    if s3 is not None:
        from app.services.storage.s3 import S3Storage

        bucket, key = s3
        scratch = jobs_dir(settings) / BACKUPS / f"upload-{secrets.token_hex(4)}.zip"
        return scratch, (S3Storage(bucket, ""), key)
    named = Path(destination).expanduser()
    if named.is_symlink():
        raise ValueError(f"{destination!r} is a symbolic link (to {os.readlink(named)!r}): a backup never writes "
                         f"through a link, which could overwrite another file with the secrets; name the archive's "
                         f"own file")
    target = named.resolve()
    if target.is_dir():
        raise ValueError(f"{destination!r} is a folder: name the archive's file (e.g. {target / 'v3d-backup.zip'})")
    return target, None


@contextlib.contextmanager
def _snapshot(engine: Engine) -> Iterator[sa.Connection]:
    """One read transaction over the whole database (module docstring)."""
    with engine.connect() as conn:
        if engine.dialect.name == "postgresql":
            conn = conn.execution_options(isolation_level="REPEATABLE READ")
        with conn.begin():
            if engine.dialect.name == "postgresql":
                conn.exec_driver_sql("SET TRANSACTION READ ONLY")
            yield conn


def _revision(conn: sa.Connection) -> str:
    if not sa.inspect(conn).has_table("alembic_version"):
        raise ValueError("the database has no schema (no Alembic revision): nothing to back up")
    return str(conn.execute(sa.text("SELECT version_num FROM alembic_version")).scalar_one())


def _tables(conn: sa.Connection) -> list[sa.Table]:
    """The database's tables as they are (reflected), parents before children (foreign keys)."""
    meta = sa.MetaData()
    with warnings.catch_warnings():  # an index on an expression is no part of the rows (the migrations make it)
        warnings.simplefilter("ignore", sa.exc.SAWarning)
        meta.reflect(conn)
    return [t for t in meta.sorted_tables if t.name not in SKIPPED_TABLES]


def _write_tables(conn: sa.Connection, tables: list[sa.Table], writer: ArchiveWriter,
                  progress: Optional[Progress]) -> int:
    """Each table's rows, in primary-key order, to ``tables/<name>.jsonl``; the rows written."""
    dialect = conn.dialect.name
    counts = {t.name: int(conn.execute(sa.select(sa.func.count()).select_from(t)).scalar_one()) for t in tables}
    total, done = sum(counts.values()), 0
    for table in tables:
        columns = list(table.columns)
        kinds = [column_kind(c.type) for c in columns]
        encoders = [encoder(k) for k in kinds]
        order = list(table.primary_key.columns) or columns
        stmt = sa.select(*(read_column(c, k, dialect) for c, k in zip(columns, kinds, strict=True))).order_by(*order)
        member = f"tables/{table.name}.jsonl"
        written = 0
        with writer.member(member, compress=True) as out:
            result = conn.execution_options(stream_results=True).execute(stmt)
            for batch in result.partitions(BATCH_ROWS):
                out.write(b"".join(
                    orjson.dumps([enc(v) for enc, v in zip(encoders, row, strict=True)]) + b"\n" for row in batch))
                written += len(batch)
                done += len(batch)
                if progress is not None:
                    progress("tables", done, total)
        writer.manifest.tables.append(TableEntry(name=table.name, rows=written, member=member,
                                                 columns=[[c.name, k] for c, k in zip(columns, kinds, strict=True)]))
    return done


@dataclass
class _Named:
    """What the snapshot names beyond its rows: store keys, and local dataset folders with the files of each."""

    keys: list[str]
    local: dict[str, list[str]]


def _named_objects(conn: sa.Connection, tables: list[sa.Table], storage: Storage) -> _Named:
    """The store objects and local files the snapshot's rows name: each frame's image (or its archive, or its folder
    of numbered frames), each import's kept upload, each export job's file (not a backup job's)."""
    by_name = {t.name: t for t in tables}
    keys: set[str] = set()
    local: dict[str, set[str]] = {}
    frames = by_name.get("frames")
    if frames is not None and "image_root" in frames.c:
        cols = [frames.c[n] for n in ("image_root", "image_zip", "image_path") if n in frames.c]
        for root, *files in conn.execute(sa.select(*cols).where(frames.c.image_root.is_not(None)).distinct()):
            for relative in (f for f in files if f):
                if root.startswith(STORED):
                    try:
                        keys.add(join_key(root[len(STORED):], relative))
                    except ValueError:
                        continue  # a name no store holds: its frame shows no image here either
                else:
                    local.setdefault(root, set()).add(relative)
    jobs = by_name.get("jobs")
    if jobs is not None:
        kinds = read_column(jobs.c.params, "json", conn.dialect.name), read_column(jobs.c.result, "json",
                                                                                  conn.dialect.name)
        for kind, params, result in conn.execute(sa.select(jobs.c.kind, *kinds)):
            params = orjson.loads(params) if params else {}
            result = orjson.loads(result) if result else {}
            if kind == "import" and isinstance(params, dict) and params.get("upload_key"):
                with contextlib.suppress(ValueError):
                    keys.update(obj.key for obj in storage.list(join_key(str(params["upload_key"]))))
            if kind == "export" and isinstance(result, dict) and result.get("file"):
                with contextlib.suppress(ValueError):
                    keys.add(join_key("exports", str(result["file"]).rpartition("/")[2]))
    return _Named(sorted(keys), {root: sorted(rel) for root, rel in sorted(local.items())})


def _write_objects(named: _Named, writer: ArchiveWriter, storage: Storage, files: DatasetFiles, local_files: bool,
                   progress: Optional[Progress]) -> list[str]:
    """Copy the named objects into the archive (``store/<key>``, ``local/<n>/<file>``); the names not found."""
    missing: list[str] = []
    total = len(named.keys) + sum(len(v) for v in named.local.values())
    done = 0
    for key in named.keys:
        path = storage.local_path(key)
        if path is not None and path.is_dir():  # a folder of numbered frames, kept in a folder store
            for obj in storage.list(key):
                _copy_key(obj.key, writer, storage, missing)
        elif path is None and not storage.exists(key) and any(True for _ in storage.list(key)):
            for obj in storage.list(key):  # the same, in a remote store
                _copy_key(obj.key, writer, storage, missing)
        else:
            _copy_key(key, writer, storage, missing)
        done += 1
        if progress is not None:
            progress("files", done, total)
    for n, (root, relatives) in enumerate(named.local.items()):
        entry = LocalRoot(root=root, member_prefix=f"local/{n}/" if local_files else None)
        writer.manifest.local_roots.append(entry)
        for relative in relatives:
            done += 1
            if progress is not None:
                progress("files", done, total)
            if not local_files:
                continue
            try:
                path = files.locate(root, relative).path
            except (OutsideDataset, FileNotFoundError):
                path = None
            if path is None or not path.exists():
                missing.append(f"{root}/{relative}" if not root.startswith(IN_DATA_ROOT) else root + relative)
                continue
            found = [path] if path.is_file() else sorted(p for p in path.rglob("*") if p.is_file())
            for file in found:
                name = f"{entry.member_prefix}{join_key(relative, file.relative_to(path).as_posix())}" \
                    if file != path else f"{entry.member_prefix}{join_key(relative)}"
                if name in writer.manifest.members:
                    continue
                with open(file, "rb") as stream:
                    writer.copy(name, stream)
                entry.files += 1
    return missing


def _copy_key(key: str, writer: ArchiveWriter, storage: Storage, missing: list[str]) -> None:
    member = f"store/{key}"
    if member in writer.manifest.members:
        return
    try:
        with storage.open(key) as stream:
            writer.copy(member, stream)
    except FileNotFoundError:
        missing.append(key)
        return
    writer.manifest.objects[key] = member
