"""Plots of the monocular benchmark (matplotlib, Agg backend): the precision-threshold curve and the
sensitivity study of the paper (Fig. precision, Fig. sensitivity), each written as PNG and SVG."""
from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from app.geometry.pitch import BALL_DIAMETER_M
from app.geometry.sensitivity import centre_sensitivity, size_sensitivity
from app.services.evaluation.monocular import ReferenceView

#: Variations of the sensitivity study (paper: box size +-10 %, centre up to 2 % of the diagonal).
SIZE_PCT = tuple(float(v) for v in np.linspace(-10.0, 10.0, 41))
SHIFT_PCT = tuple(float(v) for v in np.linspace(0.0, 2.0, 21))


def _pyplot() -> Any:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def _save(fig: Any, out_dir: Path, stem: str) -> list[Path]:
    out_dir.mkdir(parents=True, exist_ok=True)
    paths = [out_dir / f"{stem}.png", out_dir / f"{stem}.svg"]
    for p in paths:
        fig.savefig(p, dpi=120, bbox_inches="tight")
    return paths


def plot_precision_curve(report: dict[str, Any], out_dir: str | Path) -> list[Path]:
    """``precision_threshold.png/.svg``: precision against the 3D threshold, whole set and per split."""
    plt = _pyplot()
    fig, ax = plt.subplots(figsize=(5.5, 4))
    series = [("all", report)] + sorted(report.get("splits", {}).items())
    for name, rep in series:
        c = rep["curve"]
        y = [np.nan if v is None else 100 * v for v in c["precision"]]
        ax.plot(c["thresholds_m"], y, label=f"{name} (n = {rep['counts']['localised']})",
                lw=2 if name == "all" else 1.2, ls="-" if name == "all" else "--")
    ax.axvline(2.0, color="grey", lw=0.8, ls=":")
    ax.set_xlabel("threshold τ3D (m)")
    ax.set_ylabel("precision (%)")
    ax.set_ylim(0, 101)
    ax.set_title("Monocular 3D ball: precision-threshold")
    ax.grid(alpha=0.3)
    ax.legend()
    paths = _save(fig, Path(out_dir), "precision_threshold")
    plt.close(fig)
    return paths


def sensitivity_curves(views: list[ReferenceView], ball_diameter_m: float = BALL_DIAMETER_M, samples: int = 100,
                       seed: int = 0, estimator: str = "exact") -> dict[str, Any]:
    """Errors (m) against the reference 3D ball of up to ``samples`` views (drawn with ``seed``) under
    the size and centre variations of their reference boxes, with the monocular ``estimator``
    (``"paper"`` or ``"exact"``, :data:`app.services.evaluation.monocular.ESTIMATORS`)."""
    exact = estimator == "exact"
    rng = np.random.default_rng(seed)
    pick = sorted(rng.choice(len(views), size=min(samples, len(views)), replace=False)) if views else []
    rows = []
    for i in pick:
        v = views[i]
        rows.append({
            "stem": v.stem, "distance_m": float(np.linalg.norm(v.ball - v.camera.C)),
            "size_error_m": size_sensitivity(v.camera, v.box, v.ball, np.array(SIZE_PCT), ball_diameter_m,
                                             exact).tolist(),
            "centre_error_m": centre_sensitivity(v.camera, v.box, v.ball, np.array(SHIFT_PCT), ball_diameter_m,
                                                 (v.width, v.height), exact).tolist(),
        })
    return {"size_pct": list(SIZE_PCT), "shift_pct": list(SHIFT_PCT), "estimator": estimator, "views": rows}


def plot_sensitivity(study: dict[str, Any], out_dir: str | Path) -> list[Path]:
    """``sensitivity.png/.svg``: error against box size (left) and centre shift (right), coloured by distance."""
    plt = _pyplot()
    from matplotlib import cm, colors

    rows = study["views"]
    dist = [r["distance_m"] for r in rows] or [0.0, 1.0]
    norm = colors.Normalize(vmin=min(dist), vmax=max(dist))
    cmap = plt.get_cmap("viridis")
    fig, (a, b) = plt.subplots(1, 2, figsize=(10, 4), sharey=False)
    for r in rows:
        col = cmap(norm(r["distance_m"]))
        a.plot(study["size_pct"], r["size_error_m"], color=col, lw=0.8, alpha=0.8)
        b.plot(study["shift_pct"], r["centre_error_m"], color=col, lw=0.8, alpha=0.8)
    a.set_xlabel("box size variation (% of the box size)")
    b.set_xlabel("box centre shift (% of the image diagonal)")
    for ax in (a, b):
        ax.set_ylabel("3D error (m)")
        ax.grid(alpha=0.3)
    fig.suptitle(f"Sensitivity of monocular 3D ball localisation ({len(rows)} views)")
    fig.colorbar(cm.ScalarMappable(norm=norm, cmap=cmap), ax=[a, b], label="camera-to-ball distance (m)")
    paths = _save(fig, Path(out_dir), "sensitivity")
    plt.close(fig)
    return paths
