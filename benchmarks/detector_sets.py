"""More sets like ``../shared/data/synthetic/detector/`` (views nobody labelled and a simulated ball detector's
predictions), made from the doubts seeds (``doubts-seeds/seed-N``) as the shared README describes those two, for
measuring the detector in the loop on sets no rule was chosen on (``benchmarks/detector_fill.py --sets seed-N``).

Recipe (the shared README's, section ``data/synthetic/detector``; the numbers are its, not fitted here):

* about a third (0.35) of the views where the ball is visible (``system_ball_in_image``, not an out-of-frame view, a
  ball box labelled) and no corruption touches (the system's ``corruption`` is empty) lose their Ball box, every
  system keeping at least one labelled view; each removed label is listed in the truth's ``unlabelled`` (league,
  season, match, action, image, the true centre in px, the diameter d in px);
* a detector is run on every image: the true ball is found with probability 0.85 (centre off by a normal law of
  0.12 d per axis, each side off by up to 20 %, a score around 0.83), plus a Poisson number of false detections of
  mean 1.2 per image, 60 % on a player's head or feet (the release's player boxes of that image), the rest anywhere
  below the top fifth, a ball's size, one in ten with a score above 0.85.

Writes ``OUT/seed-N-unlabelled/`` (SoccerNet-v3 layout, labels only), ``OUT/seed-N-unlabelled.truth.json`` and
``OUT/seed-N-predictions.csv``. Run: ``.venv/bin/python benchmarks/detector_sets.py seed-203 seed-205 [--out DIR]``.
"""
from __future__ import annotations

import argparse
import csv
import json
import sys
from pathlib import Path
from typing import Any, Sequence

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from app.core.paths import SHARED_DIR  # noqa: E402  # after the path is set

SEEDS = SHARED_DIR / "data" / "synthetic" / "doubts-seeds"
UNLABEL_RATE, RECALL, FP_RATE, FP_ON_PLAYERS, FP_CONFIDENT = 0.35, 0.85, 1.2, 0.6, 0.1


def _visible(v: dict[str, Any]) -> bool:
    return bool(v.get("system_ball_in_image") and not v.get("out_of_frame_view") and v.get("ball_center_px")
                and v.get("annotated_box") is not None)


def make(name: str, out: Path, seed: int) -> None:
    rng = np.random.default_rng(seed)
    src = SEEDS / name
    truth = json.loads((SEEDS / f"{name}.truth.json").read_text())
    tree = out / f"{name}-unlabelled"
    unlabelled: list[dict[str, Any]] = []
    rows: list[list[Any]] = []
    for g in truth["games"]:
        game_dir = Path(g["league"], g["season"], g["match"])
        labels = json.loads((src / game_dir / "Labels-v3.json").read_text())
        entries = {**{k: v for k, v in labels["actions"].items()}, **{k: v for k, v in labels["replays"].items()}}
        for s in g["systems"]:
            removable = [v for v in s["views"] if _visible(v) and not s.get("corruption")]
            labelled = [v for v in s["views"] if v.get("annotated_box") is not None]
            drop = [v for v in removable if rng.random() < UNLABEL_RATE]
            if len(drop) >= len(labelled):  # every system keeps a labelled view
                drop = drop[:len(labelled) - 1]
            for v in drop:
                e = entries[v["image"]]
                e["bboxes"] = [b for b in e.get("bboxes", []) if b.get("class") != "Ball"]
                unlabelled.append({"league": g["league"], "season": g["season"], "match": g["match"],
                                   "action": s["action"], "image": v["image"], "center": v["ball_center_px"],
                                   "d": v["d_true"]})
            for v in s["views"]:
                rows += _detect(rng, g, v, entries[v["image"]])
        (tree / game_dir).mkdir(parents=True, exist_ok=True)
        (tree / game_dir / "Labels-v3.json").write_text(json.dumps(labels))
    truth["unlabelled"] = unlabelled
    truth["detector"] = {"seed": seed, "unlabel_rate": UNLABEL_RATE, "recall": RECALL, "fp_rate": FP_RATE,
                         "predictions": len(rows), "made_by": "benchmarks/detector_sets.py"}
    (out / f"{name}-unlabelled.truth.json").write_text(json.dumps(truth))
    with (out / f"{name}-predictions.csv").open("w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["league", "season", "match", "image", "x1", "y1", "x2", "y2", "score"])
        w.writerows(rows)
    print(f"{name}: {len(unlabelled)} unlabelled views, {len(rows)} predictions", flush=True)


def _detect(rng: np.random.Generator, g: dict[str, Any], v: dict[str, Any], entry: dict[str, Any]) -> list[list[Any]]:
    """One image's detections (module docstring)."""
    W, H = v["width"], v["height"]
    d_ball = float(v.get("d_true") or 12.0)
    out = []

    def row(cx: float, cy: float, w: float, h: float, score: float) -> None:
        x1, y1, x2, y2 = max(cx - w / 2, 0.0), max(cy - h / 2, 0.0), min(cx + w / 2, W), min(cy + h / 2, H)
        if x2 > x1 and y2 > y1:
            out.append([g["league"], g["season"], g["match"], v["image"], f"{x1:.2f}", f"{y1:.2f}", f"{x2:.2f}",
                        f"{y2:.2f}", f"{score:.3f}"])

    if _visible(v) or (v.get("system_ball_in_image") and not v.get("out_of_frame_view") and v.get("ball_center_px")):
        if rng.random() < RECALL:
            c = np.asarray(v["ball_center_px"], float) + rng.normal(0.0, 0.12 * d_ball, 2)
            row(c[0], c[1], d_ball * rng.uniform(0.85, 1.2), d_ball * rng.uniform(0.85, 1.2),
                float(np.clip(rng.normal(0.83, 0.1), 0.3, 0.99)))
    players = [b["points"] for b in entry.get("bboxes", []) if str(b.get("class", "")).startswith("Player")]
    for _ in range(rng.poisson(FP_RATE)):
        if players and rng.random() < FP_ON_PLAYERS:
            p = players[rng.integers(len(players))]
            h = p["y2"] - p["y1"]
            y = p["y1"] + 0.08 * h if rng.random() < 0.5 else p["y2"] - 0.03 * h
            cx, cy = (p["x1"] + p["x2"]) / 2 + rng.normal(0, 0.1 * (p["x2"] - p["x1"])), y + rng.normal(0, 0.03 * h)
        else:
            cx, cy = rng.uniform(0, W), rng.uniform(0.2 * H, H)
        size = d_ball * rng.uniform(0.7, 1.4)
        score = rng.uniform(0.85, 0.97) if rng.random() < FP_CONFIDENT else rng.uniform(0.1, 0.85)
        row(cx, cy, size, size * rng.uniform(0.85, 1.15), float(score))
    return out


def main(argv: Sequence[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("sets", nargs="+")
    ap.add_argument("--out", type=Path, default=Path("/tmp/v3d-detector-sets"))
    ap.add_argument("--seed", type=int, default=11)
    args = ap.parse_args(argv)
    args.out.mkdir(parents=True, exist_ok=True)
    for i, name in enumerate(args.sets):
        make(name, args.out, args.seed + i)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
