"""Uploads and zip archives from outside: received to disk under a size limit, unpacked safely.

One home for the rules every upload follows (the dataset imports of ``POST /api/imports`` and the
predictions of ``POST /api/evaluations/monocular``):

* every upload is bounded by a setting in MB (:func:`upload_limit`): ``V3D_MAX_UPLOAD_MB`` for all, and below it the
  setting an upload route or an import format declares as its own (the predictions of the monocular benchmark:
  ``V3D_MAX_PREDICTIONS_MB``), enforced while the body streams (``app.api.bodies``);
* :func:`receive` copies an upload to a file chunk by chunk, counting bytes, and stops at the limit
  (:class:`UploadTooLarge`, HTTP 413) without ever holding the upload in memory;
* :func:`unpack_zip` checks the whole central directory before writing anything: every member name
  is relative without ``..``, drive or backslash tricks (``app.datasets.files.is_safe_member``), no member is a
  symbolic link, names are unique, the member count and the total uncompressed size (members of nested
  zips included) stay under the limits, and so does the compression ratio (``V3D_MAX_ZIP_RATIO``, 100:1
  beyond the first MiB, ``app.datasets.files.ratio_cap``) of each member and of each archive (nested ones
  included) and, where the caller bounds it, each extracted member's size (zip bombs); then extracts, counting
  the bytes really written against the same bounds (``app.datasets.files.member_chunks``: a header that lies
  gains nothing), and checks every image (``.png``, ``.jpg``, ``.jpeg``, in nested zips too) from its header,
  streamed (``app.datasets.files.image_header``: PNG or JPEG, at most ``V3D_MAX_IMAGE_PIXELS``; nothing is
  decoded): a file named like an image that is not one is refused naming it. Refusals raise
  :class:`~app.core.errors.DatasetError` naming the archive and the member (HTTP 400) and leave
  nothing extracted.

``zipfile`` never yields more than a member's declared size (it stops there and checks the CRC), so
the declared sizes checked before extraction already bound what extraction can write; the count while
writing holds the bounds whatever the reader does.
"""
from __future__ import annotations

import shutil
import stat
import zipfile
from dataclasses import dataclass
from pathlib import Path
from typing import IO, BinaryIO, Callable, Iterable

from app.core.config import Settings
from app.core.errors import DatasetError, ServiceError
from app.datasets.files import MAX_IMAGE_PIXELS, MAX_ZIP_RATIO, image_header, is_safe_member, member_chunks, ratio_cap

#: File names decoded to check they are images.
IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg")
_CHUNK = 1 << 20
MB = 1 << 20


#: The setting bounding every upload (MB); a route or an import format may declare a smaller one of its own.
MAX_UPLOAD_SETTING = "V3D_MAX_UPLOAD_MB"


class UploadTooLarge(ServiceError):
    """An upload above the size limit (HTTP 413) named by ``setting``; nothing of it is kept."""

    def __init__(self, limit_bytes: int, field: str, setting: str = MAX_UPLOAD_SETTING) -> None:
        super().__init__(f"{field}: the upload is larger than the limit of {limit_bytes / MB:g} MB ({setting})")
        self.field = field


@dataclass(frozen=True)
class ArchiveLimits:
    """Bounds of an uploaded zip: ``max_members`` members and ``max_unpacked_bytes`` uncompressed bytes
    in all, nested image zips included; each member and each archive unpacking to at most
    ``app.datasets.files.ratio_cap`` of its packed bytes at ``max_ratio``; each extracted member to at most
    ``max_member_bytes`` (None: no bound of its own)."""

    max_members: int
    max_unpacked_bytes: int
    max_image_pixels: int = MAX_IMAGE_PIXELS
    max_ratio: float = MAX_ZIP_RATIO
    max_member_bytes: int | None = None

    @classmethod
    def from_settings(cls, settings: Settings, max_member_bytes: int | None = None) -> "ArchiveLimits":
        """``V3D_MAX_UPLOAD_MEMBERS``, ``V3D_MAX_UNPACKED_MB``, ``V3D_MAX_IMAGE_PIXELS`` and ``V3D_MAX_ZIP_RATIO``;
        ``max_member_bytes`` as given."""
        return cls(settings.max_upload_members, int(settings.max_unpacked_mb * MB), settings.max_image_pixels,
                   settings.max_zip_ratio, max_member_bytes)


def upload_limit_bytes(settings: Settings) -> int:
    """``V3D_MAX_UPLOAD_MB`` in bytes."""
    return int(settings.max_upload_mb * MB)


def upload_limit(settings: Settings, setting: str = MAX_UPLOAD_SETTING) -> tuple[int, str]:
    """The bytes an upload bounded by ``setting`` (the environment name of a setting in MB, e.g.
    ``V3D_MAX_PREDICTIONS_MB``) may carry, and the setting that binds: the smaller of it and ``V3D_MAX_UPLOAD_MB``,
    which bounds every upload.

    >>> upload_limit(Settings(_env_file=None, max_upload_mb=2048), "V3D_MAX_PREDICTIONS_MB")
    (67108864, 'V3D_MAX_PREDICTIONS_MB')
    >>> upload_limit(Settings(_env_file=None, max_upload_mb=0.25), "V3D_MAX_PREDICTIONS_MB")
    (262144, 'V3D_MAX_UPLOAD_MB')

    Raises:
        AttributeError: ``setting`` names no setting of :class:`~app.core.config.Settings`.
    """
    overall = upload_limit_bytes(settings)
    own = int(getattr(settings, setting.removeprefix("V3D_").lower()) * MB)
    return (own, setting) if own < overall else (overall, MAX_UPLOAD_SETTING)


def receive(chunks: Iterable[bytes], path: Path, limit_bytes: int, field: str = "file",
            setting: str = MAX_UPLOAD_SETTING) -> int:
    """Write ``chunks`` to ``path``, stopping as soon as more than ``limit_bytes`` arrived; returns the
    size written (bytes).

    Raises:
        UploadTooLarge: the limit (named ``setting``) was passed (the partial file is removed).
    """
    size = 0
    try:
        with open(path, "wb") as out:
            for chunk in chunks:
                size += len(chunk)
                if size > limit_bytes:
                    raise UploadTooLarge(limit_bytes, field, setting)
                out.write(chunk)
    except BaseException:
        path.unlink(missing_ok=True)
        raise
    return size


def file_chunks(handle: BinaryIO) -> Iterable[bytes]:
    """The content of an open binary file, 1 MB at a time."""
    return iter(lambda: handle.read(_CHUNK), b"")


def is_image_name(name: str) -> bool:
    """True for a member or file named like an image (:data:`IMAGE_SUFFIXES`, any case)."""
    return name.lower().endswith(IMAGE_SUFFIXES)


def check_image(stream: IO[bytes], where: str, max_pixels: int = MAX_IMAGE_PIXELS) -> None:
    """Check the image in the open binary ``stream`` from its header (``app.datasets.files.image_header``);
    raises :class:`DatasetError` naming ``where`` when it is not a PNG or JPEG within ``max_pixels``."""
    image_header(stream, where, max_pixels)


def _is_symlink(info: zipfile.ZipInfo) -> bool:
    return info.create_system == 3 and stat.S_ISLNK(info.external_attr >> 16)


def _checked_members(zf: zipfile.ZipFile, where: str, limits: ArchiveLimits, budget: list[int],
                     packed_bytes: int) -> list[zipfile.ZipInfo]:
    """The archive's members after the checks of the module docstring; ``budget`` is [members left,
    bytes left], shared with nested archives; ``packed_bytes`` the archive's own size."""
    seen: set[str] = set()
    infos = zf.infolist()
    total = 0
    for info in infos:
        name = info.filename
        if not is_safe_member(name):
            raise DatasetError(where, f"member {name!r}", "unsafe name (absolute, drive or '..' component); "
                                                          "refusing the archive")
        if _is_symlink(info):
            raise DatasetError(where, f"member {name!r}", "is a symbolic link; refusing the archive")
        key = name.rstrip("/")
        if key in seen:
            raise DatasetError(where, f"member {name!r}", "appears twice; refusing the archive")
        seen.add(key)
        budget[0] -= 1
        budget[1] -= info.file_size
        total += info.file_size
        if budget[0] < 0:
            raise DatasetError(where, None, f"more than {limits.max_members} members (V3D_MAX_UPLOAD_MEMBERS); "
                                            "refusing the archive")
        if budget[1] < 0:
            raise DatasetError(where, None, f"more than {limits.max_unpacked_bytes / MB:g} MB uncompressed "
                                            "(V3D_MAX_UNPACKED_MB); refusing the archive")
        if info.file_size > ratio_cap(info.compress_size, limits.max_ratio):
            raise DatasetError(where, f"member {name!r}", f"unpacks to {info.file_size:,} bytes from "
                                                          f"{info.compress_size:,}, more than {limits.max_ratio:g} to "
                                                          "1 (V3D_MAX_ZIP_RATIO; a zip bomb); refusing the archive")
    if total > ratio_cap(packed_bytes, limits.max_ratio):
        raise DatasetError(where, None, f"unpacks to {total:,} bytes from {packed_bytes:,}, more than "
                                        f"{limits.max_ratio:g} to 1 (V3D_MAX_ZIP_RATIO; a zip bomb); refusing the "
                                        "archive")
    return infos


def _check_nested(zf: zipfile.ZipFile, info: zipfile.ZipInfo, where: str, limits: ArchiveLimits,
                  budget: list[int]) -> None:
    """A zip inside the upload (e.g. a game's ``Frames-v3.zip``, read in place, never extracted): the
    same member checks, and its images decoded."""
    inner_where = f"{where}!{info.filename}"
    with zf.open(info) as handle:
        try:
            inner = zipfile.ZipFile(handle)
        except zipfile.BadZipFile as exc:
            raise DatasetError(inner_where, None, f"named like a zip but is not a readable one ({exc})") from None
        with inner:
            _check_inner(inner, inner_where, limits, budget, info.file_size)


def _check_inner(inner: zipfile.ZipFile, inner_where: str, limits: ArchiveLimits, budget: list[int],
                 packed_bytes: int) -> None:
    for member in _checked_members(inner, inner_where, limits, budget, packed_bytes):
        if not member.is_dir() and is_image_name(member.filename):
            with inner.open(member) as stream:
                check_image(stream, f"{inner_where}!{member.filename}", limits.max_image_pixels)


def _size_of(archive: Path | BinaryIO) -> int:
    """Bytes of the zip file ``archive`` (a path, or an open seekable file: its position is kept)."""
    if isinstance(archive, Path):
        return archive.stat().st_size
    here = archive.tell()
    try:
        return archive.seek(0, 2)
    finally:
        archive.seek(here)


def _extract(zf: zipfile.ZipFile, info: zipfile.ZipInfo, target: Path, where: str, limits: ArchiveLimits,
             left: list[int]) -> None:
    """Write the member ``info`` to ``target``, counting its bytes against its own bounds (the member's ratio,
    ``max_member_bytes``) and ``left[0]``, the bytes the whole archive may still unpack to."""
    cap = ratio_cap(info.compress_size, limits.max_ratio)
    if limits.max_member_bytes is not None:
        if info.file_size > limits.max_member_bytes:
            raise DatasetError(where, f"member {info.filename!r}",
                               f"unpacks to {info.file_size:,} bytes, more than the "
                                                                   f"{limits.max_member_bytes:,} such a file may hold")
        cap = min(cap, limits.max_member_bytes)
    with open(target, "wb") as out:
        for chunk in member_chunks(zf, info, f"{where}!{info.filename}", cap, _CHUNK):
            left[0] -= len(chunk)
            if left[0] < 0:
                raise DatasetError(where, None, "unpacks to more than its bounds (V3D_MAX_UNPACKED_MB, "
                                                "V3D_MAX_ZIP_RATIO; counted while unpacking); refusing the archive")
            out.write(chunk)


def unpack_zip(archive: Path | BinaryIO, dest: Path, limits: ArchiveLimits, *, where: str | None = None,
               keep: Callable[[str], bool] | None = None) -> Path:
    """Extract the zip ``archive`` into the folder ``dest`` (created) after the checks of the module
    docstring; returns ``dest``.

    Args:
        archive: the zip file on disk, or an open seekable binary file of it (an upload's spool).
        dest: the folder to extract into; removed again when the archive is refused.
        limits: member count, uncompressed size, compression ratio and extracted member size bounds.
        where: the name used in messages (default: the archive's file name).
        keep: extract only the members whose name it accepts (all are still checked).

    Raises:
        DatasetError: not a zip, an unsafe, linked or repeated member, too many members or bytes, a member
            or archive unpacking beyond ``limits.max_ratio`` to 1 or a member beyond ``limits.max_member_bytes``
            (from the directory, and counted while unpacking), a file named like an image that is not a PNG
            or JPEG within V3D_MAX_IMAGE_PIXELS (naming the archive and the member; nothing is left in ``dest``).
    """
    where = where or (archive.name if isinstance(archive, Path) else "upload.zip")
    try:
        zf = zipfile.ZipFile(archive)
    except (zipfile.BadZipFile, OSError) as exc:
        raise DatasetError(where, None, f"not a readable zip archive ({exc})") from None
    budget = [limits.max_members, limits.max_unpacked_bytes]
    packed = _size_of(archive)
    left = [min(limits.max_unpacked_bytes, ratio_cap(packed, limits.max_ratio))]
    dest.mkdir(parents=True, exist_ok=True)
    try:
        with zf:
            infos = _checked_members(zf, where, limits, budget, packed)
            root = dest.resolve()
            for info in infos:
                if info.is_dir() or (keep is not None and not keep(info.filename)):
                    continue
                target = (root / info.filename.replace("\\", "/")).resolve()
                if root not in target.parents:  # belt and braces: is_safe_member already refused it
                    raise DatasetError(where, f"member {info.filename!r}", "lands outside the destination")
                target.parent.mkdir(parents=True, exist_ok=True)
                _extract(zf, info, target, where, limits, left)
                if is_image_name(info.filename):
                    with open(target, "rb") as stream:
                        check_image(stream, f"{where}!{info.filename}", limits.max_image_pixels)
                elif info.filename.lower().endswith(".zip"):
                    _check_nested(zf, info, where, limits, budget)
    except zipfile.BadZipFile as exc:
        shutil.rmtree(dest, ignore_errors=True)
        raise DatasetError(where, None, f"corrupt zip archive ({exc})") from None
    except BaseException:
        shutil.rmtree(dest, ignore_errors=True)
        raise
    return dest
