"""The backup archive: one zip file holding ``manifest.json`` and every member it lists with its SHA-256.

Members (POSIX names inside the zip):

* ``tables/<table>.jsonl``: a table's rows in primary-key order, one JSON array a line, its values in the manifest's
  column order, each written as its column's neutral kind says (``app.services.backup.rows``), so that SQLite and
  PostgreSQL read the same archive;
* ``store/<key>``: an object of the store (``V3D_STORAGE_URL``) the snapshot names (frame images and archives, kept
  uploads, export results), restored under the same key;
* ``local/<n>/<path>``: a file of a dataset folder on the machine that made the backup (a command-line import's or
  the demo's images, ``Frame.image_root`` an absolute path or under the data root), restored into the target's store
  under ``restored/<backup id>/<n>/<path>`` with the frames naming it there;
* ``manifest.json``: :class:`Manifest`, written last (it holds the other members' digests).

Trust is earned by :func:`verify_archive` before anything is read for a restore (restic's and borg's rule): every
member listed is present and hashes to its digest, and no member is unlisted. A zip member's own CRC is checked too
(``zipfile`` raises on a mismatch), and every failure names the member being read.
"""
from __future__ import annotations

import hashlib
import json
import os
import zipfile
import zlib
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import IO, Any, BinaryIO, Iterator, Optional
from urllib.parse import urlsplit

#: The archive's own format, refused when a restore does not know it (an archive of a later v3d).
FORMAT = "v3d-backup"
FORMAT_VERSION = 1
MANIFEST = "manifest.json"
#: Bytes read and hashed at a time.
CHUNK_BYTES = 1 << 20


class BrokenArchive(ValueError):
    """The archive cannot be trusted: ``member`` (None: the archive as a whole) is missing, unreadable, unlisted or
    does not hash to its digest. The message says which and why."""

    def __init__(self, message: str, member: str | None = None) -> None:
        super().__init__(message)
        self.member = member


@dataclass
class TableEntry:
    """One table of the snapshot: its ``name``, ``rows``, ``columns`` (name, neutral kind) and archive ``member``."""

    name: str
    rows: int
    columns: list[list[str]]
    member: str


@dataclass
class LocalRoot:
    """A dataset folder of the machine that made the backup (a frame's ``image_root``): ``root`` as the frames name
    it; ``member_prefix`` where its files lie in the archive (``local/<n>/``), or None when they were left out
    (``v3d backup --without-local-files``: a restore names the roots missing on its target); ``files`` kept."""

    root: str
    member_prefix: str | None
    files: int = 0


@dataclass
class Manifest:
    """What ``manifest.json`` says (module docstring): the archive's format, the v3d version and schema revision that
    made it, its ``backup_id`` (the restored local files' key folder), when (ISO UTC), from which engine, each table,
    each store object (key -> member), each local dataset folder, and every member's ``sha256`` and ``size``."""

    v3d_version: str
    schema_revision: str
    backup_id: str
    created_at: str
    engine: str
    tables: list[TableEntry] = field(default_factory=list)
    objects: dict[str, str] = field(default_factory=dict)
    local_roots: list[LocalRoot] = field(default_factory=list)
    members: dict[str, dict[str, Any]] = field(default_factory=dict)
    format: str = FORMAT
    format_version: int = FORMAT_VERSION

    def to_json(self) -> bytes:
        """The manifest as ``manifest.json`` holds it (indented, keys in a fixed order)."""
        return json.dumps(asdict(self), indent=1).encode()

    @classmethod
    def from_json(cls, data: bytes) -> "Manifest":
        """The manifest of ``data``.

        Raises:
            BrokenArchive: not a manifest of this format (member ``manifest.json``).
        """
        try:
            raw = json.loads(data)
            if raw.get("format") != FORMAT:
                raise ValueError(f"format {raw.get('format')!r} is not {FORMAT!r}")
            if int(raw.get("format_version", 0)) > FORMAT_VERSION:
                raise ValueError(f"format version {raw['format_version']} is newer than this v3d's "
                                 f"({FORMAT_VERSION}): restore it with the v3d that made it")
            return cls(
                **{k: raw[k] for k in ("v3d_version", "schema_revision", "backup_id", "created_at", "engine")},
                tables=[TableEntry(**t) for t in raw["tables"]], objects=dict(raw["objects"]),
                local_roots=[LocalRoot(**r) for r in raw["local_roots"]], members=dict(raw["members"]),
                format=raw["format"], format_version=int(raw["format_version"]))
        except (ValueError, KeyError, TypeError, AttributeError) as exc:
            raise BrokenArchive(f"{MANIFEST}: not a v3d backup manifest ({exc})", MANIFEST) from None


class ArchiveWriter:
    """Writes the archive's members into a zip, hashing each as it goes; :meth:`close` adds the manifest.

    Table rows are deflated (JSON text shrinks about tenfold, at the fastest level: the backup's time is the
    database's read), store objects stored as they are (images and zips are compressed already).
    """

    def __init__(self, target: Path, manifest: Manifest) -> None:
        self.manifest = manifest
        self._target = target
        self._file = open_secret(target)
        self._zip = zipfile.ZipFile(self._file, "w", allowZip64=True)

    def member(self, name: str, compress: bool) -> "_HashedMember":
        """A member ``name`` open for writing (a context manager; its digest is recorded when it closes)."""
        if name in self.manifest.members or name == MANIFEST:
            raise ValueError(f"archive member {name!r} written twice")
        info = zipfile.ZipInfo(name, date_time=(1980, 1, 1, 0, 0, 0))
        info.compress_type = zipfile.ZIP_DEFLATED if compress else zipfile.ZIP_STORED
        if compress:
            info._compresslevel = 1  # type: ignore[attr-defined]  # zipfile's own per-member level (3.7+)
        return _HashedMember(self, name, self._zip.open(info, "w", force_zip64=True))

    def copy(self, name: str, stream: BinaryIO) -> int:
        """Copy the open binary ``stream`` to the stored member ``name``; its size in bytes."""
        with self.member(name, compress=False) as out:
            for chunk in iter(lambda: stream.read(CHUNK_BYTES), b""):
                out.write(chunk)
            return out.size

    def close(self) -> None:
        """Write ``manifest.json`` (with each member's stored bytes' digest too, :func:`stored_digests`) and close the
        zip."""
        self._zip.fp.flush()  # type: ignore[union-attr]  # the members written so far, read back for their digests
        for name, digest in stored_digests(self._target, self._zip.infolist()).items():
            self.manifest.members[name]["stored_sha256"] = digest
        self._zip.writestr(zipfile.ZipInfo(MANIFEST, date_time=(1980, 1, 1, 0, 0, 0)), self.manifest.to_json())
        self._zip.close()
        self._file.close()

    def abort(self) -> None:
        """Close the zip without a manifest (the caller removes the file)."""
        try:
            self._zip.close()
        finally:
            self._file.close()


#: The mode of every archive v3d writes, and of its ``.part`` from its first byte: it holds every password and token
#: hash and the session key, so only its owner reads it, whatever the umask.
SECRET_MODE = 0o600


def open_secret(path: Path) -> BinaryIO:
    """``path`` created (or emptied) for writing and reading with mode :data:`SECRET_MODE` from the start, never
    through a symbolic link (``O_NOFOLLOW``: a link planted at the name is refused, its target left alone).

    Raises:
        OSError: the file cannot be made (a link at ``path`` included: ``ELOOP``).
    """
    fd = os.open(path, os.O_RDWR | os.O_CREAT | os.O_TRUNC | getattr(os, "O_NOFOLLOW", 0), SECRET_MODE)
    try:
        os.fchmod(fd, SECRET_MODE)  # a file left by an older run keeps its mode through O_CREAT: set it again
        return os.fdopen(fd, "w+b")
    except BaseException:
        os.close(fd)
        raise


class _HashedMember:
    def __init__(self, writer: ArchiveWriter, name: str, out: IO[bytes]) -> None:
        self._writer, self.name, self._out = writer, name, out
        self._hash = hashlib.sha256()
        self.size = 0

    def write(self, data: bytes) -> None:
        self._hash.update(data)
        self._out.write(data)
        self.size += len(data)

    def __enter__(self) -> "_HashedMember":
        return self

    def __exit__(self, *exc: object) -> None:
        self._out.close()
        if exc[0] is None:
            self._writer.manifest.members[self.name] = {"sha256": self._hash.hexdigest(), "size": self.size}


def stored_digests(path: Path, infos: list[zipfile.ZipInfo]) -> dict[str, str]:
    """The SHA-256 of each member's bytes as stored in the zip at ``path`` (compressed: a changed byte that
    decompresses to the same content, a deflate block's header bit, is seen too)."""
    out = {}
    with open(path, "rb") as f:
        for info in infos:
            f.seek(info.header_offset)
            header = f.read(30)
            f.seek(info.header_offset + 30 + int.from_bytes(header[26:28], "little")
                   + int.from_bytes(header[28:30], "little"))
            digest, left = hashlib.sha256(), info.compress_size
            while left > 0:
                chunk = f.read(min(CHUNK_BYTES, left))
                if not chunk:
                    break
                digest.update(chunk)
                left -= len(chunk)
            out[info.filename] = digest.hexdigest()
    return out


def read_manifest(archive: zipfile.ZipFile) -> Manifest:
    """The archive's manifest (not yet checked against its members: :func:`verify_archive`).

    Raises:
        BrokenArchive: no manifest, or an unreadable one.
    """
    try:
        data = archive.read(MANIFEST)
    except KeyError:
        raise BrokenArchive(f"{MANIFEST} is missing: not a complete v3d backup (one whose writing was cut short "
                            f"has none)", MANIFEST) from None
    except (zipfile.BadZipFile, OSError, EOFError) as exc:
        raise BrokenArchive(f"{MANIFEST}: unreadable ({exc})", MANIFEST) from None
    return Manifest.from_json(data)


def open_archive(path: Path) -> zipfile.ZipFile:
    """The archive at ``path`` opened for reading.

    Raises:
        BrokenArchive: not a zip file, or a cut one (its directory is at the end and missing).
        FileNotFoundError: no such file.
    """
    if not path.is_file():
        raise FileNotFoundError(f"{path}: no such archive")
    try:
        return zipfile.ZipFile(path)
    except (zipfile.BadZipFile, OSError, EOFError) as exc:
        raise BrokenArchive(f"{path.name}: not a complete zip archive ({exc}): a backup cut short or another "
                            f"file") from None


def verify_archive(path: Path, progress: Any = None, max_line: Optional[int] = None) -> Manifest:
    """Check every member of the archive at ``path`` against its manifest (module docstring); its manifest.

    ``progress(stage, done, total)`` (``app.core.progress.Progress``), when given, is told the bytes hashed.
    ``max_line``: the longest line a table member may hold (bytes; :class:`LineTooLong` past it), checked in the same
    read, so a restore refuses such a table before it writes anything.

    Raises:
        BrokenArchive: the first member that fails, named (missing, unlisted, unreadable, another digest or size, a
            line past ``max_line``).
        FileNotFoundError: no such file.
    """
    with open_archive(path) as archive:
        manifest = read_manifest(archive)
        names = {i.filename for i in archive.infolist()}
        unlisted = sorted(names - set(manifest.members) - {MANIFEST})
        if unlisted:
            raise BrokenArchive(f"{unlisted[0]}: in the archive but not in its manifest", unlisted[0])
        sizes = {name: declared_size(name, expected) for name, expected in manifest.members.items()}
        tables = {t.member for t in manifest.tables}
        total = sum(sizes.values())
        done = 0
        for name, expected in manifest.members.items():
            if name not in names:
                raise BrokenArchive(f"{name}: listed in the manifest but missing from the archive", name)
            size = sizes[name]
            if archive.getinfo(name).file_size != size:
                raise BrokenArchive(f"{name}: the zip says it holds {archive.getinfo(name).file_size:,} bytes, the "
                                    f"manifest {size:,}: the member is broken or was changed", name)
            digest = hashlib.sha256()
            read = 0
            lines_of = _LineBound(name, max_line) if max_line is not None and name in tables else None
            try:
                with archive.open(name) as stream:
                    # never more than one byte past what the manifest declares: a member that inflates beyond it
                    # (a zip bomb whose header lies too) is refused at that byte, not read to its end
                    while chunk := stream.read(min(CHUNK_BYTES, size - read + 1)):
                        read += len(chunk)
                        if read > size:
                            raise BrokenArchive(f"{name}: holds more than the {size:,} bytes its manifest declares "
                                                f"(refused at the first byte past them)", name)
                        digest.update(chunk)
                        if lines_of is not None:
                            lines_of.feed(chunk)
                        done += len(chunk)
                        if progress is not None:
                            progress("verify", done, total)
            except (zipfile.BadZipFile, zlib.error, OSError, EOFError, ValueError) as exc:  # a CRC, a cut file
                if isinstance(exc, BrokenArchive):
                    raise
                raise BrokenArchive(f"{name}: unreadable ({type(exc).__name__}: {exc})", name) from None
            if read != size:
                raise BrokenArchive(f"{name}: holds {read:,} bytes, its manifest declares {size:,}", name)
            if digest.hexdigest() != expected.get("sha256"):
                raise BrokenArchive(f"{name}: its SHA-256 is {digest.hexdigest()}, the manifest says "
                                    f"{expected.get('sha256')}: the member is broken or was changed", name)
        stored = stored_digests(path, [archive.getinfo(n) for n in manifest.members])
        for name, expected in manifest.members.items():
            if "stored_sha256" in expected and stored[name] != expected["stored_sha256"]:
                raise BrokenArchive(f"{name}: its stored bytes' SHA-256 is {stored[name]}, the manifest says "
                                    f"{expected['stored_sha256']}: the member is broken or was changed", name)
        _check_manifest_names(manifest)
    return manifest


def declared_size(name: str, entry: dict[str, Any]) -> int:
    """The size in bytes the manifest declares for member ``name`` (its ``entry`` in ``members``).

    Raises:
        BrokenArchive: none, or not a whole number of bytes (a hand-made manifest).
    """
    size = entry.get("size") if isinstance(entry, dict) else None
    if not isinstance(size, int) or isinstance(size, bool) or size < 0:
        raise BrokenArchive(f"{MANIFEST}: member {name!r} declares no size in bytes", MANIFEST)
    return size


def _check_manifest_names(manifest: Manifest) -> None:
    """Refuse a manifest whose members named for tables and objects are not its own members (a hand-made archive)."""
    named = [t.member for t in manifest.tables] + list(manifest.objects.values())
    for member in named:
        if member not in manifest.members:
            raise BrokenArchive(f"{member}: named by the manifest's tables or objects but not a member", member)


class LineTooLong(BrokenArchive):
    """A table member's line (one row) longer than a restore reads (``V3D_RESTORE_MAX_LINE_MB``)."""


class _LineBound:
    """Follows a member's lines through the chunks it is read in, holding no line: refuses one longer than
    ``max_bytes`` (:class:`LineTooLong`, its number named) as soon as its bytes are seen."""

    def __init__(self, member: str, max_bytes: int) -> None:
        self.member, self.max_bytes = member, max_bytes
        self.run = 0  # bytes of the line being read, so far
        self.number = 1

    def feed(self, chunk: bytes) -> None:
        parts = chunk.split(b"\n")
        for i, part in enumerate(parts):
            self.run += len(part)
            if self.run > self.max_bytes:
                raise LineTooLong(f"{self.member}: line {self.number} is longer than {self.max_bytes:,} bytes, the "
                                  f"longest row a restore reads (V3D_RESTORE_MAX_LINE_MB)", self.member)
            if i < len(parts) - 1:  # a newline ends it
                self.run = 0
                self.number += 1


def lines(archive: zipfile.ZipFile, member: str, max_bytes: int) -> Iterator[bytes]:
    """The lines of the member ``member`` (a table's rows), read as a stream, none held past ``max_bytes``.

    Raises:
        LineTooLong: a line longer than ``max_bytes`` (named with its number), at its ``max_bytes + 1``-th byte.
    """
    with archive.open(member) as stream:
        number = 0
        while line := stream.readline(max_bytes + 1):
            number += 1
            if len(line.rstrip(b"\n")) > max_bytes:
                raise LineTooLong(f"{member}: line {number} is longer than {max_bytes:,} bytes, the longest row a "
                                  f"restore reads (V3D_RESTORE_MAX_LINE_MB)", member)
            if line.strip():
                yield line


def replace_into(part: Path, target: Path) -> None:
    """Rename the complete ``part`` to ``target`` (the same folder: atomic), flushed to disk first."""
    with open(part, "rb") as f:
        os.fsync(f.fileno())
    os.replace(part, target)


def s3_location(name: str, what: str) -> Optional[tuple[str, str]]:
    """The bucket and key of an archive named ``s3://BUCKET/KEY``; None for any other name (a file path).

    Raises:
        ValueError: an ``s3://`` name without a bucket or a key, naming ``what`` it was given as (an archive, a
            destination).
    """
    if not name.startswith("s3://"):
        return None
    parts = urlsplit(name)
    key = parts.path.strip("/")
    if not parts.netloc or not key:
        raise ValueError(f"{name!r}: an S3 {what} is s3://BUCKET/KEY")
    return parts.netloc, key
