"""What backs each 3D ball, against the truth (``benchmarks/VOUCH.md``): on each shared set with a truth, every stored
3D ball's tier (``app.geometry.ball_evidence``) and each evidence's figures, with the ball's error.

For each set (the doubts sets: dev-large and seeds 201-205, labels as imported; the detector sets
``../shared/data/synthetic/detector/<set>-unlabelled`` with their predictions imported, source ``detector``):

1. import it once with ``v3d import soccernet-v3`` into a cached SQLite database (``--db-dir``; the slow part), the
   same cache as ``benchmarks/doubts_seeds.py`` and ``benchmarks/detector_fill.py``;
2. copy it, ``v3d recompute`` with this tree's code (and, for a detector set, ``v3d import predictions`` first);
3. in process, for every system with a truth: its stored ball's error (m), its stored tier and reasons, and the facts
   the rule reads (``app.services.derivation.ball.ball_facts`` on the stored rows: views in kept pairs, labels the
   detector confirms, each label's size over the sphere's at the ball, kept pairs whose players agree, the sigma,
   label doubts on the ball's views).

Prints per set and tier the balls within 0.5 m, 0.5-1 m and beyond 1 m, and the vouched share of the right balls;
``--facts OUT`` writes every ball's facts and error (JSON lines) for the per-evidence separation
(:func:`separation`, ``--separation``).

Run: ``.venv/bin/python benchmarks/ball_evidence.py [--sets dev-large seed-201 ... det-dev-large det-seed-204]
[--json OUT] [--facts OUT] [--separation]``.
"""
from __future__ import annotations

import argparse
import json
import shutil
import sys
from collections import Counter
from pathlib import Path
from typing import Any, Sequence

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from benchmarks.detector_fill import paths as detector_paths  # noqa: E402  # after the path is set
from benchmarks.detector_fill import template as detector_template  # noqa: E402  # after the path is set
from benchmarks.doubts_seeds import SETS, V3D, _run, template  # noqa: E402  # after the path is set

#: Sets that chose the rule's thresholds (``app.geometry.ball_evidence``); the others were read only after it was
#: fixed.
CHOOSING_SETS: tuple[str, ...] = ("dev-large", "seed-201", "seed-202", "det-dev-large")
ALL_SETS: tuple[str, ...] = (*SETS, "det-dev-large", "det-seed-204")
RIGHT_M, WRONG_M = 0.5, 1.0


def prepared(name: str, db_dir: Path) -> tuple[str, Path]:
    """A recomputed copy of set ``name`` (``det-`` sets with their predictions imported): its URL and truth."""
    if name.startswith("det-"):
        base = name[4:]
        tree, truth, pred = detector_paths(base, db_dir)
        src = detector_template(base, tree, db_dir / "det")
    else:
        src, pred = template(name, db_dir), None
        truth = SETS[name].with_name(SETS[name].name + ".truth.json")
    dst = db_dir / f"{name}.{ROOT.name}-evidence.sqlite3"
    for extra in (dst.with_name(dst.name + "-wal"), dst.with_name(dst.name + "-shm")):
        extra.unlink(missing_ok=True)
    shutil.copyfile(src, dst)
    url = f"sqlite:///{dst}"
    if pred is not None:
        _run(V3D + ["import", "predictions", str(pred), "--source", "detector"], url)
    _run(V3D + ["recompute"], url)
    return url, truth


def read_balls(url: str, truth: Path) -> list[dict[str, Any]]:
    """Every system with a truth ball and a stored 3D ball: its error, tier, reasons and facts."""
    import numpy as np
    import sqlalchemy as sa
    from sqlalchemy.orm import Session

    from app.core.config import Settings
    from app.geometry.ball_evidence import label_size_ratio
    from app.services.derivation.ball import ball_facts
    from app.services.derivation.cameras import stored_camera
    from app.services.evaluation.ball_yield import _systems, truth_balls

    settings = Settings()
    true = truth_balls(json.loads(truth.read_text()))
    corruption = {(g["match"], str(s["action"])): s.get("corruption")
                  for g in json.loads(truth.read_text())["games"] for s in g["systems"]}
    out = []
    with Session(sa.create_engine(url)) as session:
        for match, system in _systems(session, 500, settings.max_predictions_per_frame):
            t = true.get((match, system.name))
            tri = system.triangulation
            if t is None or tri is None or tri.ball3d is None:
                continue
            cameras = {f.id: stored_camera(f.calibration.camera) for f in system.frames
                       if f.calibration is not None and f.calibration.camera is not None}
            kept = [(p.frame_a_id, p.frame_b_id) for p in tri.pairs if p.kept]
            used = {v for pair in kept for v in pair}
            errors = [p.error_px / tri.tau_px for p in tri.pairs if p.kept and p.error_px is not None]
            facts = ball_facts(system, tri.ball3d, kept, tri.sigma_m, cameras, settings, None,
                               max(errors, default=None))
            out.append({"system": f"{match}/{system.name}", "corruption": corruption.get((match, system.name)),
                        "error_m": float(np.linalg.norm(np.asarray(tri.ball3d) - t)),
                        "tier": system.ball_evidence.value, "reasons": system.ball_evidence_reasons,
                        "views": len(facts.views), "detected": sum(bool(v.detected) for v in facts.views),
                        "with_predictions": sum(v.detected is not None for v in facts.views),
                        "size_ratios": [label_size_ratio(cameras[f.id], np.asarray(tri.ball3d), f.ball_label.box,
                                                         settings.ball_diameter_m)
                                        for f in system.frames if f.id in used and f.ball_label is not None
                                        and f.ball_label.box is not None],
                        "doubted": len(facts.doubted),
                        "players_pairs": facts.players_pairs, "pairs": len(kept), "sigma_m": facts.sigma_m,
                        "others": [[o.name, o.distance_1920, o.size_ratio, o.depth_1920] for o in facts.others],
                        "pair_error_tau": facts.pair_error_tau, "agreeing": facts.agreeing,
                        "labelled_others": [[o.name, o.distance_1920, o.size_ratio, o.depth_1920]
                                            for o in facts.labelled_others]})
    return out


def tiers(balls: list[dict[str, Any]]) -> dict[str, Any]:
    """Per tier: balls right (within 0.5 m), 0.5-1 m off and wrong (beyond 1 m); the vouched share of the right."""
    out: dict[str, Any] = {}
    for b in balls:
        e = b["error_m"]
        c = out.setdefault(b["tier"], Counter())
        c["right" if e <= RIGHT_M else "mid" if e <= WRONG_M else "wrong"] += 1
    right = sum(c["right"] for c in out.values())
    return {"tiers": {k: dict(v) for k, v in out.items()}, "right": right,
            "vouched_share_of_right": out.get("vouched", Counter())["right"] / right if right else None}


def separation(balls: list[dict[str, Any]]) -> dict[str, Any]:
    """Each evidence alone: of the right balls (within 0.5 m) and the wrong ones (beyond 1 m), how many it backs."""
    def size_ok(b: dict[str, Any], t: float) -> bool:
        r = [x for x in b["size_ratios"] if x is not None]
        return bool(r) and all(1 / (1 + t) <= x <= 1 + t for x in r)

    def sees(b: dict[str, Any]) -> bool:
        return any(o[1] <= min(20.0, o[3] / 2) and abs(o[2] - 1) <= 0.5 for o in b["others"] + b["labelled_others"])

    tests = {
        "3+ views in kept pairs": lambda b: b["views"] >= 3,
        "3+ views that all agree": lambda b: b["agreeing"] >= 3,
        "another view sees it (within tau)": sees,
        "the detector confirms every label": lambda b: b["detected"] >= 2 and b["detected"] == b["views"],
        "the players agree (a kept pair)": lambda b: b["players_pairs"] >= 1,
        "pair error <= tau / 3": lambda b: b["pair_error_tau"] is not None and b["pair_error_tau"] <= 1 / 3,
        "sigma <= 0.5 m": lambda b: b["sigma_m"] is not None and b["sigma_m"] <= 0.5,
        "label sizes within 50 %": lambda b: size_ok(b, 0.5),
        "no label doubt on its views": lambda b: b["doubted"] == 0,
    }
    right = [b for b in balls if b["error_m"] <= RIGHT_M]
    wrong = [b for b in balls if b["error_m"] > WRONG_M]
    mid = [b for b in balls if RIGHT_M < b["error_m"] <= WRONG_M]
    return {k: {"right": sum(map(f, right)), "mid": sum(map(f, mid)), "wrong": sum(map(f, wrong))}
            for k, f in tests.items()} | {"_of": {"right": len(right), "mid": len(mid), "wrong": len(wrong)}}


def main(argv: Sequence[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--sets", nargs="*", default=list(ALL_SETS))
    ap.add_argument("--db-dir", type=Path, default=Path("/tmp/v3d-doubts-seeds"))
    ap.add_argument("--json", type=Path, default=None)
    ap.add_argument("--facts", type=Path, default=None)
    ap.add_argument("--separation", action="store_true")
    ap.add_argument("--no-recompute", action="store_true", help="read the copies of an earlier run as they are")
    args = ap.parse_args(argv)
    report: dict[str, Any] = {}
    facts_out = args.facts.open("w") if args.facts else None
    for name in args.sets:
        if args.no_recompute:
            dst = args.db_dir / f"{name}.{ROOT.name}-evidence.sqlite3"
            url = f"sqlite:///{dst}"
            truth = (detector_paths(name[4:], args.db_dir)[1] if name.startswith("det-")
                     else SETS[name].with_name(SETS[name].name + ".truth.json"))
        else:
            url, truth = prepared(name, args.db_dir)
        balls = read_balls(url, truth)
        report[name] = {"role": "chose" if name in CHOOSING_SETS else "read only", **tiers(balls)}
        if args.separation:
            report[name]["separation"] = separation(balls)
        if facts_out:
            for b in balls:
                facts_out.write(json.dumps({"set": name, **b}) + "\n")
        print(f"[{name}] {json.dumps(report[name])}", flush=True)
    if facts_out:
        facts_out.close()
    if args.json:
        args.json.write_text(json.dumps(report, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())


def detection_away_candidates(url: str, truth: Path, score_min: float = 0.0) -> dict[str, Any]:
    """A candidate label doubt, measured before it is kept (``benchmarks/VOUCH.md``): a view of the 3D ball whose
    label no detection confirms (``app.geometry.ball_evidence.detection_at_label``) while one of its detections away
    from the label (scoring at least ``score_min``) meets the rays of the ball's other views within the doubts'
    consensus tolerance at a ball's size there (``app.geometry.doubts.detected.check_or_why``, the check
    ``ball_detected`` makes). Counts the systems it would flag: clean ones (no corruption in the truth), and corrupted
    ones with the truth's culprit view named or not."""
    import numpy as np
    import sqlalchemy as sa
    from sqlalchemy.orm import Session

    from app.core.config import Settings
    from app.geometry.ball_evidence import detection_at_label
    from app.geometry.doubts.detected import Detection, check_or_why
    from app.geometry.pair_error import REFERENCE_WIDTH_PX
    from app.geometry.triangulation import BallObservation
    from app.geometry.weighting import camera_of, rule_scale
    from app.services.derivation.doubts import doubt_settings, doubt_views, stored_detections
    from app.services.evaluation.ball_yield import _systems

    settings = Settings()
    s = doubt_settings(settings)
    truth_of = {(g["match"], str(x["action"])): x for g in json.loads(truth.read_text())["games"] for x in g["systems"]}
    counts: Counter = Counter()
    with Session(sa.create_engine(url)) as session:
        for match, system in _systems(session, 500, settings.max_predictions_per_frame):
            t = truth_of.get((match, system.name))
            tri = system.triangulation
            if t is None or tri is None or tri.ball3d is None:
                continue
            used = {v for p in tri.pairs if p.kept for v in (p.frame_a_id, p.frame_b_id)}
            views = {v.view_id: v for v in doubt_views(system)}
            dets = stored_detections(system, settings.max_predictions_per_frame)
            names = {f.id: f.name for f in system.frames}
            flagged = []
            for fid in used:
                v = views[fid]
                if fid not in dets or v.box is None or detection_at_label(v.box, [d.box for d in dets[fid]]):
                    continue
                voters = [BallObservation(o, camera_of(views[o]), np.array([(views[o].box[0] + views[o].box[2]) / 2,
                                                                            (views[o].box[1] + views[o].box[3]) / 2]),
                                          REFERENCE_WIDTH_PX / rule_scale(views[o], s))
                          for o in used if o != fid and views[o].box is not None]
                tol = {o: s.consensus_tau_px for o in [*used]}
                for d in dets[fid]:
                    if d.score < score_min:
                        continue
                    got = check_or_why(v, Detection(d.source, d.score, d.box), voters, tol, s,
                                       settings.doubt_detection_size_tolerance)
                    if not isinstance(got, str):
                        flagged.append(names[fid])
                        break
            if not flagged:
                continue
            if not t.get("corruption"):
                counts["clean_flagged"] += 1
            elif t.get("corrupted_view") in flagged:
                counts["corrupted_culprit_named"] += 1
            else:
                counts["corrupted_other_named"] += 1
        counts["clean"] = sum(1 for x in truth_of.values() if not x.get("corruption"))
        counts["corrupted"] = sum(1 for x in truth_of.values() if x.get("corruption"))
    return dict(counts)


def evidence_cost(url: str, limit: int = 300) -> dict[str, float]:
    """CPU time (ms, medians over at most ``limit`` systems) of one system's recomputation
    (``recompute_system``, in a session rolled back after) and, within it, of gathering its ball's evidence
    (``ball_facts`` and the rule, asked again on the same rows right after): what the evidence adds to an edit."""
    import statistics
    import time

    import sqlalchemy as sa
    from sqlalchemy.orm import Session

    from app.core.config import Settings
    from app.db.models import System
    from app.geometry.ball_evidence import ball_evidence
    from app.services.derivation.ball import ball_facts
    from app.services.derivation.cameras import stored_camera
    from app.services.derivation.recompute import load_for_recompute, recompute_system

    settings = Settings()
    whole, facts_ms = [], []
    with Session(sa.create_engine(url)) as session:
        ids = list(session.scalars(sa.select(System.id).order_by(System.id).limit(limit)))
        systems = load_for_recompute(session, ids, predictions=settings.max_predictions_per_frame)
        for sid in ids:
            system = systems[sid]
            t0 = time.process_time()
            tri = recompute_system(session, system, settings)
            whole.append((time.process_time() - t0) * 1e3)
            cameras = {f.id: stored_camera(f.calibration.camera) for f in system.frames
                       if f.calibration is not None and f.calibration.camera is not None}
            kept = [(p.frame_a_id, p.frame_b_id) for p in tri.pairs if p.kept]
            t0 = time.process_time()
            ball_evidence(ball_facts(system, tri.ball3d, kept, tri.sigma_m, cameras, settings))
            facts_ms.append((time.process_time() - t0) * 1e3)
        session.rollback()
    return {"recompute_median_ms": statistics.median(whole), "evidence_median_ms": statistics.median(facts_ms),
            "evidence_share": statistics.median(facts_ms) / statistics.median(whole), "systems": len(ids)}
