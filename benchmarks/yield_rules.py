"""Where each lost 3D ball goes (``benchmarks/YIELD.md``, "The table by rule"): on imported sets with truth, every
system where the paper's rules give a right ball (within 0.5 m) and v3d's rules none or a worse one, with the v3d rule
that refused it, and every wrong ball (more than 1 m off) the paper keeps, with the v3d rule that refuses it; and the
right and wrong counts of the paper's rules, of v3d's rules by class (the parallax threshold, the play volume tested
on each pair, the calibration weights: ``weak_calibrations`` and ``outweighed``; the default ``ball_rule``
"weights") and of v3d's rule by evidence (``ball_rule`` "evidence", ``app.services.derivation.ball.system_ball``
with the bound ``ball_max_sigma_m``), all in process on the same stored calibrations and labels.

Attribution, by ablation on the same views: a right ball lost goes to each class rule whose removal alone gives the
system a right ball again ("several" when none alone does); a wrong ball avoided goes to each class rule that alone,
added to the paper's rules, leaves the system without a wrong ball. The rule by evidence is attributed by the reasons
its pairs were dropped with (``players_disagree``, ``beyond_joint_sigma``, ``sigma_above_bound``,
``outside_play_volume``), and the views below admission it takes in (``ball.takes_part``): a right ball the
rule by evidence has and the paper's rules not goes to ``below_admission`` when a view below admission is in one of
its kept pairs, else to ``weighed`` (the pairs' weighing and the joint-sigma gate).

Run: ``.venv/bin/python benchmarks/yield_rules.py DB.sqlite3=TRUTH.json ... [--json OUT]`` (databases as imported by
``v3d import soccernet-v3``; read only).
"""
from __future__ import annotations

import argparse
import json
import shutil
import sys
from collections import Counter
from pathlib import Path
from typing import Any, Sequence

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from app.core.config import Settings  # noqa: E402  # after the path is set
from app.db.session import upgrade_database  # noqa: E402  # after the path is set
from app.geometry.pitch import within_play_volume  # noqa: E402  # after the path is set
from app.geometry.triangulation import BallObservation, PairGeometryMemo, triangulate_ball  # noqa: E402  # after the path is set
from app.services.derivation.ball import system_ball, takes_part  # noqa: E402  # after the path is set
from app.services.derivation.cameras import stored_camera  # noqa: E402  # after the path is set
from app.services.derivation.doubts import calibration_weights, weighed_views  # noqa: E402  # after the path is set
from app.services.evaluation.ball_yield import RIGHT_M, WRONG_M, _systems, paper_ball, truth_balls  # noqa: E402  # after the path is set

CLASS_RULES = ("parallax", "play_volume", "weights")


def _observations(system: Any, by_evidence: bool = False) -> tuple[list[BallObservation], dict[int, Any]]:
    """The observations v3d's recomputation triangulates (the views that take part, ``ball.takes_part``, under
    the rule by class or, ``by_evidence``, by evidence; labelled, not suggested) and the cameras of the calibrated
    frames."""
    cameras, obs = {}, []
    for f in system.frames:
        cal = f.calibration
        if cal is not None and cal.camera is not None and cal.status.value == "calibrated":
            cameras[f.id] = stored_camera(cal.camera)
        label = f.ball_label
        centre = None if label is None else label.centre
        if centre is not None and not label.suggested and takes_part(f, by_evidence):
            obs.append(BallObservation(f.id, cameras[f.id], np.asarray(centre, float), float(f.width)))
    return obs, cameras


def _class_ball(obs: list[BallObservation], weights: dict[int, float], settings: Settings, memo: PairGeometryMemo,
                rules: set[str]) -> np.ndarray | None:
    r = triangulate_ball(obs, tau_px=settings.triangulation_tau_px, rule=settings.pair_error_rule,
                         min_baseline_m=settings.min_baseline_m,
                         min_parallax_deg=2.0 if "parallax" in rules else 0.0,
                         play_volume=(lambda p: bool(within_play_volume(p)[0])) if "play_volume" in rules else None,
                         view_weights=weights if "weights" in rules else None, geometry=memo)
    return r.point


def _err(ball: np.ndarray | None, t: np.ndarray) -> float | None:
    return None if ball is None else float(np.linalg.norm(ball - t))


def _right(e: float | None) -> bool:
    return e is not None and e <= RIGHT_M


def _wrong(e: float | None) -> bool:
    return e is not None and e > WRONG_M


def measure(url: str, truth: Any, settings: Settings) -> dict[str, Any]:
    """The counts and the table by rule of one database against its truth (module docstring)."""
    import sqlalchemy as sa
    from sqlalchemy.orm import Session

    true = truth_balls(truth)
    by_evidence = settings.model_copy(update={"ball_rule": "evidence"})
    counts = {k: Counter() for k in ("paper", "v3d_class", "v3d_evidence")}
    lost: dict[str, Counter] = {k: Counter() for k in ("v3d_class", "v3d_evidence")}
    avoided: dict[str, Counter] = {k: Counter() for k in ("v3d_class", "v3d_evidence")}
    kept_wrong: dict[str, int] = Counter()
    gained: Counter = Counter()  # right balls the rule by evidence has and the paper's rules not, by what made them
    with Session(sa.create_engine(url)) as session:
        for match, system in _systems(session, 200, settings.max_predictions_per_frame):
            t = true.get((match, system.name))
            if t is None:
                continue
            obs, cameras = _observations(system)
            weighed = weighed_views(system, settings, cameras)
            weights = calibration_weights(system, settings, weighed=weighed)
            memo = PairGeometryMemo()
            e = {"paper": _err(paper_ball(system, settings), t),
                 "v3d_class": _err(_class_ball(obs, weights, settings, memo, set(CLASS_RULES)), t)}
            judged, _ = system_ball(system, _observations(system, True)[0], by_evidence, weighed, memo,
                                    weighs_calibrations=True)
            in_ball = {v for p in judged.pairs if p.kept for v in (p.view_a, p.view_b)}
            below = any(f.id in in_ball and not f.calibration.admitted for f in system.frames)
            e["v3d_evidence"] = _err(judged.point, t)
            for k, v in e.items():
                counts[k]["with_ball"] += v is not None
                counts[k]["right"] += _right(v)
                counts[k]["wrong"] += _wrong(v)
            reasons = {p.reason for p in judged.pairs if not p.kept} & {
                "players_disagree", "beyond_joint_sigma", "sigma_above_bound", "outside_play_volume"}
            for k in ("v3d_class", "v3d_evidence"):
                worse = not _right(e[k]) and (e[k] is None or e[k] > (e["paper"] or 0.0))
                if _right(e["paper"]) and worse:
                    lost[k][_why_lost(k, obs, weights, settings, memo, t, reasons)] += 1
                if _wrong(e["paper"]) and not _wrong(e[k]):
                    avoided[k][_why_avoided(k, obs, weights, settings, memo, t, reasons)] += 1
                if _wrong(e[k]):
                    kept_wrong[k] += 1
            if _right(e["v3d_evidence"]) and not _right(e["paper"]):
                gained["below_admission" if below else "weighed"] += 1
    return {"counts": {k: dict(v) for k, v in counts.items()},
            "right_lost_by_rule": {k: dict(v) for k, v in lost.items()},
            "wrong_avoided_by_rule": {k: dict(v) for k, v in avoided.items()},
            "right_gained_by_evidence": dict(gained)}


def _why_lost(k: str, obs, weights, settings, memo, t, reasons: set[str]) -> str:
    if k == "v3d_evidence":
        return "+".join(sorted(reasons)) or "fused otherwise"
    alone = [r for r in CLASS_RULES if _right(_err(_class_ball(obs, weights, settings, memo,
                                                               set(CLASS_RULES) - {r}), t))]
    return "+".join(alone) if alone else "several"


def _why_avoided(k: str, obs, weights, settings, memo, t, reasons: set[str]) -> str:
    if k == "v3d_evidence":
        return "+".join(sorted(reasons)) or "fused otherwise"
    alone = [r for r in CLASS_RULES if not _wrong(_err(_class_ball(obs, weights, settings, memo, {r}), t))]
    return "+".join(alone) if alone else "several"


def main(argv: Sequence[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("sets", nargs="+", help="DB.sqlite3=TRUTH.json")
    ap.add_argument("--json", type=Path, default=None)
    args = ap.parse_args(argv)
    settings = Settings()
    report = {}
    for item in args.sets:
        db, truth = item.split("=", 1)
        work = Path(db).with_suffix(".rules.sqlite3")  # a copy at this tree's schema: the import is left as it was
        shutil.copyfile(db, work)
        upgrade_database(f"sqlite:///{work}")
        r = measure(f"sqlite:///{work}", json.loads(Path(truth).read_text()), settings)
        report[Path(db).stem] = r
        print(Path(db).stem, json.dumps(r), flush=True)
    if args.json:
        args.json.write_text(json.dumps(report, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
