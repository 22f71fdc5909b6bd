"""Benchmark of ``calibrate_frame`` on the real SoccerNet-calibration test sets (run by hand).

For each set under ``../shared/data/real`` (sn22 test main camera, 1,454 frames; wc14 test, 186
frames) it calibrates every frame at 960x540 in this one process (one core), scores the cameras with
the official JaC (:func:`app.geometry.jac.evaluate_jac`, thresholds 5, 10 and 20 px) and prints:

* completeness (calibrated / frames), mean JaC@5/10/20 px over the calibrated frames, final score
  (completeness x mean JaC@5, SoccerNet's), the fraction of calibrated frames admitted (the admission rule of a
  multi-view system, :func:`app.geometry.jac.jac_admitted` with the settings' gamma and threshold: JaC@0.5 % > 0.75
  by default; 0.5 % of the 960x540 diagonal is 5.51 px);
* median and 99th percentile time per frame, as CPU time of this process (robust to other load on a
  shared machine) and as wall time;
* refusals with their reasons, flags, and the peer numbers for reference (PnLCalib fed the same
  ground-truth lines, official evaluator, from ``official-jac-pnlcalib.json``).

Usage: ``.venv/bin/python benchmarks/calibration.py [--limit N] [--sets sn22,wc14] [--json out.json]``
"""
from __future__ import annotations

import argparse
import collections
import json
import statistics
import sys
import time
import zipfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from app.core.config import Settings
from app.core.paths import SHARED_DIR
from app.geometry.annotations import from_soccernet_calibration
from app.geometry.calibration import CalibrationPrior, calibrate_frame
from app.geometry.jac import evaluate_jac, gamma_thresholds, jac_admitted
from app.services.calibration.admission import admission_args
from app.services.wording.words import refusal_sentence

SETS = {"sn22": "sn-calib-2022-test-main", "wc14": "wc14-test"}
TARGETS = {"sn22": (0.837, 0.985), "wc14": (0.902, 0.979)}
W, H = 960, 540


def _peer(folder: Path) -> tuple[float, float]:
    data = json.loads((folder / "official-jac-pnlcalib.json").read_text())["frames"]
    vals = [v[0] for v in data.values() if v is not None]
    return float(np.mean(vals)), len(vals) / len(data)


def run_set(key: str, limit: int | None) -> dict:
    folder = SHARED_DIR / "data" / "real" / SETS[key]
    with zipfile.ZipFile(folder / "annotations.zip") as z:
        names = sorted(n for n in z.namelist() if n.endswith(".json"))[:limit]
        frames = [(Path(n).stem, json.loads(z.read(n))) for n in names]
    prior = CalibrationPrior(expected_side=1)  # main broadcast cameras
    cpu_ms, wall_ms, jac, admitted = [], [], [], []
    refusals: list[tuple[str, str]] = []
    flags: collections.Counter[str] = collections.Counter()
    admission = admission_args(Settings())
    gamma_px = gamma_thresholds(W, H, (admission["admit_jac_gamma"],))[0]
    for frame, data in frames:
        lines = from_soccernet_calibration(data, W, H)
        c0, w0 = time.process_time(), time.perf_counter()
        result = calibrate_frame(lines, W, H, prior=prior, compute_jac=False)
        cpu_ms.append((time.process_time() - c0) * 1e3)
        wall_ms.append((time.perf_counter() - w0) * 1e3)
        flags.update(f.split(":")[0] for f in result.flags)
        if result.camera is None:
            refusals.append((frame, refusal_sentence(result.refusal) or ""))
            continue
        scores = evaluate_jac(result.camera, lines, W, H, (5.0, 10.0, 20.0, gamma_px)).jac
        jac.append([scores[5.0], scores[10.0], scores[20.0]])
        admitted.append(jac_admitted(scores[gamma_px], admission["admit_jac_min"]))
    J = np.array(jac).reshape(-1, 3)
    completeness = len(J) / len(frames)
    peer_jac, peer_completeness = _peer(folder)
    return {
        "set": key, "frames": len(frames), "calibrated": len(J), "completeness": completeness,
        "jac_5": float(J[:, 0].mean()), "jac_10": float(J[:, 1].mean()), "jac_20": float(J[:, 2].mean()),
        "final_score": completeness * float(J[:, 0].mean()), "admitted_fraction": float(np.mean(admitted)),
        "cpu_ms_median": statistics.median(cpu_ms), "cpu_ms_p99": float(np.percentile(cpu_ms, 99)),
        "wall_ms_median": statistics.median(wall_ms), "wall_ms_p99": float(np.percentile(wall_ms, 99)),
        "flags": dict(flags), "refusals": refusals, "peer_jac_5": peer_jac, "peer_completeness": peer_completeness,
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--limit", type=int, default=None, help="first N frames of each set only")
    ap.add_argument("--sets", default="sn22,wc14")
    ap.add_argument("--json", type=Path, default=None, help="write the rows here")
    args = ap.parse_args()
    rows = [run_set(k, args.limit) for k in args.sets.split(",")]
    head = (f"{'set':5} {'frames':>6} {'compl.':>7} {'JaC@5':>7} {'JaC@10':>7} {'JaC@20':>7} {'final':>7} "
            f"{'admit.':>6} {'cpu ms med':>10} {'p99':>6} {'wall med':>8} {'p99':>6}   target JaC@5/compl.   PnLCalib")
    print(head)
    for r in rows:
        t = TARGETS[r["set"]]
        print(f"{r['set']:5} {r['frames']:6d} {r['completeness']:7.4f} {r['jac_5']:7.4f} {r['jac_10']:7.4f} "
              f"{r['jac_20']:7.4f} {r['final_score']:7.4f} {r['admitted_fraction']:6.3f} {r['cpu_ms_median']:10.1f} "
              f"{r['cpu_ms_p99']:6.1f} {r['wall_ms_median']:8.1f} {r['wall_ms_p99']:6.1f}   "
              f"{t[0]:.3f} / {t[1]:.3f} {'ok' if r['jac_5'] >= t[0] and r['completeness'] >= t[1] else 'MISSED':6}  "
              f"{r['peer_jac_5']:.4f} / {r['peer_completeness']:.4f}")
    for r in rows:
        print(f"\n{r['set']}: flags {r['flags']}; {len(r['refusals'])} refused")
        for frame, reason in r["refusals"]:
            print(f"  {frame}: {reason}")
    if args.json:
        args.json.write_text(json.dumps(rows, indent=1))


if __name__ == "__main__":
    main()
