"""Frame images: where a frame's image bytes are (a zip member, a file, or a frame of a video or frame
folder decoded on demand) and how to stream them with a strong ETag. Zip members are never extracted."""
from __future__ import annotations

import mimetypes
import zipfile
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Optional

from app.datasets.files import is_safe_member
from app.db.models import Frame
from app.core.errors import ServiceError

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
    archive's directory, no decompression), the file's modification time and size for a file.
    """

    media_type: str
    etag: str
    size: int
    zip_path: Optional[Path] = None
    member: Optional[str] = None
    path: Optional[Path] = None
    #: Bytes decoded on demand (a frame of a video or frame folder, ``app.services.issia.sequences``).
    data: Optional[bytes] = None

    def chunks(self) -> Iterator[bytes]:
        """The image bytes in 64 KiB chunks, read from the file or straight out of the archive."""
        if self.data is not None:
            yield from (self.data[i:i + _CHUNK] for i in range(0, len(self.data), _CHUNK))
            return
        if self.path is not None:
            with self.path.open("rb") as fh:
                yield from iter(lambda: fh.read(_CHUNK), b"")
            return
        assert self.zip_path is not None and self.member is not None
        with zipfile.ZipFile(self.zip_path) as zf, zf.open(self.member) as fh:
            yield from iter(lambda: fh.read(_CHUNK), b"")


def _media_type(name: str) -> str:
    return mimetypes.guess_type(name)[0] or "application/octet-stream"


def frame_image(frame: Frame) -> FrameImage:
    """Locate a frame's image without reading it (zip members are never extracted).

    Raises:
        ImageUnavailable: the frame has no image (SoccerNet-calibration imports ship none), its
            member name is unsafe, or the archive, member or file is missing.
    """
    where = f"frame {frame.id}"
    if frame.media_frame is not None and frame.image_path:
        return _media_frame_image(frame, where)
    if frame.image_zip and frame.image_member:
        member = frame.image_member
        if not is_safe_member(member):
            raise ImageUnavailable(f"{where}: refusing unsafe archive member name {member!r}")
        zip_path = Path(frame.image_zip)
        try:
            with zipfile.ZipFile(zip_path) as zf:
                info = zf.getinfo(member)
        except FileNotFoundError:
            raise ImageUnavailable(f"{where}: image archive {zip_path} is missing") from None
        except KeyError:
            raise ImageUnavailable(f"{where}: {member!r} is not in {zip_path}") from None
        except (zipfile.BadZipFile, OSError) as exc:
            raise ImageUnavailable(f"{where}: cannot read image archive {zip_path} ({exc})") from None
        return FrameImage(
            media_type=_media_type(member), etag=f'"{info.CRC:08x}-{info.file_size:x}"', size=info.file_size,
            zip_path=zip_path, member=member,
        )
    if frame.image_path:
        path = Path(frame.image_path)
        try:
            st = path.stat()
        except OSError:
            raise ImageUnavailable(f"{where}: image file {path} is missing") from None
        return FrameImage(
            media_type=_media_type(path.name), etag=f'"{st.st_mtime_ns:x}-{st.st_size:x}"', size=st.st_size,
            path=path,
        )
    raise ImageUnavailable(
        f"{where} has no image (its dataset ships none, e.g. SoccerNet-calibration): "
        f"draw on a blank {frame.width}x{frame.height} canvas"
    )


def _media_frame_image(frame: Frame, where: str) -> FrameImage:
    """A frame of a video or frame folder (ISSIA), decoded and resized to the frame's own size, PNG."""
    from app.core.errors import DatasetError
    from app.services.issia.sequences import read_video_frame

    path = Path(frame.image_path or "")
    try:
        st = path.stat()
        data = read_video_frame(frame)
    except (OSError, DatasetError) as exc:
        raise ImageUnavailable(f"{where}: cannot read frame {frame.media_frame} of {path} ({exc})") from None
    etag = f'"{st.st_mtime_ns:x}-{st.st_size:x}-{frame.media_frame:x}-{int(frame.media_flipped)}-{frame.width}x{frame.height}"'
    return FrameImage(media_type="image/png", etag=etag, size=len(data), data=data)
