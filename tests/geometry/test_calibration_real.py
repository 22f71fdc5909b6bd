"""Calibration on shared data: a handful of real SoccerNet-calibration frames scored with the official
JaC, and the synthetic SoccerNet-v3 dev game whose truth cameras are known."""
from __future__ import annotations

import json
import zipfile
from pathlib import Path

import numpy as np
import pytest

from app.geometry.annotations import from_soccernet_calibration, from_soccernet_v3
from app.geometry.calibration import CalibrationPrior, calibrate_frame
from app.geometry.calibration.result import REFUSAL_CODES
from app.geometry.camera import Camera
from app.geometry.jac import evaluate_jac

pytestmark = pytest.mark.shared


@pytest.mark.parametrize("folder", ["sn-calib-2022-test-main", "wc14-test"])
def test_real_frames_calibrate_with_high_official_jac(shared_dir: Path, folder: str) -> None:
    with zipfile.ZipFile(shared_dir / "data" / "real" / folder / "annotations.zip") as z:
        names = sorted(n for n in z.namelist() if n.endswith(".json"))[:15]
        frames = [json.loads(z.read(n)) for n in names]
    jac5, refused = [], []
    for data in frames:
        lines = from_soccernet_calibration(data, 960, 540)
        result = calibrate_frame(lines, 960, 540, prior=CalibrationPrior(expected_side=1), compute_jac=False)
        if result.camera is None:
            # e.g. sn22 frame 00020: its goal is labelled left, its box right
            assert result.refusal.code in REFUSAL_CODES
            refused.append(result.refusal)
            continue
        assert "probably_mirrored" not in result.flags  # these main cameras stand on the y > 0 side
        jac5.append(evaluate_jac(result.camera, lines, 960, 540, (5.0,)).jac[5.0])
    assert len(refused) <= 1
    # Peers fed the same lines: PnLCalib 0.80 (sn22) / 0.85 (wc14) over whole sets.
    assert np.mean(jac5) >= 0.85
    assert np.median(jac5) >= 0.9


def test_synthetic_dev_game_recovers_truth_cameras(shared_dir: Path) -> None:
    root = shared_dir / "data" / "synthetic"
    truth = json.loads((root / "soccernet-v3-dev.truth.json").read_text())
    game = truth["games"][0]
    labels = json.loads((root / "soccernet-v3-dev" / game["url_local"] / "Labels-v3.json").read_text())
    items = {**labels["actions"], **labels["replays"]}
    errors, focal = [], []
    for system in game["systems"]:
        if system["corruption"] is not None:
            continue
        for view in system["views"]:
            width, height = view["width"], view["height"]
            lines = from_soccernet_v3(items[view["image"]]["lines"], width, height)
            result = calibrate_frame(lines, width, height, compute_jac=False)  # never raises
            if result.camera is None or len(lines) < 5:
                continue
            true_cam = Camera.from_soccernet(view["camera"])
            errors.append(float(np.linalg.norm(result.camera.C - true_cam.C)))
            focal.append(abs(result.camera.K[0, 0] / true_cam.K[0, 0] - 1.0))
    assert len(errors) >= 15
    assert np.median(errors) < 1.0  # metres (cameras 20 to 100 m from the pitch)
    assert np.median(focal) < 0.02
