"""The one safe unpacker of uploads (``app.services.transfer.archives``): real zips made here, each hostile
kind refused naming its member, nothing left extracted; a valid tree unpacked byte for byte."""
from __future__ import annotations

import io
import stat
import zipfile
from pathlib import Path

import cv2
import numpy as np
import pytest

from app.core.errors import DatasetError
from app.services.transfer.archives import ArchiveLimits, UploadTooLarge, receive, unpack_zip

LIMITS = ArchiveLimits(max_members=100, max_unpacked_bytes=10 << 20)


def _png(width: int = 8, height: int = 6) -> bytes:
    ok, buf = cv2.imencode(".png", np.full((height, width, 3), 90, np.uint8))
    assert ok
    return buf.tobytes()


def _zip(path: Path, members: dict[str, bytes], links: dict[str, str] | None = None) -> Path:
    with zipfile.ZipFile(path, "w", compression=zipfile.ZIP_DEFLATED) as zf:
        for name, data in members.items():
            zf.writestr(name, data)
        for name, target in (links or {}).items():
            info = zipfile.ZipInfo(name)
            info.create_system = 3
            info.external_attr = (stat.S_IFLNK | 0o777) << 16
            zf.writestr(info, target)
    return path


def _frames_zip(members: dict[str, bytes]) -> bytes:
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w") as zf:
        for name, data in members.items():
            zf.writestr(name, data)
    return buf.getvalue()


def test_a_valid_tree_is_unpacked_byte_for_byte(tmp_path: Path) -> None:
    members = {"l/s/g/Labels-v3.json": b'{"actions": {}}', "l/s/g/Frames-v3.zip": _frames_zip({"1.png": _png()}),
               "l/s/g/2.jpg": cv2.imencode(".jpg", np.zeros((4, 4, 3), np.uint8))[1].tobytes()}
    out = unpack_zip(_zip(tmp_path / "ok.zip", members), tmp_path / "out", LIMITS)
    assert {p.relative_to(out).as_posix(): p.read_bytes() for p in out.rglob("*") if p.is_file()} == members


@pytest.mark.parametrize("name", ["../evil.json", "/etc/evil.json", "a/../../evil.json", "C:/evil.json",
                                  "a\\..\\..\\evil.json"])
def test_zip_slip_and_absolute_names_are_refused_naming_the_member(tmp_path: Path, name: str) -> None:
    archive = _zip(tmp_path / "slip.zip", {"ok.json": b"{}", name: b"x"})
    with pytest.raises(DatasetError, match=r"slip.zip: member .*evil.json.*unsafe name") as err:
        unpack_zip(archive, tmp_path / "out", LIMITS)
    assert name in str(err.value) or name.replace("\\", "\\\\") in str(err.value)
    assert not (tmp_path / "out").exists() and not (tmp_path / "evil.json").exists()


def test_symbolic_links_are_refused(tmp_path: Path) -> None:
    archive = _zip(tmp_path / "link.zip", {"a.json": b"{}"}, links={"passwd": "/etc/passwd"})
    with pytest.raises(DatasetError, match=r"member 'passwd'.*symbolic link"):
        unpack_zip(archive, tmp_path / "out", LIMITS)
    assert not (tmp_path / "out").exists()


def test_a_file_named_like_an_image_that_is_not_one_is_refused_naming_it(tmp_path: Path) -> None:
    archive = _zip(tmp_path / "img.zip", {"g/1.png": _png(), "g/2.png": b"not a png at all"})
    with pytest.raises(DatasetError, match=r"img.zip!g/2.png: not a PNG or JPEG image"):
        unpack_zip(archive, tmp_path / "out", LIMITS)
    nested = _zip(tmp_path / "nested.zip",
                  {"g/Frames-v3.zip": _frames_zip({"1.png": _png(), "7.png": b"\x89PNG broken"})})
    with pytest.raises(DatasetError, match=r"nested.zip!g/Frames-v3.zip!7.png: not a PNG or JPEG image"):
        unpack_zip(nested, tmp_path / "out2", LIMITS)
    assert not (tmp_path / "out").exists() and not (tmp_path / "out2").exists()


def test_zip_bombs_are_refused_before_extraction(tmp_path: Path) -> None:
    """10 MB of zeros compress to about 10 kB: the declared uncompressed size is over the limit, and
    nothing is written; too many members likewise, nested archives counted."""
    bomb = _zip(tmp_path / "bomb.zip", {"a.json": b"{}", "zeros.bin": bytes(11 << 20)})
    assert bomb.stat().st_size < 100_000
    with pytest.raises(DatasetError, match=r"bomb.zip: more than 10 MB uncompressed \(V3D_MAX_UNPACKED_MB\)"):
        unpack_zip(bomb, tmp_path / "out", LIMITS)
    many = _zip(tmp_path / "many.zip", {f"{i}.txt": b"" for i in range(101)})
    with pytest.raises(DatasetError, match=r"more than 100 members \(V3D_MAX_UPLOAD_MEMBERS\)"):
        unpack_zip(many, tmp_path / "out", LIMITS)
    inner = _zip(tmp_path / "inner.zip", {"g/Frames-v3.zip": _frames_zip({f"{i}.txt": b"" for i in range(100)})})
    with pytest.raises(DatasetError, match=r"inner.zip!g/Frames-v3.zip: more than 100 members"):
        unpack_zip(inner, tmp_path / "out", LIMITS)
    assert not (tmp_path / "out").exists()


def test_repeated_names_and_non_zips_are_refused(tmp_path: Path) -> None:
    twice = tmp_path / "twice.zip"
    with zipfile.ZipFile(twice, "w") as zf:
        zf.writestr("a.json", b"{}")
        with pytest.warns(UserWarning, match="Duplicate name"):
            zf.writestr("a.json", b"[]")
    with pytest.raises(DatasetError, match=r"member 'a.json': appears twice"):
        unpack_zip(twice, tmp_path / "out", LIMITS)
    text = tmp_path / "text.zip"
    text.write_bytes(b"hello")
    with pytest.raises(DatasetError, match=r"text.zip: not a readable zip archive"):
        unpack_zip(text, tmp_path / "out", LIMITS)


def test_receive_stops_at_the_limit_without_keeping_the_file(tmp_path: Path) -> None:
    chunks = (bytes(1000) for _ in range(10))
    with pytest.raises(UploadTooLarge, match=r"file: the upload is larger than the limit"):
        receive(chunks, tmp_path / "up", 9_999)
    assert not (tmp_path / "up").exists()
    assert receive((bytes(1000) for _ in range(10)), tmp_path / "up", 10_000) == 10_000
    assert (tmp_path / "up").stat().st_size == 10_000


def test_a_json_member_unpacking_past_the_limit_is_refused_before_it_is_read(tmp_path: Path,
                                                                            monkeypatch: pytest.MonkeyPatch) -> None:
    """Was: a SoccerNet-calibration zip read in place (a data-root import, ``v3d import``) had each JSON member read
    whole (``archive.read``): one small member unpacking to gigabytes filled the memory. Its declared size is now
    checked from the archive's directory first (zipfile never unpacks past it)."""
    from app.datasets import files
    from app.datasets.sn_calibration import frame_entries

    monkeypatch.setattr(files, "MAX_JSON_MEMBER_BYTES", 1 << 20)
    bomb = _zip(tmp_path / "set.zip", {"1.json": b"{}", "2.json": b" " * (2 << 20)})
    assert bomb.stat().st_size < 50_000
    with pytest.raises(files.InputFileError, match=r"set.zip:2.json: unpacks to 2097152 bytes, more than the 1048576"):
        files.json_files(bomb, "cameras")
    with pytest.raises(DatasetError, match=r"set.zip: 2.json: unpacks to 2097152 bytes"):
        list(frame_entries(bomb))
    _zip(tmp_path / "fine.zip", {"1.json": b"{}", "2.json": b" " * (1 << 20)})
    assert [f.name for f in files.json_files(tmp_path / "fine.zip", "cameras")] == ["1.json", "2.json"]
