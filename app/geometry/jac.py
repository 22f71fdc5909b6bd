"""JaC, the calibration quality score, exactly as SoccerNet's official evaluator computes it.

Reference: repository SoccerNet/sn-calibration, ``src/evaluate_camera.py`` (``get_polylines``,
``distance_to_polyline``, ``evaluate_camera_prediction`` and the mirror handling of its
``__main__``), ``src/evaluate_extremities.py`` (``mirror_labels``, ``scale_points``) and
``src/soccerpitch.py`` (``sample_field_points``); method.md section 4. Vectorised (and compiled) rewrite, same
arithmetic:

1. the pitch is sampled every 0.9 m on straight elements and 0.2 m on circles
   (``get_polylines(..., sampling_factor=0.9)``) and projected with the camera as the evaluator
   does (:func:`app.geometry.projection.project_pitch_polylines`, ``mode="evaluator"``);
2. for a class both projected and annotated, every annotated point's distance to the projected
   polyline (point to segment) is measured; the class is a true positive when all of them are
   ``< threshold``, otherwise a false positive; a projected class without annotation is a false
   positive, an annotated class without projection a false negative;
3. ``JaC = TP / (TP + FP + FN)`` in float32 (the evaluator's confusion matrix is float32), for the
   annotation and for its mirror (:data:`app.geometry.pitch.MIRROR_CLASSES`); the mirror is kept
   only when strictly better.

Thresholds are in pixels of the evaluation image (official: 5, 10, 20 px at 960x540) or, as
SoccerNet-v3D states them, a fraction gamma of the image diagonal (:func:`gamma_thresholds`).
Annotations are :data:`~app.geometry.annotations.FieldLines` in pixels of that image
(normalised SoccerNet points become ``x (W - 1), y (H - 1)``, the evaluator's ``scale_points``);
the camera must be expressed at that resolution (:meth:`Camera.scaled`), as the evaluator, which
never rescales, requires.
"""
from __future__ import annotations

import math
import numbers
from dataclasses import dataclass
from types import MappingProxyType
from typing import Iterable, Literal, Mapping, Sequence

import numpy as np
from numba import njit

from app.geometry.annotations import AnnotationError, FieldLines, image_diagonal
from app.geometry.camera import Camera
from app.geometry.pitch import MIRROR_CLASSES
from app.geometry.projection import (
    EVALUATOR_DIST_CIRCLES_M,
    EVALUATOR_DIST_M,
    project_pitch_polylines,
)

#: Official SoccerNet thresholds, pixels at 960x540.
OFFICIAL_THRESHOLDS_PX: tuple[float, ...] = (5.0, 10.0, 20.0)
#: SoccerNet-v3D thresholds as fractions of the image diagonal (0.5 %, 1 %, 2 %).
JAC_GAMMAS: tuple[float, ...] = (0.005, 0.01, 0.02)

Outcome = Literal["TP", "FP", "FN"]


@dataclass(frozen=True)
class JaCAtThreshold:
    """JaC at one threshold.

    Attributes:
        threshold_px: the threshold, pixels.
        jac: ``TP / (TP + FP + FN)``, the official float32 value as a Python float (0 when no class
            is either projected or annotated).
        tp, fp, fn: class counts of the labelling kept.
        classes: class -> ``"TP"``, ``"FP"`` or ``"FN"``, for the labelling kept (mirrored class
            names when :attr:`mirrored`).
        mirrored: True when the mirrored labelling scored strictly better and was kept.
    """

    threshold_px: float
    jac: float
    tp: int
    fp: int
    fn: int
    classes: Mapping[str, Outcome]
    mirrored: bool


@dataclass(frozen=True)
class JaCResult:
    """JaC of one camera against one annotated frame, at several thresholds.

    Attributes:
        width, height: evaluation image size, pixels.
        per_threshold: one :class:`JaCAtThreshold` per requested threshold, in the order asked.
        distances_px: class -> (M,) distance in pixels from each annotated point of that class
            (all its polylines, in order) to the projected polyline, for the classes both annotated
            and projected, direct labelling.
        mirrored_distances_px: the same for the mirrored labelling (keys are mirrored class names).
        projected_classes: classes whose projection reaches the image.
    """

    width: int
    height: int
    per_threshold: tuple[JaCAtThreshold, ...]
    distances_px: Mapping[str, np.ndarray]
    mirrored_distances_px: Mapping[str, np.ndarray]
    projected_classes: frozenset[str]

    @property
    def jac(self) -> dict[float, float]:
        """threshold (px) -> JaC."""
        return {t.threshold_px: t.jac for t in self.per_threshold}

    def at(self, threshold_px: float) -> JaCAtThreshold:
        """The result at ``threshold_px``. Raises KeyError when it was not evaluated."""
        for t in self.per_threshold:
            if t.threshold_px == threshold_px:
                return t
        raise KeyError(f"threshold {threshold_px!r} px was not evaluated; have {list(self.jac)}")


def jac_admitted(jac: float | None, admit_jac_min: float) -> bool:
    """The admission rule (method.md section 4): a calibration whose JaC at the admission's gamma is strictly
    above ``admit_jac_min`` (a fraction in [0, 1]; ``V3D_ADMIT_JAC_MIN``) joins the triangulation; no JaC (a
    refused fit, no lines to judge) never does. The one home of the comparison: stored calibrations
    (``app.services.calibration.admission``), its SQL form, the rig's feed and ISSIA's cameras all call it.

    >>> jac_admitted(0.76, 0.75), jac_admitted(0.75, 0.75), jac_admitted(None, 0.75)
    (True, False, False)
    """
    return jac is not None and jac > admit_jac_min


def point_to_polyline_distances(points: np.ndarray, polyline: np.ndarray) -> np.ndarray:
    """Distance from each point to a polyline, as the evaluator's ``distance_to_polyline``.

    Per segment, the point is projected on the segment's line (homogeneous cross products); when the
    foot falls strictly inside the segment (``0 < k < 1``) the distance to the foot counts,
    otherwise the distance to the nearer end. A one-point polyline gives the distance to that point.
    Degenerate (zero-length) segments fall back to their end points. Same arithmetic as the
    evaluator, one compiled pass over points and segments (:func:`_polyline_distances`).

    Args:
        points: (M, 2) pixels.
        polyline: (K, 2) pixels, K >= 1.

    Returns:
        (M,) distances, pixels.

    Raises:
        ValueError: wrong shapes or an empty polyline.

    >>> point_to_polyline_distances(np.array([[5.0, 3.0], [-4.0, 3.0]]), np.array([[0.0, 0.0], [10.0, 0.0]])).tolist()
    [3.0, 5.0]
    """
    p = np.asarray(points, dtype=float)
    q = np.asarray(polyline, dtype=float)
    if p.ndim != 2 or p.shape[1] != 2:
        raise ValueError(f"points must have shape (M, 2), got {p.shape}")
    if q.ndim != 2 or q.shape[1] != 2 or len(q) == 0:
        raise ValueError(f"polyline must have shape (K, 2) with K >= 1, got {q.shape}")
    if len(q) == 1:
        return np.sqrt(np.square(p[:, 0] - q[0, 0]) + np.square(p[:, 1] - q[0, 1]))
    return _polyline_distances(np.ascontiguousarray(p), np.ascontiguousarray(q))


@njit(cache=True, error_model="numpy", nogil=True)
def _polyline_distances(p: np.ndarray, q: np.ndarray) -> np.ndarray:  # pragma: no cover - compiled
    """:func:`point_to_polyline_distances` of (M, 2) points to a (K, 2) polyline, K >= 2, C-contiguous.

    Each (point, segment) pair is computed with the operations, in the order, of the evaluator's numpy arithmetic
    (no fused or reordered operation: numba's default keeps IEEE semantics), so the distances are equal to the bit;
    the work is the JaC's largest share, and one pass spares the (M, K) temporaries of a few dozen numpy calls. The
    square root is taken once per point, of the smallest squared distance: the square root is correctly rounded and
    monotonic, so ``sqrt(min(x))`` equals ``min(sqrt(x))``. A NaN propagates as numpy's ``minimum`` and ``min`` do.
    """
    ns = q.shape[0] - 1
    ox, oy, ex, ey = q[:-1, 0].copy(), q[:-1, 1].copy(), q[1:, 0].copy(), q[1:, 1].copy()
    # Per segment: its line l = o x e, normalised so that (l0, l1) is a unit normal, and its direction v.
    l0, l1, l2 = np.empty(ns), np.empty(ns), np.empty(ns)
    fz, vx, vy, vv = np.empty(ns), np.empty(ns), np.empty(ns), np.empty(ns)
    m02, m12 = np.empty(ns), np.empty(ns)  # the foot's terms -l0 l2 and l1 l2
    for s in range(ns):
        a0, a1, a2 = oy[s] - ey[s], ex[s] - ox[s], ox[s] * ey[s] - oy[s] * ex[s]
        n = np.sqrt(a0 * a0 + a1 * a1)
        l0[s], l1[s], l2[s] = a0 / n, a1 / n, a2 / n
        fz[s] = l1[s] * l1[s] + l0[s] * l0[s]
        m02[s], m12[s] = -l0[s] * l2[s], l1[s] * l2[s]
        vx[s], vy[s] = ex[s] - ox[s], ey[s] - oy[s]
        vv[s] = vx[s] * vx[s] + vy[s] * vy[s]
    out = np.empty(p.shape[0])
    for i in range(p.shape[0]):
        px, py = p[i, 0], p[i, 1]
        best = np.inf
        for s in range(ns):
            # Foot of the perpendicular: ((l0, l1, 0) x p) x l, dehomogenised; k its place along the segment.
            c2 = l0[s] * py - l1[s] * px
            fx = (m02[s] - c2 * l1[s]) / fz[s]
            fy = (c2 * l0[s] - m12[s]) / fz[s]
            k = ((fx - ox[s]) * vx[s] + (fy - oy[s]) * vy[s]) / vv[s]
            if k > 0 and k < 1:
                d2 = (fx - px) * (fx - px) + (fy - py) * (fy - py)
            else:
                d_o = (px - ox[s]) * (px - ox[s]) + (py - oy[s]) * (py - oy[s])
                d_e = (px - ex[s]) * (px - ex[s]) + (py - ey[s]) * (py - ey[s])
                d2 = d_o if (d_o < d_e or d_o != d_o) else d_e  # numpy's minimum: NaN if either is
            if d2 < best or d2 != d2:
                best = d2
                if d2 != d2:
                    break  # numpy's min: NaN once any is
        out[i] = np.sqrt(best)
    return out


def gamma_thresholds(width: float, height: float, gammas: Iterable[float] = JAC_GAMMAS) -> tuple[float, ...]:
    """Thresholds in pixels for JaC@gamma: ``gamma * sqrt(W^2 + H^2)`` (method.md section 4).

    Raises:
        ValueError: a gamma that is not a positive finite number.

    >>> [round(t, 2) for t in gamma_thresholds(960, 540)]
    [5.51, 11.01, 22.03]
    """
    out: list[float] = []
    for g in gammas:
        if isinstance(g, bool) or not isinstance(g, numbers.Real) or not (math.isfinite(g) and g > 0):
            raise ValueError(f"gamma must be a positive fraction of the image diagonal, got {g!r}")
        out.append(float(g) * image_diagonal(width, height))
    return tuple(out)


def _points_by_class(lines: FieldLines) -> dict[str, np.ndarray]:
    """Annotated points per class, all polylines of a class stacked; classes without points dropped
    (the evaluator's ``scale_points`` drops them)."""
    if not isinstance(lines, Mapping):
        raise AnnotationError("lines must be a mapping class -> list of (N, 2) pixel arrays")
    out: dict[str, np.ndarray] = {}
    for cls, polys in lines.items():
        if cls not in MIRROR_CLASSES:
            raise AnnotationError(f"lines: unknown line class {cls!r}")
        arrays = [np.asarray(p, dtype=float) for p in polys]
        for i, a in enumerate(arrays):
            if a.size and a.shape != (2,) and (a.ndim != 2 or a.shape[1] != 2):
                raise AnnotationError(f"lines, class {cls!r}, polyline {i}: expected (N, 2) pixels, "
                                      f"got shape {a.shape}")
        arrays = [a.reshape(-1, 2) for a in arrays]
        pts = np.concatenate(arrays, axis=0) if arrays else np.zeros((0, 2))
        if not np.all(np.isfinite(pts)):
            raise AnnotationError(f"lines, class {cls!r}: coordinates must be finite")
        if len(pts):
            out[cls] = pts
    return out


def _class_distances(projected: Mapping[str, np.ndarray], annotated: Mapping[str, np.ndarray]) -> dict[str, np.ndarray]:
    return {cls: point_to_polyline_distances(pts, projected[cls]) for cls, pts in annotated.items() if cls in projected}


def _score(projected: frozenset[str], annotated: Iterable[str], worst: Mapping[str, float],
           threshold: float) -> tuple[np.float32, dict[str, Outcome]]:
    """Official confusion counts at one threshold; ``worst`` is each common class's largest
    point distance (all points ``< threshold`` <=> the largest one is)."""
    annotated = set(annotated)
    classes: dict[str, Outcome] = {}
    for cls in projected - annotated:
        classes[cls] = "FP"
    for cls in annotated - projected:
        classes[cls] = "FN"
    for cls, d in worst.items():
        classes[cls] = "TP" if d < threshold else "FP"
    tp = sum(v == "TP" for v in classes.values())
    total = np.float32(len(classes))
    jac = np.float32(tp) / total if total > 0 else np.float32(0.0)
    return jac, classes


def _check_thresholds(thresholds_px: Sequence[float]) -> tuple[float, ...]:
    out: list[float] = []
    for t in thresholds_px:
        if isinstance(t, bool) or not isinstance(t, numbers.Real) or not (math.isfinite(t) and t > 0):
            raise ValueError(f"thresholds_px must hold positive finite pixel distances, got {t!r}")
        out.append(float(t))
    if not out:
        raise ValueError("thresholds_px must hold at least one threshold")
    return tuple(out)


def evaluate_jac(camera: Camera, lines: FieldLines, width: int, height: int,
                 thresholds_px: Sequence[float] = OFFICIAL_THRESHOLDS_PX) -> JaCResult:
    """JaC of ``camera`` against the annotated field lines of one frame, as the official evaluator.

    Args:
        camera: the camera, expressed at ``width`` x ``height``.
        lines: annotated field lines, pixels of the ``width`` x ``height`` image; a class may hold
            several polylines (their points are pooled, as the evaluator holds one point list per
            class). "Goal unknown" / "Line unknown" have no model element: they count as false
            negatives, as in the evaluator.
        width, height: evaluation image size, pixels.
        thresholds_px: distance thresholds, pixels (strict ``<``).

    Returns:
        :class:`JaCResult`.

    Raises:
        AnnotationError: an unknown class, a polyline that is not (N, 2) or non-finite coordinates
            in ``lines``.
        ValueError: a threshold that is not a positive finite number, bad image size.
    """
    thresholds = _check_thresholds(thresholds_px)
    annotated = _points_by_class(lines)
    projected = {cls: runs[0] for cls, runs in project_pitch_polylines(
        camera, width, height, EVALUATOR_DIST_M, EVALUATOR_DIST_CIRCLES_M, mode="evaluator").items()}
    projected_classes = frozenset(projected)
    mirrored = {MIRROR_CLASSES[cls]: pts for cls, pts in annotated.items()}
    d_direct = _class_distances(projected, annotated)
    d_mirror = _class_distances(projected, mirrored)
    worst_direct = {cls: float(d.max()) for cls, d in d_direct.items()}
    worst_mirror = {cls: float(d.max()) for cls, d in d_mirror.items()}
    results = []
    for t in thresholds:
        jac1, classes1 = _score(projected_classes, annotated, worst_direct, t)
        jac2, classes2 = _score(projected_classes, mirrored, worst_mirror, t)
        use_mirror = bool(jac2 > jac1)
        jac, classes = (jac2, classes2) if use_mirror else (jac1, classes1)
        counts = {o: sum(v == o for v in classes.values()) for o in ("TP", "FP", "FN")}
        results.append(JaCAtThreshold(threshold_px=t, jac=float(jac), tp=counts["TP"], fp=counts["FP"],
                                      fn=counts["FN"], classes=MappingProxyType(classes), mirrored=use_mirror))
    return JaCResult(width=int(width), height=int(height), per_threshold=tuple(results),
                     distances_px=MappingProxyType(d_direct), mirrored_distances_px=MappingProxyType(d_mirror),
                     projected_classes=projected_classes)


def jac_at_gammas(camera: Camera, lines: FieldLines, width: int, height: int,
                  gammas: Sequence[float] = JAC_GAMMAS) -> dict[float, float]:
    """JaC@gamma: JaC with threshold ``gamma * image diagonal`` (SoccerNet-v3D, method.md section 4).

    Args:
        camera: the camera, expressed at ``width`` x ``height``.
        lines: annotated field lines, pixels of that image.
        width, height: the frame's own resolution, pixels.
        gammas: fractions of the diagonal (default 0.5 %, 1 %, 2 %).

    Returns:
        gamma -> JaC in [0, 1].

    Raises:
        AnnotationError, ValueError: as :func:`evaluate_jac`; ValueError for a non-positive gamma.
    """
    gammas = tuple(gammas)
    result = evaluate_jac(camera, lines, width, height, gamma_thresholds(width, height, gammas))
    return {float(g): t.jac for g, t in zip(gammas, result.per_threshold, strict=True)}
