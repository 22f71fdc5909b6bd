"""Why each view nobody labelled was or was not filled right by one pass of the doubts' fixes, under the current rules,
in process (``benchmarks/DETECTOR.md``): the doubts of every system as the recomputation makes them
(``judge_system``, the kind's own doubts, ``check_detections``), each fix applied as ``detector_fill_eval.py`` applies
it (every label doubt's snap, exclusion, ``near_duplicate_view`` aside), the 3D ball triangulated again from the
labels so placed (the recomputation's weights; a few systems fewer than the served pass count right), and for each
unlabelled view the first check of the real code path that refused its true detection.

Categories (``reasons``): ``filled right`` / ``filled wrong`` with the doubt that filled (kind:code); ``no camera``;
``camera not voting`` (too few line classes and an unsure camera, mirrored, no vote); ``detector missed`` (no
prediction within the scorer's tolerance of the true centre); ``no labelled view takes part`` (the detections among
themselves: not this path's); ``labelled views disagree``; ``lone ray contradicted``; and, where a labelled view
takes part, ``consensus: <check>`` or ``one ray: <check>`` naming the check that refused the true detection
(``prefilter``, ``play_volume``, ``rays_meet``, ``size``, ``baseline_parallax``, ``keeps_ball``, ``epipolar``,
``unsure ray``, ``unsure view`` (a camera whose sigma no longer tells where the ball lies), ``half vote``,
``third view``, ``margin``, ``placed``, ``explained``,
``views disagree``, ``another chosen``, ``one_view filled others``, ``no box``). With ``--detail``, ``placed`` lists
each true detection that only the spread bound refused (``app.geometry.doubts.pairings._placed``) with the ball its
pairing would have made: its spread (m, one standard deviation), how far it lies from the true ball (m) and its height.

Run: ``.venv/bin/python benchmarks/fill_diagnosis.py DB.sqlite3 TRUTH.json PREDICTIONS.csv`` (a database with the
predictions imported).
"""
from __future__ import annotations

import argparse
import csv
import json
import sys
from collections import Counter
from pathlib import Path
from typing import Any, Hashable, Sequence

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))


def _truth(truth_path: Path, pred_path: Path) -> tuple[dict, dict, dict, dict]:
    truth = json.loads(truth_path.read_text())
    unl = {(u["match"], u["image"]): u for u in truth["unlabelled"]}
    tview = {(g["match"], v["image"]): v for g in truth["games"] for s in g["systems"] for v in s["views"]}
    tball = {(g["match"], s["action"]): np.asarray(s["ball_3d"], float) for g in truth["games"] for s in g["systems"]}
    preds: dict[tuple[str, str], list[tuple[float, float]]] = {}
    with pred_path.open() as f:
        for r in csv.DictReader(f):
            preds.setdefault((r["match"], r["image"]), []).append(
                ((float(r["x1"]) + float(r["x2"])) / 2, (float(r["y1"]) + float(r["y2"])) / 2))
    return unl, tview, tball, preds


def _right(u: dict[str, Any], cx: float, cy: float) -> bool:
    """The scorer's rule: the centre within max(3 px, d / 2) of the true centre."""
    return bool(np.hypot(cx - u["center"][0], cy - u["center"][1]) <= max(3.0, u["d"] / 2))


def _why_consensus(v: Any, true_dets: Sequence[Any], cons: Any, voters: Sequence[Any], tol: Any, sigma: Any,
                   s: Any, size_tol: float) -> str:
    from app.geometry.doubts.detected import PREFILTER, _near_point, check_or_why
    from app.geometry.doubts.detections import _keeps_ball

    whys = []
    for d in true_dets:
        if d not in _near_point(v, [d], cons.point, PREFILTER * tol[v.view_id], s):
            whys.append("prefilter")
            continue
        c = check_or_why(v, d, voters, tol, s, size_tol)
        if isinstance(c, str):
            whys.append(c)
        elif not _keeps_ball(c, cons.point, voters, sigma):
            whys.append("keeps_ball")
        else:
            whys.append("another chosen")
    return "consensus: " + (sorted(whys, key=_ORDER.index)[-1] if whys else "?")


_ORDER = ["prefilter", "unsure ray", "unsure view", "play_volume", "epipolar", "rays_meet", "baseline_parallax", "size",
          "half vote", "third view", "margin", "placed", "explained", "head or feet", "keeps_ball", "views disagree",
          "another chosen"]


def _why_one_ray(lone: Any, v: Any, true_dets: Sequence[Any], detections: Any, by_id: Any, thirds: Any, wtol: Any,
                 sigma: Any, s: Any, size_tol: float, half_vote: bool, refused: list[Any] | None = None) -> str:
    """The furthest check of :func:`app.geometry.doubts.pairings._one_ray` the view's true detection reached;
    ``refused`` collects the pairings of true detections that only the spread bound refused (``placed``)."""
    from app.geometry.doubts.detected import PREFILTER, _near_ray
    from app.geometry.doubts.pairings import (
        _chosen,
        _explained,
        _judged,
        _Member,
        _member,
        _on_epipolar,
        _on_ray_within_sigmas,
        _placed,
        _telling,
        _told_from_players,
        meet_or_why,
    )

    if not _telling(lone, float(sigma.get(lone.view_id, 0.0)), s):
        return "one ray: unsure ray"
    if not _telling(v, float(sigma.get(v.view_id, 0.0)), s):
        return "one ray: unsure view"
    near = _near_ray(lone, v, detections.get(v.view_id, ()), PREFILTER * wtol[v.view_id], s)
    ray = _Member(lone, by_id[lone.view_id], None, size_tol)
    whys = []
    for d in true_dets:
        if d not in near:
            whys.append("prefilter")
        elif half_vote and sum(_on_ray_within_sigmas(lone, v, e, sigma, s) for e in near) > 1:
            whys.append("half vote")
        elif not _on_epipolar(lone, v, d, sigma, s):
            whys.append("epipolar")
        elif isinstance(p := meet_or_why([ray, _member(v, d, s, size_tol)], wtol, s), str):
            whys.append(p)
        elif _judged(p, thirds, detections, wtol, s, size_tol).missed:
            whys.append("third view")
        else:
            pairings = [_judged(q, thirds, detections, wtol, s, size_tol) for e in near
                        if _on_epipolar(lone, v, e, sigma, s)
                        and not isinstance(q := meet_or_why([ray, _member(v, e, s, size_tol)], wtol, s), str)]
            c = _chosen([q for q in pairings if not q.missed], s)
            if c is None:
                whys.append("margin")
            elif d not in c[0].detections().values():
                whys.append("another chosen")
            elif not _placed(c[0], sigma):
                whys.append("placed")
                if refused is not None:
                    refused.append(c[0])
            elif not _explained(c[0], sigma, s):
                whys.append("explained")
            elif not _told_from_players(c[0], v):
                whys.append("head or feet")
            else:
                whys.append("views disagree")
    return "one ray: " + (sorted(whys, key=_ORDER.index)[-1] if whys else "?")


def diagnose(url: str, truth_path: Path, pred_path: Path, detail: bool = False) -> dict[str, Any]:
    """The breakdown (module docstring) of the database at ``url`` (predictions imported), with the in-process pass's
    fills (right / wrong / invented), systems with a right 3D ball before and after, and those made wrong."""
    import sqlalchemy as sa
    from sqlalchemy.orm import Session

    from app.core.config import Settings
    from app.db.models import Game, System
    from app.geometry.doubts.detections import _few_lined, _tolerances, _witnesses, check_detections
    from app.geometry.doubts.judge import _voters_consensus, _votes, judge_system
    from app.geometry.doubts.pairings import _lone_ray, _spread
    from app.geometry.pitch import within_play_volume
    from app.geometry.triangulation import BallObservation, pair_geometry, triangulate_ball
    from app.geometry.weighting import camera_of, centre_of
    from app.services.derivation.doubts import (
        calibration_weights,
        doubt_settings,
        stored_detections,
        weighed_views,
        with_players,
    )
    from app.services.derivation.recompute import load_for_recompute
    from app.services.kinds import kind_of

    unl, tview, tball, preds = _truth(truth_path, pred_path)
    placed: list[dict[str, Any]] = []
    settings = Settings()
    s = doubt_settings(settings)
    size_tol = settings.doubt_detection_size_tolerance
    reasons: Counter[str] = Counter()
    cases: list[dict[str, Any]] = []
    right_before = right_after = made_wrong = invented = 0
    made_wrong_systems: list[str] = []
    with Session(sa.create_engine(url)) as session:
        ids = list(session.scalars(sa.select(System.id)))
        systems = load_for_recompute(session, ids, predictions=settings.max_predictions_per_frame)
        games = {g.id: g for g in session.scalars(sa.select(Game))}
        for system in systems.values():
            match = games[system.game_id].match
            weighed = weighed_views(system, settings)
            views = weighed.views
            cams = {v.view_id: v.camera for v in views if v.camera is not None}
            found = judge_system(views, s, pair_geometry, weighed.weighed)
            found = kind_of(system).judge_doubts(system, found, cams)
            detections = stored_detections(system, settings.max_predictions_per_frame)
            views = with_players(system, views, detections)
            if detections:
                found = check_detections(views, found, detections, s, size_tol, pair_geometry, weighed.weighed)
            boxes: dict[Hashable, tuple[np.ndarray, str]] = {}
            excluded: set[Hashable] = set()
            for d in found:
                sug = d.suggestion or {}
                if not d.accuses_label or d.view_id is None or d.kind == "near_duplicate_view":
                    continue
                if sug.get("action") == "snap_box" and sug.get("box"):
                    boxes[d.view_id] = (np.asarray(sug["box"], float), f"{d.kind}:{d.code}")
                elif sug.get("action") == "exclude_view":
                    excluded.add(d.view_id)
            # the 3D ball after the pass: the labels so placed, the recomputation's weights
            by_frame = {f.id: f for f in system.frames}
            obs = []
            for v in views:
                f = by_frame[v.view_id]
                if v.camera is None or not v.admitted or v.excluded or v.view_id in excluded or v.suggested:
                    continue
                if v.view_id in boxes:
                    b = boxes[v.view_id][0]
                    c = np.array([(b[0] + b[2]) / 2, (b[1] + b[3]) / 2])
                elif v.box is not None or v.point is not None:
                    c = centre_of(v)
                else:
                    continue
                obs.append(BallObservation(v.view_id, camera_of(v), c, f.width))
            res = triangulate_ball(obs, tau_px=settings.triangulation_tau_px, rule=settings.pair_error_rule,
                                   min_baseline_m=settings.min_baseline_m, min_parallax_deg=settings.min_parallax_deg,
                                   play_volume=lambda p: bool(within_play_volume(p)[0]),
                                   view_weights=calibration_weights(system, settings, weighed=weighed))
            t = tball.get((match, system.name))
            before = system.triangulation.ball3d if system.triangulation is not None else None
            eb = None if before is None or t is None else float(np.linalg.norm(np.asarray(before) - t))
            ea = None if res.point is None or t is None else float(np.linalg.norm(np.asarray(res.point) - t))
            right_before += eb is not None and eb <= 0.5
            right_after += ea is not None and ea <= 0.5
            if ea is not None and ea > 1.0 and not (eb is not None and eb > 1.0):
                made_wrong += 1
                made_wrong_systems.append(f"{match} {system.name}: {eb} -> {ea:.2f} m "
                                          f"({', '.join(by_frame[k].name + ' ' + w for k, (_, w) in boxes.items())})")
            # each unlabelled view: filled, or why not
            vote = _votes(views, s, weighed.weighed)
            cons, lone_contradicted = _voters_consensus(vote, s, pair_geometry)
            lined = _few_lined(views, vote, s, weighed.weighed)
            sigma = {**vote.sigma, **{v.view_id: sig for v, sig in lined}}
            usable = {v.view_id for v in [*vote.unlabelled, *(w for w, _ in lined)]}
            tol = _tolerances([*vote.judged, *vote.helpers, *(w for w, _ in lined)], sigma, vote.tau)
            witnesses, wtol = _witnesses(views, sigma, tol, s, weighed.weighed)
            by_id = {o.view_id: o for o in vote.obs}
            codes = Counter(d.code for d in found if d.kind == "ball_detected")
            for v in views:
                key = (match, v.name)
                if v.box is not None or v.point is not None:
                    continue
                if key not in unl:
                    if v.view_id in boxes:
                        tv = tview.get(key)
                        invented += tv is not None and not (tv.get("system_ball_in_image")
                                                            and not tv.get("out_of_frame_view"))
                    continue
                u = unl[key]
                true_dets = [d for d in detections.get(v.view_id, ()) if _right(u, *d.centre)]
                if v.view_id in boxes:
                    b, how = boxes[v.view_id]
                    why = ("filled right " if _right(u, (b[0] + b[2]) / 2, (b[1] + b[3]) / 2)
                           else "filled wrong ") + how
                elif v.camera is None:
                    why = "no camera"
                elif v.view_id not in usable:
                    why = "camera not voting"
                elif not true_dets:
                    why = "detector missed"
                elif cons.point is not None and not cons.ambiguous:
                    why = _why_consensus(v, true_dets, cons, [by_id[i] for i in cons.inliers], tol, sigma, s,
                                         size_tol)
                elif len(vote.labelled) >= 2:
                    why = "labelled views disagree"
                elif (lone := _lone_ray(vote)) is None:
                    why = "no labelled view takes part"
                elif lone_contradicted:
                    why = "lone ray contradicted"
                elif codes.get("one_view"):
                    why = "one ray: one_view filled others"
                else:
                    refused: list[Any] = []
                    why = _why_one_ray(lone, v, true_dets, detections, by_id, witnesses, wtol, sigma, s, size_tol,
                                       half_vote=lone not in vote.labelled, refused=refused)
                    for p in refused if t is not None else ():
                        # what the bound kept out: the ball such a fill would make, against the truth
                        spread = _spread(p, sigma)
                        placed.append({"system": f"{match} {system.name}", "view": v.name,
                                       "spread_m": None if spread is None else round(spread, 3),
                                       "off_m": round(float(np.linalg.norm(p.ball - t)), 3),
                                       "height_m": round(-float(p.ball[2]), 2)})
                reasons[why] += 1
                if detail:
                    cases.append({"system": f"{match} {system.name}", "view": v.name, "why": why,
                                  "line_classes": v.line_classes, "sigma": round(float(sigma.get(v.view_id, -1)), 1),
                                  "labelled": len(vote.labelled), "helpers": len(vote.helpers),
                                  "system_fills": sorted(w for _, w in boxes.values()),
                                  "views": len(views),
                                  "path": ("consensus" if cons.point is not None and not cons.ambiguous
                                           else "lone ray" if _lone_ray(vote) is not None else
                                           "disagree" if len(vote.labelled) >= 2 else "none")})
    right = sum(n for k, n in reasons.items() if k.startswith("filled right"))
    wrong = sum(n for k, n in reasons.items() if k.startswith("filled wrong"))
    out: dict[str, Any] = {"unlabelled": len(unl), "right": right, "wrong": wrong, "invented": invented,
                           "systems_right": [right_before, right_after], "made_wrong": made_wrong,
                           "made_wrong_systems": made_wrong_systems,
                           "reasons": dict(sorted(reasons.items(), key=lambda x: -x[1]))}
    if detail:
        out["cases"] = cases
        out["placed"] = placed
    return out


def main(argv: Sequence[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("db", type=Path)
    ap.add_argument("truth", type=Path)
    ap.add_argument("predictions", type=Path)
    ap.add_argument("--detail", action="store_true")
    ap.add_argument("--json", type=Path)
    a = ap.parse_args(argv)
    r = diagnose(f"sqlite:///{a.db}", a.truth, a.predictions, a.detail)
    if a.json:
        a.json.write_text(json.dumps(r, indent=1))
    print(json.dumps({k: v for k, v in r.items() if k != "cases"}, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
