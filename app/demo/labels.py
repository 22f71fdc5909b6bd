"""Annotations of the demo frames, made the way SoccerNet-v3 annotators make them.

* Field lines: for each pitch element visible in the image, a few points of its projected model
  (straight lines: the two ends of the visible part and a point or two between them; circles:
  several points along each visible arc), moved by about 1 px (at 1920 px wide) across the line.
* Ball boxes: loose, as the real labels are (mean IoU near 0.6 and size error near 20 % against the
  precise box of the exact ball image, paper Table "bboxopt"), rounded to whole pixels.
* Player boxes: the figure's extent to within a pixel or two.

Pixels: continuous coordinates, origin at the top-left corner of the image, of the image's own
resolution. World: SoccerNet frame (metres, z down).
"""
from __future__ import annotations

from typing import Mapping

import numpy as np

from app.geometry import metrics
from app.geometry.camera import Camera
from app.geometry.pitch import GOAL_CLASSES, LINE_CLASSES

#: Sigma (px at 1920 px wide) of the annotators' click noise across the line, truncated at 1.5 sigma.
LINE_SIGMA_PX_AT_1920 = 1.0
#: A visible piece shorter than this (px at 1920 px wide) is not annotated.
MIN_VISIBLE_PX_AT_1920 = 10.0

#: Loose ball boxes: log size factor ~ N(bias, sigma), log aspect ~ N(0, aspect), centre offset
#: ~ N(0, centre * diameter) per axis. Chosen so that against the precise box the mean IoU is about
#: 0.6 and the mean size error about 20 % (measured by ``tests/demo``).
BALL_BOX_NOISE: Mapping[str, float] = {"size_bias": 0.10, "size_sigma": 0.19, "aspect_sigma": 0.08,
                                       "centre_sigma": 0.14, "min_size_px": 3.0}


def clip_segments_to_rect(p0: np.ndarray, p1: np.ndarray, width: float, height: float
                          ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Clip segments to the rectangle ``[0, width] x [0, height]`` (Liang-Barsky, vectorised).

    Args:
        p0, p1: (N, 2) segment ends, pixels.
        width, height: rectangle size, pixels.

    Returns:
        ``(t0, t1, keep)``: (N,) parameters of the clipped part ``p0 + t (p1 - p0)``, t in [0, 1],
        and (N,) bool, False where the segment misses the rectangle.

    >>> t0, t1, keep = clip_segments_to_rect(np.array([[-10.0, 5.0]]), np.array([[10.0, 5.0]]), 20, 20)
    >>> float(t0[0]), float(t1[0]), bool(keep[0])
    (0.5, 1.0, True)
    """
    d = p1 - p0
    t0 = np.zeros(len(p0))
    t1 = np.ones(len(p0))
    keep = np.ones(len(p0), dtype=bool)
    for p, q in ((-d[:, 0], p0[:, 0]), (d[:, 0], width - p0[:, 0]),
                 (-d[:, 1], p0[:, 1]), (d[:, 1], height - p0[:, 1])):
        parallel = p == 0
        keep &= ~(parallel & (q < 0))
        with np.errstate(divide="ignore", invalid="ignore"):
            r = np.where(parallel, 0.0, q / np.where(parallel, 1.0, p))
        t0 = np.where(~parallel & (p < 0), np.maximum(t0, r), t0)
        t1 = np.where(~parallel & (p > 0), np.minimum(t1, r), t1)
    keep &= t0 <= t1
    return t0, t1, keep


def visible_runs(uv: np.ndarray, in_front: np.ndarray, width: float, height: float) -> list[np.ndarray]:
    """Pieces of a projected polyline that lie inside ``[0, width] x [0, height]``.

    A piece that leaves the image ends exactly on the border; points behind the camera break the
    polyline.

    Args:
        uv: (N, 2) projected points, pixels (NaN allowed where ``in_front`` is False).
        in_front: (N,) bool, the point is in front of the camera.
        width, height: clipping rectangle, pixels.

    Returns:
        List of (M, 2) pixel polylines, M >= 2.
    """
    if len(uv) < 2:
        return []
    ok = in_front[:-1] & in_front[1:]
    p0, p1 = uv[:-1], uv[1:]
    safe0, safe1 = np.where(ok[:, None], p0, 0.0), np.where(ok[:, None], p1, 0.0)
    t0, t1, keep = clip_segments_to_rect(safe0, safe1, width, height)
    keep &= ok
    idx = np.flatnonzero(keep)
    if len(idx) == 0:
        return []
    a = safe0[idx] + t0[idx, None] * (safe1[idx] - safe0[idx])
    b = safe0[idx] + t1[idx, None] * (safe1[idx] - safe0[idx])
    # A kept segment continues the previous run when it is the next segment, the previous one
    # reached its end point and this one starts at its start point (no border crossing between).
    joined = np.zeros(len(idx), dtype=bool)
    joined[1:] = (np.diff(idx) == 1) & (t1[idx[:-1]] == 1.0) & (t0[idx[1:]] == 0.0)
    starts = np.flatnonzero(~joined)
    ends = np.append(starts[1:], len(idx))
    return [np.vstack([a[s:s + 1], b[s:e]]) for s, e in zip(starts, ends, strict=True)]


def polyline_length(points: np.ndarray) -> float:
    """Length of an (N, 2) polyline, same unit as the points."""
    return float(np.sum(np.linalg.norm(np.diff(points, axis=0), axis=1))) if len(points) > 1 else 0.0


def _resample(run: np.ndarray, fractions: np.ndarray) -> np.ndarray:
    """Points at the given fractions (0..1) of a polyline's arc length."""
    seg = np.linalg.norm(np.diff(run, axis=0), axis=1)
    s = np.concatenate([[0.0], np.cumsum(seg)])
    target = fractions * s[-1]
    return np.stack([np.interp(target, s, run[:, 0]), np.interp(target, s, run[:, 1])], axis=1)


def _normals(run: np.ndarray, fractions: np.ndarray) -> np.ndarray:
    """Unit normals of a polyline at the given arc-length fractions."""
    eps = 1e-3
    a = _resample(run, np.clip(fractions - eps, 0, 1))
    b = _resample(run, np.clip(fractions + eps, 0, 1))
    t = b - a
    t /= np.maximum(np.linalg.norm(t, axis=1, keepdims=True), 1e-12)
    return np.stack([-t[:, 1], t[:, 0]], axis=1)


def annotate_field_lines(camera: Camera, model: Mapping[str, np.ndarray], width: int, height: int,
                         rng: np.random.Generator) -> list[tuple[str, np.ndarray]]:
    """Field-line labels of one frame, as a SoccerNet-v3 annotator would click them.

    Args:
        camera: true camera of the frame, at the frame's resolution.
        model: class -> (N, 3) densely sampled model polyline (world metres), e.g.
            ``sample_pitch_polylines(0.1, 0.1)``.
        width, height: image size, pixels.
        rng: random generator.

    Returns:
        List of ``(class, (K, 2) pixels)`` in SoccerNet's class order; a class cut into several
        visible pieces appears once per piece. Points lie within ``[0, W - 1] x [0, H - 1]``.
    """
    scale = width / 1920.0
    sigma = LINE_SIGMA_PX_AT_1920 * scale
    min_len = MIN_VISIBLE_PX_AT_1920 * scale
    out: list[tuple[str, np.ndarray]] = []
    for cls in LINE_CLASSES:
        if cls not in model:
            continue
        uv, ok = camera.project(model[cls])
        for run in visible_runs(uv, ok, width - 1.0, height - 1.0):
            if polyline_length(run) < min_len:
                continue
            if cls.startswith("Circle"):
                n = int(np.clip(polyline_length(run) / (60.0 * scale), 4, 12))
                fr = np.linspace(0.0, 1.0, n)
                fr[1:-1] += rng.uniform(-0.3, 0.3, n - 2) / (n - 1)
            else:
                extra = int(rng.integers(0, 3)) if cls not in GOAL_CLASSES else 0
                fr = np.concatenate([[0.0], np.sort(rng.uniform(0.15, 0.85, extra)), [1.0]])
            pts = _resample(run, fr)
            noise = np.clip(rng.normal(0.0, sigma, len(fr)), -1.5 * sigma, 1.5 * sigma)
            pts = pts + _normals(run, fr) * noise[:, None]
            pts = np.clip(pts, [0.0, 0.0], [width - 1.0, height - 1.0])
            out.append((cls, pts))
    return out


def box_iou(a: np.ndarray, b: np.ndarray) -> float:
    """IoU of two boxes ``[x1, y1, x2, y2]`` (pixels): ``app.geometry.metrics.box_iou`` as a float."""
    return float(metrics.box_iou(np.asarray(a, dtype=float), np.asarray(b, dtype=float)))


def box_size_error(box: np.ndarray, reference: np.ndarray) -> float:
    """``|diag(box) - diag(reference)| / diag(reference)`` as a fraction (method.md section 8):
    ``app.geometry.metrics.box_size_error_pct`` / 100."""
    return float(metrics.box_size_error_pct(np.asarray(box, dtype=float), np.asarray(reference, dtype=float))) / 100.0


def loose_ball_box(precise: np.ndarray, width: int, height: int, rng: np.random.Generator) -> np.ndarray:
    """A ball box as a hurried annotator draws it around the precise box.

    Args:
        precise: ``[x1, y1, x2, y2]`` tight box of the exact ball image, pixels.
        width, height: image size (the box is kept inside it).
        rng: random generator.

    Returns:
        ``[x1, y1, x2, y2]`` whole pixels, at least ``min_size_px`` wide and high, inside the image.
    """
    nz = BALL_BOX_NOISE
    cx, cy = (precise[0] + precise[2]) / 2, (precise[1] + precise[3]) / 2
    d = float(np.mean([precise[2] - precise[0], precise[3] - precise[1]]))
    size = d * float(np.exp(rng.normal(nz["size_bias"], nz["size_sigma"])))
    aspect = float(np.exp(rng.normal(0.0, nz["aspect_sigma"])))
    w = max(nz["min_size_px"], size * np.sqrt(aspect))
    h = max(nz["min_size_px"], size / np.sqrt(aspect))
    cx += rng.normal(0.0, nz["centre_sigma"] * d)
    cy += rng.normal(0.0, nz["centre_sigma"] * d)
    return _int_box(cx - w / 2, cy - h / 2, cx + w / 2, cy + h / 2, width, height)


def _int_box(x1: float, y1: float, x2: float, y2: float, width: int, height: int) -> np.ndarray:
    x1, y1 = int(np.clip(np.round(x1), 0, width - 2)), int(np.clip(np.round(y1), 0, height - 2))
    x2, y2 = int(np.clip(np.round(x2), x1 + 1, width - 1)), int(np.clip(np.round(y2), y1 + 1, height - 1))
    return np.array([x1, y1, x2, y2], dtype=float)


def misplaced_ball_box(box: np.ndarray, width: int, height: int, rng: np.random.Generator,
                       avoid: np.ndarray) -> np.ndarray:
    """The same box moved to a wrong spot: 15-30 % of the image width away from ``avoid`` (the
    true ball centre, pixels), inside the lower two thirds of the image (where the grass is)."""
    w, h = box[2] - box[0], box[3] - box[1]
    for _ in range(100):
        ang = rng.uniform(0, 2 * np.pi)
        r = rng.uniform(0.15, 0.3) * width
        c = avoid + r * np.array([np.cos(ang), np.sin(ang)])
        if w < c[0] < width - w and height / 3 < c[1] < height - h:
            break
    return _int_box(c[0] - w / 2, c[1] - h / 2, c[0] + w / 2, c[1] + h / 2, width, height)


def jitter_box(box: np.ndarray, width: int, height: int, rng: np.random.Generator) -> np.ndarray | None:
    """A player box as annotated: the figure's extent moved by about 1 px (at 1920) per side, clipped
    to the image and rounded; None when less than half of the figure is inside the image or the
    visible part is under 8 px high."""
    sigma = 1.5 * width / 1920.0
    b = box + rng.normal(0.0, sigma, 4)
    area = (b[2] - b[0]) * (b[3] - b[1])
    c = np.array([max(b[0], 0), max(b[1], 0), min(b[2], width - 1), min(b[3], height - 1)])
    if c[2] <= c[0] or c[3] <= c[1] or (c[2] - c[0]) * (c[3] - c[1]) < 0.5 * area or c[3] - c[1] < 8:
        return None
    return _int_box(c[0], c[1], c[2], c[3], width, height)
