"""The dataset at a glance (``v3d stats``): counts per system kind and split, the paper's Fig. 3 (systems kept
against the JaC admission threshold) and distributions.

:func:`dataset_stats` returns::

    {"kinds": {kind: {"systems", "images", "calibrated_images", "admitted_images",
                      "splits": {split: {the same four counts}}}},
     "jac_sweep": [{"threshold", "systems_kept"}, ...],
     "jac_sweep_by_kind": {kind: [{"threshold", "systems_kept"}, ...]},
     "admission": {"gamma", "jac_min"},
     "stale_systems": n,
     "ball_evidence": {"vouched": n, "unconfirmed": n, "doubted": n, "none": n},
     "distributions": {name: {"edges": [...], "counts": [...], "n", "above"}}}

* images are the frames; calibrated: with a camera; admitted: the calibration is admitted (JaC above the
  admission threshold, ``Settings.admit_jac_min``). A view's split is its kind's (``app.services.kinds``:
  a release's split where imported, else the kind's own); a system counts in each split it has a view in.
* ``jac_sweep``: a multi-view system is kept at threshold t when at least two of its views have a camera with
  JaC at the admission gamma (``Settings.admit_jac_gamma``) above t (the paper's Fig. 3), for t in
  :data:`JAC_THRESHOLDS`, over every system and per kind (``jac_sweep_by_kind``: the paper's figure is SoccerNet-v3's;
  ISSIA's static cameras have one calibration each); ``admission`` is the threshold in force
  (``Settings.admit_jac_gamma``, ``admit_jac_min``), so that a plot can mark it; ``stale_systems`` counts the systems
  computed with other settings (a changed ``V3D_PROFILE``,
  ``app.services.derivation.recompute.systems_computed_otherwise``): their figures here are stale until
  ``v3d recompute``; ``ball_evidence`` counts the systems per tier of what backs their 3D ball (the stored
  ``System.ball_evidence``, ``app.geometry.ball_evidence``; every tier present, 0 for none).
* distributions (:data:`HISTOGRAM_BINS` equal bins between the smallest and largest value, a long tail counted
  apart, :func:`histogram`): ``jac`` (JaC at the
  admission gamma of every calibrated view), ``pair_reprojection_error_px`` (every triangulation pair's error),
  ``ball_distance_m`` (camera centre to the system's 3D ball, SoccerNet world, metres, each admitted view of a
  triangulated system) and ``box_size_px`` (diagonal of every current ball box, pixels).
"""
from __future__ import annotations

from typing import Any

import numpy as np
import sqlalchemy as sa
from sqlalchemy.orm import Session, selectinload

from app.core.config import Settings
from app.db.models import BallEvidence, Frame, System, TriangulationPair
from app.services.calibration.admission import admission_jac
from app.services.derivation.recompute import systems_computed_otherwise
from app.services.kinds import kind_of

#: JaC admission thresholds of the sweep (Fig. 3), 0 to 1 by 0.05.
JAC_THRESHOLDS = tuple(round(0.05 * i, 2) for i in range(21))
HISTOGRAM_BINS = 20
_COUNTS = ("systems", "images", "calibrated_images", "admitted_images")


#: A distribution's long tail starts at Tukey's far-out fence, the third quartile plus this many interquartile
#: ranges: the bins end there and the values beyond are counted in ``above`` (a few wrong labels' reprojection
#: errors of hundreds of pixels would otherwise put every other value in the first bin).
TAIL_IQR = 3.0


def histogram(values: list[float], bins: int = HISTOGRAM_BINS) -> dict[str, Any]:
    """``{"edges": bins + 1 edges, "counts": bins counts, "n", "above"}`` of the finite ``values``: equal bins
    from the smallest value to the largest, or, when values lie beyond the far-out fence (:data:`TAIL_IQR`), to the
    fence, the ``above`` values beyond it; ``n`` counts every value (``sum(counts) + above == n``; empty lists for
    none).

    >>> histogram([0.0, 1.0, 2.0, 3.0], bins=3)["counts"]
    [1, 1, 2]
    >>> h = histogram([1.0, 2.0, 2.0, 3.0, 500.0], bins=2); h["edges"], h["counts"], h["above"]
    ([1.0, 3.5, 6.0], [4, 0], 1)
    """
    v = np.asarray([x for x in values if x is not None and np.isfinite(x)], float)
    if v.size == 0:
        return {"edges": [], "counts": [], "n": 0, "above": 0}
    lo, hi = float(v.min()), float(v.max())
    q1, q3 = (float(q) for q in np.percentile(v, [25, 75]))
    fence = q3 + TAIL_IQR * (q3 - q1)
    if lo < fence < hi:
        hi = fence
    counts, edges = np.histogram(v[v <= hi], bins=bins, range=(lo, hi) if hi > lo else None)
    return {"edges": [float(e) for e in edges], "counts": [int(c) for c in counts], "n": int(v.size),
            "above": int(np.count_nonzero(v > hi))}


def _sweep(per_system_jacs: list[list[float]]) -> list[dict[str, Any]]:
    """Systems kept at each threshold of :data:`JAC_THRESHOLDS`: those with two views or more whose JaC is above it."""
    return [{"threshold": t, "systems_kept": sum(1 for jacs in per_system_jacs if sum(j > t for j in jacs) >= 2)}
            for t in JAC_THRESHOLDS]


def evidence_counts(session: Session) -> dict[str, int]:
    """Systems per tier of what backs their 3D ball (``System.ball_evidence``), every tier of ``BallEvidence`` in
    its order, 0 for none."""
    found = dict(session.execute(sa.select(System.ball_evidence, sa.func.count()).group_by(System.ball_evidence)).all())
    return {t.value: int(found.get(t, 0)) for t in BallEvidence}


def dataset_stats(session: Session, settings: Settings) -> dict[str, Any]:
    """The statistics of the whole database (module docstring)."""
    kinds: dict[str, dict[str, Any]] = {}
    jac_values: list[float] = []
    per_system_jacs: list[tuple[str, list[float]]] = []
    distances: list[float] = []
    sizes: list[float] = []
    query = (sa.select(System).order_by(System.id)
             .options(selectinload(System.game), selectinload(System.triangulation),
                      selectinload(System.frames).options(selectinload(Frame.calibration),
                                                          selectinload(Frame.ball_label))))
    for system in session.scalars(query.execution_options(yield_per=500)):
        policy = kind_of(system)
        k = kinds.setdefault(system.kind.value, {**{c: 0 for c in _COUNTS}, "splits": {}})
        k["systems"] += 1
        seen_splits: set[str] = set()
        jacs: list[float] = []
        ball = system.triangulation.ball3d if system.triangulation is not None else None
        for f in system.frames:
            split = policy.split(system, f)
            sp = k["splits"].setdefault(split, {c: 0 for c in _COUNTS})
            if split not in seen_splits:
                sp["systems"] += 1
                seen_splits.add(split)
            cal = f.calibration
            camera = cal.camera if cal is not None else None
            calibrated = cal is not None and camera is not None
            admitted = cal is not None and camera is not None and bool(cal.admitted)
            for target in (k, sp):
                target["images"] += 1
                target["calibrated_images"] += int(calibrated)
                target["admitted_images"] += int(admitted)
            if cal is not None and camera is not None:
                jac = admission_jac(cal, settings)
                if jac is not None:
                    jac_values.append(float(jac))
                    jacs.append(float(jac))
                if admitted and ball is not None:
                    centre = np.asarray(camera["position_meters"], dtype=float)
                    distances.append(float(np.linalg.norm(np.asarray(ball, float) - centre)))
            label = f.ball_label
            if label is not None and label.box is not None:
                x1, y1, x2, y2 = label.box
                sizes.append(float(np.hypot(x2 - x1, y2 - y1)))
        per_system_jacs.append((system.kind.value, jacs))
    sweep = _sweep([jacs for _, jacs in per_system_jacs])
    by_kind = {kind: _sweep([jacs for k, jacs in per_system_jacs if k == kind]) for kind in kinds}
    errors = [e for (e,) in session.execute(sa.select(TriangulationPair.error_px)
                                            .where(TriangulationPair.error_px.is_not(None))) if e is not None]
    return {
        "kinds": kinds,
        "jac_sweep": sweep,
        "jac_sweep_by_kind": by_kind,
        "admission": {"gamma": settings.admit_jac_gamma, "jac_min": settings.admit_jac_min},
        "stale_systems": systems_computed_otherwise(session, settings),
        "ball_evidence": evidence_counts(session),
        "distributions": {"jac": histogram(jac_values), "pair_reprojection_error_px": histogram(errors),
                          "ball_distance_m": histogram(distances), "box_size_px": histogram(sizes)},
    }
