"""Epipolar geometry across the play volume: where a label's ray lies inside the volume a ball can occupy,
the segment another view's ray draws in a view, a label's distance to it (a pair too poorly conditioned to
triangulate is judged so), and the single-view ball a box implies.
"""
from __future__ import annotations

import math

import numpy as np

from app.geometry.ball import ball_from_box_exact
from app.geometry.camera import Camera
from app.geometry.doubts.contract import DoubtSettings, DoubtView, _inside
from app.geometry.weighting import camera_of, centre_of, label_centre, project_point, ray_at_height, rule_scale


def _sees(v: DoubtView, ball: np.ndarray) -> bool:
    """The view shows the ball: it has a ball label, or the ball projects inside its image (a camera at
    the same place that looks elsewhere is another shot, not a duplicate)."""
    if label_centre(v) is not None:
        return True
    uv = project_point(v, ball)
    return uv is not None and _inside(v, uv, 0.0)


def _single_view_ball(v: DoubtView, s: DoubtSettings) -> tuple[np.ndarray | None, str]:
    """The ball one labelled view places: on the grass along its ray when the box size agrees (most
    balls are on the ground), else at the monocular estimate (method.md section 6, exact silhouette);
    a point label goes on the grass. Returns (point or None, how it was placed)."""
    c = centre_of(v)
    ray = camera_of(v).rays(c.reshape(1, 2))[0]
    grass = ray_at_height(camera_of(v).C, ray, -s.ball_diameter_m / 2)
    mono = _mono(v, s)
    if mono is None:
        return grass, "grass"
    if grass is not None:
        ratio = np.linalg.norm(mono - camera_of(v).C) / np.linalg.norm(grass - camera_of(v).C)
        if abs(ratio - 1.0) <= s.ground_box_tolerance:
            return grass, "grass"
    return mono, "box"


def _mono(v: DoubtView, s: DoubtSettings) -> np.ndarray | None:
    """The monocular ball of the view's box (method.md section 6, exact silhouette), world metres, or None
    without a box or where the camera cannot place it (a badly distorted camera far outside its valid field)."""
    if v.box is None:
        return None
    try:
        with np.errstate(all="ignore"):
            mono = ball_from_box_exact(camera_of(v), np.asarray(v.box, float), s.ball_diameter_m)[0]
    except (ValueError, np.linalg.LinAlgError):
        return None
    return mono if np.all(np.isfinite(mono)) else None


def ray_in_play_volume(camera: Camera, pixel: np.ndarray, s: DoubtSettings) -> tuple[float, float] | None:
    """The depths ``t`` (metres along the unit ray from the camera centre) at which the ball seen at
    ``pixel`` would lie in the play volume (``s.play_volume``, :class:`app.geometry.pitch.PlayVolume`), at least 1 m in
    front of the
    camera: ``(t_near, t_far)``, or None when the ray never enters it (slab intersection of the ray with
    the volume's box)."""
    ray = camera.rays(np.asarray(pixel, float).reshape(1, 2))[0]
    C = camera.C
    lo, hi = s.play_volume.bounds()
    t0, t1 = 1.0, math.inf
    for k in range(3):
        if abs(ray[k]) < 1e-12:
            if not lo[k] <= C[k] <= hi[k]:
                return None
            continue
        a, b = (lo[k] - C[k]) / ray[k], (hi[k] - C[k]) / ray[k]
        t0, t1 = max(t0, min(a, b)), min(t1, max(a, b))
    return (float(t0), float(t1)) if t0 < t1 else None


def _segment(labelled: DoubtView, other: DoubtView, s: DoubtSettings, samples: int = 64,
             by_box: bool = False) -> tuple[np.ndarray, np.ndarray] | None:
    """The labelled view's ball ray across the play volume (:func:`ray_in_play_volume`), seen in
    ``other``: ``(world points (N, 3), pixels (N, 2) of other, NaN where behind its camera)``, ``samples``
    points evenly spread in depth; None when the ray misses the volume. ``by_box``: only the depths
    the view's box size allows (the monocular depth, method.md section 6, within ``ground_box_tolerance``
    of it), for a box label."""
    span = ray_in_play_volume(camera_of(labelled), centre_of(labelled), s)
    if span is None:
        return None
    ray = camera_of(labelled).rays(centre_of(labelled).reshape(1, 2))[0]
    mono = _mono(labelled, s) if by_box else None
    if mono is not None:  # the box's size bounds the depth (boxes err by ~20 % in size)
        d = float(np.linalg.norm(mono - camera_of(labelled).C))
        span = (max(span[0], d * (1 - s.ground_box_tolerance)), min(span[1], d * (1 + s.ground_box_tolerance)))
        if span[0] >= span[1]:
            return None
    t = np.linspace(span[0], span[1], samples)
    pts = camera_of(labelled).C + t[:, None] * ray
    uv, ok = camera_of(other).project(pts)
    uv = np.where(ok[:, None], uv, np.nan)
    return pts, uv


def _polyline_distance(uv: np.ndarray, p: np.ndarray) -> tuple[float, int]:
    """Distance (px) from ``p`` to the polyline ``uv`` (N, 2; NaN rows break it) and the index of the
    nearest vertex; ``(inf, -1)`` without a finite segment."""
    a, b = uv[:-1], uv[1:]
    ok = np.isfinite(a).all(1) & np.isfinite(b).all(1)
    if not ok.any():
        return math.inf, -1
    a, b = a[ok], b[ok]
    ab = b - a
    L = np.maximum(np.sum(ab * ab, axis=1), 1e-12)
    t = np.clip(np.sum((p - a) * ab, axis=1) / L, 0.0, 1.0)
    d = np.linalg.norm(a + t[:, None] * ab - p, axis=1)
    k = int(np.argmin(d))
    idx = np.flatnonzero(ok)[k] + (1 if t[k] > 0.5 else 0)
    return float(d[k]), int(idx)


def epipolar_pair_error(a: DoubtView, b: DoubtView, s: DoubtSettings) -> float | None:
    """How far (px at 1920 width) two labelled views are from seeing one ball the game could hold: the
    smaller of the two distances from a view's label to the other view's ball ray across the play
    volume, seen in it (its epipolar segment). It needs no triangulation, so it judges pairs of any
    conditioning: a near-duplicate pair (the rays nearly parallel, no depth) and a pair whose rays meet
    only under the grass are tested as well as a wide one. ``inf`` when a ray misses the play volume;
    None when neither segment is seen by the other camera."""
    best: float | None = None
    for x, y in ((a, b), (b, a)):
        seg = _segment(x, y, s)
        if seg is None:
            return math.inf
        d, _ = _polyline_distance(seg[1], centre_of(y))
        if math.isfinite(d):
            d *= rule_scale(y, s)
            best = d if best is None else min(best, d)
    return best
