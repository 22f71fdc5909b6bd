"""``v3d restore``: a backup archive (``app.services.backup.archive``) into the database and store the settings name,
from any engine to any engine (SQLite + a folder, PostgreSQL + S3).

The order, so that nothing is written unless the whole can be, and a restore cut short is never served:

1. the archive is verified whole (every member's SHA-256 and size against its manifest, read in bounded chunks and
   refused at the first byte past the size declared) before anything else;
2. its schema revision must be one this v3d knows, every key it will write must fit the target store (S3 names
   hold 1,024 bytes), every frame must name its images in the archive, a store, the data root or one of the archive's
   own dataset folders, and its expanded size must fit the target's free disk space: refused, named, before any
   write; a table's row is never read past ``V3D_RESTORE_MAX_LINE_MB``;
3. the target database must hold no data (an empty or only-migrated database counts as empty), unless ``replace``;
4. the target is marked (``app.db.session.RESTORING_TABLE``): from here until the mark is dropped at the very end,
   ``v3d serve`` and every command refuse the database with words, and running the restore again finishes it (it
   starts over on the marked database);
5. the tables are dropped and made again by the migrations at the archive's revision, the rows inserted as they were
   (ids included; no import cap applies: they are rows, not a dataset), the store's objects written under their keys,
   a local dataset folder's files under ``restored/<backup id>/<n>/`` with its frames naming them there, the schema
   migrated to head, PostgreSQL's sequences moved past the ids restored; then the mark is dropped. Jobs the archive
   held queued or running are kept failed, never run here (:data:`NOT_RUN_HERE`).

Passwords, API tokens and the session-signing key are rows: they keep working, and whoever made the archive is an
admin of the target. ``--new-secrets`` (an archive someone else made) restores the data with a new session key, every
API token revoked and every account but the restoring admin's disabled (``users.take_over``). Times, ids, versions
(ETags), release documents and hashes are restored as stored, so every answer and every release export is the same.
"""
from __future__ import annotations

import secrets
import shutil
import time
import warnings
import zipfile
from dataclasses import dataclass, field
from pathlib import Path, PurePosixPath
from typing import Any, Optional

import orjson
import sqlalchemy as sa
from sqlalchemy.engine import Engine

from app.core.config import Settings, jobs_dir
from app.core.errors import ConflictError, InvalidInputError
from app.core.progress import Progress
from app.datasets.files import is_safe_member
from app.db.in_use import exclusive
from app.db.session import (
    RESTORING_TABLE,
    V3dSession,
    alembic_config,
    make_engine,
    refresh_statistics,
    unfinished_restore,
    upgrade_database,
)
from app.services.accounts.users import TakenOver, take_over
from app.services.backup.archive import MANIFEST, BrokenArchive, Manifest, lines, s3_location, verify_archive
from app.services.backup.rows import decoder, write_type
from app.services.backup.snapshot import BACKUPS, SKIPPED_TABLES
from app.services.storage import storage_for
from app.services.storage.datasets import IN_DATA_ROOT, STORED
from app.services.storage.stores import Storage, join_key

#: Rows inserted per statement batch.
BATCH_ROWS = 2000
#: Tables a deployment writes without anyone's data in them (the session key the migrations make, login counters):
#: a target holding rows only there counts as empty, and they are replaced by the archive's.
MACHINE_TABLES = frozenset({"server_secrets", "rate_limit_counters"})
#: The store's folder a backup's local dataset files are restored under (``restored/<backup id>/<n>/...``).
RESTORED = "restored"


class TargetNotEmpty(ConflictError):
    """The target database holds data and the restore was not told to replace it."""


@dataclass
class RestoreReport:
    """What a restore did: the archive's ``manifest``, the ``rows`` and ``objects`` written, the local dataset folders
    whose files were not in the archive and are not on this machine (``missing_roots``), ``seconds``, and the jobs the
    archive held queued or running, kept failed (``jobs_not_run``)."""

    manifest: Manifest
    rows: int = 0
    objects: int = 0
    missing_roots: list[str] = field(default_factory=list)
    seconds: float = 0.0
    jobs_not_run: int = 0
    taken_over: Optional[TakenOver] = None


def fetch_archive(archive: str, settings: Settings) -> tuple[Path, bool]:
    """A local file holding ``archive`` (a path, or ``s3://BUCKET/KEY`` fetched through the store's credentials into
    the jobs folder), and whether it is such a temporary copy (the caller removes it).

    Raises:
        FileNotFoundError: no such file or key.
        ValueError: an ``s3://`` name without bucket or key.
    """
    s3 = s3_location(archive, "archive")
    if s3 is not None:
        from app.services.storage.s3 import S3Storage

        bucket, key = s3
        target = jobs_dir(settings) / BACKUPS / f"fetched-{secrets.token_hex(4)}.zip"
        return S3Storage(bucket, "").get_file(key, target), True
    path = Path(archive).expanduser()
    if not path.is_file():
        raise FileNotFoundError(f"{archive}: no such archive")
    return path, False


def verify(archive: str, settings: Settings, progress: Optional[Progress] = None) -> Manifest:
    """Verify ``archive`` whole (``archive.verify_archive``) and that this v3d knows its schema revision.

    Raises:
        BrokenArchive: a member missing, unlisted, unreadable or changed (named), or a revision unknown here.
        FileNotFoundError: no such archive.
    """
    path, temporary = fetch_archive(archive, settings)
    try:
        manifest = verify_archive(path, progress, max_line_bytes(settings))
    finally:
        if temporary:
            path.unlink(missing_ok=True)
    _known_revision(manifest)
    return manifest


def restore_backup(archive: str, settings: Settings, *, replace: bool = False,
                   progress: Optional[Progress] = None, new_secrets: Optional[tuple[str, str]] = None) -> RestoreReport:
    """Restore ``archive`` into ``settings``' database and store (module docstring). ``new_secrets`` (an admin's name
    and password): an archive someone else made, whose accounts, tokens and session key must not work here
    (``app.services.accounts.users.take_over``, before the database is served; its report in ``taken_over``).

    Raises:
        BrokenArchive: the archive is not whole, a member is not the size its manifest declares, a row is longer
            than ``V3D_RESTORE_MAX_LINE_MB``, or a frame names a file outside the archive (nothing written).
        InvalidInputError: a key the target store cannot hold (field ``key``), or the archive expands to more than
            the target's disks have free (field ``archive``; nothing written).
        TargetNotEmpty: the database holds data and ``replace`` is off, or it is another archive's unfinished
            restore (nothing written).
        FileNotFoundError: no such archive.
    """
    started = time.monotonic()
    path, temporary = fetch_archive(archive, settings)
    try:
        max_line = max_line_bytes(settings)
        manifest = verify_archive(path, progress, max_line)
        _known_revision(manifest)
        storage = storage_for(settings)
        writes = _store_writes(manifest)
        _check_keys(storage, writes)
        with zipfile.ZipFile(path) as zf:
            _check_frame_files(zf, manifest, max_line)
        _check_room(manifest, writes, settings, storage)
        with exclusive(settings.database_url):  # no server or job runner uses it, and none starts meanwhile
            report = _restore_into(archive, path, manifest, settings, storage, writes, replace, max_line, progress,
                                   new_secrets)
    finally:
        if temporary:
            path.unlink(missing_ok=True)
    report.seconds = round(time.monotonic() - started, 3)
    return report


def _restore_into(archive: str, path: Path, manifest: Manifest, settings: Settings, storage: Storage,
                  writes: list[tuple[str, str]], replace: bool, max_line: int,
                  progress: Optional[Progress], new_secrets: Optional[tuple[str, str]]) -> RestoreReport:
    """Steps 3 to 5 of the module docstring, the archive verified and checked."""
    engine = make_engine(settings.database_url)
    try:
        label = archive if archive.startswith("s3://") else str(Path(archive).expanduser().resolve())
        _check_target(engine, label, replace)
        _mark(engine, label)
        report = RestoreReport(manifest=manifest)
        with zipfile.ZipFile(path) as zf:
            _rebuild_schema(engine, settings.database_url, manifest.schema_revision)
            report.rows = _insert_rows(engine, zf, manifest, progress, max_line)
            report.jobs_not_run = _fail_unfinished_jobs(engine)
            report.objects = _write_store(zf, storage, writes, progress)
            report.missing_roots = _name_local_roots(engine, manifest, settings)
        upgrade_database(settings.database_url, "head", restoring=True)
        _advance_sequences(engine)
        with V3dSession(engine) as session:
            refresh_statistics(session)
            if new_secrets is not None:  # while the database is still marked: never served with the archive's keys
                report.taken_over = take_over(session, *new_secrets)
        _unmark(engine)
    finally:
        engine.dispose()
    return report


def _known_revision(manifest: Manifest) -> None:
    from alembic.script import ScriptDirectory
    from alembic.util.exc import CommandError

    try:
        ScriptDirectory.from_config(alembic_config()).get_revision(manifest.schema_revision)
    except (CommandError, KeyError, ValueError):
        raise BrokenArchive(f"manifest.json: schema revision {manifest.schema_revision!r} (v3d "
                            f"{manifest.v3d_version}) is unknown to this v3d: restore it with that version or a "
                            f"later one", "manifest.json") from None


def _store_writes(manifest: Manifest) -> list[tuple[str, str]]:
    """``(member, key)`` of every object the restore writes to the store: the store's objects under their keys, the
    local dataset files under ``restored/<backup id>/<n>/``.

    Raises:
        BrokenArchive: a key or name no store holds (``..``, an absolute name: an archive made by hand).
    """
    out = []
    try:
        for key, member in manifest.objects.items():
            out.append((member, join_key(key)))
        backup_id = join_key(manifest.backup_id)
        for n, root in enumerate(manifest.local_roots):
            if root.member_prefix is None:
                continue
            for member in manifest.members:
                if member.startswith(root.member_prefix):
                    out.append((member, join_key(RESTORED, backup_id, str(n), member[len(root.member_prefix):])))
    except ValueError as exc:
        raise BrokenArchive(f"manifest.json: {exc}", "manifest.json") from None
    return out


def max_line_bytes(settings: Settings) -> int:
    """The longest table row (one line of a ``tables/*.jsonl`` member) a restore reads, in bytes
    (``V3D_RESTORE_MAX_LINE_MB``): what bounds its memory whatever the archive holds."""
    return int(settings.restore_max_line_mb * 2**20)


def _check_frame_files(zf: zipfile.ZipFile, manifest: Manifest, max_line: int) -> None:
    """Refuse, before anything is written, frames that name a file outside the archive: an ``image_root`` that is
    neither a store key, a folder under the target's data root, nor one of the manifest's ``local_roots`` (the dataset
    folders an ordinary backup lists, their files carried or named as missing); an image path, zip or member that is
    absolute or leads out with ``..``. A restored frame is served to every role, so a row naming ``/home/...`` would
    show the target's own files.

    Raises:
        BrokenArchive: the first such frame, named (member ``tables/frames.jsonl``).
    """
    entry = next((t for t in manifest.tables if t.name == "frames"), None)
    if entry is None:
        return
    names = [c for c, _ in entry.columns]
    at = {n: names.index(n) for n in ("id", "image_root", "image_path", "image_zip", "image_member") if n in names}
    roots = {r.root for r in manifest.local_roots}
    for root in roots:
        if not (root.startswith((STORED, IN_DATA_ROOT)) or PurePosixPath(root).is_absolute()):
            raise BrokenArchive(f"{MANIFEST}: local dataset folder {root[:200]!r} is neither absolute nor under a "
                                f"data root: an archive made by hand; nothing was restored", MANIFEST)
    for line in lines(zf, entry.member, max_line):
        try:
            values = orjson.loads(line)
            row = {n: values[i] for n, i in at.items()}
        except (orjson.JSONDecodeError, IndexError, TypeError):
            raise BrokenArchive(f"{entry.member}: a row that is not a list of {len(names)} values", entry.member) \
                from None
        where = f"{entry.member}: frame {row.get('id')}"
        folder = row.get("image_root")
        if folder is not None and not (isinstance(folder, str) and (folder.startswith((STORED, IN_DATA_ROOT))
                                                                      or folder in roots)):
            raise BrokenArchive(f"{where} names the image folder {str(folder)[:200]!r}, which is neither in a store, "
                                f"under a data root, nor one of the archive's own dataset folders (its manifest's "
                                f"local_roots): it would show a file of this machine; nothing was restored",
                                entry.member)
        for column in ("image_path", "image_zip", "image_member"):
            name = row.get(column)
            if name is not None and not (isinstance(name, str) and is_safe_member(name)):
                raise BrokenArchive(f"{where}: its {column} {str(name)[:200]!r} is absolute or leads out of its "
                                    f"dataset's folder: nothing was restored", entry.member)


def _check_room(manifest: Manifest, writes: list[tuple[str, str]], settings: Settings, storage: Storage) -> None:
    """Refuse, before anything is written, an archive that expands to more than the target's disks hold: its
    files (their sizes as the manifest declares them, each checked by :func:`archive.verify_archive`) against the free
    space of a folder store's disk, its rows against a SQLite database's, each leaving ``V3D_RESTORE_SPARE_MB`` free.
    A remote store or database server is not measured from here.

    Raises:
        InvalidInputError: a disk with too little room, named with the sizes (field ``archive``).
    """
    needs: dict[int, list[Any]] = {}  # device -> [a folder on it, bytes needed]

    def need(folder: Optional[Path], size: int) -> None:
        if folder is None or size <= 0:
            return
        existing = folder.resolve()
        while not existing.exists() and existing != existing.parent:
            existing = existing.parent
        entry = needs.setdefault(existing.stat().st_dev, [existing, 0])
        entry[1] += size

    sizes = {name: int(m["size"]) for name, m in manifest.members.items()}
    need(storage.local_path(RESTORED), sum(sizes[member] for member, _key in writes))
    url = sa.engine.make_url(settings.database_url)
    if url.get_backend_name() == "sqlite" and url.database not in (None, "", ":memory:"):
        need(Path(str(url.database)).parent, sum(sizes[t.member] for t in manifest.tables))
    spare = int(settings.restore_spare_mb * 2**20)
    for folder, size in needs.values():
        free = shutil.disk_usage(folder).free
        if size + spare > free:
            raise InvalidInputError(
                f"the archive expands to {size / 2**20:,.1f} MB on the disk of {folder}, which has "
                f"{free / 2**20:,.1f} MB free and keeps {spare / 2**20:,.0f} MB spare (V3D_RESTORE_SPARE_MB): nothing "
                f"was restored; free some space or restore onto another disk", field="archive")


def _check_keys(storage: Storage, writes: list[tuple[str, str]]) -> None:
    for _member, key in writes:
        refusal = storage.key_refusal(key)
        if refusal is not None:
            raise InvalidInputError(f"the target store cannot hold {refusal}; nothing was restored", field="key")


def holding_data(engine: Engine) -> list[str]:
    """The tables of ``engine``'s database that hold rows of a deployment's data (not :data:`MACHINE_TABLES`)."""
    with engine.connect() as conn:
        names = [n for n in sa.inspect(conn).get_table_names()
                 if n not in SKIPPED_TABLES and n not in MACHINE_TABLES]
        return [n for n in sorted(names)
                if conn.execute(sa.text(f'SELECT 1 FROM "{n}" LIMIT 1')).first() is not None]


def _check_target(engine: Engine, label: str, replace: bool) -> None:
    unfinished = unfinished_restore(engine)
    if unfinished is not None:
        if unfinished == label or replace:
            return  # finished now (started over), or replaced by this archive
        raise TargetNotEmpty(f"the database holds an unfinished restore of {unfinished}: run `v3d restore "
                             f"{unfinished}` again to finish it, or pass --replace to restore {label} instead")
    held = holding_data(engine)
    if held and not replace:
        raise TargetNotEmpty(f"the target database holds data (tables {', '.join(held[:6])}"
                             f"{', ...' if len(held) > 6 else ''}): nothing was restored. Restore into an empty "
                             f"database, or pass --replace to drop what it holds")


def _mark(engine: Engine, label: str) -> None:
    with engine.begin() as conn:
        conn.execute(sa.text(f"CREATE TABLE IF NOT EXISTS {RESTORING_TABLE} (archive TEXT NOT NULL)"))
        conn.execute(sa.text(f"DELETE FROM {RESTORING_TABLE}"))
        conn.execute(sa.text(f"INSERT INTO {RESTORING_TABLE} (archive) VALUES (:a)"), {"a": label})


def _unmark(engine: Engine) -> None:
    with engine.begin() as conn:
        conn.execute(sa.text(f"DROP TABLE {RESTORING_TABLE}"))


def _rebuild_schema(engine: Engine, url: str, revision: str) -> None:
    """Drop every table but the mark, and migrate the empty database to ``revision``."""
    meta = sa.MetaData()
    with engine.begin() as conn, warnings.catch_warnings():
        warnings.simplefilter("ignore", sa.exc.SAWarning)  # an index on an expression: dropped with its table
        meta.reflect(conn)
        meta.drop_all(conn, tables=[t for t in meta.sorted_tables if t.name != RESTORING_TABLE])
        if engine.dialect.name == "postgresql":
            # the migrations' own functions (the audit's append-only triggers) outlive their tables: dropped too, or
            # migrating again fails on them; an extension's functions are left alone
            for (signature,) in conn.execute(sa.text(
                    "SELECT p.oid::regprocedure::text FROM pg_proc p JOIN pg_namespace n ON n.oid = p.pronamespace "
                    "WHERE n.nspname = current_schema() AND NOT EXISTS (SELECT 1 FROM pg_depend d WHERE "
                    "d.objid = p.oid AND d.deptype = 'e')")).all():
                conn.execute(sa.text(f"DROP FUNCTION IF EXISTS {signature} CASCADE"))
    upgrade_database(url, revision, restoring=True)


def _insert_rows(engine: Engine, zf: zipfile.ZipFile, manifest: Manifest, progress: Optional[Progress],
                 max_line: int) -> int:
    """Every table's rows, parents first (the archive's order), in batches; the rows inserted."""
    dialect = engine.dialect.name
    total = sum(t.rows for t in manifest.tables)
    done = 0
    with engine.connect() as conn:
        present = {n: {c["name"] for c in sa.inspect(conn).get_columns(n)} for n in sa.inspect(conn).get_table_names()}
    for entry in manifest.tables:
        if entry.name not in present:
            raise BrokenArchive(f"{entry.member}: table {entry.name!r} is not in the schema at revision "
                                f"{manifest.schema_revision}", entry.member)
        unknown = [c for c, _ in entry.columns if c not in present[entry.name]]
        if unknown:
            raise BrokenArchive(f"{entry.member}: columns {unknown} are not in table {entry.name!r} at revision "
                                f"{manifest.schema_revision}", entry.member)
        names = [c for c, _ in entry.columns]
        decoders = [decoder(k, dialect) for _, k in entry.columns]
        table = sa.Table(entry.name, sa.MetaData(), *(sa.Column(c, write_type(k, dialect)) for c, k in entry.columns))
        with engine.begin() as conn:
            conn.execute(sa.delete(table))  # what the migrations made (the session key): the archive's replaces it
            batch: list[dict[str, Any]] = []
            for line in lines(zf, entry.member, max_line):
                values = orjson.loads(line)
                batch.append({n: d(v) for n, d, v in zip(names, decoders, values, strict=True)})
                if len(batch) >= BATCH_ROWS:
                    conn.execute(sa.insert(table), batch)
                    done += len(batch)
                    batch = []
                    if progress is not None:
                        progress("rows", done, total)
            if batch:
                conn.execute(sa.insert(table), batch)
                done += len(batch)
            if progress is not None:
                progress("rows", done, total)
    return done


#: What a job the archive held queued or running says once restored: it is never run on the target.
NOT_RUN_HERE = "restored from an archive: not run here"


def _fail_unfinished_jobs(engine: Engine) -> int:
    """The archive's queued and running jobs kept as failed (:data:`NOT_RUN_HERE`), never claimed by the target's
    runners: a job row names paths and actions of the machine that made it (an import's folder, an upload to clean
    up), and an archive from elsewhere must not make the target read or remove its own files. The jobs changed."""
    with engine.begin() as conn:
        result = conn.execute(sa.text("UPDATE jobs SET state = 'failed', message = :m, owner = NULL, "
                                      "finished_at = CURRENT_TIMESTAMP WHERE state IN ('queued', 'running')"),
                              {"m": NOT_RUN_HERE})
        return int(result.rowcount or 0)


def _write_store(zf: zipfile.ZipFile, storage: Storage, writes: list[tuple[str, str]],
                 progress: Optional[Progress]) -> int:
    for n, (member, key) in enumerate(writes, 1):
        with zf.open(member) as stream:
            storage.put_stream(key, stream)  # type: ignore[arg-type]  # a zip member reads as a binary file
        if progress is not None:
            progress("files", n, len(writes))
    return len(writes)


def _name_local_roots(engine: Engine, manifest: Manifest, settings: Settings) -> list[str]:
    """Frames of a local dataset folder whose files the archive holds name them in the store now; the folders whose
    files it does not hold and this machine lacks."""
    missing = []
    with engine.begin() as conn:
        for n, root in enumerate(manifest.local_roots):
            if root.member_prefix is None:
                if not _present_here(root.root, settings):
                    missing.append(root.root)
                continue
            conn.execute(sa.text("UPDATE frames SET image_root = :new WHERE image_root = :old"),
                         {"new": STORED + join_key(RESTORED, manifest.backup_id, str(n)), "old": root.root})
    return missing


def _advance_sequences(engine: Engine) -> None:
    """PostgreSQL: each table's id sequence moved past the largest id restored (the next insert takes the next)."""
    if engine.dialect.name != "postgresql":
        return
    with engine.begin() as conn:
        inspector = sa.inspect(conn)
        for table in inspector.get_table_names():
            for column in inspector.get_columns(table):
                seq = conn.execute(sa.text("SELECT pg_get_serial_sequence(:t, :c)"),
                                   {"t": f'"{table}"', "c": column["name"]}).scalar()
                if seq is None:
                    continue
                conn.execute(sa.text(f'SELECT setval(:s, COALESCE((SELECT max("{column["name"]}") FROM "{table}"), '
                                     f'0) + 1, false)'), {"s": seq})


def _present_here(root: str, settings: Settings) -> bool:
    """Whether the dataset folder ``root`` (a frame's ``image_root`` that is no store key) is on this machine."""
    if root.startswith(IN_DATA_ROOT):
        return settings.data_root is not None and (Path(settings.data_root) / root[len(IN_DATA_ROOT):]).is_dir()
    return Path(root).is_dir()
