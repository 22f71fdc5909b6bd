"""``v3d calibrate`` on a small zip made here: two synthetic frames with a known camera, one frame
with a single line (refused) and one unreadable file; its output is then scored by ``v3d jac``."""
from __future__ import annotations

import json
import re
import zipfile
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

import app.cli.calibration  # registers ``v3d calibrate``
import app.cli.evaluation  # noqa: F401  # registers ``v3d jac``
from app.cli._root import cli
from app.geometry.annotations import to_soccernet_calibration
from app.geometry.calibration import principal_point
from app.geometry.camera import Camera, look_at_rotation
from tests.geometry.test_calibration import synthetic_lines

W, H = 960, 540
runner = CliRunner()


def _truth(centre: tuple[float, float, float], target: tuple[float, float, float], focal: float) -> Camera:
    pp = principal_point(W, H)
    K = np.array([[focal, 0.0, pp[0]], [0.0, focal, pp[1]], [0.0, 0.0, 1.0]])
    return Camera(K=K, R=look_at_rotation(np.array(centre), np.array(target)), C=np.array(centre))


TRUTHS = {
    "1": _truth((0.0, 62.0, -18.0), (0.0, -4.0, 0.0), 900.0),
    "2": _truth((-8.0, 58.0, -16.0), (-38.0, -2.0, 0.0), 1300.0),
}


@pytest.fixture()
def annotations_zip(tmp_path: Path) -> Path:
    path = tmp_path / "frames.zip"
    with zipfile.ZipFile(path, "w") as z:
        for frame, cam in TRUTHS.items():
            lines = synthetic_lines(cam, W, H, sigma_px=0.5, seed=int(frame))
            z.writestr(f"{frame}.json", json.dumps(to_soccernet_calibration(lines, W, H)))
        z.writestr("3.json", json.dumps({"Side line top": [{"x": 0.0, "y": 0.2}, {"x": 1.0, "y": 0.25}]}))
        z.writestr("4.json", "{not json")
    return path


@pytest.mark.parametrize("workers", ["1", "2"])
def test_calibrate_writes_cameras_and_summary(annotations_zip: Path, tmp_path: Path, workers: str) -> None:
    out = tmp_path / "cams"
    result = runner.invoke(cli, ["calibrate", str(annotations_zip), str(out), "--workers", workers,
                                 "--expected-side", "+1"])
    assert result.exit_code == 0, result.output
    assert "4 frames" in result.output and "2 calibrated, 1 refused, 1 unreadable" in result.output
    assert sorted(p.name for p in out.glob("camera_*.json")) == ["camera_1.json", "camera_2.json"]
    for frame, truth in TRUTHS.items():
        cam = Camera.from_soccernet(json.loads((out / f"camera_{frame}.json").read_text()))
        assert np.linalg.norm(cam.C - truth.C) < 1.0
        assert abs(cam.K[0, 0] / truth.K[0, 0] - 1.0) < 0.02
    summary = json.loads((out / "calibration_summary.json").read_text())
    assert summary["3"]["status"] == "refused" and "too few field lines" in summary["3"]["reason"]
    assert summary["4"]["status"] == "unreadable"
    assert summary["1"]["status"] == "calibrated" and summary["1"]["rms_px"] < 1.5


def test_output_is_scored_by_v3d_jac(annotations_zip: Path, tmp_path: Path) -> None:
    out = tmp_path / "cams"
    assert runner.invoke(cli, ["calibrate", str(annotations_zip), str(out), "--workers", "1"]).exit_code == 0
    # v3d jac reads every *.json of the annotations: score against the two good frames only.
    ann = tmp_path / "ann"
    ann.mkdir()
    with zipfile.ZipFile(annotations_zip) as z:
        for frame in TRUTHS:
            (ann / f"{frame}.json").write_bytes(z.read(f"{frame}.json"))
    report = tmp_path / "jac.json"
    result = runner.invoke(cli, ["jac", str(ann), str(out), "--json", str(report)])
    assert result.exit_code == 0, result.output
    payload = json.loads(report.read_text())
    assert payload["completeness"] == 1.0
    assert payload["mean_jac"][0] >= 0.9  # JaC@5 px of near-exact labels


def test_missing_input_is_a_clear_error(tmp_path: Path) -> None:
    result = runner.invoke(cli, ["calibrate", str(tmp_path / "nope.zip"), str(tmp_path / "out")])
    assert result.exit_code != 0
    # rich wraps long paths in a box
    def flat(text):
        return re.sub(r"[\s\u2502]+", " ", text)
    assert "no such file or folder" in flat(result.output)
    (tmp_path / "notes.txt").write_text("not a set")
    result = runner.invoke(cli, ["calibrate", str(tmp_path / "notes.txt"), str(tmp_path / "out")])
    assert result.exit_code != 0
    assert "neither a folder nor a zip" in flat(result.output)
