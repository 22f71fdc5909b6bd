"""Frame images: where a frame's image bytes are (a zip member, a file, or a frame of a video or frame
folder decoded on demand) and how to stream them with a strong ETag. Zip members are never extracted.

A frame stores its dataset's folder (``Frame.image_root``: a folder of the store, a folder under the data root, or an
absolute folder, ``app.services.storage.datasets``) and the zip or file relative to it; the file is resolved again
(links included) each time it is served and refused when it lies outside that folder (:func:`stored_image_file`), so
that a stored reference can never reach the rest of the disk. A file in a remote store (S3) is read in ranges: a zip
member without fetching its archive.
Its media type comes from the image's header, read again when it is served (PNG or JPEG within
``V3D_MAX_IMAGE_PIXELS``, and the type the import checked, ``Frame.image_type``), never from its name:
anything else is not served."""
from __future__ import annotations

import zipfile
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import IO, BinaryIO, Optional

import numpy as np

from app.core.errors import DatasetError, ServiceError
from app.datasets.files import IMAGE_MEDIA_TYPES, MAX_IMAGE_PIXELS, image_header, is_safe_member
from app.datasets.issia import IssiaSequence, read_frame_image
from app.db.models import Frame
from app.services.storage.datasets import DatasetFiles, Located, OutsideDataset
from app.services.storage.stores import Storage, StorageError

#: Bytes per streamed chunk.
_CHUNK = 64 * 1024


def frame_has_image(frame: Frame) -> bool:
    """True when the frame says where its pixels are (a zip member or a file)."""
    return bool(frame.image_path) or bool(frame.image_zip and frame.image_member)


class ImageUnavailable(ServiceError, LookupError):
    """A frame's image cannot be served: the dataset has none, or its file or member is gone."""


@dataclass(frozen=True)
class FrameImage:
    """Where a frame's image bytes are and how to describe them over HTTP.

    ``etag`` is strong and cheap: the member's CRC-32 and size for a zip member (read from the
    archive's directory, no decompression), the file's modification time and size for a file (its store's ETag and
    size in a remote store).
    """

    media_type: str
    etag: str
    size: int
    zip_path: Optional[Path] = None
    member: Optional[str] = None
    path: Optional[Path] = None
    #: Bytes decoded on demand (a frame of a video or frame folder, ``app.services.issia.sequences``).
    data: Optional[bytes] = None
    #: The file (``member`` None) or the archive in a remote store.
    storage: Optional[Storage] = None
    key: Optional[str] = None

    def chunks(self, start: int = 0, end: Optional[int] = None) -> Iterator[bytes]:
        """The image bytes ``start`` to ``end`` (exclusive; default: to the last) in 64 KiB chunks, read from the
        file (from ``start`` on) or straight out of the archive (the member's bytes before ``start`` read and
        dropped: a member is a stream)."""
        end = self.size if end is None else min(end, self.size)
        if self.data is not None:
            yield from (self.data[i:min(i + _CHUNK, end)] for i in range(start, end, _CHUNK))
            return
        if self.member is None:
            with _open(Located(self.path, self.storage, self.key)) as fh:
                fh.seek(start)
                yield from _limited(fh, end - start)
            return
        with _open(Located(self.zip_path, self.storage, self.key)) as raw, zipfile.ZipFile(raw) as zf, \
                zf.open(self.member) as fh:
            skip = start
            while skip > 0 and (piece := fh.read(min(_CHUNK, skip))):
                skip -= len(piece)
            yield from _limited(fh, end - start)


def _limited(stream: IO[bytes], count: int) -> Iterator[bytes]:
    """At most ``count`` bytes of ``stream`` in 64 KiB chunks."""
    while count > 0 and (chunk := stream.read(min(_CHUNK, count))):
        count -= len(chunk)
        yield chunk


def _open(located: Located) -> BinaryIO:
    """The located file open for reading (a remote one read in ranges as it is read)."""
    if located.path is not None:
        return located.path.open("rb")
    assert located.storage is not None and located.key is not None
    return located.storage.open(located.key)


def _default_files(files: Optional[DatasetFiles]) -> DatasetFiles:
    """``files``, else the process's own settings' (the command line's exports)."""
    if files is not None:
        return files
    from app.core.config import get_settings

    return DatasetFiles.from_settings(get_settings())


def stored_image_file(frame: Frame, relative: str, files: Optional[DatasetFiles] = None) -> Located:
    """The file ``relative`` (``Frame.image_zip`` or ``Frame.image_path``) of the frame's dataset folder
    ``Frame.image_root`` (``app.services.storage.datasets.DatasetFiles.locate``): a local file resolved (``..`` and
    links followed), or a key of a remote store. ``files``: the store and data root (default: the process's).

    Raises:
        ImageUnavailable: the frame has no dataset folder, the file resolves outside it (an absolute
            name, ``..``, a link placed after the import), or it lies under a data root this node has not.
    """
    if not frame.image_root:
        raise ImageUnavailable(f"frame {frame.id}: its image reference has no dataset folder; import it again")
    try:
        return _default_files(files).locate(frame.image_root, relative)
    except OutsideDataset:
        raise ImageUnavailable(f"frame {frame.id}: refusing an image reference outside its dataset's folder") from None
    except FileNotFoundError as exc:
        raise ImageUnavailable(f"frame {frame.id}: {exc}") from None


def _checked_media_type(frame: Frame, stream: IO[bytes], name: str, max_pixels: int) -> str:
    """``image/png`` or ``image/jpeg`` from the header of the open image ``stream``
    (``app.datasets.files.image_header``), when it is the type the import checked (``Frame.image_type``;
    rows imported before the check have none).

    Raises:
        ImageUnavailable: not a PNG or JPEG within ``max_pixels`` pixels, or not the type checked at import.
    """
    try:
        header = image_header(stream, name, max_pixels)
    except DatasetError as exc:
        raise ImageUnavailable(f"frame {frame.id}: not served: {exc}") from None
    if frame.image_type is not None and header.type != frame.image_type:
        raise ImageUnavailable(f"frame {frame.id}: not served: {name} is no longer the {frame.image_type} "
                               "image that was imported")
    return IMAGE_MEDIA_TYPES[header.type]


def frame_image(frame: Frame, max_pixels: int = MAX_IMAGE_PIXELS, files: Optional[DatasetFiles] = None) -> FrameImage:
    """Locate a frame's image and check its header (zip members are never extracted; nothing is
    decoded but an ISSIA video frame, which is served as a PNG v3d encodes).

    Raises:
        ImageUnavailable: the frame has no image (SoccerNet-calibration imports ship none), its
            member name is unsafe, its file resolves outside its dataset's folder
            (:func:`stored_image_file`), the archive, member or file is missing, or it is not a PNG or
            JPEG image within ``max_pixels`` pixels (whatever its name).
        StorageError: the store holding it cannot be used now (unreachable, refusing, no answer in time).

    ``files``: the store and data root its reference names (default: the process's settings').
    """
    where = f"frame {frame.id}"
    if frame.media_frame is not None and frame.image_path:
        return _media_frame_image(frame, where, max_pixels, files)
    if frame.image_zip and frame.image_member:
        member = frame.image_member
        if not is_safe_member(member):
            raise ImageUnavailable(f"{where}: refusing unsafe archive member name {member!r}")
        located = stored_image_file(frame, frame.image_zip, files)
        try:
            with _open(located) as raw, zipfile.ZipFile(raw) as zf:
                info = zf.getinfo(member)
                with zf.open(info) as stream:
                    media_type = _checked_media_type(frame, stream, member, max_pixels)
        except StorageError:
            raise  # the store cannot be used now: not a missing image (503, ``app.api.errors``)
        except FileNotFoundError:
            raise ImageUnavailable(f"{where}: image archive {frame.image_zip} is missing") from None
        except KeyError:
            raise ImageUnavailable(f"{where}: {member!r} is not in {frame.image_zip}") from None
        except (zipfile.BadZipFile, OSError) as exc:
            raise ImageUnavailable(f"{where}: cannot read image archive {frame.image_zip} "
                                   f"({type(exc).__name__})") from None
        return FrameImage(
            media_type=media_type, etag=f'"{info.CRC:08x}-{info.file_size:x}"', size=info.file_size,
            zip_path=located.path, member=member, storage=located.storage, key=located.key,
        )
    if frame.image_path:
        located = stored_image_file(frame, frame.image_path, files)
        try:
            if located.path is not None:
                st = located.path.stat()
                size, etag = st.st_size, f'"{st.st_mtime_ns:x}-{st.st_size:x}"'
            else:
                assert located.storage is not None and located.key is not None
                stored = located.storage.stat(located.key)
                size, etag = stored.size, f'"{stored.etag}-{stored.size:x}"'
            with _open(located) as stream:
                media_type = _checked_media_type(frame, stream, frame.image_path, max_pixels)
        except StorageError:
            raise
        except OSError:
            raise ImageUnavailable(f"{where}: image file {frame.image_path} is missing") from None
        return FrameImage(media_type=media_type, etag=etag, size=size, path=located.path, storage=located.storage,
                          key=located.key)
    raise ImageUnavailable(
        f"{where} has no image (its dataset ships none, e.g. SoccerNet-calibration): "
        f"draw on a blank {frame.width}x{frame.height} canvas"
    )


def _media_frame_image(frame: Frame, where: str, max_pixels: int, files: Optional[DatasetFiles]) -> FrameImage:
    """A frame of a video or frame folder (ISSIA), decoded and resized to the frame's own size, PNG (a video in a
    remote store is read from this node's copy of it, ``DatasetFiles.local_copy``)."""
    try:
        path = _default_files(files).local_copy(stored_image_file(frame, frame.image_path or "", files))
        st = path.stat()
        data = read_video_frame(frame, max_pixels, files)
    except (OSError, DatasetError):
        raise ImageUnavailable(f"{where}: cannot read frame {frame.media_frame} of {frame.image_path}") from None
    etag = (f'"{st.st_mtime_ns:x}-{st.st_size:x}-{frame.media_frame:x}-{int(frame.media_flipped)}-'
            f'{frame.width}x{frame.height}"')
    return FrameImage(media_type="image/png", etag=etag, size=len(data), data=data)


def read_video_frame(frame: Frame, max_pixels: int = MAX_IMAGE_PIXELS, files: Optional[DatasetFiles] = None) -> bytes:
    """The view's image at its own (annotation) resolution, PNG bytes, decoded on demand from its
    video (``Frame.image_path``, frame ``Frame.media_frame``) or frame folder, flipped back when
    ``Frame.media_flipped`` (:func:`app.datasets.issia.read_frame_image`).

    Raises:
        DatasetError: the video or folder is missing or the frame cannot be read.
    """
    import cv2

    if frame.image_path is None or frame.media_frame is None:
        raise DatasetError(Path(f"frame {frame.id}"), None, "no video or frame folder")
    cid = frame.name
    try:
        media = _default_files(files).local_copy(stored_image_file(frame, frame.image_path, files))
    except (ImageUnavailable, OSError):
        raise DatasetError(frame.image_path, None, "missing") from None
    if not media.exists():
        raise DatasetError(frame.image_path, None, "missing")
    seq = IssiaSequence(root=media.parent, camera_ids=(cid,), image_size=(frame.width, frame.height), cameras={},
                        lines={}, frames=(), points=np.empty((0, 1, 2)), media={cid: media},
                        flipped=frozenset({cid}) if frame.media_flipped else frozenset())
    img = read_frame_image(seq, cid, frame.media_frame, max_pixels=max_pixels).image
    ok, buf = cv2.imencode(".png", img, [cv2.IMWRITE_PNG_COMPRESSION, 1])
    if not ok:
        raise DatasetError(media, f"frame {frame.media_frame}", "cannot be encoded as PNG")
    return buf.tobytes()
