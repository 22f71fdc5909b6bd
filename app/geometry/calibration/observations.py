"""Annotated field lines paired with their pitch-model elements, as flat arrays for the solver.

Every annotated point becomes one scalar residual against the model element of its class: a 3D
straight segment (side lines, box lines, middle line, goal posts and crossbars, which stand off the
ground plane) or a ground circle (central circle, penalty arcs). Keeping the points in flat arrays
with an element index per point lets :mod:`app.geometry.calibration.residuals` evaluate all of them
in a few vectorised numpy operations.

World frame: SoccerNet (metres, origin at the centre spot, z down). Image: pixels of the frame.
"""
from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np

from app.geometry.annotations import FieldLines
from app.geometry.pitch import CIRCLES, GOAL_CLASSES, KEY_POINTS, LINE_EXTREMITY_KEYS, UNKNOWN_CLASSES

#: Circle classes (their model is a ground circle, not a segment).
CIRCLE_CLASSES: frozenset[str] = frozenset(CIRCLES)


@dataclass(frozen=True)
class Observations:
    """Annotated points of one frame with their model elements.

    Attributes:
        seg_classes: (S,) class of each straight element that is annotated.
        seg_a, seg_b: (S, 3) world end points of those elements, metres.
        seg_points: (N, 2) annotated pixels on straight elements.
        seg_index: (N,) index into ``seg_classes`` of each point.
        seg_weight: (N,) residual weight of each point (see :func:`build_observations`).
        circle_classes: (Q,) annotated circle classes.
        circle_centre: (Q, 2) world centre (x, y) on the ground, metres; radius in ``circle_radius`` (Q,).
        circle_points, circle_index, circle_weight: as for segments, (M, 2), (M,), (M,).
    """

    seg_classes: tuple[str, ...]
    seg_a: np.ndarray
    seg_b: np.ndarray
    seg_points: np.ndarray
    seg_index: np.ndarray
    seg_weight: np.ndarray
    circle_classes: tuple[str, ...]
    circle_centre: np.ndarray
    circle_radius: np.ndarray
    circle_points: np.ndarray
    circle_index: np.ndarray
    circle_weight: np.ndarray

    @cached_property
    def seg_ah_t(self) -> np.ndarray:
        """(4, S) homogeneous start points of the straight elements, as columns."""
        return np.vstack([self.seg_a.T, np.ones(len(self.seg_a))])

    @cached_property
    def seg_bh_t(self) -> np.ndarray:
        """(4, S) homogeneous end points of the straight elements, as columns."""
        return np.vstack([self.seg_b.T, np.ones(len(self.seg_b))])

    @cached_property
    def circle_conics(self) -> np.ndarray:
        """(Q, 3, 3) ground conics ``Q`` of the circles: ``(x, y, 1) Q (x, y, 1)^T = 0`` on the circle."""
        cx, cy, r = self.circle_centre[:, 0], self.circle_centre[:, 1], self.circle_radius
        q = np.zeros((len(r), 3, 3))
        q[:, 0, 0] = q[:, 1, 1] = 1.0
        q[:, 0, 2] = q[:, 2, 0] = -cx
        q[:, 1, 2] = q[:, 2, 1] = -cy
        q[:, 2, 2] = cx * cx + cy * cy - r * r
        return q

    @cached_property
    def all_points(self) -> np.ndarray:
        """(N + M, 2) straight-element points then circle points, pixels."""
        return np.concatenate([self.seg_points, self.circle_points])

    @cached_property
    def circle_point_cx(self) -> np.ndarray:
        """(M,) world x of the centre of each circle point's circle, metres."""
        return self.circle_centre[self.circle_index, 0] if len(self.circle_index) else np.zeros(0)

    @cached_property
    def circle_point_cy(self) -> np.ndarray:
        """(M,) world y of the centre of each circle point's circle, metres."""
        return self.circle_centre[self.circle_index, 1] if len(self.circle_index) else np.zeros(0)

    @cached_property
    def circle_point_k(self) -> np.ndarray:
        """(M,) ``cx^2 + cy^2 - r^2`` of each circle point's circle (last entry of its conic), m^2."""
        if not len(self.circle_index):
            return np.zeros(0)
        c, r = self.circle_centre[self.circle_index], self.circle_radius[self.circle_index]
        return c[:, 0] ** 2 + c[:, 1] ** 2 - r**2

    @cached_property
    def kernel_arrays(self) -> tuple[np.ndarray, ...]:
        """The arrays the compiled residuals read (:mod:`.residuals`), C-contiguous float64 (the index
        int64): ``(seg_a, seg_b, seg_index, seg_points, seg_weight, circle_point_cx, circle_point_cy,
        circle_point_k, circle_points, circle_weight)``."""
        def f(a):
            return np.ascontiguousarray(a, dtype=np.float64)
        return (f(self.seg_a.reshape(-1, 3)), f(self.seg_b.reshape(-1, 3)),
                np.ascontiguousarray(self.seg_index, dtype=np.int64), f(self.seg_points.reshape(-1, 2)),
                f(self.seg_weight), f(self.circle_point_cx), f(self.circle_point_cy), f(self.circle_point_k),
                f(self.circle_points.reshape(-1, 2)), f(self.circle_weight))

    @cached_property
    def ground_points(self) -> np.ndarray:
        """(G, 2) annotated pixels of ground elements (straight ones but goal posts and crossbars, then
        circles), C-contiguous."""
        goal = np.array([c in GOAL_CLASSES for c in self.seg_classes], dtype=bool)
        keep = ~goal[self.seg_index] if len(self.seg_points) else np.zeros(0, bool)
        return np.ascontiguousarray(np.concatenate([self.seg_points[keep], self.circle_points]).reshape(-1, 2),
                                    dtype=np.float64)

    @property
    def n_points(self) -> int:
        """Number of annotated points used (straight and circular)."""
        return len(self.seg_points) + len(self.circle_points)

    @property
    def classes(self) -> tuple[str, ...]:
        """Every annotated class with a model element."""
        return self.seg_classes + self.circle_classes

    def constraint_count(self) -> int:
        """Independent scalar constraints the labels give on a camera, counted per element.

        A straight element seen at two distinct points or more fixes its image line (2), one point
        gives 1; a circle gives min(points, 5) (a conic has five degrees of freedom).
        """
        n = 0
        for i in range(len(self.seg_classes)):
            pts = self.seg_points[self.seg_index == i]
            n += min(2, _distinct(pts))
        for i in range(len(self.circle_classes)):
            n += min(5, _distinct(self.circle_points[self.circle_index == i]))
        return n

    def ground_line_directions(self) -> tuple[int, int]:
        """Number of annotated ground (z = 0) straight elements along world x and along world y."""
        nx = ny = 0
        for c, a, b in zip(self.seg_classes, self.seg_a, self.seg_b, strict=True):
            if c in GOAL_CLASSES:
                continue
            if abs(b[0] - a[0]) > abs(b[1] - a[1]):
                nx += 1
            else:
                ny += 1
        return nx, ny


def _distinct(pts: np.ndarray, tol_px: float = 1.0) -> int:
    if len(pts) == 0:
        return 0
    span = np.linalg.norm(pts - pts[0], axis=1)
    return 1 if span.max() < tol_px else len(pts)


def class_weights(counts: dict[str, int], points_per_class: float = 4.0) -> dict[str, float]:
    """Per-point weight so that a class counts like at most ``points_per_class`` points.

    JaC judges a class as a whole (all its points must be close), so a circle drawn with 30 points
    must not outweigh a side line drawn with 2. Weight ``sqrt(min(1, k / n))`` on a squared residual
    gives a class of ``n > k`` points the total weight of ``k`` points.
    """
    return {c: float(np.sqrt(min(1.0, points_per_class / max(n, 1)))) for c, n in counts.items()}


def build_observations(lines: FieldLines) -> Observations:
    """Pair every annotated point with the model element of its class.

    Classes without a model element ("Line unknown", "Goal unknown") are skipped.

    Args:
        lines: :data:`~app.geometry.annotations.FieldLines`, pixels.

    Returns:
        :class:`Observations` (arrays may be empty).

    >>> obs = build_observations({"Middle line": [np.array([[480.0, 0.0], [470.0, 539.0]])]})
    >>> obs.seg_classes, obs.seg_a.tolist(), obs.n_points
    (('Middle line',), [[0.0, -34.0, 0.0]], 2)
    """
    seg_classes: list[str] = []
    circle_classes: list[str] = []
    seg_pts: list[np.ndarray] = []
    seg_idx: list[np.ndarray] = []
    cir_pts: list[np.ndarray] = []
    cir_idx: list[np.ndarray] = []
    counts = {c: sum(len(p) for p in polys) for c, polys in lines.items()}
    weights = class_weights(counts)
    seg_w: list[np.ndarray] = []
    cir_w: list[np.ndarray] = []
    for cls in sorted(lines):
        if cls in UNKNOWN_CLASSES or counts[cls] == 0:
            continue
        pts = np.concatenate([np.asarray(p, dtype=float).reshape(-1, 2) for p in lines[cls]])
        if cls in CIRCLE_CLASSES:
            cir_idx.append(np.full(len(pts), len(circle_classes)))
            circle_classes.append(cls)
            cir_pts.append(pts)
            cir_w.append(np.full(len(pts), weights[cls]))
        elif cls in LINE_EXTREMITY_KEYS:
            seg_idx.append(np.full(len(pts), len(seg_classes)))
            seg_classes.append(cls)
            seg_pts.append(pts)
            seg_w.append(np.full(len(pts), weights[cls]))
        else:  # pragma: no cover - LINE_CLASSES and the model are kept in step by pitch.py
            raise KeyError(f"line class {cls!r} has no model element")

    def cat(parts: list[np.ndarray], shape: tuple[int, ...], dtype: type = float) -> np.ndarray:
        return np.concatenate(parts).astype(dtype) if parts else np.zeros(shape, dtype=dtype)

    return Observations(
        seg_classes=tuple(seg_classes),
        seg_a=np.array([KEY_POINTS[LINE_EXTREMITY_KEYS[c][0]] for c in seg_classes]).reshape(-1, 3),
        seg_b=np.array([KEY_POINTS[LINE_EXTREMITY_KEYS[c][1]] for c in seg_classes]).reshape(-1, 3),
        seg_points=cat(seg_pts, (0, 2)),
        seg_index=cat(seg_idx, (0,), int),
        seg_weight=cat(seg_w, (0,)),
        circle_classes=tuple(circle_classes),
        circle_centre=np.array([CIRCLES[c][0][:2] for c in circle_classes]).reshape(-1, 2),
        circle_radius=np.array([CIRCLES[c][1] for c in circle_classes], dtype=float),
        circle_points=cat(cir_pts, (0, 2)),
        circle_index=cat(cir_idx, (0,), int),
        circle_weight=cat(cir_w, (0,)),
    )
