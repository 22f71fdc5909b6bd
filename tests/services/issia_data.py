"""A stretch of the synthetic ISSIA dev sequence written to a temporary folder (tests need fewer than
its 200 frames): the calibration and lines JSON copied, ``ball_points.csv`` cut to a frame range, the
videos linked (not copied) when asked."""
from __future__ import annotations

import csv
import json
import shutil
from pathlib import Path

DEV = ("data", "synthetic", "issia-dev")


def dev_dir(shared_dir: Path) -> Path:
    return shared_dir.joinpath(*DEV)


def dev_truth(shared_dir: Path) -> dict:
    return json.loads((shared_dir / "data" / "synthetic" / "issia-dev.truth.json").read_text())


def write_issia_stretch(shared_dir: Path, dest: Path, first: int = 0, last: int = 39, *, videos: bool = True,
                        calibration: bool = True, lines: bool = True) -> Path:
    """``dest`` holding frames ``first..last`` of the dev sequence; returns ``dest``."""
    src = dev_dir(shared_dir)
    dest.mkdir(parents=True, exist_ok=True)
    if calibration:
        shutil.copy(src / "issia_calibration.json", dest)
    if lines:
        shutil.copy(src / "issia_lines.json", dest)
    with (src / "ball_points.csv").open(newline="") as fh:
        rows = list(csv.reader(fh))
    with (dest / "ball_points.csv").open("w", newline="") as fh:
        csv.writer(fh).writerows([rows[0]] + [r for r in rows[1:] if first <= int(r[0]) <= last])
    if videos:
        shutil.copytree(src / "videos", dest / "videos")  # copied (4 MB): a link out of the dataset is refused
    return dest
