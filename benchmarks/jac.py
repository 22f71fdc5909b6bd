"""v3d's JaC against SoccerNet's official evaluator: speed and agreement.

On the first ``--frames`` frames (sorted by id) of the SoccerNet-calibration 2022 test split that
have a PnLCalib camera (``/work/shared/data/real/sn-calib-2022-test-main``), at 5, 10 and 20 px
(960x540), both implementations start from the same parsed JSON objects (camera dict, normalised
annotation dict) and do one (frame, threshold) evaluation, mirror included:

* official: ``SoccerNet.Evaluation.utils_calibration`` of the PyPI package ``SoccerNet`` (the
  ``bench`` extra), as its ``CameraCalibration.evaluate`` runs it per threshold: ``scale_points``,
  ``get_polylines(..., sampling_factor=0.9)``, ``evaluate_camera_prediction`` for the annotation and
  its mirror, the better accuracy;
* v3d: ``Camera.from_soccernet``, ``from_soccernet_calibration`` and ``evaluate_jac`` with that one
  threshold; also all three thresholds in one call (what v3d does in practice), per threshold.

Prints median CPU ms per (frame, threshold), the speed ratio, and the agreement of the values with the
official package and with ``official-jac-pnlcalib.json`` (pairs within 1e-6). If the package is not
installed it says so and compares with the ~0.1 s per (frame, threshold) reported for it.

Run: ``cd /work/main && .venv/bin/python benchmarks/jac.py [--frames 200] [--shared ../shared]``
(install the official package with ``.venv/bin/pip install SoccerNet``; the official side takes about
0.1-0.2 s per pair, so 200 frames take 2-5 minutes).
"""
from __future__ import annotations

import argparse
import json
import sys
import time
import warnings
import zipfile
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from app.core.paths import SHARED_DIR
from app.geometry.annotations import from_soccernet_calibration
from app.geometry.camera import Camera
from app.geometry.jac import evaluate_jac

W, H = 960, 540
THRESHOLDS = (5.0, 10.0, 20.0)
OFFICIAL_FIGURE_S = 0.1  # reported CPU time of the official evaluator per (frame, threshold)


def load_frames(folder: Path, n: int) -> tuple[list[tuple[str, dict, dict]], dict]:
    official = json.loads((folder / "official-jac-pnlcalib.json").read_text())["frames"]
    with zipfile.ZipFile(folder / "annotations.zip") as za, zipfile.ZipFile(folder / "pnlcalib-cameras.zip") as zc:
        cams = {Path(c).name: c for c in zc.namelist()}
        names = sorted((Path(a).stem, a) for a in za.namelist() if a.endswith(".json"))
        frames = [(fr, json.loads(za.read(a)), json.loads(zc.read(cams[f"camera_{fr}.json"])))
                  for fr, a in names if f"camera_{fr}.json" in cams]
    return frames[:n], official


def official_jac(sn, annotation: dict, camera: dict, threshold: float) -> float:
    """One (frame, threshold) as ``CameraCalibration.evaluate`` does it."""
    gt = sn.scale_points(annotation, W, H)
    pred = sn.get_polylines(camera, W, H, sampling_factor=0.9)
    c1, _, _ = sn.evaluate_camera_prediction(pred, gt, threshold)
    c2, _, _ = sn.evaluate_camera_prediction(pred, sn.mirror_labels(gt), threshold)
    a1 = c1[0, 0] / c1.sum() if c1.sum() > 0 else 0.0
    a2 = c2[0, 0] / c2.sum() if c2.sum() > 0 else 0.0
    return float(a1 if a1 > a2 else a2)


def v3d_jac(annotation: dict, camera: dict, thresholds: tuple[float, ...]) -> list[float]:
    lines = from_soccernet_calibration(annotation, W, H)
    return [t.jac for t in evaluate_jac(Camera.from_soccernet(camera), lines, W, H, thresholds).per_threshold]


def timed(fn, *args):
    """``(fn(*args), CPU seconds)``: process CPU time, so that other jobs on the machine do not count."""
    t0 = time.process_time()
    out = fn(*args)
    return out, time.process_time() - t0


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--frames", type=int, default=200)
    ap.add_argument("--repeats", type=int, default=3, help="v3d timing repeats (median kept)")
    ap.add_argument("--shared", type=Path, default=SHARED_DIR)
    args = ap.parse_args()
    folder = args.shared / "data" / "real" / "sn-calib-2022-test-main"
    frames, official_file = load_frames(folder, args.frames)
    print(f"{len(frames)} sn22 test frames with a PnLCalib camera, thresholds {THRESHOLDS} px at {W}x{H}")

    v3d_single, v3d_batch, v3d_values = [], [], {}
    for fr, ann, cam in frames:
        v3d_values[fr] = v3d_jac(ann, cam, THRESHOLDS)
        for t in THRESHOLDS:
            v3d_single.append(np.median([timed(v3d_jac, ann, cam, (t,))[1] for _ in range(args.repeats)]))
        v3d_batch.append(np.median([timed(v3d_jac, ann, cam, THRESHOLDS)[1] for _ in range(args.repeats)]) / 3)
    v3d_ms = 1000 * float(np.median(v3d_single))
    print(f"v3d      median {v3d_ms:8.3f} CPU ms per (frame, threshold), one threshold per call")
    print(f"v3d      median {1000 * float(np.median(v3d_batch)):8.3f} CPU ms per (frame, threshold), "
          f"three thresholds per call")

    file_ok = sum(abs(v - w) <= 1e-6 for fr, _, _ in frames
                  for v, w in zip(v3d_values[fr], official_file[fr], strict=False))
    print(f"agreement with official-jac-pnlcalib.json: {file_ok}/{3 * len(frames)} pairs within 1e-6")

    try:
        from SoccerNet.Evaluation import utils_calibration as sn
    except ImportError as exc:
        print(f"official evaluator not importable ({exc}); install it with `.venv/bin/pip install SoccerNet`.")
        print(f"against the reported ~{1000 * OFFICIAL_FIGURE_S:.0f} ms per (frame, threshold): "
              f"v3d is {1000 * OFFICIAL_FIGURE_S / v3d_ms:.0f}x faster")
        return
    official_times, agree, worst = [], 0, 0.0
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # the evaluator divides by zero on parallel lines
        for fr, ann, cam in frames:
            for t, mine in zip(THRESHOLDS, v3d_values[fr], strict=False):
                value, dt = timed(official_jac, sn, ann, cam, t)
                official_times.append(dt)
                agree += abs(value - mine) <= 1e-6
                worst = max(worst, abs(value - mine))
    off_ms = 1000 * float(np.median(official_times))
    print(f"official median {off_ms:8.3f} CPU ms per (frame, threshold) (PyPI SoccerNet, utils_calibration)")
    print(f"speed ratio official / v3d: {off_ms / v3d_ms:.0f}x (one threshold per call), "
          f"{off_ms / (1000 * float(np.median(v3d_batch))):.0f}x (three per call)")
    print(f"agreement with the official package: {agree}/{len(official_times)} pairs within 1e-6 "
          f"(largest difference {worst:.2e})")


if __name__ == "__main__":
    main()
