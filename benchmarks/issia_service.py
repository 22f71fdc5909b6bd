"""ISSIA-3D through the service: import the dev sequence, then score the **stored** values against the truth.

Usage: ``python -m benchmarks.issia_service [--data DIR] [--truth FILE] [--json OUT]``

Both modes (``issia_calibration.json``; ``issia_lines.json`` alone), each into a fresh SQLite file:
``v3d import issia`` (``app.services.issia.import_issia``), then the figures of issue 9 from the
stored ``TrajectoryPoint`` rows (``ball_3D``, ``ball_3D_smoothed``, ``cam_list``): the same
definitions as :mod:`benchmarks.issia` (which scores the pure fit). Also times the import and one
edit's round trip (a label moved and back, each re-fitted and committed).
"""
from __future__ import annotations

import argparse
import json
import tempfile
import time
from pathlib import Path

import numpy as np
import sqlalchemy as sa
from sqlalchemy.orm import Session

from benchmarks.issia import SHARED


def service_figures(session: Session, game_id: int, truth: dict) -> dict:
    """Figures of the stored sequence ``game_id`` against ``truth`` (issia-dev.truth.json)."""
    from app.services.issia_trajectory import load_sequence

    systems = {s.frame_index: s for s in load_sequence(session, game_id)}
    good2, seen, e3, es = [], [], [], []
    n_out = out_kept = n_ok = ok_kept = 0
    for fr in truth["frames"]:
        s = systems.get(fr["frame"])
        if s is None:
            continue
        tp = s.trajectory_point
        ids = {f.name: f.id for f in s.frames}
        true = np.asarray(fr["ball_3d"], float)
        ok = [ids[f"cam{c}"] for c, v in fr["cams"].items() if v["annotated"] and not v["outlier"]]
        bad = [ids[f"cam{c}"] for c, v in fr["cams"].items() if v["annotated"] and v["outlier"]]
        kept = set(tp.cam_list or []) if tp is not None else set()
        if len(ok) >= 2:
            good2.append(fr["frame"])
            e3.append(np.nan if tp is None or tp.ball3d is None else float(np.linalg.norm(np.asarray(tp.ball3d) - true)))
        if any(v["in_image"] for v in fr["cams"].values()):
            seen.append(fr["frame"])
            es.append(np.nan if tp is None or tp.ball3d_smoothed is None
                      else float(np.linalg.norm(np.asarray(tp.ball3d_smoothed) - true)))
        n_out += len(bad)
        out_kept += sum(i in kept for i in bad)
        n_ok += len(ok)
        ok_kept += sum(i in kept for i in ok)
    e3a, esa = np.array(e3), np.array(es)
    return {
        "frames_two_correct_labels": len(good2),
        "ball_3D_coverage": float(np.mean(np.isfinite(e3a))) if len(e3a) else None,
        "ball_3D_median_error_m": float(np.nanmedian(e3a)) if np.isfinite(e3a).any() else None,
        "frames_ball_in_an_image": len(seen),
        "smoothed_coverage": float(np.mean(np.isfinite(esa))) if len(esa) else None,
        "smoothed_median_error_m": float(np.nanmedian(esa)) if np.isfinite(esa).any() else None,
        "outlier_labels": n_out, "outliers_in_cam_list": out_kept,
        "correct_labels": n_ok, "correct_kept_share": ok_kept / n_ok if n_ok else None,
    }


def run(data: Path, truth: dict, from_lines: bool, workdir: Path) -> dict:
    """Import ``data`` into a fresh database in one mode; figures, import and edit timings."""
    from app.core.config import Settings
    from app.db.models import Game, System
    from app.db.session import make_engine, make_session_factory, upgrade_database
    from app.services.editing import update_ball_label
    from app.services.issia import import_issia

    url = f"sqlite:///{workdir / ('lines' if from_lines else 'json')}.sqlite3"
    upgrade_database(url)
    engine = make_engine(url)
    session = make_session_factory(engine)()
    settings = Settings(database_url=url)
    t0 = time.perf_counter()
    report = import_issia(session, data, settings, from_lines=from_lines)
    t_import = time.perf_counter() - t0
    game = session.scalars(sa.select(Game)).one()
    figures = service_figures(session, game.id, truth)
    mid = session.scalars(sa.select(System).where(System.game_id == game.id)
                          .order_by(System.frame_index).offset(report.systems // 2).limit(1)).one()
    frame = next(f for f in mid.frames if f.ball_label is not None and f.ball_label.point is not None)
    p = list(frame.ball_label.point)
    t1 = time.perf_counter()
    update_ball_label(session, frame.id, point=[p[0] + 3.0, p[1]], settings=settings)
    t_edit = time.perf_counter() - t1
    update_ball_label(session, frame.id, point=p, settings=settings)
    session.close()
    engine.dispose()
    return {"mode": "lines" if from_lines else "calibration_json", **figures, "import_s": t_import,
            "edit_round_trip_s": t_edit, "cameras_calibrated": report.calibrated}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", type=Path, default=SHARED / "issia-dev")
    ap.add_argument("--truth", type=Path, default=SHARED / "issia-dev.truth.json")
    ap.add_argument("--json", type=Path)
    args = ap.parse_args(argv)
    truth = json.loads(args.truth.read_text())
    results = []
    with tempfile.TemporaryDirectory() as tmp:
        for from_lines in (False, True):
            r = run(args.data, truth, from_lines, Path(tmp))
            results.append(r)
            print(f"== {r['mode']} ==")
            for k, v in r.items():
                print(f"  {k}: {v}")
    if args.json:
        args.json.write_text(json.dumps(results, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
