"""The storage interface every kept file goes through, and its folder implementation (:class:`FileStorage`).

A key is a relative POSIX name (``uploads/20261127-101500-ab12cd34/game/Frames-v3.zip``, ``exports/job-7-coco.zip``):
no empty, ``.`` or ``..`` component, no backslash, never absolute (:func:`checked_key`), so that no key reaches
outside its store. A missing key raises :class:`FileNotFoundError` in every store; any other failure of the store
raises :class:`StorageError` (an :class:`OSError`), so that callers that already handle a missing or unreadable file
handle a store's failures the same way.
"""
from __future__ import annotations

import contextlib
import os
import shutil
import tempfile
from abc import ABC, abstractmethod
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import BinaryIO, Optional

#: The longest name of one file (bytes), on the file systems a folder store lies on (ext4, XFS, APFS: 255).
NAME_MAX_BYTES = 255


class StorageError(OSError):
    """The store failed (unreachable, refused, broken answer, no answer in time): anything but a missing key. Its
    message says so in words, naming the store (the API answers it 503 with ``Retry-After``)."""


class KeyTooLong(ValueError):
    """A key the store cannot hold (S3: its full name above :data:`MAX_S3_KEY_BYTES` bytes of UTF-8). ``key`` the key,
    ``size`` its full name's bytes, ``limit`` the store's."""

    def __init__(self, key: str, size: int, limit: int, url: str) -> None:
        self.key, self.size, self.limit = key, size, limit
        super().__init__(f"{key!r} makes a name of {size:,} bytes in the store {url}, which holds at most {limit:,}")


#: The longest object name S3 holds (bytes of UTF-8).
MAX_S3_KEY_BYTES = 1024


@dataclass(frozen=True)
class StoredObject:
    """One stored file: its ``key``, ``size`` (bytes), ``modified`` (seconds since the epoch) and ``etag`` (a
    strong validator of its content: the S3 ETag, or the file's modification time and size)."""

    key: str
    size: int
    modified: float
    etag: str


def checked_key(key: str) -> str:
    """``key`` when it is a safe relative POSIX name (see the module docstring).

    >>> checked_key("exports/job-1-coco.zip")
    'exports/job-1-coco.zip'
    >>> checked_key("uploads/../secret")
    Traceback (most recent call last):
    ...
    ValueError: unsafe storage key 'uploads/../secret'
    """
    parts = key.split("/")
    if not key or "\\" in key or key.startswith("/") or any(p in ("", ".", "..") for p in parts):
        raise ValueError(f"unsafe storage key {key!r}")
    return key


def join_key(*parts: str) -> str:
    """Key parts joined with ``/`` (empty parts and outer slashes dropped), checked (:func:`checked_key`).

    >>> join_key("uploads/", "x", "game/Frames-v3.zip")
    'uploads/x/game/Frames-v3.zip'
    """
    return checked_key("/".join(p.strip("/") for p in parts if p.strip("/")))


class Storage(ABC):
    """Where v3d keeps its files: uploads, frame images and archives, export results.

    ``url`` names the store as ``V3D_STORAGE_URL`` does (``file:///srv/v3d`` or ``s3://bucket/prefix``).
    """

    url: str

    def check_fits(self, key: str) -> str:
        """``key`` when the store can hold it (a folder: any safe key; S3: see :class:`KeyTooLong`).

        Raises:
            ValueError: an unsafe key (:func:`checked_key`); :class:`KeyTooLong`: a key too long for the store.
        """
        return checked_key(key)

    @abstractmethod
    def local_path(self, key: str) -> Optional[Path]:
        """The file (or folder) holding ``key`` on this machine when the store is a folder; None for a remote
        store (read it through :meth:`open` or :meth:`get_file`)."""

    @abstractmethod
    def put_file(self, key: str, source: Path) -> None:
        """Store the file ``source`` as ``key`` (replacing it; big files in parts)."""

    @abstractmethod
    def put_stream(self, key: str, stream: BinaryIO) -> None:
        """Store what the open binary ``stream`` holds from its position on as ``key`` (big ones in parts)."""

    @abstractmethod
    def get_file(self, key: str, target: Path) -> Path:
        """Copy ``key`` to the local file ``target`` (written beside it and renamed when complete); ``target``.

        Raises:
            FileNotFoundError: no such key.
        """

    @abstractmethod
    def open(self, key: str) -> BinaryIO:
        """``key`` as a seekable binary file (a remote store reads the ranges asked for, as ``zipfile`` seeks):
        read it, seek in it, close it.

        Raises:
            FileNotFoundError: no such key.
        """

    @abstractmethod
    def stat(self, key: str) -> StoredObject:
        """The stored file ``key``.

        Raises:
            FileNotFoundError: no such key (a folder of a file store is none either).
        """

    @abstractmethod
    def list(self, prefix: str) -> Iterator[StoredObject]:
        """Every stored file whose key starts with ``prefix/`` (``prefix`` a folder's key), in no given order."""

    @abstractmethod
    def delete(self, key: str) -> None:
        """Remove the file ``key`` (nothing when it is missing)."""

    def exists(self, key: str) -> bool:
        """True when the file ``key`` is stored."""
        try:
            self.stat(key)
        except FileNotFoundError:
            return False
        return True

    def delete_tree(self, prefix: str) -> None:
        """Remove every file under the folder key ``prefix`` (nothing when there is none)."""
        for obj in list(self.list(prefix)):
            self.delete(obj.key)

    def put_tree(self, prefix: str, folder: Path) -> None:
        """Store every file under the local ``folder`` as ``prefix/<its path relative to folder>``: all or nothing.
        Every key is checked before the first file is stored; when one cannot be stored, those stored are removed.

        Raises:
            KeyTooLong: a file's key is too long for the store (nothing stored).
            StorageError: the store failed (the files stored removed, as far as the store lets).
        """
        files = [(self.check_fits(join_key(prefix, path.relative_to(folder).as_posix())), path)
                 for path in sorted(folder.rglob("*")) if path.is_file()]
        stored: list[str] = []
        try:
            for key, path in files:
                self.put_file(key, path)
                stored.append(key)
        except BaseException:
            # only what was stored: a store that stopped answering is not asked again for nothing
            with contextlib.suppress(OSError):  # the store that failed may fail its cleaning too
                for key in stored:
                    self.delete(key)
            raise

    def get_tree(self, prefix: str, folder: Path) -> Path:
        """Copy every file under the folder key ``prefix`` into the local ``folder`` (made in a sibling
        ``.part`` folder and renamed when complete, so that a folder that exists is whole); ``folder``.

        Raises:
            FileNotFoundError: nothing is stored under ``prefix``.
        """
        objects = list(self.list(prefix))
        if not objects:
            raise FileNotFoundError(f"nothing stored under {prefix!r} in {self.url}")
        part = folder.with_name(folder.name + ".part")
        shutil.rmtree(part, ignore_errors=True)
        try:
            for obj in objects:
                relative = obj.key[len(prefix.rstrip("/")) + 1:]
                target = part.joinpath(*checked_key(relative).split("/"))
                target.parent.mkdir(parents=True, exist_ok=True)
                self.get_file(obj.key, target)
            os.replace(part, folder)
        except BaseException:
            shutil.rmtree(part, ignore_errors=True)
            raise
        return folder

    def url_for(self, key: str, expires_s: int = 300) -> Optional[str]:
        """A short-lived URL a client may read ``key`` from directly; None when the store has none (a folder)."""
        return None

    @abstractmethod
    def check_reachable(self) -> None:
        """One cheap request to the store, at start-up, so that a store that cannot be used is said at once.

        Raises:
            StorageError: the store cannot be used (unreachable, refusing v3d's credentials, no such bucket).
        """

    def key_refusal(self, key: str) -> Optional[str]:
        """Why this store cannot hold ``key`` (a checked key, :func:`checked_key`), in words; None when it can."""
        return None


class FileStorage(Storage):
    """A folder as the store (``file:///srv/v3d``; by default the jobs folder: the layout v3d always had)."""

    def __init__(self, root: Path) -> None:
        self.root = Path(root).expanduser().resolve()
        self.url = self.root.as_uri()

    def path(self, key: str) -> Path:
        """The file of ``key`` under the root."""
        return self.root.joinpath(*checked_key(key).split("/"))

    def local_path(self, key: str) -> Optional[Path]:
        """The file of ``key`` under the root."""
        return self.path(key)

    def key_refusal(self, key: str) -> Optional[str]:
        """A component of more than :data:`NAME_MAX_BYTES` bytes (UTF-8): no file system of this machine names it."""
        long = next((part for part in key.split("/") if len(part.encode()) > NAME_MAX_BYTES), None)
        if long is not None:
            return (f"{key!r}: its part {long[:40]!r}... is {len(long.encode())} bytes; a file name holds "
                    f"{NAME_MAX_BYTES}")
        return None

    def put_file(self, key: str, source: Path) -> None:
        """Copy ``source`` into place (nothing when it is the key's own file: an upload unpacked where it is
        kept)."""
        target = self.path(key)
        if Path(source).resolve() == target:
            return
        with open(source, "rb") as stream:
            self.put_stream(key, stream)

    def put_stream(self, key: str, stream: BinaryIO) -> None:
        """Write the stream beside the key's file and rename it into place when complete."""
        target = self.path(key)
        target.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(dir=target.parent, prefix=f".{target.name}.", suffix=".part")
        try:
            with os.fdopen(fd, "wb") as out:
                shutil.copyfileobj(stream, out, 1 << 20)
            os.replace(tmp, target)
        except BaseException:
            Path(tmp).unlink(missing_ok=True)
            raise

    def put_tree(self, prefix: str, folder: Path) -> None:
        """Nothing when ``folder`` is the prefix's own folder, else as :meth:`Storage.put_tree`."""
        if Path(folder).resolve() == self.path(prefix):
            return
        super().put_tree(prefix, folder)

    def get_file(self, key: str, target: Path) -> Path:
        """Copy the key's file to ``target``."""
        with open(self.path(key), "rb") as stream:
            target.parent.mkdir(parents=True, exist_ok=True)
            part = target.with_name(target.name + ".part")
            with open(part, "wb") as out:
                shutil.copyfileobj(stream, out, 1 << 20)
            os.replace(part, target)
        return target

    def open(self, key: str) -> BinaryIO:
        """The key's file, open for reading."""
        return open(self.path(key), "rb")

    def stat(self, key: str) -> StoredObject:
        """The key's file (a folder is no stored file: FileNotFoundError)."""
        path = self.path(key)
        st = path.stat()
        if not path.is_file():
            raise FileNotFoundError(f"{key!r} is not a stored file")
        return StoredObject(key, st.st_size, st.st_mtime, f"{st.st_mtime_ns:x}-{st.st_size:x}")

    def list(self, prefix: str) -> Iterator[StoredObject]:
        """The files under the prefix's folder."""
        folder = self.path(prefix)
        if not folder.is_dir():
            return
        for path in folder.rglob("*"):
            if path.is_file():
                key = path.relative_to(self.root).as_posix()
                st = path.stat()
                yield StoredObject(key, st.st_size, st.st_mtime, f"{st.st_mtime_ns:x}-{st.st_size:x}")

    def delete(self, key: str) -> None:
        """Remove the key's file."""
        self.path(key).unlink(missing_ok=True)

    def check_reachable(self) -> None:
        """The root folder is made if missing and can be written."""
        try:
            self.root.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise StorageError(f"the file store {self.url} cannot be used: {exc.strerror}") from None
        if not os.access(self.root, os.W_OK | os.X_OK):
            raise StorageError(f"the file store {self.url} cannot be used: v3d may not write in it")

    def delete_tree(self, prefix: str) -> None:
        """Remove the prefix's folder."""
        shutil.rmtree(self.path(prefix), ignore_errors=True)
