"""Reading the files of a dataset safely: JSON (UTF-8, errors naming the file), zip archives whose
entry names are checked before anything is read (an absolute name, a drive or a ``..`` component
refuses the archive), the ``*.json`` files of a folder or zip, image sizes. No database.

Every problem raises :class:`~app.core.errors.DatasetError` naming the file (``archive.zip!member``
inside zips) and the field, except :func:`json_files`, the lister of the offline commands, which raises
:class:`InputFileError`.
"""
from __future__ import annotations

import contextlib
import functools
import gc
import json
import math
import os
import struct
import sys
import zipfile
import zlib
from dataclasses import dataclass
from pathlib import Path, PurePosixPath
from typing import IO, Any, Callable, Iterator, Mapping

import orjson

from app.core.config import Settings
from app.core.errors import DatasetError

#: Image files a frame may come with.
IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg")


def json_problem(exc: Exception) -> str | None:
    """What is wrong with a JSON text whose parsing raised ``exc``, in words, or None when ``exc`` is not a parse
    failure: not UTF-8, invalid or truncated, nested deeper than Python's parser goes (``RecursionError``), or an
    integer longer than Python converts (``ValueError``, ``sys.get_int_max_str_digits``)."""
    if isinstance(exc, UnicodeDecodeError):
        return f"not UTF-8 text ({exc.reason} at byte {exc.start})"
    if isinstance(exc, json.JSONDecodeError):
        return f"invalid or truncated JSON: {exc.msg} at line {exc.lineno} column {exc.colno}"
    if isinstance(exc, RecursionError):
        return "JSON nested too deep to be read (arrays or objects inside one another, thousands deep)"
    if isinstance(exc, ValueError) and "digits" in str(exc):
        return f"an integer of more than {sys.get_int_max_str_digits()} digits, longer than can be read"
    return None


@contextlib.contextmanager
def no_collections() -> Iterator[None]:
    """No garbage collection inside the block: for parsing a JSON text, and for reading what a reader needs of it
    before the parsed document is dropped. A parse makes containers no cycle can join (each is referenced by its
    parent alone), so a collection during it finds nothing, yet the count of new objects starts hundreds of young
    collections and full ones over the whole process (a labels file of 120,000 boxes: some 700 collections, half a
    second of an import); and the first collection after it traverses every object of the document still held. A
    document dropped inside the block is never traversed. The collector is started again only if it ran before
    (another thread may parse meanwhile: it then parses without collections too; no result changes)."""
    running = gc.isenabled()
    gc.disable()
    try:
        yield
    finally:
        if running:
            gc.enable()


def load_json_bytes(raw: bytes, where: str) -> Any:
    """``raw`` parsed as UTF-8 JSON; raises :class:`DatasetError` naming ``where`` (the file) otherwise
    (:func:`json_problem`). orjson parses first (three times faster than ``json``: a labels file may hold 120,000
    boxes), without garbage collections (:func:`no_collections`); a text it refuses is parsed by ``json``, whose answer
    stands, word for word (``NaN``, integers past 64 bits, lone surrogates, JSON nested past orjson's 1,024 levels, and
    every error's words)."""
    try:
        with no_collections():
            return orjson.loads(raw)
    except orjson.JSONDecodeError:
        pass
    try:
        return json.loads(raw.decode("utf-8"))
    except (ValueError, RecursionError) as exc:
        problem = json_problem(exc)
        if problem is None:
            raise
        raise DatasetError(where, None, problem) from None


def load_json_file(path: Path) -> Any:
    """The JSON file ``path`` parsed; raises :class:`DatasetError` naming it when unreadable or invalid."""
    try:
        raw = path.read_bytes()
    except OSError as exc:
        raise DatasetError(path, None, f"cannot read: {exc.strerror}") from None
    return load_json_bytes(raw, str(path))


def read_text_file(path: Path, max_bytes: int, what: str = "text file") -> str:
    """The UTF-8 text of a small input file (a BOM dropped), refused beyond ``max_bytes``.

    Raises:
        DatasetError: naming ``path``: missing, larger than ``max_bytes``, unreadable or not UTF-8 (``what``
            says what it should have been, e.g. "CSV").
    """
    try:
        if path.stat().st_size > max_bytes:
            raise DatasetError(path, None, f"larger than {max_bytes} bytes")
        return path.read_text(encoding="utf-8-sig")
    except FileNotFoundError:
        raise DatasetError(path, None, "missing") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise DatasetError(path, None, f"not a readable {what}: {exc}") from exc


# ----- the closed world of an import: every file it reads lies inside the dataset's own folder
def dataset_root(path: str | Path) -> Path:
    """The folder an import of ``path`` may read from, resolved: ``path`` itself when it is a folder, the
    folder holding it when it is a file (a ``Labels-v3.json``, a zip of a calibration set).

    >>> import tempfile
    >>> d = Path(tempfile.mkdtemp())
    >>> _ = (d / "set.zip").write_bytes(b"")
    >>> dataset_root(d) == d.resolve(), dataset_root(d / "set.zip") == d.resolve()
    (True, True)
    """
    resolved = Path(path).expanduser().resolve()
    return resolved if resolved.is_dir() or not resolved.exists() else resolved.parent


def inside_dataset(root: Path, path: str | Path, field: str | None = None) -> Path:
    """``path`` resolved (``..`` and symbolic links followed; a relative ``path`` from the working directory, as
    the input it was built from), when it lies inside the dataset folder ``root`` (:func:`dataset_root`); a link
    inside the dataset that points out of it is refused.

    Raises:
        DatasetError: naming ``path`` (as the dataset names it, not where a link points) and ``field``,
            when it resolves outside ``root``; nothing is read from it.

    >>> import os, tempfile
    >>> d = Path(tempfile.mkdtemp()).resolve()
    >>> os.symlink("/etc/passwd", d / "0.png")
    >>> inside_dataset(d, d / "1.png") == d / "1.png"
    True
    >>> inside_dataset(d, d / "0.png", "image")  # doctest: +ELLIPSIS, +NORMALIZE_WHITESPACE
    Traceback (most recent call last):
    ...
    app.core.errors.DatasetError: ...0.png: image: resolves outside the dataset's folder (a link or '..' leading out
    of it); an import reads only inside its own folder
    """
    root = Path(root).resolve()
    # ``path`` is what the reader built from its input (the folder or file given, joined with names from the
    # dataset): a relative one is relative to the working directory like that input, never to ``root``
    # (joined to ``root`` it named a file that does not exist inside it, so a link leading out passed).
    resolved = Path(path).expanduser().resolve()
    if not resolved.is_relative_to(root):
        raise DatasetError(path, field, "resolves outside the dataset's folder (a link or '..' leading out of it); "
                                        "an import reads only inside its own folder")
    return resolved


def dataset_relative(root: Path, path: str | Path, field: str | None = None) -> str:
    """``path`` as stored in the database: POSIX, relative to the dataset folder ``root``
    (:func:`inside_dataset` checks it first)."""
    return inside_dataset(root, path, field).relative_to(Path(root).resolve()).as_posix()


def refuse_links_out(path: str | Path, field: str = "path") -> None:
    """Walk the dataset ``path`` (a folder, links not followed; a file alone) and refuse it when a
    symbolic link in it resolves outside it (:func:`inside_dataset`): the check ``POST /api/imports``
    answers at once (400), before the import job reads anything. Readers check each file they read too.

    Raises:
        DatasetError: naming the first link leading out (its path inside the dataset) and ``field``.
    """
    root = dataset_root(path)
    start = Path(path)
    if not start.is_dir():
        inside_dataset(root, start, field)
        return
    for folder, dirs, files in os.walk(start, followlinks=False):
        for name in sorted(dirs + files):
            entry = Path(folder) / name
            if entry.is_symlink():
                inside_dataset(root, entry, field)


def is_safe_member(name: str) -> bool:
    """True for a relative archive member name without ``..``, drive or backslash tricks.

    >>> is_safe_member("12_1.png"), is_safe_member("frames/12.png")
    (True, True)
    >>> is_safe_member("../secret.png"), is_safe_member("/etc/passwd"), is_safe_member("a\\\\..\\\\b")
    (False, False, False)
    """
    posix = name.replace("\\", "/")
    parts = PurePosixPath(posix).parts
    return bool(parts) and not posix.startswith("/") and ".." not in parts and ":" not in parts[0]


def safe_names(zf: zipfile.ZipFile, zip_path: Path) -> list[str]:
    """The archive's entry names; raises when one is absolute or has a ``..`` component
    (:func:`is_safe_member`, the rule the image route applies too)."""
    names = zf.namelist()
    for name in names:
        if name and not is_safe_member(name):
            raise DatasetError(zip_path, f"entry {name!r}", "unsafe entry name (absolute, drive or '..' "
                                                            "component); refusing the archive")
    return names


#: Default of ``V3D_MAX_ZIP_RATIO``: the most a zip member, or a whole zip, may unpack to per byte it packs, beyond
#: its first :data:`RATIO_FLOOR_BYTES` (a zip bomb of repeated bytes packs about 1000:1; JSON labels about 10:1,
#: images about 1:1).
MAX_ZIP_RATIO = 100.0
#: What any member or archive may unpack to whatever its ratio (a small file of repeated bytes packs far beyond
#: :data:`MAX_ZIP_RATIO` and is no bomb).
RATIO_FLOOR_BYTES = 1 << 20


def ratio_cap(packed_bytes: int, max_ratio: float = MAX_ZIP_RATIO) -> int:
    """The most bytes ``packed_bytes`` of a zip (a member's compressed size, or a whole archive's) may unpack
    to: :data:`RATIO_FLOOR_BYTES` plus ``max_ratio`` per packed byte.

    >>> ratio_cap(0), ratio_cap(300_000)
    (1048576, 31048576)
    """
    return RATIO_FLOOR_BYTES + int(max_ratio * max(packed_bytes, 0))


def member_chunks(zf: zipfile.ZipFile, info: zipfile.ZipInfo, where: str, max_bytes: int,
                  chunk_bytes: int = 1 << 20) -> Iterator[bytes]:
    """The unpacked bytes of the zip member ``info``, ``chunk_bytes`` at a time, counted as they come: the
    member is refused as soon as it has given more than ``max_bytes`` (whatever its header declared), so no
    more than ``max_bytes + chunk_bytes`` are ever held or written.

    Raises:
        DatasetError: naming ``where`` (``archive.zip!member``), past ``max_bytes``.
    """
    seen = 0
    with zf.open(info) as src:
        while chunk := src.read(chunk_bytes):
            seen += len(chunk)
            if seen > max_bytes:
                raise DatasetError(where, None, f"unpacks to more than {max_bytes:,} bytes (counted while unpacking; "
                                                "a zip bomb); refusing the archive")
            yield chunk


def open_zip(path: Path) -> zipfile.ZipFile:
    """The zip archive ``path``; raises :class:`DatasetError` naming it when it is not a readable zip."""
    try:
        return zipfile.ZipFile(path)
    except (zipfile.BadZipFile, OSError) as exc:
        raise DatasetError(path, None, f"not a readable zip archive ({exc})") from None


def mapping(value: Any, file: str | Path, where: str) -> Mapping[str, Any]:
    """``value`` when it is a JSON object; raises :class:`DatasetError` naming ``file`` and ``where`` otherwise."""
    if not isinstance(value, Mapping):
        raise DatasetError(file, where, f"expected a JSON object, got {type(value).__name__}")
    return value


def image_size_field(meta: Any, file: str | Path, where: str) -> tuple[int, int]:
    """``(width, height)`` in pixels of an ``imageMetadata`` object (integers > 1), else :class:`DatasetError`."""
    meta = mapping(meta, file, where)
    out = []
    for key in ("width", "height"):
        v = meta.get(key)
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) or v != int(v) or v <= 1:
            raise DatasetError(file, f"{where}.{key}", f"image {key} must be an integer > 1, got {v!r}")
        out.append(int(v))
    return out[0], out[1]


#: Default of ``V3D_MAX_IMAGE_PIXELS``: the most pixels (width x height) an imported image may have.
MAX_IMAGE_PIXELS = 50_000_000
#: Image types a frame may be, as :func:`image_header` names them, and the media type each is served as.
IMAGE_MEDIA_TYPES = {"png": "image/png", "jpeg": "image/jpeg"}


@dataclass(frozen=True)
class ImageHeader:
    """What an image's header says: ``type`` ("png" or "jpeg", a key of :data:`IMAGE_MEDIA_TYPES`) and
    its size in pixels."""

    type: str
    width: int
    height: int


def image_header(stream: IO[bytes], where: str, max_pixels: int = MAX_IMAGE_PIXELS) -> ImageHeader:
    """Type and size of the image in the open binary ``stream`` (a file, or a zip member opened with
    ``ZipFile.open``: streamed, never read whole), from its header only: a PNG's signature and ``IHDR`` chunk (the
    first 33 bytes, which the PNG specification puts first; its CRC checked), a JPEG's markers up to its frame header
    (``SOFn``), every segment before it skipped, never kept. Nothing else is read, so that a chunk or segment of tens
    of megabytes before the pixels costs nothing here (Pillow's ``Image.open`` reads and keeps each one); nothing is
    decoded.

    Raises:
        DatasetError: naming ``where``: not a PNG or JPEG (whatever its name says: an HTML page named
            ``0.png`` is refused), a broken header, or more than ``max_pixels`` pixels (``V3D_MAX_IMAGE_PIXELS``).

    >>> import io
    >>> from PIL import Image
    >>> def png(w, h):
    ...     buf = io.BytesIO()
    ...     Image.new("1", (w, h)).save(buf, "PNG")
    ...     return buf.getvalue()
    >>> image_header(io.BytesIO(png(960, 540)), "0.png")
    ImageHeader(type='png', width=960, height=540)
    >>> image_header(io.BytesIO(png(8000, 7000)), "big.png")  # doctest: +NORMALIZE_WHITESPACE
    Traceback (most recent call last):
    ...
    app.core.errors.DatasetError: big.png: image of 8000x7000 = 56,000,000 pixels, above V3D_MAX_IMAGE_PIXELS
    (50,000,000)
    >>> image_header(io.BytesIO(b"<html><script>alert(1)</script>"), "0.html")
    Traceback (most recent call last):
    ...
    app.core.errors.DatasetError: 0.html: not a PNG or JPEG image (read from its header; the name does not count)
    """
    try:
        try:
            found = _png_header(stream) or _jpeg_header(stream)
        except _JpegAfter as started:
            found = _jpeg_header(stream, started.head)
    except (OSError, EOFError, ValueError, zipfile.BadZipFile):
        found = None
    if found is None:
        raise DatasetError(where, None,
                           "not a PNG or JPEG image (read from its header; the name does not count)")
    kind, width, height = found
    if width < 1 or height < 1:
        raise DatasetError(where, None, f"image of {width}x{height} pixels")
    if width * height > max_pixels:
        raise DatasetError(where, None, f"image of {width}x{height} = {width * height:,} pixels, above "
                                        f"V3D_MAX_IMAGE_PIXELS ({max_pixels:,})")
    return ImageHeader(kind, width, height)


_PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
#: The bit depths each PNG colour type allows (PNG specification, table 11.1).
_PNG_DEPTHS = {0: {1, 2, 4, 8, 16}, 2: {8, 16}, 3: {1, 2, 4, 8}, 4: {8, 16}, 6: {8, 16}}
#: JPEG's start-of-frame markers (every ``SOFn`` but DHT C4, JPG C8 and DAC CC), which carry the image's size.
_JPEG_FRAMES = {0xC0, 0xC1, 0xC2, 0xC3, 0xC5, 0xC6, 0xC7, 0xC9, 0xCA, 0xCB, 0xCD, 0xCE, 0xCF}
#: Markers without a length (TEM, RST0-7): nothing to skip.
_JPEG_ALONE = {0x01, *range(0xD0, 0xD8)}


def _read_exactly(stream: IO[bytes], n: int) -> bytes:
    data = stream.read(n)
    if len(data) != n:
        raise EOFError("the image ends inside its header")
    return data


def _png_header(stream: IO[bytes]) -> tuple[str, int, int] | None:
    """("png", width, height) from the signature and ``IHDR``; None when the stream does not start as a PNG (only
    its first 8 bytes read then, and the stream put back when it can seek)."""
    start = stream.tell() if stream.seekable() else None
    head = stream.read(8)
    if head != _PNG_SIGNATURE:
        if start is not None:
            stream.seek(start)
            return None
        if head[:2] == b"\xff\xd8":  # a JPEG, read on from the bytes already read
            raise _JpegAfter(head)
        raise ValueError("neither a PNG nor a JPEG")
    chunk = _read_exactly(stream, 25)
    length, kind, data, crc = struct.unpack(">I", chunk[:4])[0], chunk[4:8], chunk[8:21], chunk[21:25]
    if length != 13 or kind != b"IHDR" or zlib.crc32(kind + data) != struct.unpack(">I", crc)[0]:
        raise ValueError("no valid IHDR chunk first")
    width, height, depth, colour = struct.unpack(">IIBB", data[:10])
    if depth not in _PNG_DEPTHS.get(colour, ()) or width >= 1 << 31 or height >= 1 << 31:
        raise ValueError("an IHDR of no PNG")
    return "png", width, height


class _JpegAfter(Exception):
    """A stream that cannot seek, found to start as a JPEG: the bytes read so far."""

    def __init__(self, head: bytes) -> None:
        self.head = head


def _skip(stream: IO[bytes], n: int) -> None:
    """Pass ``n`` bytes of ``stream``: a seek, or reads of at most 64 KiB dropped."""
    if stream.seekable():
        stream.seek(n, os.SEEK_CUR)
        return
    while n > 0:
        n -= len(_read_exactly(stream, min(n, 1 << 16)))


def _jpeg_header(stream: IO[bytes], head: bytes | None = None) -> tuple[str, int, int] | None:
    """("jpeg", width, height) from the first ``SOFn`` segment, every segment before it skipped; None when the stream
    does not start as a JPEG."""
    pending = bytearray(head if head is not None else stream.read(2))
    if pending[:2] != b"\xff\xd8":
        return None
    del pending[:2]

    def byte() -> int:
        if pending:
            return pending.pop(0)
        return _read_exactly(stream, 1)[0]

    while True:
        if byte() != 0xFF:
            raise ValueError("no JPEG marker where one belongs")
        marker = byte()
        while marker == 0xFF:  # fill bytes
            marker = byte()
        if marker in _JPEG_ALONE:
            continue
        if marker in (0xD8, 0xD9, 0xDA):  # another start, the end or the scan before any frame header
            raise ValueError("no JPEG frame header before the scan")
        length = (byte() << 8) | byte()
        if length < 2:
            raise ValueError("a JPEG segment shorter than its length field")
        if marker in _JPEG_FRAMES:
            if length < 7:
                raise ValueError("a JPEG frame header too short")
            _precision, height, width = byte(), (byte() << 8) | byte(), (byte() << 8) | byte()
            return "jpeg", width, height
        rest = length - 2
        taken = min(rest, len(pending))
        del pending[:taken]
        _skip(stream, rest - taken)


#: The most bytes an imported image file or zip member may have by default (``Settings.max_image_mb``,
#: ``V3D_MAX_IMAGE_MB``); above it the import is refused naming the file, so that what is kept and served costs at most
#: that much to read, streamed (never held: :func:`image_header` reads the header alone).
MAX_IMAGE_BYTES = int(Settings.model_fields["max_image_mb"].default * (1 << 20))


def _check_image_bytes(size: int, where: str, max_bytes: int) -> None:
    if size > max_bytes:
        raise DatasetError(where, None, f"an image of {size:,} bytes, more than the {max_bytes:,} "
                                        f"V3D_MAX_IMAGE_MB ({max_bytes / (1 << 20):g} MB) lets an image have")


def file_image_header(path: Path, where: str | Path, max_pixels: int = MAX_IMAGE_PIXELS,
                      max_bytes: int = MAX_IMAGE_BYTES) -> ImageHeader:
    """:func:`image_header` of the file ``path`` (``where`` names it in messages); a file above ``max_bytes``
    (``V3D_MAX_IMAGE_MB``) is refused, naming it and the setting."""
    try:
        with open(path, "rb") as fh:
            _check_image_bytes(os.fstat(fh.fileno()).st_size, str(where), max_bytes)
            return image_header(fh, str(where), max_pixels)
    except OSError as exc:
        raise DatasetError(where, None, f"cannot read: {exc.strerror}") from None


def member_image_header(zf: zipfile.ZipFile, member: str, where: str,
                        max_pixels: int = MAX_IMAGE_PIXELS, max_bytes: int = MAX_IMAGE_BYTES) -> ImageHeader:
    """:func:`image_header` of the zip member ``member`` (streamed out of the archive, never read whole); a member
    above ``max_bytes`` (``V3D_MAX_IMAGE_MB``) is refused, naming it and the setting."""
    try:
        _check_image_bytes(zf.getinfo(member).file_size, where, max_bytes)
        with zf.open(member) as fh:
            return image_header(fh, where, max_pixels)
    except (KeyError, OSError, zipfile.BadZipFile) as exc:
        raise DatasetError(where, None, f"cannot read ({type(exc).__name__})") from None


# ----- the JSON files of a folder or zip (the offline commands' inputs and SoccerNet-calibration sets)
class InputFileError(Exception):
    """An input path or file of a command cannot be used; the message names the path or file."""


@dataclass(frozen=True)
class JsonFile:
    """One ``*.json`` file of a folder or zip."""

    label: str  # how to name the file in messages, e.g. "cams.zip:test/camera_1.json"
    name: str  # its path inside the folder or zip (POSIX)
    read: Callable[[], bytes]

    def load(self) -> Any:
        """The parsed JSON. Raises :class:`InputFileError` naming the file when it is not UTF-8 JSON."""
        try:
            return json.loads(self.read().decode("utf-8"))
        except (ValueError, RecursionError) as exc:
            problem = json_problem(exc)
            if problem is None:
                raise
            raise InputFileError(f"{self.label}: not readable JSON ({problem})") from None


#: The most a JSON member of a zip may unpack to (a SoccerNet-calibration frame file or a camera is a few kB): a
#: member is read whole to be parsed, so a small member unpacking to gigabytes (a zip bomb) is refused from the
#: archive's directory before anything is read.
MAX_JSON_MEMBER_BYTES = 64 * 1024 * 1024


def json_files(path: Path, what: str) -> list[JsonFile]:
    """Every ``*.json`` file of a folder (recursively) or a zip (``__MACOSX/`` left out), sorted by path.

    Raises:
        InputFileError: ``path`` is missing, or neither a folder nor a zip archive (the message
            starts with ``what``, the argument's name); a zip's JSON member unpacks to more than
            :data:`MAX_JSON_MEMBER_BYTES` or :func:`ratio_cap` of its compressed size (from the archive's
            directory; the read counts the bytes again: :func:`member_chunks`).
    """
    if not path.exists():
        raise InputFileError(f"{what}: no such file or folder: {path}")
    if path.is_dir():
        return [JsonFile(str(p), p.relative_to(path).as_posix(), p.read_bytes)
                for p in sorted(path.rglob("*.json")) if p.is_file()]
    if zipfile.is_zipfile(path):
        archive = zipfile.ZipFile(path)
        names = sorted(n for n in archive.namelist()
                       if n.endswith(".json") and not n.endswith("/") and not n.startswith("__MACOSX/"))
        for n in names:
            info = archive.getinfo(n)
            size = info.file_size  # zipfile never unpacks a member past its declared size
            if size > MAX_JSON_MEMBER_BYTES:
                archive.close()
                raise InputFileError(f"{path}:{n}: unpacks to {size} bytes, more than the "
                                     f"{MAX_JSON_MEMBER_BYTES} a JSON file may hold")
            if size > ratio_cap(info.compress_size):
                archive.close()
                raise InputFileError(f"{path}:{n}: unpacks to {size} bytes from {info.compress_size}, more than "
                                     f"{MAX_ZIP_RATIO:g} to 1 (a zip bomb)")

        def read(n: str) -> bytes:
            info = archive.getinfo(n)
            cap = min(MAX_JSON_MEMBER_BYTES, ratio_cap(info.compress_size))
            return b"".join(member_chunks(archive, info, f"{path}!{n}", cap))

        return [JsonFile(f"{path}:{n}", n, functools.partial(read, n)) for n in names]
    raise InputFileError(f"{what}: {path} is neither a folder nor a zip archive")
