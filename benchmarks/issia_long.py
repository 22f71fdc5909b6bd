"""The issue-9 figures on longer ISSIA-like sequences (:mod:`benchmarks.issia_synth`), where they fail and why.

Usage::

    python -m benchmarks.issia_long [--seeds 1,2,3] [--seconds 60] [--long-seconds 180 --long-seed 4]
                                    [--workdir /tmp/issia-long] [--json OUT] [--timing-lengths 8,30,60,120,180]
                                    [--refits 12]

For each (seed, length) it generates a sequence into ``--workdir`` (outside the checkout: generated data is
never committed), scores it in both camera modes with :func:`benchmarks.issia.evaluate` (cameras from
``issia_calibration.json``, and from ``issia_lines.json`` alone) and checks each figure against its
target (issue 9):

* ``ball_3D`` given for >= 95 % of the frames with two or more correct labels, median error <= 0.06 m;
* ``ball_3D_smoothed`` given for >= 98 % of the frames where the ball is in an image, median <= 0.045 m;
* no outlier label in ``cam_list``; >= 97 % of the correct labels kept.

Then it **diagnoses** (:func:`diagnose`) every failing item against the truth's motion: frames with two or
more correct labels but no ``ball_3D``, frames whose ``ball_3D`` or ``ball_3D_smoothed`` is more than
:data:`BAD_M` off, outlier labels kept, correct labels left out. Each is put in the first matching context,
in this order: ``camera not used`` (the label's camera was refused), ``kick`` / ``bounce`` / ``roll start`` /
``stop`` / ``wall`` (within :data:`NEAR` frames of that event of the truth), ``no label`` (the frame has no kept label:
the trajectory interpolates), ``short piece`` (the fitted piece holding it spans fewer than 8 frames),
otherwise ``steady``; and runs of consecutive failing frames are listed with their context.

Timing: :func:`~app.geometry.trajectory.fit_trajectory` on the first N seconds of the long sequence, and
:func:`~app.geometry.trajectory.refit_window` after moving one label by 3 px at ``--refits`` frames spread over
it (median and max), wall and process CPU seconds; the machine is shared, so CPU time is the steadier one.
"""
from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np

from app.core.config import Settings
from app.datasets.issia import FPS, read_issia
from app.geometry.trajectory import fit_trajectory, refit_window
from app.services.calibration.admission import admission_args
from app.services.issia.cameras import sequence_cameras
from app.services.issia.trajectory import fit_args
from benchmarks.issia import evaluate
from benchmarks.issia_synth import generate

#: Targets of issue 9: (figure, comparison, value).
TARGETS = (("ball_3D_coverage", ">=", 0.95), ("ball_3D_median_error_m", "<=", 0.06),
           ("smoothed_coverage", ">=", 0.98), ("smoothed_median_error_m", "<=", 0.045),
           ("outliers_in_cam_list", "<=", 0), ("correct_kept_share", ">=", 0.97))
#: A position further than this from the truth (m) counts as a failure in the diagnosis.
BAD_M = 0.25
#: Frames on either side of an event of the truth that count as "near" it.
NEAR = 3
SHORT_PIECE = 8
CONTEXTS = ("camera not used", "kick", "bounce", "roll start", "stop", "wall", "no label", "short piece", "steady")


def met(figures: dict) -> dict[str, bool]:
    """Per target of :data:`TARGETS`: met (``None`` figures fail)."""
    out = {}
    for name, op, value in TARGETS:
        v = figures.get(name)
        out[name] = v is not None and (v >= value if op == ">=" else v <= value)
    return out


def _events(truth: dict) -> list[tuple[float, str]]:
    """(frame, kind) of the truth's kicks and events (fractional frames for events between frames)."""
    fps = float(truth["fps"])
    ev = [(float(k["frame"]) + 0.5, "kick") for k in truth["kicks"] if k["frame"] > 0]  # it acts after its frame
    ev += [(e["t"] * fps, {"bounce": "bounce", "roll": "roll start", "stop": "stop", "wall": "wall"}[e["kind"]])
           for e in truth.get("events", [])]
    return sorted(ev)


def _context(f: int, cam: int | None, truth_events, fit, used: list[bool]) -> tuple[str, str]:
    """(context, detail) of a failure at frame ``f`` (camera index ``cam`` for a label)."""
    if cam is not None and not used[cam]:
        return "camera not used", ""
    near = [(abs(t - f), t, k) for t, k in truth_events if abs(t - f) <= NEAR + 0.5]
    if near:
        d, t, k = min(near)
        return k, f"{k} at frame {t:.1f}"
    if not fit.kept_labels(f):
        return "no label", ""
    piece = next((p for p in fit.pieces if p.first_frame <= f <= p.last_frame), None)
    if piece is not None and piece.last_frame - piece.first_frame + 1 < SHORT_PIECE:
        return "short piece", f"{piece.kind} {piece.first_frame}-{piece.last_frame}"
    return "steady", ""


def _runs(frames: list[int], gap: int = 2) -> list[tuple[int, int]]:
    out: list[list[int]] = []
    for f in sorted(frames):
        if out and f - out[-1][1] <= gap:
            out[-1][1] = f
        else:
            out.append([f, f])
    return [(a, b) for a, b in out]


def diagnose(fit, truth: dict, camera_ids, used: list[bool]) -> dict:
    """Every failing item of the issue's figures, with its context (module docstring).

    Returns ``{"counts": {item: {context: n}}, "runs": [ {item, first, last, context, detail, max_error_m,
    labels, sources, phase} ], "smoothed_error_by_correct_labels": {"0" | "1" | "2" | "3+": {frames, median_m,
    p90_m, max_m}}}``: ``labels`` the correct labels per frame of the run, ``phase`` the truth's phases in it;
    the last, over the frames where the ball is in an image, by their number of correct labels.
    """
    idx = {c: k for k, c in enumerate(camera_ids)}
    ev = _events(truth)
    T = np.array([fr["ball_3d"] for fr in truth["frames"]])[: len(fit.positions)]
    e3 = np.linalg.norm(fit.ball_3d - T, axis=1)
    es = np.linalg.norm(fit.positions - T, axis=1)
    items: dict[str, list[tuple[int, int | None]]] = {k: [] for k in (
        "ball_3D missing", "ball_3D off", "smoothed missing", "smoothed off", "outlier kept", "correct left out")}
    n_ok = []
    for fr in truth["frames"][: len(T)]:
        f = fr["frame"]
        ok = [idx[c] for c, v in fr["cams"].items() if v["annotated"] and not v["outlier"]]
        bad = [idx[c] for c, v in fr["cams"].items() if v["annotated"] and v["outlier"]]
        n_ok.append(len(ok))
        if len(ok) >= 2:
            if not np.isfinite(e3[f]):
                items["ball_3D missing"].append((f, None))
            elif e3[f] > BAD_M:
                items["ball_3D off"].append((f, None))
        if any(v["in_image"] for v in fr["cams"].values()):
            if not np.isfinite(es[f]):
                items["smoothed missing"].append((f, None))
            elif es[f] > BAD_M:
                items["smoothed off"].append((f, None))
        items["outlier kept"] += [(f, k) for k in bad if k in fit.cam_lists[f]]
        items["correct left out"] += [(f, k) for k in ok if k not in fit.cam_lists[f]]
    counts: dict[str, dict[str, int]] = {}
    runs = []
    n_ok_a = np.array(n_ok)
    seen = np.array([any(v["in_image"] for v in fr["cams"].values()) for fr in truth["frames"][: len(T)]])
    by_labels = {}
    for name, sel in (("0", n_ok_a == 0), ("1", n_ok_a == 1), ("2", n_ok_a == 2), ("3+", n_ok_a >= 3)):
        e = es[seen & sel]
        e = e[np.isfinite(e)]
        if len(e):
            by_labels[name] = {"frames": int(len(e)), "median_m": float(np.median(e)),
                               "p90_m": float(np.percentile(e, 90)), "max_m": float(np.max(e))}
    for item, hits in items.items():
        ctx = [(f, k, *_context(f, k, ev, fit, used)) for f, k in hits]
        counts[item] = {c: n for c in CONTEXTS if (n := sum(x[2] == c for x in ctx))}
        by_frame = {f: (k, c, d) for f, k, c, d in ctx}
        for a, b in _runs([f for f, *_ in ctx]):
            inside = [by_frame[f] for f in range(a, b + 1) if f in by_frame]
            cs = sorted({c for _, c, _ in inside}, key=CONTEXTS.index)
            err = es if item.startswith("smoothed") else e3
            fin = err[a:b + 1][np.isfinite(err[a:b + 1])]
            runs.append({
                "item": item, "first": a, "last": b, "context": cs[0], "contexts": cs,
                "detail": "; ".join(sorted({d for _, _, d in inside if d})),
                "cameras": sorted({camera_ids[k] for k, _, _ in inside if k is not None}),
                "max_error_m": float(fin.max()) if len(fin) else None,
                "labels": n_ok[a:b + 1][:20],
                "sources": sorted({s or "none" for s in fit.sources[a:b + 1]}),
                "phase": sorted({truth["frames"][f]["phase"] for f in range(a, b + 1)}),
            })
    return {"counts": counts, "runs": runs, "smoothed_error_by_correct_labels": by_labels}


def run_sequence(data: Path, truth: dict) -> list[dict]:
    """Both modes on one sequence: figures (:func:`benchmarks.issia.evaluate`), targets met, diagnosis."""
    seq = read_issia(data)
    out = []
    for from_lines in (False, True):
        figures, fit = evaluate(seq, truth, from_lines=from_lines)
        used = [c in figures["cameras_used"] for c in seq.camera_ids]
        figures.pop("pieces")
        figures["pieces"] = len(fit.pieces)
        figures["met"] = met(figures)
        figures["diagnosis"] = diagnose(fit, truth, seq.camera_ids, used)
        out.append(figures)
    return out


def timing(data: Path, lengths_s: list[float], refits: int, fps: float = FPS) -> list[dict]:
    """Fit and one-label re-fit times on the first N seconds of ``data`` (calibration-JSON cameras)."""
    seq = read_issia(data)
    choice = sequence_cameras(seq, **admission_args(Settings()), pair_rules=fit_args(Settings()))
    cams = [choice[c].camera for c in seq.camera_ids]
    widths = [seq.image_size[0]] * len(cams)
    dense = seq.dense_points()
    rows = []
    for secs in lengths_s:
        n = min(int(round(secs * fps)), len(dense))
        pts = dense[:n].copy()
        t0, c0 = time.perf_counter(), time.process_time()
        fit = fit_trajectory(pts, cams, widths, fps, **fit_args(Settings()))
        fit_wall, fit_cpu = time.perf_counter() - t0, time.process_time() - c0
        walls, cpus = [], []
        labelled = [f for f in range(n) if np.isfinite(pts[f]).all(axis=1).any()]
        for f in labelled[len(labelled) // (2 * refits)::max(len(labelled) // refits, 1)][:refits]:
            k = int(np.nonzero(np.isfinite(pts[f]).all(axis=1))[0][0])
            edited = pts.copy()
            edited[f, k, 0] += 3.0
            t0, c0 = time.perf_counter(), time.process_time()
            refit_window(fit, edited, cams, widths, f, f, **fit_args(Settings()))
            walls.append(time.perf_counter() - t0)
            cpus.append(time.process_time() - c0)
        rows.append({"seconds": n / fps, "frames": n, "pieces": len(fit.pieces), "fit_wall_s": fit_wall,
                     "fit_cpu_s": fit_cpu, "refits": len(walls),
                     "refit_wall_median_s": float(np.median(walls)) if walls else None,
                     "refit_wall_max_s": float(np.max(walls)) if walls else None,
                     "refit_cpu_median_s": float(np.median(cpus)) if cpus else None,
                     "refit_cpu_max_s": float(np.max(cpus)) if cpus else None})
        print(f"  timing {n / fps:6.1f} s ({n} frames, {len(fit.pieces)} pieces): fit {fit_wall:6.2f} s wall "
              f"{fit_cpu:6.2f} s CPU; refit median {rows[-1]['refit_wall_median_s']:.3f} s max "
              f"{rows[-1]['refit_wall_max_s']:.3f} s wall", flush=True)
    return rows


def _fmt(v, digits=3):
    if v is None:
        return "-"
    if isinstance(v, float):
        return f"{v:.{digits}f}"
    return str(v)


def print_table(results: list[dict]) -> None:
    print("| seed | s | mode | ball_3D given | median | smoothed given | median | p90 | outliers in cam_list "
          "| correct kept | fit s | targets missed |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|")
    for r in results:
        f = r["figures"]
        missed = [k for k, ok in f["met"].items() if not ok]
        print(f"| {r['seed']} | {r['seconds']:g} | {f['mode']} | {_fmt(f['ball_3D_coverage'])} | "
              f"{_fmt(f['ball_3D_median_error_m'])} | {_fmt(f['smoothed_coverage'])} | "
              f"{_fmt(f['smoothed_median_error_m'])} | {_fmt(f['smoothed_p90_error_m'])} | "
              f"{f['outliers_in_cam_list']} of {f['outlier_labels']} | {_fmt(f['correct_kept_share'])} | "
              f"{_fmt(f['fit_s'], 1)} | {', '.join(missed) or 'none'} |")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", default="1,2,3")
    ap.add_argument("--seconds", type=float, default=60.0)
    ap.add_argument("--long-seconds", type=float, default=180.0, help="0: no long sequence")
    ap.add_argument("--long-seed", type=int, default=4)
    ap.add_argument("--workdir", type=Path, default=Path("/tmp/v3d-issia-synth"))
    ap.add_argument("--timing-lengths", default="8,30,60,120,180", help="seconds of the long sequence; empty: none")
    ap.add_argument("--refits", type=int, default=12)
    ap.add_argument("--json", type=Path)
    args = ap.parse_args(argv)
    runs = [(int(s), args.seconds) for s in args.seeds.split(",") if s.strip()]
    if args.long_seconds > 0:
        runs.append((args.long_seed, args.long_seconds))
    results = []
    for seed, secs in runs:
        data = args.workdir / f"seed{seed}-{secs:g}s"
        truth = generate(data, seconds=secs, seed=seed)
        print(f"== seed {seed}, {secs:g} s: {truth['summary']['kicks']} kicks, events {truth['summary']['events']}, "
              f"{sum(v['outliers'] for v in truth['summary']['per_camera'].values())} outlier labels", flush=True)
        for figures in run_sequence(data, truth):
            results.append({"seed": seed, "seconds": secs, "figures": figures})
            d = figures["diagnosis"]
            print(f"  {figures['mode']}: met {figures['met']}", flush=True)
            for item, c in d["counts"].items():
                if c:
                    print(f"    {item}: {c}")
            print("    smoothed error by correct labels in the frame: " + "; ".join(
                f"{k}: {v['frames']} frames, median {v['median_m']:.3f} p90 {v['p90_m']:.2f} max {v['max_m']:.2f} m"
                for k, v in d["smoothed_error_by_correct_labels"].items()))
            if figures["cameras_refused"]:
                print(f"    cameras refused: {figures['cameras_refused']}")
    print_table(results)
    timings = []
    lengths = [float(x) for x in args.timing_lengths.split(",") if x.strip()]
    if lengths and args.long_seconds > 0:
        print("== timing (calibration JSON cameras)")
        timings = timing(args.workdir / f"seed{args.long_seed}-{args.long_seconds:g}s", lengths, args.refits)
    if args.json:
        args.json.write_text(json.dumps({"results": results, "timing": timings}, indent=1, default=float))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
