"""The store's contract, on a folder and on a real S3 server (SeaweedFS on loopback, ``tests.seaweed``): files and
streams in and out, big files in parts, ranges read as a seekable file, listings, removal, presigned URLs; and a
frame's image read from its zip archive in the store without fetching the archive (``app.services.images``)."""
from __future__ import annotations

import hashlib
import io
import os
import zipfile
from pathlib import Path

import httpx
import pytest

from app.db.models import Frame
from app.services.images.serving import ImageUnavailable, frame_image
from app.services.storage import open_storage
from app.services.storage.datasets import DatasetFiles
from app.services.storage.s3 import MULTIPART_BYTES, S3Storage
from app.services.storage.stores import FileStorage, Storage
from tests.conftest import sizes
from tests.seaweed import Seaweed, seaweed_for_tests
from tests.services.images.test_streamed_images import _png_with_private_chunk, six_parallel_reads

pytestmark = pytest.mark.processes

# The smallest PNG: 1x1, one grey pixel.
PNG = bytes.fromhex("89504e470d0a1a0a0000000d4948445200000001000000010800000000"
                    "3a7e9b550000000a49444154789c63600000000200017355d5350000000049454e44ae426082")


@pytest.fixture(scope="module")
def seaweed(tmp_path_factory: pytest.TempPathFactory):
    with seaweed_for_tests(tmp_path_factory.mktemp("seaweed")) as server:
        yield server


@pytest.fixture(params=["file", "s3"])
def store(request: pytest.FixtureRequest, tmp_path: Path) -> Storage:
    if request.param == "file":
        return FileStorage(tmp_path / "store")
    server: Seaweed = request.getfixturevalue("seaweed")
    return S3Storage(server.bucket, f"t/{tmp_path.name}", client=server.client())


def test_files_and_streams_go_in_and_come_back(store: Storage, tmp_path: Path):
    src = tmp_path / "a.bin"
    src.write_bytes(b"0123456789" * 1000)
    store.put_file("uploads/u1/a.bin", src)
    store.put_stream("uploads/u1/sub/b.txt", io.BytesIO(b"hello"))
    assert store.exists("uploads/u1/a.bin") and not store.exists("uploads/u1/missing")
    assert store.stat("uploads/u1/a.bin").size == 10_000
    back = store.get_file("uploads/u1/a.bin", tmp_path / "back" / "a.bin")
    assert back.read_bytes() == src.read_bytes()
    assert sorted(o.key for o in store.list("uploads/u1")) == ["uploads/u1/a.bin", "uploads/u1/sub/b.txt"]
    assert list(store.list("uploads/none")) == []
    with store.open("uploads/u1/a.bin") as fh:  # seekable: what zipfile needs
        fh.seek(9_995)
        assert fh.read() == b"56789"
        fh.seek(3)
        assert fh.read(4) == b"3456"
    store.put_stream("uploads/u1/empty", io.BytesIO(b""))
    with store.open("uploads/u1/empty") as fh:
        assert fh.read() == b"" and store.stat("uploads/u1/empty").size == 0
    store.delete("uploads/u1/empty")
    tree = store.get_tree("uploads/u1", tmp_path / "tree")
    assert (tree / "sub" / "b.txt").read_bytes() == b"hello" and not (tmp_path / "tree.part").exists()
    store.delete("uploads/u1/a.bin")
    assert not store.exists("uploads/u1/a.bin")
    store.delete("uploads/u1/a.bin")  # a missing key is nothing to remove
    store.delete_tree("uploads/u1")
    assert list(store.list("uploads/u1")) == []


def test_missing_keys_and_unsafe_keys(store: Storage, tmp_path: Path):
    with pytest.raises(FileNotFoundError):
        store.stat("exports/none.zip")
    with pytest.raises(FileNotFoundError):
        store.open("exports/none.zip")
    with pytest.raises(FileNotFoundError):
        store.get_file("exports/none.zip", tmp_path / "x")
    with pytest.raises(FileNotFoundError):
        store.get_tree("uploads/none", tmp_path / "y")
    for key in ("../x", "/etc/passwd", "a//b", "a\\b", ""):
        with pytest.raises(ValueError):
            store.put_stream(key, io.BytesIO(b"x"))


def test_a_big_file_goes_in_parts_and_comes_back_whole(seaweed: Seaweed, tmp_path: Path):
    store = S3Storage(seaweed.bucket, "big", client=seaweed.client())
    big = tmp_path / "big.zip"
    big.write_bytes(os.urandom(1 << 20) * (MULTIPART_BYTES // (1 << 20) + 1))  # 17 MiB: two parts
    store.put_file("exports/big.zip", big)
    assert store.stat("exports/big.zip").etag.endswith("-2")  # S3's ETag of a two-part upload
    back = store.get_file("exports/big.zip", tmp_path / "back.zip")
    assert hashlib.sha256(back.read_bytes()).digest() == hashlib.sha256(big.read_bytes()).digest()
    with store.open("exports/big.zip") as fh:
        fh.seek(MULTIPART_BYTES - 3)
        assert fh.read(6) == big.read_bytes()[MULTIPART_BYTES - 3:MULTIPART_BYTES + 3]
        fh.seek(0)  # read whole: the ranges before the last bytes read when it was opened, then those
        assert hashlib.sha256(fh.read()).digest() == hashlib.sha256(big.read_bytes()).digest()


def test_a_presigned_url_reads_the_object(seaweed: Seaweed):
    store = S3Storage(seaweed.bucket, "signed", client=seaweed.client())
    store.put_stream("exports/x.txt", io.BytesIO(b"signed bytes"))
    url = store.url_for("exports/x.txt", 60)
    assert url is not None and "Signature" in url
    assert httpx.get(url).content == b"signed bytes"
    assert FileStorage(Path("/nonexistent")).url_for("exports/x.txt") is None


def test_open_storage_reads_the_url():
    assert isinstance(open_storage("file:///srv/v3d"), FileStorage)
    s3 = open_storage("s3://bucket/some/prefix")
    assert isinstance(s3, S3Storage) and (s3.bucket, s3.prefix) == ("bucket", "some/prefix")
    for bad in ("http://x", "s3://", "/srv/v3d"):
        with pytest.raises(ValueError):
            open_storage(bad)


def _frame(root: str, *, zip_name: str | None = None, member: str | None = None, path: str | None = None) -> Frame:
    return Frame(id=1, name="0.png", width=1, height=1, image_root=root, image_zip=zip_name, image_member=member,
                 image_path=path, image_type="png")


def test_a_frame_image_is_read_from_its_archive_in_the_store(store: Storage, tmp_path: Path):
    archive = io.BytesIO()
    with zipfile.ZipFile(archive, "w") as zf:
        zf.writestr("big.bin", os.urandom(600_000))  # the member lies past the first range read
        zf.writestr("0.png", PNG)
    archive.seek(0)
    store.put_stream("uploads/u2/league/game/Frames-v3.zip", archive)
    store.put_stream("uploads/u2/league/game/1.png", io.BytesIO(PNG))
    files = DatasetFiles(store, None, tmp_path / "scratch")
    member = frame_image(_frame("storage:uploads/u2", zip_name="league/game/Frames-v3.zip", member="0.png"),
                         files=files)
    assert member.media_type == "image/png" and b"".join(member.chunks()) == PNG
    assert b"".join(member.chunks(10, 30)) == PNG[10:30]  # a range of a member: the bytes before it dropped
    single = frame_image(_frame("storage:uploads/u2/league", path="game/1.png"), files=files)
    assert b"".join(single.chunks()) == PNG and single.size == len(PNG)
    assert b"".join(single.chunks(len(PNG) - 5)) == PNG[-5:]  # a range of a file: read from its start
    for escape in ("../u1/x.png", "/etc/passwd"):
        with pytest.raises(ImageUnavailable):
            frame_image(_frame("storage:uploads/u2", path=escape), files=files)
    with pytest.raises(ImageUnavailable):
        frame_image(_frame("storage:uploads/u2", path="gone.png"), files=files)


def test_a_frame_under_the_data_root_is_read_there(tmp_path: Path):
    (tmp_path / "data" / "sn").mkdir(parents=True)
    (tmp_path / "data" / "sn" / "0.png").write_bytes(PNG)
    files = DatasetFiles(FileStorage(tmp_path / "jobs"), tmp_path / "data", tmp_path / "jobs")
    assert files.reference(tmp_path / "data" / "sn") == "data-root:sn"
    assert b"".join(frame_image(_frame("data-root:sn", path="0.png"), files=files).chunks()) == PNG
    with pytest.raises(ImageUnavailable):  # a folder outside the data root is none of its datasets
        frame_image(_frame("data-root:../elsewhere", path="0.png"), files=files)
    with pytest.raises(ImageUnavailable):  # a node without the data root cannot read it
        frame_image(_frame("data-root:sn", path="0.png"), files=DatasetFiles(files.storage, None, files.scratch))


def test_a_remote_video_or_frame_folder_is_read_from_this_nodes_copy(seaweed: Seaweed, tmp_path: Path):
    """OpenCV reads a video (or a folder of numbered frames) from a local file: a remote one is fetched once into
    ``<jobs dir>/cache/<key>``, whole; an upload's keys are never written again (each upload has a folder of its own),
    so the copy stays the object as stored."""
    store = S3Storage(seaweed.bucket, "cache", client=seaweed.client())
    store.put_stream("uploads/u3/videos/cam1.mp4", io.BytesIO(b"video bytes"))
    store.put_stream("uploads/u3/frames/cam2/000001.png", io.BytesIO(PNG))
    store.put_stream("uploads/u3/frames/cam2/000002.png", io.BytesIO(PNG))
    files = DatasetFiles(store, None, tmp_path / "jobs")
    video = files.local_copy(files.locate("storage:uploads/u3", "videos/cam1.mp4"))
    assert video == tmp_path / "jobs" / "cache" / "uploads" / "u3" / "videos" / "cam1.mp4"
    assert video.read_bytes() == b"video bytes"
    folder = files.local_copy(files.locate("storage:uploads/u3", "frames/cam2"))
    assert sorted(p.name for p in folder.iterdir()) == ["000001.png", "000002.png"]
    store.delete_tree("uploads/u3")  # the copy is read, not the store, from now on
    assert files.local_copy(files.locate("storage:uploads/u3", "videos/cam1.mp4")).read_bytes() == b"video bytes"
    with pytest.raises(FileNotFoundError):
        files.local_copy(files.locate("storage:uploads/u3", "videos/gone.mp4"))


@pytest.mark.parametrize("megabytes", sizes(8, 40))
def test_six_parallel_reads_of_a_big_image_from_the_s3_store_hold_no_chunk(seaweed: Seaweed, tmp_path: Path,
                                                                          megabytes: int) -> None:
    """An image with a private chunk of megabytes before its pixels, kept in the S3 store as a file and as a member of
    its zip, read six times at once: each read is byte for byte, and Python never holds the chunk (the folder
    store's test: ``tests/services/images/test_streamed_images.py``)."""
    store = S3Storage(seaweed.bucket, f"streamed/{tmp_path.name}", client=seaweed.client())
    peak = six_parallel_reads(store, tmp_path, _png_with_private_chunk(megabytes << 20))
    assert peak < (megabytes << 20) // 2, f"{peak:,} bytes held at once"
