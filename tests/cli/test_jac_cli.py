"""``v3d jac`` on small inputs built here: three annotated frames, two cameras (one exact, one moved).

The scene is a camera 60 m straight above the centre spot (f = 500 px at 960x540). Frame "1" gets
that camera, frame "2" the same camera moved 0.72 m along the pitch (every ground line moves 6 px),
frame "3" no camera at all.
"""
from __future__ import annotations

import json
import zipfile
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

import app.cli.evaluation  # noqa: F401  # registers ``v3d jac``
from app.cli._root import cli
from app.geometry.annotations import from_soccernet_calibration
from app.geometry.camera import Camera
from app.geometry.jac import evaluate_jac
from app.geometry.projection import project_pitch_polylines

W, H = 960, 540
runner = CliRunner()


def overhead(x: float = 0.0) -> Camera:
    return Camera.from_parameters(focal_px=500.0, principal_point=(480.0, 270.0), pan_deg=0.0, tilt_deg=0.0,
                                  roll_deg=0.0, position_m=[x, 0.0, -60.0])


def annotation() -> dict:
    """Normalised SoccerNet-calibration JSON: three vertices from the middle of each projected element."""
    out = {}
    for cls, runs in project_pitch_polylines(overhead(), W, H).items():
        run = max(runs, key=len)
        idx = np.linspace(0.25, 0.75, 3) * (len(run) - 1)
        pts = run[np.round(idx).astype(int)] / [W - 1, H - 1]
        out[cls] = [{"x": float(x), "y": float(y)} for x, y in pts]
    return out


@pytest.fixture()
def inputs(tmp_path: Path) -> tuple[Path, Path]:
    ann = tmp_path / "annotations.zip"
    with zipfile.ZipFile(ann, "w") as z:
        for frame in ("1", "2", "3"):
            z.writestr(f"test/{frame}.json", json.dumps(annotation()))
    cams = tmp_path / "cameras"
    cams.mkdir()
    (cams / "camera_1.json").write_text(json.dumps(overhead().to_soccernet()))
    (cams / "camera_2.json").write_text(json.dumps(overhead(0.72).to_soccernet()))
    return ann, cams


def expected_frame_2(thresholds) -> list[float]:
    lines = from_soccernet_calibration(annotation(), W, H)
    return [t.jac for t in evaluate_jac(overhead(0.72), lines, W, H, thresholds).per_threshold]


def test_scores_completeness_mean_and_final(inputs, tmp_path):
    ann, cams = inputs
    out = tmp_path / "out.json"
    result = runner.invoke(cli, ["jac", str(ann), str(cams), "--json", str(out)])
    assert result.exit_code == 0, result.output
    assert "3 annotated frames, 2 with a camera: completeness 0.6667" in result.output
    data = json.loads(out.read_text())
    assert data["thresholds_px"] == [5.0, 10.0, 20.0] and data["gammas"] is None
    assert data["frames"]["1"] == [1.0, 1.0, 1.0]
    assert data["frames"]["3"] is None
    second = expected_frame_2((5, 10, 20))
    assert data["frames"]["2"] == second
    assert second[0] < 1.0 and second[2] == 1.0  # 6 px off: fails at 5 px, passes at 20 px
    assert data["completeness"] == pytest.approx(2 / 3)
    assert data["mean_jac"] == pytest.approx([(1 + v) / 2 for v in second])
    assert data["final_score"] == pytest.approx([2 / 3 * (1 + v) / 2 for v in second])
    assert f"{(1 + second[0]) / 2:.4f}" in result.output


def test_gammas_and_a_zip_of_cameras(inputs, tmp_path):
    ann, cams = inputs
    cam_zip = tmp_path / "cams.zip"
    with zipfile.ZipFile(cam_zip, "w") as z:
        for p in cams.iterdir():
            z.write(p, f"preds/{p.name}")
    out = tmp_path / "g.json"
    result = runner.invoke(cli, ["jac", str(ann), str(cam_zip), "--gammas", "0.005,0.02", "--json", str(out)])
    assert result.exit_code == 0, result.output
    data = json.loads(out.read_text())
    assert data["gammas"] == [0.005, 0.02]
    assert data["thresholds_px"] == pytest.approx([0.005 * np.hypot(W, H), 0.02 * np.hypot(W, H)])
    assert data["frames"]["2"] == expected_frame_2(data["thresholds_px"])
    assert "5.51 px" in result.output


@pytest.mark.parametrize("extra, message", [
    (["--thresholds", "5,x"], "--thresholds"),
    (["--thresholds", "5", "--gammas", "0.01"], "either --thresholds or --gammas"),
    (["--gammas", "0,0.01"], "--gammas"),
])
def test_bad_options_are_reported(inputs, extra, message):
    ann, cams = inputs
    result = runner.invoke(cli, ["jac", str(ann), str(cams), *extra])
    assert result.exit_code == 2
    assert message in result.output


def test_missing_paths_are_named(inputs, tmp_path):
    ann, cams = inputs
    result = runner.invoke(cli, ["jac", str(tmp_path / "nowhere"), str(cams)])
    assert result.exit_code == 2 and "ANNOTATIONS: no such file or folder" in result.output
    result = runner.invoke(cli, ["jac", str(ann), str(tmp_path / "nocams.zip")])
    assert result.exit_code == 2 and "CAMERAS: no such file or folder" in result.output
    empty = tmp_path / "empty"
    empty.mkdir()
    result = runner.invoke(cli, ["jac", str(empty), str(cams)])
    assert result.exit_code == 2 and "no *.json annotation file" in result.output


def test_unreadable_json_names_the_file(inputs):
    ann, cams = inputs
    (cams / "camera_2.json").write_text("{not json")
    result = runner.invoke(cli, ["jac", str(ann), str(cams)])
    assert result.exit_code == 2
    assert "camera_2.json: not readable JSON" in result.output


def test_malformed_camera_and_annotation_name_the_file(inputs, tmp_path):
    ann, cams = inputs
    (cams / "camera_1.json").write_text(json.dumps({"pan_degrees": 0.0}))
    result = runner.invoke(cli, ["jac", str(ann), str(cams)])
    assert result.exit_code == 2 and "camera_1.json: camera JSON lacks field(s)" in result.output
    bad_ann = tmp_path / "bad"
    bad_ann.mkdir()
    (bad_ann / "1.json").write_text(json.dumps({"Side line middle": [{"x": 0.1, "y": 0.2}]}))
    (cams / "camera_1.json").write_text(json.dumps(overhead().to_soccernet()))
    result = runner.invoke(cli, ["jac", str(bad_ann), str(cams)])
    assert result.exit_code == 2 and "1.json" in result.output and "Side line middle" in result.output
