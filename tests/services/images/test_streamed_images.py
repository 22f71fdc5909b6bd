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

from app.core.errors import DatasetError
from app.datasets.files import MAX_IMAGE_BYTES, file_image_header, member_image_header
from app.db.models import Frame
from app.services.images.serving import frame_image
from app.services.storage.datasets import DatasetFiles
from app.services.storage.stores import FileStorage
from tests.conftest import sizes


def _png_with_private_chunk(extra: int) -> bytes:
    """A 1920x1080 PNG whose ``IHDR`` is followed by a private ancillary chunk (``prVt``) of ``extra`` bytes."""
    buf = io.BytesIO()
    Image.new("RGB", (1920, 1080), (30, 120, 40)).save(buf, "PNG")
    png = buf.getvalue()
    payload = bytes(range(256)) * (extra // 256) + b"\0" * (extra % 256)
    chunk = struct.pack(">I", extra) + b"prVt" + payload + struct.pack(">I", zlib.crc32(b"prVt" + payload))
    return png[:33] + chunk + png[33:]  # signature and IHDR, the private chunk, the rest


@pytest.mark.parametrize("megabytes", sizes(8, 40))
def test_a_big_private_chunk_costs_nothing_to_check_or_serve(tmp_path: Path, megabytes: int) -> None:
    png = _png_with_private_chunk(megabytes << 20)
    digest = hashlib.sha256(png).hexdigest()
    store = FileStorage(tmp_path / "store")
    (tmp_path / "store" / "uploads" / "u" / "game").mkdir(parents=True)
    (tmp_path / "store" / "uploads" / "u" / "game" / "0.png").write_bytes(png)
    with zipfile.ZipFile(tmp_path / "store" / "uploads" / "u" / "game" / "Frames-v3.zip", "w") as zf:
        zf.writestr("0.png", png)  # deflated: a member is a stream
    files = DatasetFiles(store, None, tmp_path / "scratch")
    frames = [Frame(id=1, name="0.png", width=1920, height=1080, image_root="storage:uploads/u",
                    image_path="game/0.png", image_type="png"),
              Frame(id=2, name="0.png", width=1920, height=1080, image_root="storage:uploads/u",
                    image_zip="game/Frames-v3.zip", image_member="0.png", image_type="png")]
    got: list[str] = []

    def serve(frame: Frame) -> None:  # what GET /api/frames/{id}/image does: the header check, then the stream
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
    assert peak < (megabytes << 20) // 2, f"{peak:,} bytes held at once"  # never the chunk, let alone six
    with zipfile.ZipFile(tmp_path / "store" / "uploads" / "u" / "game" / "Frames-v3.zip") as zf:  # import's check
        tracemalloc.start()
        try:
            assert member_image_header(zf, "0.png", "Frames-v3.zip!0.png").width == 1920
            _, peak = tracemalloc.get_traced_memory()
        finally:
            tracemalloc.stop()
    assert peak < 1 << 20


def test_an_image_above_the_per_image_cap_is_refused_at_import(tmp_path: Path) -> None:
    png = _png_with_private_chunk(1 << 20)
    for name, size in (("0.png", MAX_IMAGE_BYTES + 1), ("1.png", MAX_IMAGE_BYTES)):
        with open(tmp_path / name, "wb") as out:  # the PNG, then zeros to ``size`` (a sparse file: no time, no disk)
            out.write(png)
            out.truncate(size)
    with pytest.raises(DatasetError) as refused:
        file_image_header(tmp_path / "0.png", "game/0.png")
    assert str(refused.value) == (f"game/0.png: an image of {MAX_IMAGE_BYTES + 1:,} bytes, more than the "
                                  f"{MAX_IMAGE_BYTES:,} an image may have")
    assert MAX_IMAGE_BYTES >= 64 << 20
    assert file_image_header(tmp_path / "1.png", "game/1.png").height == 1080  # at the cap: kept
