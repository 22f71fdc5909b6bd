"""Benchmark of the doubt judge (``app.geometry.doubts.judge_system``) on the synthetic SoccerNet-v3 dev sets.

Each set is imported exactly as the service does (``import_soccernet_v3`` into a fresh, Alembic-migrated
SQLite database with ``Settings()``: v3d's own calibration, game rig, mirror flags), once: ``--db-dir``
keeps the databases between runs so that a sweep does not re-import. Every stored system becomes
:class:`DoubtView` s through ``app.services.derivation.doubts.doubt_views`` (the adapter the service uses), is
judged, and the doubts are scored against the truth file beside the set, exactly as issue 6 scores them:

* a corrupted system is *observable* when its corrupted view has at least 4 line classes (visible minus
  dropped) and at least one other view with a ball label has at least 4; it is *caught* when a
  label-accusing doubt names the corrupted view; for a desync or wrong-ball system with exactly one such
  other view, any label-accusing doubt of the system counts;
* *clean* systems (no corruption, no near duplicate) with a label-accusing doubt: false alarms;
* *guilty view*: the observable corrupted systems except desync / wrong-ball ones with a single other
  usable view, where a label-accusing doubt names the corrupted view;
* *suggestion*: on no-ball systems with two or more other usable views, the distance (px at 1920 width)
  between the centre of the ``snap_box`` suggested for the corrupted view and the centre of the truth's
  precise box (no suggestion: a miss, infinite distance);
* *near duplicates* (both views with at least 4 line classes): named when a ``near_duplicate_view`` doubt
  names either view;
* *out-of-frame views* whose true ball centre lies at least one ball diameter + 10 px (at 1920 width)
  outside the image, called ``ball_missing``.

The sweep varies one threshold at a time around the defaults (:class:`DoubtSettings`) and plots precision
(systems with a label-accusing doubt that do have a corruption or a near duplicate) against recall
(observable corrupted systems caught), one curve per threshold, as ``doubts-pr.png`` under ``--plots``.

Chosen operating point (the defaults of :class:`DoubtSettings` and ``Settings.doubt_*``), measured on this
2-core machine:

* dev-large (256 systems): caught 19/19 observable corrupted systems (100 %), guilty view named 15/15,
  clean systems flagged 1/203 (0.5 %: a replay whose own calibration is 5.6 m off), near duplicates named
  4/4, out-of-frame views called missing 0/39, suggested box centres 1.5 and 24.8 px from the truth (median
  13.2 px; the 24.8 px one is the missing view's own calibration error: its camera puts the TRUE ball 22.7 px
  off); dev (40 systems): caught 2/2, guilty 2/2, clean flagged 0/30, near duplicates 1/1.
* ``consensus_tau_px`` 25: every value from 8 to 30 gives the same figures, 40 and above miss a desynchronised
  replay whose two-view error is 30-40 px; 25 is above the triangulation's tau (20) with room for the
  larger calibration errors of real data. ``min_line_classes`` 4: 2 flags 9 clean systems (rig cameras
  fitted to 2 classes), 5 misses corrupted views. ``near_duplicate_max_deg`` 3: flat from 0.5 to 8, clean
  systems flagged from 12. ``inside_margin_px`` 0: -40 calls an out-of-frame view.
* ``judge_system``: median 0.26 ms, p99 about 5 ms, max 9 ms per system; the 256 systems in 0.13 s.

Run: ``.venv/bin/python benchmarks/doubts.py [--db-dir /tmp/v3d-doubts] [--plots /tmp] [--json OUT]
[--sweep/--no-sweep]``. The test ``tests/geometry/test_doubts.py`` runs :func:`score` on one game.
"""
from __future__ import annotations

import argparse
import json
import sys
import time
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path
from typing import Any, Iterable, Sequence

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from sqlalchemy import select
from sqlalchemy.orm import selectinload

from app.core.config import Settings
from app.core.paths import SHARED_DIR
from app.db.models import Frame, System
from app.db.session import make_engine, make_session_factory, upgrade_database
from app.geometry.doubts import LABEL_KINDS, Doubt, DoubtSettings, DoubtView, judge_system
from app.services.derivation.doubts import doubt_settings, doubt_views
from app.services.transfer.importing import import_soccernet_v3

SETS = {"dev-large": "soccernet-v3-dev-large", "dev": "soccernet-v3-dev"}
MIN_CLASSES = 4


# ----- the adapter: stored rows -> DoubtView (to move into app/services) --------------------------------
# ----- data -------------------------------------------------------------------------------------------
def ensure_database(shared: Path, name: str, db_dir: Path, source: Path | None = None) -> str:
    """URL of a SQLite database holding the set ``name`` imported by the service (imported when absent).

    ``source``: import this SoccerNet-v3 tree instead of the whole set (a subset of its games)."""
    db_dir.mkdir(parents=True, exist_ok=True)
    path = db_dir / f"{SETS[name]}.sqlite3"
    url = f"sqlite:///{path}"
    if path.exists():
        return url
    tmp = path.with_suffix(".part")
    tmp.unlink(missing_ok=True)
    tmp_url = f"sqlite:///{tmp}"
    upgrade_database(tmp_url)
    engine = make_engine(tmp_url)
    try:
        with make_session_factory(engine)() as session:
            t0 = time.perf_counter()
            import_soccernet_v3(session, source or shared / "data" / "synthetic" / SETS[name],
                                Settings(_env_file=None, database_url=tmp_url))
            print(f"imported {name} in {time.perf_counter() - t0:.1f} s", file=sys.stderr)
    finally:
        engine.dispose()
    tmp.rename(path)
    return url


def load_judged_input(url: str) -> list[tuple[tuple[str, str, str, str], list[DoubtView]]]:
    """((league, season, match, system name), views) for every stored system."""
    engine = make_engine(url)
    try:
        with make_session_factory(engine)() as session:
            systems = session.scalars(select(System).options(
                selectinload(System.game), selectinload(System.frames).options(
                    selectinload(Frame.calibration), selectinload(Frame.ball_label),
                    selectinload(Frame.field_lines), selectinload(Frame.review)))).all()
            return [((s.game.league, s.game.season, s.game.match, s.name), doubt_views(s))
                    for s in systems]
    finally:
        engine.dispose()


def load_truth(shared: Path, name: str) -> dict[tuple[str, str, str, str], dict]:
    raw = json.loads((shared / "data" / "synthetic" / f"{SETS[name]}.truth.json").read_text())
    return {(g["league"], g["season"], g["match"], s["action"]): s for g in raw["games"] for s in g["systems"]}


# ----- scoring ----------------------------------------------------------------------------------------
def _classes(v: dict) -> int:
    return len(set(v["visible_line_classes"]) - set(v.get("dropped_line_classes") or []))


def _outside_px_1920(v: dict) -> float:
    x, y = v["ball_center_px"]
    dx = max(-x, x - v["width"], 0.0)
    dy = max(-y, y - v["height"], 0.0)
    return max(dx, dy) * 1920.0 / v["width"]


@dataclass
class Score:
    """The issue's figures on one set (counts and rates; ``suggestion_px`` at 1920 width)."""

    systems: int = 0
    observable: int = 0
    caught: int = 0
    guilty_total: int = 0
    guilty_named: int = 0
    clean: int = 0
    clean_flagged: int = 0
    near_dup: int = 0
    near_dup_named: int = 0
    out_of_frame: int = 0
    out_of_frame_called: int = 0
    suggestion_px: list[float] = field(default_factory=list)
    flagged: int = 0
    flagged_with_problem: int = 0
    misses: list[str] = field(default_factory=list)
    false_alarms: list[str] = field(default_factory=list)

    def rates(self) -> dict[str, Any]:
        def pct(a, b):
            return round(100.0 * a / b, 1) if b else None
        sugg = [x for x in self.suggestion_px]
        return {
            "caught_pct": pct(self.caught, self.observable), "caught": f"{self.caught}/{self.observable}",
            "guilty_pct": pct(self.guilty_named, self.guilty_total),
            "guilty": f"{self.guilty_named}/{self.guilty_total}",
            "clean_false_alarm_pct": pct(self.clean_flagged, self.clean),
            "clean_flagged": f"{self.clean_flagged}/{self.clean}",
            "near_dup_named_pct": pct(self.near_dup_named, self.near_dup),
            "near_dup": f"{self.near_dup_named}/{self.near_dup}",
            "out_of_frame_called_missing": f"{self.out_of_frame_called}/{self.out_of_frame}",
            "suggestion_median_px_1920": None if not sugg else round(float(np.median(sugg)), 2),
            "suggestion_max_px_1920": None if not sugg else round(float(np.max(sugg)), 2),
            "suggestions": len(sugg),
            "precision_pct": pct(self.flagged_with_problem, self.flagged),
            "recall_pct": pct(self.caught, self.observable),
        }


def score(judged: Iterable[tuple[tuple[str, str, str, str], list[DoubtView], list[Doubt]]],
          truth: dict[tuple[str, str, str, str], dict]) -> Score:
    """Score judged systems against the truth (rules in the module docstring)."""
    sc = Score()
    for key, views, doubts in judged:
        t = truth[key]
        sc.systems += 1
        name_of = {v.view_id: v.name for v in views}
        tv = {v["image"]: v for v in t["views"]}
        label = [d for d in doubts if d.kind in LABEL_KINDS]
        named = {name_of.get(d.view_id) for d in label if d.view_id is not None}
        tag = f"{key[2][:22]}/{key[3]}"
        if label:
            sc.flagged += 1
            sc.flagged_with_problem += bool(t["corruption"] or t["near_duplicate_view"])
        corr, cv = t["corruption"], t["corrupted_view"]
        if corr:
            others = [v for v in t["views"] if v["image"] != cv and v["annotated_box"] is not None
                      and _classes(v) >= MIN_CLASSES]
            if _classes(tv[cv]) >= MIN_CLASSES and others:
                sc.observable += 1
                single = corr in ("desync", "wrong_ball") and len(others) == 1
                hit = bool(label) if single else cv in named
                sc.caught += hit
                if not hit:
                    sc.misses.append(f"{tag} {corr} {cv} ({len(others)} other): {[d.kind for d in label]}")
                if not single:
                    sc.guilty_total += 1
                    sc.guilty_named += cv in named
                if corr == "no_ball" and len(others) >= 2:
                    box = next((d.suggestion["box"] for d in label if d.kind == "ball_missing"
                                and name_of.get(d.view_id) == cv and d.suggestion and "box" in d.suggestion), None)
                    if box is None:
                        sc.suggestion_px.append(float("inf"))
                    else:
                        p = tv[cv]["precise_box"]
                        err = np.hypot((box[0] + box[2] - p[0] - p[2]) / 2, (box[1] + box[3] - p[1] - p[3]) / 2)
                        sc.suggestion_px.append(float(err * 1920.0 / tv[cv]["width"]))
        nd = t["near_duplicate_view"]
        if nd:
            twin = [v for v in t["views"] if v["image"] != nd and v.get("image_type") == "action"]
            pair = [tv[nd]] + twin[:1]
            if all(_classes(v) >= MIN_CLASSES for v in pair):
                sc.near_dup += 1
                ok = any(d.kind == "near_duplicate_view" and name_of.get(d.view_id) in {v["image"] for v in pair}
                         for d in label)
                sc.near_dup_named += ok
                if not ok:
                    sc.misses.append(f"{tag} near_duplicate {nd}: {[d.kind for d in label]}")
        if not corr and not nd:
            sc.clean += 1
            if label:
                sc.clean_flagged += 1
                sc.false_alarms.append(f"{tag}: " + "; ".join(f"{d.kind} {name_of.get(d.view_id)}" for d in label))
        for v in t["views"]:
            if v.get("out_of_frame_view") and _outside_px_1920(v) >= v["d_true"] * 1920.0 / v["width"] + 10.0:
                sc.out_of_frame += 1
                sc.out_of_frame_called += any(d.kind == "ball_missing" and name_of.get(d.view_id) == v["image"]
                                              for d in label)
    return sc


def judge_all(inputs: Sequence[tuple[Any, list[DoubtView]]], settings: DoubtSettings) -> tuple[list, list[float]]:
    """Judge every system; returns ((key, views, doubts) list, per-system milliseconds)."""
    out, ms = [], []
    for key, views in inputs:
        t0 = time.perf_counter()
        doubts = judge_system(views, settings)
        ms.append(1e3 * (time.perf_counter() - t0))
        out.append((key, views, doubts))
    return out, ms


SWEEPS: dict[str, list[float]] = {
    "consensus_tau_px": [8, 10, 12, 15, 20, 25, 30, 40, 60, 80, 120],
    "near_duplicate_max_deg": [0.5, 1, 2, 3, 5, 8, 12, 20],
    "min_line_classes": [2, 3, 4, 5, 6],
    "inside_margin_px": [-40, -20, 0, 20, 40],
}


def sweep(inputs_by_set: dict[str, list], truth_by_set: dict[str, dict], base: DoubtSettings) -> dict[str, list]:
    """One curve per threshold: the rates at each value, the others at ``base``."""
    curves: dict[str, list] = {}
    for name, values in SWEEPS.items():
        rows = []
        for value in values:
            s = replace(base, **{name: value})
            judged = [j for k in inputs_by_set for j in judge_all(inputs_by_set[k], s)[0]]
            truth = {key: t for k in truth_by_set for key, t in truth_by_set[k].items()}
            rows.append({"value": value, **score(judged, truth).rates()})
        curves[name] = rows
    return curves


def plot(curves: dict[str, list], chosen: dict[str, Any], out: Path) -> None:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(figsize=(7, 5))
    for name, rows in curves.items():
        xs = [r["recall_pct"] for r in rows]
        ys = [r["precision_pct"] for r in rows]
        ax.plot(xs, ys, marker="o", label=name)
        for r in rows:
            ax.annotate(f"{r['value']:g}", (r["recall_pct"], r["precision_pct"]), fontsize=7,
                        textcoords="offset points", xytext=(3, 3))
    ax.plot([chosen["recall_pct"]], [chosen["precision_pct"]], marker="*", markersize=16, color="k",
            linestyle="none", label="chosen (defaults)")
    ax.set_xlabel("recall: observable corrupted systems caught (%)")
    ax.set_ylabel("precision: flagged systems with a real problem (%)")
    ax.set_title("Doubt judge, synthetic SoccerNet-v3 dev + dev-large, v3d's own calibration")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(out, dpi=110)
    plt.close(fig)


def main(argv: Sequence[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--shared", type=Path, default=SHARED_DIR)
    ap.add_argument("--db-dir", type=Path, default=Path("/tmp/v3d-doubts"), help="cached imported databases")
    ap.add_argument("--plots", type=Path, default=Path("/tmp"))
    ap.add_argument("--json", type=Path, default=None)
    ap.add_argument("--sweep", action=argparse.BooleanOptionalAction, default=True)
    ap.add_argument("--verbose", action="store_true", help="list misses and false alarms")
    args = ap.parse_args(argv)
    base = doubt_settings(Settings(_env_file=None))
    inputs, truths, report = {}, {}, {"settings": asdict(base), "sets": {}}
    for name in SETS:
        url = ensure_database(args.shared, name, args.db_dir)
        inputs[name] = load_judged_input(url)
        truths[name] = load_truth(args.shared, name)
        judged, ms = judge_all(inputs[name], base)
        sc = score(judged, truths[name])
        five = [m for (k, v), m in zip(inputs[name], ms, strict=False) if len(v) >= 5]
        rates = {**sc.rates(), "judge_ms_median": round(float(np.median(ms)), 2),
                 "judge_ms_p99": round(float(np.percentile(ms, 99)), 2), "judge_ms_max": round(float(max(ms)), 2),
                 "judge_s_total": round(sum(ms) / 1e3, 3),
                 "judge_ms_max_5_views": round(max(five), 2) if five else None}
        report["sets"][name] = rates
        print(f"[{name}] systems {sc.systems}: " + ", ".join(f"{k} {v}" for k, v in rates.items()))
        if args.verbose:
            for line in sc.misses:
                print("  miss:", line)
            for line in sc.false_alarms:
                print("  false alarm:", line)
    if args.sweep:
        curves = sweep(inputs, truths, base)
        report["sweep"] = curves
        for name, rows in curves.items():
            print(f"sweep {name}:")
            for r in rows:
                print(f"  {r['value']:>6g}: caught {r['caught']}, guilty {r['guilty']}, clean flagged "
                      f"{r['clean_flagged']}, near-dup {r['near_dup']}, oof {r['out_of_frame_called_missing']}, "
                      f"sugg {r['suggestion_median_px_1920']}, precision {r['precision_pct']}")
        judged = [j for k in inputs for j in judge_all(inputs[k], base)[0]]
        both = score(judged, {key: t for k in truths for key, t in truths[k].items()}).rates()
        args.plots.mkdir(parents=True, exist_ok=True)
        out = args.plots / "doubts-pr.png"
        plot(curves, both, out)
        print(f"plot: {out}")
    if args.json:
        args.json.write_text(json.dumps(report, indent=2))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
