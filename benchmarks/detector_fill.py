"""A detector in the loop, measured end to end: how many views nobody labelled one pass of the doubts' fixes fills
right and wrong, with and without a detector's predictions (``benchmarks/DETECTOR.md``).

For each set (``../shared/data/synthetic/detector/<set>-unlabelled`` with ``<set>-predictions.csv``, or one made by
``benchmarks/detector_sets.py`` under ``--made-dir``):

1. import it once with ``v3d import soccernet-v3`` into a cached SQLite database (``--db-dir``; the slow part);
2. copy it twice and ``v3d recompute`` both with this tree's code; into one, ``v3d import predictions`` the set's CSV
   (source ``detector``), timed;
3. serve each copy (``v3d serve``), add an admin, and run ``../shared/tools/detector_fill_eval.py`` (one pass of every
   label doubt's one-key fix, each placement confirmed; filled right / wrong, invented, systems with a right 3D ball
   before and after, made wrong);
4. ``v3d stats yield`` (in process, :func:`yield_figures`) on the copy without predictions before and after its pass
   and on the copy with predictions after its pass: systems with a 3D ball under the paper's rules and v3d's;
5. measure, in process, the upper bound (:func:`upper_bound`): of the unlabelled views, how many have an admitted v3d
   calibration with enough line classes, how many lie in a system whose other views agree on a ball (or have one
   labelled view and another unlabelled one to pair with), and how many have a prediction within the evaluator's
   tolerance; and the detector's raw precision (a prediction within tolerance of the ball of its image, over all,
   and over those scoring at least 0.5) against the precision of the ``ball_detected`` suggestions; and, under the
   current rules, why each unlabelled view was or was not filled (:func:`benchmarks.fill_diagnosis.diagnose`: the
   check of the real code path that refused its true detection).

Without predictions the doubts are those of main by construction (``app.services.derivation.doubts.update_doubts``
checks detections only when a view has one), so the "without" column is today's main.

Run: ``.venv/bin/python benchmarks/detector_fill.py [--sets dev-large seed-204 ...] [--json OUT]``.
"""
from __future__ import annotations

import argparse
import csv
import json
import shutil
import subprocess
import sys
import time
from pathlib import Path
from typing import Any, Sequence

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from app.core.paths import SHARED_DIR
from benchmarks.doubts_seeds import V3D, _run, served_with_admin
from benchmarks.fill_diagnosis import diagnose

DETECTOR = SHARED_DIR / "data" / "synthetic" / "detector"
TOOLS = SHARED_DIR / "tools"
#: The sets the issue names (shared); the others are made by benchmarks/detector_sets.py.
SHARED_SETS = ("dev-large", "seed-204")


def paths(name: str, made_dir: Path) -> tuple[Path, Path, Path]:
    """The set's tree, truth and predictions CSV."""
    base = DETECTOR if name in SHARED_SETS else made_dir
    tree = base / f"{name}-unlabelled"
    return tree, tree.with_name(tree.name + ".truth.json"), base / f"{name}-predictions.csv"


def template(name: str, tree: Path, db_dir: Path) -> Path:
    """The cached database of the set as imported (imported when absent)."""
    db_dir.mkdir(parents=True, exist_ok=True)
    path = db_dir / f"{name}.sqlite3"
    if not path.exists():
        part = path.with_suffix(".part")
        part.unlink(missing_ok=True)
        t0 = time.perf_counter()
        _run(V3D + ["import", "soccernet-v3", str(tree)], f"sqlite:///{part}")
        print(f"[{name}] imported in {time.perf_counter() - t0:.0f} s", file=sys.stderr, flush=True)
        part.rename(path)
    return path


def copy(src: Path, tag: str) -> str:
    dst = src.with_name(f"{src.stem}.{tag}.sqlite3")
    for extra in (dst, dst.with_name(dst.name + "-wal"), dst.with_name(dst.name + "-shm")):
        extra.unlink(missing_ok=True)
    shutil.copyfile(src, dst)
    url = f"sqlite:///{dst}"
    _run(V3D + ["recompute"], url)
    return url


def fill_eval(url: str, truth: Path, port: int, out: Path) -> dict[str, Any]:
    """Serve ``url`` and run the shared detector_fill_eval.py against it."""
    with open(str(out) + ".server.log", "w") as log, \
            served_with_admin(url, port, {"V3D_KEEP_ALIVE_S": "600"}, log) as token:
        # the evaluator holds one connection for the whole pass: kept open between its requests (V3D_KEEP_ALIVE_S)
        r = subprocess.run([sys.executable, str(TOOLS / "detector_fill_eval.py"), f"http://127.0.0.1:{port}", token,
                            str(truth), str(out)], cwd=ROOT, capture_output=True, text=True)
        if r.returncode:
            raise RuntimeError(f"detector_fill_eval.py failed: {r.stderr[-2000:]}")
        return {**json.loads(out.read_text()), "line": r.stdout.strip()}


def yield_figures(url: str, truth: Path) -> dict[str, Any]:
    """``v3d stats yield`` of the database at ``url`` against the truth (in process: the same service function,
    :func:`app.services.evaluation.ball_yield.ball_yield`): systems with a 3D ball under the paper's rules and v3d's,
    and how many are right."""
    import sqlalchemy as sa
    from sqlalchemy.orm import Session

    from app.core.config import Settings
    from app.services.evaluation.ball_yield import ball_yield

    with Session(sa.create_engine(url)) as session:
        return ball_yield(session, Settings(), json.loads(truth.read_text()))


def upper_bound(url: str, truth_path: Path, pred_path: Path) -> dict[str, Any]:
    """What could be filled at all, and why not (module docstring, step 4), from the database at ``url`` after the
    predictions' import, the truth and the CSV; with the raw and the checked precision."""
    import sqlalchemy as sa
    from sqlalchemy.orm import Session

    from app.core.config import Settings
    from app.db.models import Doubt, Game, System
    from app.geometry.doubts.detections import _few_lined
    from app.geometry.doubts.judge import _voters_consensus, _votes
    from app.geometry.triangulation import pair_geometry
    from app.services.derivation.doubts import doubt_settings, doubt_views
    from app.services.derivation.recompute import load_for_recompute

    truth = json.loads(truth_path.read_text())
    unl = {(u["match"], u["image"]): u for u in truth["unlabelled"]}
    tview = {(g["match"], v["image"]): v for g in truth["games"] for s in g["systems"] for v in s["views"]}
    preds: dict[tuple[str, str], list[tuple[float, float, float]]] = {}
    with pred_path.open() as f:
        for r in csv.DictReader(f):
            cx, cy = (float(r["x1"]) + float(r["x2"])) / 2, (float(r["y1"]) + float(r["y2"])) / 2
            preds.setdefault((r["match"], r["image"]), []).append((cx, cy, float(r["score"])))

    def near(key: tuple[str, str], cx: float, cy: float) -> bool:
        v = tview.get(key)
        if v is None or not v.get("system_ball_in_image") or v.get("out_of_frame_view") or not v.get("ball_center_px"):
            return False
        c, d = v["ball_center_px"], v.get("d_true") or 0.0
        return ((cx - c[0]) ** 2 + (cy - c[1]) ** 2) ** 0.5 <= max(3.0, d / 2)

    calibrated_and_detected = 0
    raw = [near(k, cx, cy) for k, ps in preds.items() for cx, cy, _ in ps]
    raw_05 = [near(k, cx, cy) for k, ps in preds.items() for cx, cy, sc in ps if sc >= 0.5]
    s = doubt_settings(Settings())
    reasons: dict[str, int] = {}
    detected = detected_right = 0
    with Session(sa.create_engine(url)) as session:
        ids = list(session.scalars(sa.select(System.id)))
        systems = load_for_recompute(session, ids, predictions=Settings().max_predictions_per_frame)
        games = {g.id: g for g in session.scalars(sa.select(Game))}
        doubts = {(d.frame_id, d.kind): d for d in session.scalars(sa.select(Doubt))}
        for system in systems.values():
            match = games[system.game_id].match
            views = {v.view_id: v for v in doubt_views(system)}
            for f in system.frames:
                key = (match, f.name)
                d = doubts.get((f.id, "ball_detected"))
                if d is not None and d.suggestion:
                    b = d.suggestion["box"]
                    detected += 1
                    detected_right += near(key, (b[0] + b[2]) / 2, (b[1] + b[3]) / 2)
                if key not in unl:
                    continue
                v = views[f.id]
                has_pred = any(near(key, cx, cy) for cx, cy, _ in preds.get(key, []))
                calibrated_and_detected += bool(v.camera is not None and has_pred)
                vote = _votes(list(views.values()), s, None)
                cons, _ = _voters_consensus(vote, s, pair_geometry)
                if v.camera is None:
                    why = "no camera (calibration refused)"
                elif v.view_id not in {u.view_id for u in [*vote.unlabelled, *(w for w, _ in _few_lined(
                        list(views.values()), vote, s, None))]}:
                    why = ("fewer line classes than the doubts need, and an unsure calibration"
                           if v.line_classes < s.min_line_classes
                           else "its calibration carries no vote (unsure, or mirrored)")
                elif cons.point is not None and not cons.ambiguous:
                    why = "fillable (the labelled views agree on a ball)" if has_pred else "no prediction near"
                elif len(vote.labelled) == 1:
                    partners = [o for o in [*vote.unlabelled, *(w for w, _ in _few_lined(list(views.values()), vote, s,
                                                                                           None))]
                                if o.view_id != f.id and any(
                        near((match, o.name), cx, cy) for cx, cy, _ in preds.get((match, o.name), []))]
                    why = ("fillable (one labelled view and a second detected view)" if has_pred and partners
                           else "one labelled view, no second detected view to pair with" if has_pred
                           else "no prediction near")
                elif len(vote.labelled) >= 2:
                    why = "the labelled views agree on no ball"
                else:
                    why = "no labelled view takes part (refused, few lines or unsure calibrations)"
                reasons[why] = reasons.get(why, 0) + 1
    fillable = sum(n for k, n in reasons.items() if k.startswith("fillable"))
    return {"unlabelled": len(unl), "fillable": fillable, "reasons": dict(sorted(reasons.items(), key=lambda x: -x[1])),
            "calibrated_and_detected": calibrated_and_detected,
            "with_prediction_near": sum(1 for k in unl if any(near(k, cx, cy) for cx, cy, _ in preds.get(k, []))),
            "raw_precision": [sum(raw), len(raw)], "raw_precision_score_05": [sum(raw_05), len(raw_05)],
            "checked_precision": [detected_right, detected]}


def main(argv: Sequence[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--sets", nargs="*", default=list(SHARED_SETS))
    ap.add_argument("--db-dir", type=Path, default=Path("/tmp/v3d-detector-fill"))
    ap.add_argument("--made-dir", type=Path, default=Path("/tmp/v3d-detector-sets"))
    ap.add_argument("--port", type=int, default=8560)
    ap.add_argument("--json", type=Path, default=None)
    ap.add_argument("--bound-only", action="store_true", help="only step 4")
    ap.add_argument("--with-only", action="store_true",
                    help="skip the copy without predictions (its doubts are main's: measured once, in DETECTOR.md)")
    args = ap.parse_args(argv)
    report: dict[str, Any] = {}
    for i, name in enumerate(args.sets):
        tree, truth, pred = paths(name, args.made_dir)
        if args.bound_only:  # on a fresh copy: the evaluator's pass fills the views it measures
            url = copy(template(name, tree, args.db_dir), "bound")
            _run(V3D + ["import", "predictions", str(pred), "--source", "detector"], url)
            report[name] = {"bound": upper_bound(url, truth, pred)}
            print(f"[{name}] bound {json.dumps(report[name]['bound'])}", flush=True)
            continue
        src = template(name, tree, args.db_dir)
        res: dict[str, Any] = {}
        if not args.with_only:
            url = copy(src, "without")
            res["yield_labels_only"] = yield_figures(url, truth)
            res["without"] = fill_eval(url, truth, args.port + 2 * i, args.db_dir / f"{name}.without.json")
            res["yield_without_after_pass"] = yield_figures(url, truth)
            print(f"[{name}] without predictions (main): {res['without']['line']}", flush=True)
            print(f"[{name}] yield, labels only: {json.dumps(res['yield_labels_only'])}; after the pass without "
                  f"predictions: {json.dumps(res['yield_without_after_pass'])}", flush=True)
        url = copy(src, "with")
        t0 = time.perf_counter()
        _run(V3D + ["import", "predictions", str(pred), "--source", "detector"], url)
        res["import_seconds"] = time.perf_counter() - t0
        res["bound"] = upper_bound(url, truth, pred)
        res["diagnosis"] = {k: v for k, v in diagnose(url, truth, pred).items() if k != "cases"}
        res["with"] = fill_eval(url, truth, args.port + 2 * i + 1, args.db_dir / f"{name}.with.json")
        res["yield_with_after_pass"] = yield_figures(url, truth)
        print(f"[{name}] with predictions: {res['with']['line']}", flush=True)
        print(f"[{name}] yield with predictions after the pass: {json.dumps(res['yield_with_after_pass'])}",
              flush=True)
        print(f"[{name}] predictions imported and systems recomputed in {res['import_seconds']:.1f} s; "
              f"bound {json.dumps(res['bound'])}; why each unlabelled view was or was not filled, under the "
              f"current rules (benchmarks/fill_diagnosis.py, in process): {json.dumps(res['diagnosis'])}", flush=True)
        report[name] = res
    if args.json:
        args.json.write_text(json.dumps(report, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
