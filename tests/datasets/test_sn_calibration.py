"""One reader of SoccerNet-calibration sets for the import and ``v3d calibrate``
(``app.datasets.sn_calibration``): sub-folders, names by stem, skipped files, refused sets."""
from __future__ import annotations

import json
import zipfile
from pathlib import Path

import pytest

from app.core.errors import DatasetError
from app.datasets.sn_calibration import frame_entries, read_sn_calibration

FRAME = {"Side line top": [{"x": 0.1, "y": 0.2}, {"x": 0.9, "y": 0.2}],
         "Middle line": [{"x": 0.5, "y": 0.2}, {"x": 0.5, "y": 0.9}]}


def _write(root: Path, names: list[str]) -> None:
    for name in names:
        (root / name).parent.mkdir(parents=True, exist_ok=True)
        (root / name).write_text(json.dumps(FRAME))


def test_folder_with_sub_folders_is_read_whole_in_natural_order(tmp_path: Path) -> None:
    _write(tmp_path, ["10.json", "2.json", "more/3.json", "match_info.json", "camera_2.json",
                      "calibration_summary.json"])
    assert [name for name, *_ in frame_entries(tmp_path)] == ["2", "10", "3"]
    game = read_sn_calibration(tmp_path, 960, 540)
    assert [s.name for s in game.systems] == ["2", "10", "3"]
    frame = game.systems[0].frames[0]
    assert (frame.width, frame.height) == (960, 540)
    # normalised points become pixels as x (W - 1), y (H - 1)
    assert frame.lines["Side line top"][0][0] == pytest.approx([0.1 * 959, 0.2 * 539])


def test_zip_and_folder_give_the_same_frames(tmp_path: Path) -> None:
    folder = tmp_path / "set"
    _write(folder, ["1.json", "sub/2.json"])
    archive = tmp_path / "set.zip"
    with zipfile.ZipFile(archive, "w") as zf:
        for p in sorted(folder.rglob("*.json")):
            zf.write(p, f"test/{p.relative_to(folder).as_posix()}")
    from_folder = [(n, raw) for n, _w, raw, _i in frame_entries(folder)]
    from_zip = [(n, raw) for n, _w, raw, _i in frame_entries(archive)]
    assert from_folder == from_zip and [n for n, _ in from_zip] == ["1", "2"]
    assert next(iter(frame_entries(archive)))[1] == f"{archive}!test/1.json"


def test_two_frames_of_one_name_are_refused(tmp_path: Path) -> None:
    _write(tmp_path, ["a/7.json", "b/7.json"])
    with pytest.raises(DatasetError, match="two frames named '7'"):
        list(frame_entries(tmp_path))


def test_unsafe_zip_entries_refuse_the_set(tmp_path: Path) -> None:
    archive = tmp_path / "evil.zip"
    with zipfile.ZipFile(archive, "w") as zf:
        zf.writestr("1.json", json.dumps(FRAME))
        zf.writestr("../escape.png", b"x")
    with pytest.raises(DatasetError, match="unsafe entry name"):
        list(frame_entries(archive))
