"""What weighing the triangulation by calibration worth costs and gains (issue 18's yield): every system's 3D ball
against the truth under the paper's rule and under variants of ``triangulate_ball``'s ``view_weights``.

For each set recomputed by ``benchmarks/doubts_seeds.py`` (its copy ``<set>.<tree>-judge.sqlite3`` under
``--db-dir``), every system's triangulation is redone in process from the stored cameras and labels (the views
``recompute_system`` uses: admitted, labelled, included, not suggested), with the weights the service gives
(``app.services.derivation.doubts.calibration_weights``), and each ball compared with the true one: right (within
0.5 m), wrong (more than 1 m), none. Variants: ``paper`` (no weights), ``tier only`` (no least pair weight: only the
pairs of the highest weight sum averaged), ``min 1.0`` (two half votes make a ball) and ``min 1.5`` (today's
:data:`app.geometry.triangulation.MIN_PAIR_WEIGHT`: a full vote and at least a half one).

Run: ``.venv/bin/python benchmarks/triangulation_weights.py [--sets dev-large seed-201 ...] [--db-dir DIR]``
(after ``benchmarks/doubts_seeds.py`` with the same ``--db-dir``).
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import sqlalchemy as sa
from sqlalchemy.orm import Session, selectinload

from app.core.config import Settings
from app.db.models import CalibrationStatus, Frame, System
from app.geometry import triangulation as T
from app.geometry.camera import Camera
from app.geometry.pitch import within_play_volume
from app.services.derivation.doubts import calibration_weights, is_excluded
from app.services.derivation.recompute import _label_centre
from benchmarks.doubts_seeds import SETS

VARIANTS: dict[str, float | None] = {"paper": None, "tier only": 0.0, "min 1.0": 1.0, "min 1.5": 1.5}


def score(name: str, db: Path) -> dict[str, dict[str, int]]:
    """Right / wrong / none per variant for the set ``name`` recomputed in ``db``."""
    truth = json.loads(SETS[name].with_name(SETS[name].name + ".truth.json").read_text())
    true_ball = {(g["match"], s["action"]): s["ball_3d"] for g in truth["games"] for s in g["systems"]}
    st = Settings()

    def volume(p: np.ndarray) -> bool:
        return bool(within_play_volume(p)[0])  # pitch.PLAY_VOLUME, as the service

    out = {k: {"right": 0, "wrong": 0, "none": 0} for k in VARIANTS}
    with Session(sa.create_engine(f"sqlite:///{db}")) as session:
        frames = selectinload(System.frames)
        systems = session.scalars(sa.select(System).options(
            selectinload(System.game), frames.selectinload(Frame.calibration), frames.selectinload(Frame.ball_label),
            frames.selectinload(Frame.field_lines), frames.selectinload(Frame.review))).all()
        for system in systems:
            cams = {f.id: Camera.from_soccernet(f.calibration.camera) for f in system.frames
                    if f.calibration is not None and f.calibration.status is CalibrationStatus.CALIBRATED}
            obs = [T.BallObservation(f.id, cams[f.id], _label_centre(f), f.width) for f in system.frames
                   if f.calibration is not None and f.calibration.admitted and _label_centre(f) is not None
                   and not is_excluded(f) and not (f.ball_label is not None and f.ball_label.suggested)]
            weights = calibration_weights(system, st, cams)
            t = np.asarray(true_ball[(system.game.match, system.name)])
            for k, least in VARIANTS.items():
                saved, T.MIN_PAIR_WEIGHT = T.MIN_PAIR_WEIGHT, least if least is not None else T.MIN_PAIR_WEIGHT
                try:
                    r = T.triangulate_ball(obs, tau_px=st.triangulation_tau_px, rule=st.pair_error_rule,
                                           min_baseline_m=st.min_baseline_m, min_parallax_deg=st.min_parallax_deg,
                                           play_volume=volume, view_weights=None if least is None else weights)
                finally:
                    T.MIN_PAIR_WEIGHT = saved
                if r.point is None:
                    out[k]["none"] += 1
                    continue
                e = float(np.linalg.norm(r.point - t))
                out[k]["right"] += e <= 0.5
                out[k]["wrong"] += e > 1.0
    return out


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--sets", nargs="*", default=list(SETS), choices=list(SETS))
    ap.add_argument("--db-dir", type=Path, default=Path("/tmp/v3d-doubts-seeds"))
    ap.add_argument("--tree", default=ROOT.name, help="the tree whose recomputed copies to read (doubts_seeds' name)")
    args = ap.parse_args()
    for name in args.sets:
        db = args.db_dir / f"{name}.{args.tree}-judge.sqlite3"
        for k, c in score(name, db).items():
            print(f"[{name}] {k:9s}: 3D ball right {c['right']}, wrong {c['wrong']}, none {c['none']}", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
