"""The SoccerNet-v3D export as a zip archive streamed while its source is read: the live database
(:class:`LiveSource`) or a release (``app.services.releases.export.ReleaseSource``). Every member has the fixed time
stamp ``exporting.ZIP_DATE_TIME`` and members come in the games' order: the same content zips to the same bytes."""
from __future__ import annotations

import csv
import io
import tempfile
import zipfile
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from typing import Any, Protocol

from sqlalchemy.orm import Session

from app.services.storage.datasets import DatasetFiles
from app.services.transfer.exporting import (
    CSV_COLUMNS,
    ExportedGame,
    chain_games,
    iter_soccernet_v3d,
    member_compression,
    write_frames_zip,
    zip_member,
)


class _ZipSink(io.RawIOBase):
    """A write-only, unseekable stream whose written bytes are taken out in pieces (:meth:`drain`), so
    that ``zipfile`` can write an archive while it is being sent."""

    def __init__(self) -> None:
        super().__init__()
        self._parts: list[bytes] = []
        self._pos = 0

    def writable(self) -> bool:
        return True

    def write(self, b: Any) -> int:
        data = bytes(b)
        self._parts.append(data)
        self._pos += len(data)
        return len(data)

    def tell(self) -> int:
        return self._pos

    def drain(self) -> bytes:
        data = b"".join(self._parts)
        self._parts.clear()
        return data


def _stream_game_frames(session: Session, exported: ExportedGame, zf: zipfile.ZipFile,
                        sink: _ZipSink, files: DatasetFiles | None) -> Iterator[bytes]:
    """Copy the game's ``Frames-v3.zip`` (built in a temporary file) into the streamed archive ``zf``,
    stored, handing on its bytes as they are written."""
    with tempfile.TemporaryFile() as tmp:
        if not write_frames_zip(session, exported.frames, tmp, files):
            return
        tmp.seek(0)
        with zf.open(zip_member(exported.frames_path), "w", force_zip64=True) as member:
            for chunk in iter(lambda: tmp.read(1 << 20), b""):
                member.write(chunk)
                yield sink.drain()


class ExportSource(Protocol):
    """Where a SoccerNet-v3D export reads its games: the live database (:class:`LiveSource`) or a release
    (``app.services.releases.export.ReleaseSource``)."""

    def games(self, progress: Callable[[str, int, int], None] | None) -> Iterator[ExportedGame]:
        """The export's games in order (validating every folder name before the first, as
        :func:`iter_soccernet_v3d`)."""

    def members(self) -> Iterator[tuple[str, bytes]]:
        """Files the export carries beside the games and ``SNv3D.csv`` (name, bytes), written last."""


@dataclass(frozen=True)
class LiveSource:
    """The database as it is now: the accepted systems (every one with ``include_all``)."""

    session: Session
    include_all: bool = False

    def games(self, progress: Callable[[str, int, int], None] | None) -> Iterator[ExportedGame]:
        """:func:`iter_soccernet_v3d` of the database."""
        return iter_soccernet_v3d(self.session, self.include_all, progress)

    def members(self) -> Iterator[tuple[str, bytes]]:
        """None."""
        return iter(())


def stream_soccernet_v3d_zip(session: Session, include_all: bool = False,
                             progress: Callable[[str, int, int], None] | None = None,
                             images: bool = True, source: ExportSource | None = None,
                             files: DatasetFiles | None = None) -> Iterator[bytes]:
    """The export as a zip archive, produced while the database is read: each game's
    ``Labels-v3D.json`` is compressed and handed on before the next game is read, followed (``images``) by
    its ``Frames-v3.zip`` (built in a temporary file, then copied in); ``SNv3D.csv`` is spooled (in memory
    up to 8 MB, then a temporary file) and written after the games, then the source's own members (a release's
    ``v3d-release.json``). Memory stays bounded by one game and the spool. The archive is the same tree as
    :func:`export_soccernet_v3d` writes. ``progress`` as :func:`iter_soccernet_v3d`. ``source``: where the games
    are read (default: the database now, :class:`LiveSource`); ``files``: where the images' references lead
    (default: the process's settings'). Every member has the fixed time stamp
    :data:`ZIP_DATE_TIME` and members come in the games' order, so the same content gives the same bytes.

    Raises:
        InvalidInputError: as :func:`iter_soccernet_v3d`, before the first byte.
    """
    source = source or LiveSource(session, include_all)
    games = source.games(progress)
    first = next(games, None)
    sink = _ZipSink()
    with tempfile.SpooledTemporaryFile(max_size=8 << 20, mode="w+", newline="", encoding="utf-8") as spool:
        writer = csv.writer(spool)
        writer.writerow(CSV_COLUMNS)
        with zipfile.ZipFile(sink, "w", compression=zipfile.ZIP_DEFLATED, compresslevel=1) as zf:
            for exported in chain_games(first, games):
                zf.writestr(zip_member(exported.labels_path, zipfile.ZIP_DEFLATED), exported.labels_json(),
                            compresslevel=1)
                writer.writerows(exported.rows)
                yield sink.drain()
                if images:
                    yield from _stream_game_frames(session, exported, zf, sink, files)
            spool.seek(0)
            with zf.open(zip_member("SNv3D.csv", zipfile.ZIP_DEFLATED), "w", force_zip64=True) as member:
                for chunk in iter(lambda: spool.read(1 << 20), ""):
                    member.write(chunk.encode("utf-8"))
                    yield sink.drain()
            for name, data in source.members():
                zf.writestr(zip_member(name, member_compression(name)), data, compresslevel=1)
                yield sink.drain()
        yield sink.drain()
