"""Import the real SoccerNet-calibration frames and report calibration figures.

Imports ``sn-calib-2022-test-main/annotations.zip`` (1,454 frames) and ``wc14-test/annotations.zip``
(186 frames), both 960x540 without images, with ``v3d``'s import service into a fresh SQLite database
(bulk calibration in a process pool over all cores, as ``v3d import sn-calibration`` does), then
reads the stored calibrations back and prints per dataset:

* wall time of the import and of its calibration step, frames per second;
* calibrated / refused, with the refusal reasons grouped by kind;
* mean JaC at the official 5 / 10 / 20 px thresholds at 960x540 (``app.geometry.jac.evaluate_jac``
  on the stored camera and lines; note: JaC@5px, not the JaC@0.5 % of the diagonal = 5.51 px that
  v3d stores) over the calibrated frames, and completeness (calibrated / all frames), as SoccerNet's
  evaluator reports them; the stored JaC@0.5 %, 1 %, 2 % means too;
* median and 90th percentile ms of ``calibrate_frame`` per frame (inside the workers);
* for reference, the official evaluator's figures of PnLCalib's cameras on the same frames
  (``official-jac-pnlcalib.json``).

Run: ``cd /work/main && .venv/bin/python benchmarks/import_real.py [--workers 0] [--keep DB_PATH]``
(several minutes on 2 cores). ``--only wc14`` or ``--only sn22`` imports one dataset.
"""
from __future__ import annotations

import argparse
import json
import statistics
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from sqlalchemy import select
from sqlalchemy.orm import selectinload

from app.core.config import Settings
from app.core.paths import SHARED_DIR
from app.db.models import CalibrationStatus, Frame, Game, System
from app.db.session import make_engine, make_session_factory, upgrade_database
from app.geometry.annotations import lines_from_json_lists
from app.geometry.camera import Camera
from app.geometry.jac import evaluate_jac
from app.services.transfer.importing import import_sn_calibration

DATASETS = {"sn22": "sn-calib-2022-test-main", "wc14": "wc14-test"}
WIDTH, HEIGHT = 960, 540
OFFICIAL_PX = (5.0, 10.0, 20.0)


def _official(folder: Path) -> tuple[list[float], float, int]:
    data = json.loads((folder / "official-jac-pnlcalib.json").read_text())
    frames = dict(data["frames"]) if isinstance(data["frames"], list) else data["frames"]
    predicted = [v for v in frames.values() if v is not None]
    means = [float(np.mean([v[i] for v in predicted])) for i in range(3)]
    return means, len(predicted) / len(frames), len(frames)


def _figures(session, game: Game) -> dict:
    frames = session.scalars(
        select(Frame).join(System).where(System.game_id == game.id)
        .options(selectinload(Frame.calibration), selectinload(Frame.field_lines))
    ).all()
    jac_px, jac_gamma = [], []
    for f in frames:
        cal = f.calibration
        if cal.status is CalibrationStatus.CALIBRATED:
            res = evaluate_jac(Camera.from_soccernet(cal.camera), lines_from_json_lists(f.field_lines.lines),
                               f.width, f.height, OFFICIAL_PX)
            jac_px.append([t.jac for t in res.per_threshold])
            jac_gamma.append([cal.jac_0005, cal.jac_001, cal.jac_002])
    return {
        "frames": len(frames), "calibrated": len(jac_px),
        "jac_px": np.mean(jac_px, axis=0).tolist() if jac_px else [float("nan")] * 3,
        "jac_gamma": np.mean(jac_gamma, axis=0).tolist() if jac_gamma else [float("nan")] * 3,
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--shared", type=Path, default=SHARED_DIR)
    ap.add_argument("--workers", type=int, default=0, help="calibration processes (0 = all cores)")
    ap.add_argument("--only", choices=sorted(DATASETS), action="append")
    ap.add_argument("--keep", type=Path, help="keep the SQLite database at this path")
    args = ap.parse_args()

    tmp = tempfile.TemporaryDirectory()
    db_path = args.keep or Path(tmp.name) / "bench.sqlite3"
    if db_path.exists():
        sys.exit(f"{db_path} exists; choose a new path")
    url = f"sqlite:///{db_path}"
    upgrade_database(url)
    engine = make_engine(url)
    settings = Settings(database_url=url, calibration_workers=args.workers)
    for key in args.only or list(DATASETS):
        folder = args.shared / "data" / "real" / DATASETS[key]
        with make_session_factory(engine)() as session:
            t0 = time.perf_counter()
            report = import_sn_calibration(session, folder / "annotations.zip", settings, width=WIDTH, height=HEIGHT)
            wall = time.perf_counter() - t0
            game = session.scalars(select(Game).where(Game.season == DATASETS[key])).one()
            fig = _figures(session, game)
        ms = sorted(report.calibration_ms)
        official, official_completeness, official_n = _official(folder)
        print(f"\n== {key}: {folder / 'annotations.zip'} ({report.frames} frames, {WIDTH}x{HEIGHT}) ==")
        print(f"import wall time      {wall:8.1f} s  (read {report.read_seconds:.1f} s, calibrate "
              f"{report.calibration_seconds:.1f} s, store + recompute + commit {report.store_seconds:.1f} s; "
              f"{report.frames / wall:.1f} frames/s, workers={args.workers or 'all cores'})")
        print(f"calibrated / refused  {report.calibrated} / {report.refused}  "
              f"completeness {fig['calibrated'] / fig['frames']:.4f}")
        for reason, n in report.refusal_kinds().most_common():
            print(f"  refused x{n:<4d} {reason}")
        print("mean JaC@5/10/20 px   " + " / ".join(f"{v:.4f}" for v in fig["jac_px"]) + "  (over calibrated frames)")
        print("mean JaC@0.5/1/2 %    " + " / ".join(f"{v:.4f}" for v in fig["jac_gamma"])
              + "  (stored, gamma x diagonal)")
        print(f"calibrate_frame ms    median {statistics.median(ms):.1f}, p90 {ms[int(0.9 * (len(ms) - 1))]:.1f}, "
              f"max {ms[-1]:.1f}")
        print("PnLCalib (official)   " + " / ".join(f"{v:.4f}" for v in official)
              + f"  completeness {official_completeness:.4f} of {official_n}")
    engine.dispose()


if __name__ == "__main__":
    main()
