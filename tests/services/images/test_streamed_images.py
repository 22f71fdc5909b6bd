"""An image costs what its pixels cost: a PNG with a private chunk of megabytes before its pixels (within the
per-image cap) is kept and served byte for byte, and neither the header check nor the streaming of six parallel
reads holds that chunk in memory (traced Python allocations, whatever the machine's load); an image file above the
cap is refused at import naming it."""
from __future__ import annotations

import hashlib
import io
import struct
import threading
import tracemalloc
import zipfile
import zlib
from pathlib import Path

import pytest
from PIL import Image

from app.core.config import Settings
from app.core.errors import DatasetError
from app.datasets.files import MAX_IMAGE_BYTES, file_image_header, member_image_header
from app.datasets.soccernet_v3 import read_soccernet_v3_game
from app.db.models import Frame
from app.services.images.serving import frame_image
from app.services.storage.datasets import DatasetFiles
from app.services.storage.stores import FileStorage, Storage
from app.services.transfer.archives import MB
from app.services.transfer.caps import reading_limits
from tests.conftest import sizes
from tests.services.datasets import write_v3_game


def _png_with_private_chunk(extra: int) -> bytes:
    """A 1920x1080 PNG whose ``IHDR`` is followed by a private ancillary chunk (``prVt``) of ``extra`` bytes."""
    buf = io.BytesIO()
    Image.new("RGB", (1920, 1080), (30, 120, 40)).save(buf, "PNG")
    png = buf.getvalue()
    payload = bytes(range(256)) * (extra // 256) + b"\0" * (extra % 256)
    chunk = struct.pack(">I", extra) + b"prVt" + payload + struct.pack(">I", zlib.crc32(b"prVt" + payload))
    return png[:33] + chunk + png[33:]  # signature and IHDR, the private chunk, the rest


def six_parallel_reads(store: Storage, tmp_path: Path, png: bytes) -> int:
    """Six parallel reads (what ``GET /api/frames/{id}/image`` does: the header check, then the stream) of ``png``
    put in ``store`` as a file and as a member of a deflated zip, three of each; checks each read byte for byte and
    returns the most bytes Python held at once meanwhile (``tracemalloc``: whatever the machine's load)."""
    digest = hashlib.sha256(png).hexdigest()
    store.put_stream("uploads/u/game/0.png", io.BytesIO(png))
    archive = tmp_path / "Frames-v3.zip"
    with zipfile.ZipFile(archive, "w", zipfile.ZIP_DEFLATED) as zf:
        zf.writestr("0.png", png)  # deflated: a member is a stream
    with open(archive, "rb") as fh:
        store.put_stream("uploads/u/game/Frames-v3.zip", fh)
    archive.unlink()
    files = DatasetFiles(store, None, tmp_path / "scratch")
    frames = [Frame(id=1, name="0.png", width=1920, height=1080, image_root="storage:uploads/u",
                    image_path="game/0.png", image_type="png"),
              Frame(id=2, name="0.png", width=1920, height=1080, image_root="storage:uploads/u",
                    image_zip="game/Frames-v3.zip", image_member="0.png", image_type="png")]
    got: list[str] = []

    def serve(frame: Frame) -> None:
        image = frame_image(frame, files=files)
        assert (image.media_type, image.size) == ("image/png", len(png))
        h = hashlib.sha256()
        for chunk in image.chunks():
            h.update(chunk)
        got.append(h.hexdigest())

    tracemalloc.start()
    try:
        readers = [threading.Thread(target=serve, args=(frames[i % 2],)) for i in range(6)]
        for t in readers:
            t.start()
        for t in readers:
            t.join()
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert got == [digest] * 6  # byte for byte
    return peak


@pytest.mark.parametrize("megabytes", sizes(8, 40))
def test_a_big_private_chunk_costs_nothing_to_check_or_serve(tmp_path: Path, megabytes: int) -> None:
    png = _png_with_private_chunk(megabytes << 20)
    peak = six_parallel_reads(FileStorage(tmp_path / "store"), tmp_path, png)
    assert peak < (megabytes << 20) // 2, f"{peak:,} bytes held at once"  # never the chunk, let alone six
    with zipfile.ZipFile(tmp_path / "member.zip", "w") as zf:
        zf.writestr("0.png", png)
    with zipfile.ZipFile(tmp_path / "member.zip") as zf:  # the import's check
        tracemalloc.start()
        try:
            assert member_image_header(zf, "0.png", "Frames-v3.zip!0.png").width == 1920
            _, peak = tracemalloc.get_traced_memory()
        finally:
            tracemalloc.stop()
    assert peak < 1 << 20


def test_an_image_above_the_per_image_cap_is_refused_at_import(tmp_path: Path, shared_dir: Path,
                                                               monkeypatch: pytest.MonkeyPatch) -> None:
    """The cap is the setting ``V3D_MAX_IMAGE_MB`` (at least 64 MB by default): an image file or zip member above it
    refuses the import, in words naming the file and the setting; one at the cap is kept."""
    assert Settings().max_image_mb >= 64 and MAX_IMAGE_BYTES == int(Settings().max_image_mb * MB)
    png = _png_with_private_chunk(1 << 20)
    for name, size in (("0.png", MAX_IMAGE_BYTES + 1), ("1.png", MAX_IMAGE_BYTES)):
        with open(tmp_path / name, "wb") as out:  # the PNG, then zeros to ``size`` (a sparse file: no time, no disk)
            out.write(png)
            out.truncate(size)
    with pytest.raises(DatasetError) as refused:
        file_image_header(tmp_path / "0.png", "game/0.png")
    assert str(refused.value) == (f"game/0.png: an image of {MAX_IMAGE_BYTES + 1:,} bytes, more than the "
                                  f"{MAX_IMAGE_BYTES:,} V3D_MAX_IMAGE_MB (256 MB) lets an image have")
    assert file_image_header(tmp_path / "1.png", "game/1.png").height == 1080  # at the cap: kept
    # a lower cap, set as every V3D_* setting is, refuses a game's 2 MB frame at import, naming the member
    game = write_v3_game(shared_dir, tmp_path / "v3", actions=("0.png",), with_images=False)
    with zipfile.ZipFile(game / "Frames-v3.zip", "w") as zf:
        zf.writestr("0.png", _png_with_private_chunk(2 << 20))
    monkeypatch.setenv("V3D_MAX_IMAGE_MB", "1.5")
    with pytest.raises(DatasetError) as refused:
        read_soccernet_v3_game(game / "Labels-v3.json", **reading_limits(Settings()))
    assert str(refused.value).startswith(f"{game / 'Frames-v3.zip'}!0.png: an image of ")
    assert "V3D_MAX_IMAGE_MB (1.5 MB)" in str(refused.value)
    monkeypatch.setenv("V3D_MAX_IMAGE_MB", "3")
    assert read_soccernet_v3_game(game / "Labels-v3.json", **reading_limits(Settings())).systems
