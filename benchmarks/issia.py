"""ISSIA-3D on the synthetic dev sequence: per-frame triangulation and the temporal trajectory against the truth.

Usage: ``python -m benchmarks.issia [--data DIR] [--truth FILE] [--json OUT] [--plot OUT.png]``

Runs both modes: cameras from ``issia_calibration.json`` (as the paper) and from ``issia_lines.json``
alone (v3d's own calibration, each static camera once). Prints the done-when figures of issue 9:

* ``ball_3D``: coverage over frames with two or more correct labels, median error there;
* ``ball_3D_smoothed``: coverage over frames where the ball is in at least one camera's image,
  median error there;
* outlier labels left in ``cam_list`` (must be 0) and the share of correct labels kept.
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

SHARED = Path(__file__).resolve().parents[2] / "shared" / "data" / "synthetic"


def evaluate(seq, truth: dict, *, from_lines: bool) -> tuple[dict, object]:
    """Fit ``seq`` in one mode and score it against ``truth`` (issia-dev.truth.json); returns (figures, fit)."""
    t0 = time.perf_counter()
    choice = sequence_cameras(seq, from_lines=from_lines, **admission_args(Settings()), pair_rules=fit_args(Settings()))
    t1 = time.perf_counter()
    cams = [choice[c].camera for c in seq.camera_ids]
    fit = fit_trajectory(seq.dense_points(), cams, [seq.image_size[0]] * len(cams), float(truth.get("fps", FPS)),
                         **fit_args(Settings()))
    t2 = time.perf_counter()
    mid = len(fit.positions) // 2  # an edit in the middle: only the pieces it touches are fitted again
    refit_window(fit, seq.dense_points(), cams, [seq.image_size[0]] * len(cams), mid, mid, **fit_args(Settings()))
    t3 = time.perf_counter()
    idx = {c: k for k, c in enumerate(seq.camera_ids)}
    good2, seen, n_out, out_kept, n_ok, ok_kept, out_flagged = [], [], 0, 0, 0, 0, 0
    true = np.full((len(fit.positions), 3), np.nan)
    for fr in truth["frames"]:
        f = fr["frame"]
        if f >= len(true):
            continue
        true[f] = fr["ball_3d"]
        ok = [idx[c] for c, v in fr["cams"].items() if v["annotated"] and not v["outlier"]]
        bad = [idx[c] for c, v in fr["cams"].items() if v["annotated"] and v["outlier"]]
        if len(ok) >= 2:
            good2.append(f)
        if any(v["in_image"] for v in fr["cams"].values()):
            seen.append(f)
        n_out += len(bad)
        out_kept += sum(k in fit.cam_lists[f] for k in bad)
        out_flagged += sum(bool(fit.outliers[f, k]) for k in bad)
        n_ok += len(ok)
        ok_kept += sum(k in fit.cam_lists[f] for k in ok)
    e3 = np.linalg.norm(fit.ball_3d - true, axis=1)
    es = np.linalg.norm(fit.positions - true, axis=1)
    g, s = np.array(good2, int), np.array(seen, int)
    correct_flagged = int(np.sum(fit.outliers)) - out_flagged
    figures = {
        "mode": "lines" if from_lines else "calibration_json",
        "cameras_used": [c for c in seq.camera_ids if choice[c].camera is not None],
        "cameras_refused": {c: choice[c].reason for c in seq.camera_ids if choice[c].camera is None},
        "frames_two_correct_labels": int(len(g)),
        "ball_3D_coverage": float(np.mean(np.isfinite(e3[g]))) if len(g) else None,
        "ball_3D_median_error_m": float(np.nanmedian(e3[g])) if np.isfinite(e3[g]).any() else None,
        "frames_ball_in_an_image": int(len(s)),
        "smoothed_coverage": float(np.mean(np.isfinite(es[s]))) if len(s) else None,
        "smoothed_median_error_m": float(np.nanmedian(es[s])) if np.isfinite(es[s]).any() else None,
        "smoothed_p90_error_m": float(np.nanpercentile(es[s], 90)) if np.isfinite(es[s]).any() else None,
        "smoothed_max_error_m": float(np.nanmax(es[s])) if np.isfinite(es[s]).any() else None,
        "outlier_labels": n_out,
        "outliers_in_cam_list": out_kept,
        "outliers_flagged": out_flagged,
        "correct_labels": n_ok,
        "correct_kept_share": ok_kept / n_ok if n_ok else None,
        "correct_labels_flagged": correct_flagged,
        "pieces": [(p.kind, p.first_frame, p.last_frame) for p in fit.pieces],
        "calibration_s": t1 - t0,
        "fit_s": t2 - t1,
        "refit_one_frame_s": t3 - t2,
    }
    return figures, fit


def plot(fit, truth: dict, out: Path) -> None:
    """x, y and height against frame: truth, per-frame triangulation, trajectory; flagged frames marked."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    true = np.array([fr["ball_3d"] for fr in truth["frames"]])[: len(fit.positions)]
    fr = np.arange(len(fit.positions))
    flagged = np.nonzero(fit.outliers.any(axis=1))[0]
    fig, axes = plt.subplots(3, 1, figsize=(11, 8), sharex=True)
    for ax, i, name in zip(axes, range(3), ("x (m)", "y (m)", "height -z (m)"), strict=False):
        sign = -1 if i == 2 else 1
        ax.plot(fr, sign * true[:, i], color="0.6", lw=3, label="truth")
        ax.plot(fr, sign * fit.ball_3d[:, i], ".", color="tab:blue", ms=4, label="ball_3D (per frame)")
        ax.plot(fr, sign * fit.positions[:, i], color="tab:orange", lw=1, label="ball_3D_smoothed")
        for f in flagged:
            ax.axvline(f, color="tab:red", lw=0.8, ls="--")
        for p in fit.pieces[1:]:
            ax.axvline(p.first_frame - 0.5, color="k", lw=0.5, ls=":")
        ax.set_ylabel(name)
    axes[0].legend(loc="best", fontsize=8)
    axes[-1].set_xlabel("frame (25 fps); red dashed: flagged label; dotted: piece break")
    fig.tight_layout()
    fig.savefig(out, dpi=80)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", type=Path, default=SHARED / "issia-dev")
    ap.add_argument("--truth", type=Path, default=SHARED / "issia-dev.truth.json")
    ap.add_argument("--json", type=Path)
    ap.add_argument("--plot", type=Path, help="PNG of the calibration-JSON mode (and <stem>-lines.png)")
    args = ap.parse_args(argv)
    truth = json.loads(args.truth.read_text())
    seq = read_issia(args.data)
    results = []
    for from_lines in (False, True):
        figures, fit = evaluate(seq, truth, from_lines=from_lines)
        results.append(figures)
        print(f"== {figures['mode']} ==")
        for k, v in figures.items():
            print(f"  {k}: {v}")
        if args.plot:
            out = args.plot if not from_lines else args.plot.with_name(args.plot.stem + "-lines.png")
            plot(fit, truth, out)
    if args.json:
        args.json.write_text(json.dumps(results, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
