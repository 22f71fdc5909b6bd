"""The pitch model projected into an image and clipped to it.

One function, :func:`project_pitch_polylines`, serves two callers:

* the UI and the services (``mode="clip"``): every pitch element becomes the list of its pieces that
  lie inside the image, each piece ending exactly on the image border where the element leaves the
  image, in float64 pixels;
* JaC (``mode="evaluator"``): the polyline SoccerNet's official evaluator builds
  (``get_polylines`` in ``src/evaluate_camera.py`` of SoccerNet/sn-calibration), point for point,
  quirks included, so that distances to it reproduce the official JaC.

Frames and units: world points in the SoccerNet frame (metres, origin at the centre spot, z down);
image points in pixels (origin at the top-left corner, x right, y down). The camera must be
expressed at the resolution of the image it is clipped to (:meth:`Camera.scaled`); nothing here
rescales it.
"""
from __future__ import annotations

from functools import lru_cache
from typing import Literal

import numpy as np

from app.geometry.camera import MIN_DEPTH_M, Camera
from app.geometry.pitch import sample_pitch_polylines

#: Straight-element spacing (metres) of the official evaluator: ``get_polylines(..., sampling_factor=0.9)``
#: passes 0.9 as the *first* argument of ``sample_field_points(dist=0.1, dist_circles=0.2)``, so
#: straight elements are sampled every 0.9 m and circles keep the default 0.2 m.
EVALUATOR_DIST_M = 0.9
#: Circle spacing (metres) of the official evaluator (``sample_field_points``' default).
EVALUATOR_DIST_CIRCLES_M = 0.2

_MODES = ("clip", "evaluator")


@lru_cache(maxsize=8)
def _stacked_pitch(dist: float, dist_circles: float) -> tuple[np.ndarray, tuple[tuple[str, int, int], ...]]:
    """All sampled pitch points in one (N, 3) array and, per class, its slice ``(class, start, stop)``."""
    polylines = sample_pitch_polylines(dist, dist_circles)
    slices, start = [], 0
    for cls, pts in polylines.items():
        slices.append((cls, start, start + len(pts)))
        start += len(pts)
    stacked = np.concatenate(list(polylines.values()), axis=0)
    stacked.setflags(write=False)
    return stacked, tuple(slices)


def _check_size(width: int, height: int) -> tuple[int, int]:
    for name, value in (("width", width), ("height", height)):
        if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 2:
            raise ValueError(f"{name} must be an integer number of pixels >= 2, got {value!r}")
    return int(width), int(height)


def _project_like_evaluator(camera: Camera, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Project world points as SoccerNet's ``Camera.project_point`` does.

    The distorted normalised coordinates are cast to float32 and the affine map to pixels is then
    evaluated in float32 (NumPy >= 2 keeps ``float32 * float`` in float32), which is what the
    official values were computed with. Returns ``(uv (N, 2) float64 holding float32 values,
    valid (N,) bool)``; ``valid`` is False for points at depth <= 1e-3 m, which the evaluator skips.
    """
    xc = camera.points_in_camera(points)
    z = xc[:, 2]
    valid = z > MIN_DEPTH_M
    xn = xc[:, :2] / np.where(valid, z, 1.0)[:, None]
    xd = camera.distort(xn).astype(np.float32)
    k = camera.K.astype(np.float32)
    u = xd[:, 0] * k[0, 0]
    if camera.K[0, 1] != 0.0:
        u = u + xd[:, 1] * k[0, 1]
    u = u + k[0, 2]
    v = xd[:, 1] * k[1, 1] + k[1, 2]
    return np.stack([u, v], axis=1).astype(np.float64), valid


def _border_crossings(ext: np.ndarray, prev: np.ndarray, width: int, height: int) -> tuple[np.ndarray, np.ndarray]:
    """The evaluator's crossing of the line through ``prev`` and ``ext`` with the image border.

    The infinite line through the two points (homogeneous ``ext x prev``) is intersected with the
    four lines x = 0, x = W - 1, y = 0, y = H - 1 (in that order); of the intersections inside
    ``[0, W) x [0, H)``, the one nearest to ``ext`` is kept (first one on ties). Same arithmetic as
    ``get_polylines``, vectorised over T transitions.

    Args:
        ext, prev: (T, 2) pixels.

    Returns:
        ``(points (T, 2), found (T,) bool)``; rows without an admissible intersection are not found.
    """
    x, y = ext[:, 0], ext[:, 1]
    xp, yp = prev[:, 0], prev[:, 1]
    # line = cross([x, y, 1], [xp, yp, 1])
    l0 = y - yp
    l1 = xp - x
    l2 = x * yp - y * xp
    cw, ch = float(-width + 1), float(-height + 1)
    with np.errstate(divide="ignore", invalid="ignore"):
        # cross(line, side) for side = [1, 0, 0], [1, 0, -(W-1)], [0, 1, 0], [0, 1, -(H-1)], then / z.
        zero = np.zeros_like(l0)
        ix = np.stack([zero / -l1, (l1 * cw) / -l1, (-l2) / l0, (l1 * ch - l2) / l0], axis=1)
        iy = np.stack([l2 / -l1, (l2 - l0 * cw) / -l1, zero / l0, (-l0 * ch) / l0], axis=1)
        ok = (ix >= 0) & (ix < width) & (iy >= 0) & (iy < height)
        d = np.sqrt(np.square(ix - x[:, None]) + np.square(iy - y[:, None]))
    d = np.where(ok, d, np.inf)
    best = np.argmin(d, axis=1)
    rows = np.arange(len(ext))
    return np.stack([ix[rows, best], iy[rows, best]], axis=1), np.asarray(ok.any(axis=1))


def _evaluator_polylines(uv: np.ndarray, valid: np.ndarray, class_ids: np.ndarray, width: int,
                         height: int) -> tuple[np.ndarray, np.ndarray]:
    """Every class's polyline as ``get_polylines`` builds it, for all classes at once.

    Per class: in-image points and border crossings, all runs concatenated into one polyline,
    points behind the camera dropped. Input rows are grouped by class (``class_ids`` non-decreasing).

    Returns:
        ``(points (K, 2), ids (K,))``: the polylines one after the other, each row tagged with its class id.
    """
    pts, ids = uv[valid], class_ids[valid]
    inside = (pts[:, 0] >= 0) & (pts[:, 0] < width) & (pts[:, 1] >= 0) & (pts[:, 1] < height)
    # A crossing is sought where the in/out state changes between consecutive *valid* points of a
    # class; a class's first valid point never gets one (the evaluator's previous projection is then
    # all zeros, whose line with anything is degenerate).
    change = np.flatnonzero((inside[1:] != inside[:-1]) & (ids[1:] == ids[:-1])) + 1
    keep = np.flatnonzero(inside)
    crossing, found = _border_crossings(pts[change], pts[change - 1], width, height)
    change = change[found]
    keys = np.concatenate([3 * keep + 1, 3 * change])
    order = np.argsort(keys, kind="stable")
    out = np.concatenate([pts[keep], crossing[found]], axis=0)[order]
    return out, np.concatenate([ids[keep], ids[change]])[order]


def _clip_runs(uv: np.ndarray, valid: np.ndarray, width: int, height: int,
               starts: tuple[int, ...] = (0,)) -> tuple[list[np.ndarray], np.ndarray]:
    """Clip projected polylines to the rectangle [0, W] x [0, H] (Liang-Barsky on every segment), all at once.

    ``uv`` holds the polylines one after the other, polyline ``k`` starting at row ``starts[k]``
    (increasing, ``starts[0] == 0``); no segment joins two polylines. Segments touching a point behind
    the camera are dropped, which splits the polyline there. Consecutive clipped segments that share an
    end point are chained into one run. One pass over every segment of every polyline (the same
    arithmetic, element by element, as clipping each polyline on its own, in a tenth of the time).

    Returns:
        ``(runs, polyline)``: the runs (each (N >= 2, 2) pixels) in order, and the index of the polyline
        of each run.
    """
    if len(uv) < 2:
        return [], np.zeros(0, dtype=int)
    a, b = uv[:-1], uv[1:]
    seg_ok = valid[:-1] & valid[1:]
    seg_ok[[k - 1 for k in starts[1:] if 0 < k < len(uv)]] = False  # one polyline's last point to the next's first
    d = b - a
    t0 = np.zeros(len(a))
    t1 = np.ones(len(a))
    with np.errstate(divide="ignore", invalid="ignore"):
        for p, q in ((-d[:, 0], a[:, 0]), (d[:, 0], width - a[:, 0]),
                     (-d[:, 1], a[:, 1]), (d[:, 1], height - a[:, 1])):
            r = q / p
            parallel = p == 0
            seg_ok &= ~(parallel & (q < 0))
            entering = (p < 0) & ~parallel
            leaving = (p > 0) & ~parallel
            t0 = np.where(entering, np.maximum(t0, r), t0)
            t1 = np.where(leaving, np.minimum(t1, r), t1)
    seg_ok &= t0 <= t1
    idx = np.flatnonzero(seg_ok)
    if len(idx) == 0:
        return [], np.zeros(0, dtype=int)
    # Clipped ends lie on the border by construction; the clamp removes rounding (-1e-16 px).
    bounds = np.array([width, height], dtype=float)
    start = np.clip(a[idx] + t0[idx, None] * d[idx], 0.0, bounds)
    end = np.clip(a[idx] + t1[idx, None] * d[idx], 0.0, bounds)
    # A run continues from segment i to i + 1 when i ends uncut and i + 1 starts uncut.
    joined = (np.diff(idx) == 1) & (t1[idx[:-1]] == 1.0) & (t0[idx[1:]] == 0.0)
    firsts = np.concatenate([[0], np.flatnonzero(~joined) + 1])
    lasts = np.concatenate([firsts[1:], [len(idx)]])
    runs = [np.concatenate([start[s:e], end[e - 1:e]], axis=0) for s, e in zip(firsts, lasts, strict=True)]
    return runs, np.searchsorted(np.asarray(starts), idx[firsts], side="right") - 1


def project_pitch_polylines(
    camera: Camera,
    width: int,
    height: int,
    dist: float = 0.1,
    dist_circles: float = 0.2,
    *,
    mode: Literal["clip", "evaluator"] = "clip",
) -> dict[str, list[np.ndarray]]:
    """Project the pitch model's elements with ``camera`` (distortion included) into a W x H image.

    The elements are sampled by :func:`app.geometry.pitch.sample_pitch_polylines` (SoccerNet's
    ``sample_field_points``); points at depth <= 1e-3 m (behind the camera) are never projected.

    ``mode="clip"`` (UI, drawing): each element's polyline is clipped to the rectangle
    ``[0, W] x [0, H]`` segment by segment; every in-image piece is returned as its own run, which
    starts or ends exactly on the border where the element enters or leaves the image. A point
    behind the camera splits the element. Pixels are float64.

    ``mode="evaluator"`` (JaC): the polyline of SoccerNet's official ``get_polylines``
    (``src/evaluate_camera.py``): in-image means ``0 <= x < W`` and ``0 <= y < H``; where the state
    changes between consecutive projected points, the intersection of the *infinite* line through
    them with the border lines x = 0, x = W - 1, y = 0, y = H - 1 that lies in the image and is
    nearest to the later point is inserted; points behind the camera are skipped without breaking
    the polyline; all runs of a class are concatenated into **one** polyline (so a class that
    leaves and re-enters has a segment joining the two crossings, as in the evaluator); pixel
    coordinates carry the evaluator's float32 rounding (distortion output cast to float32). Use
    ``dist=EVALUATOR_DIST_M, dist_circles=EVALUATOR_DIST_CIRCLES_M`` to get the evaluator's sampling.

    Args:
        camera: the camera, expressed at this W x H resolution.
        width, height: image size, pixels.
        dist: spacing of samples on straight elements, metres.
        dist_circles: spacing of samples on circles, metres.
        mode: ``"clip"`` or ``"evaluator"``.

    Returns:
        class -> list of (N, 2) pixel arrays (N >= 1; N >= 2 in clip mode). Classes with nothing in
        the image are absent. In evaluator mode every list holds exactly one array.

    Raises:
        ValueError: unknown ``mode``; ``width`` or ``height`` not an integer >= 2; ``dist`` or
            ``dist_circles`` not positive.

    A camera 15 m up behind the bottom side line, looking across the centre spot: the middle line
    runs from the centre of the image up to the top border, where it is cut.

    >>> cam = Camera.from_parameters(focal_px=1000.0, principal_point=(480.0, 270.0), pan_deg=0.0,
    ...                              tilt_deg=60.0, roll_deg=0.0, position_m=[0.0, 60.0, -15.0])
    >>> lines = project_pitch_polylines(cam, 960, 540)
    >>> sorted(lines)
    ['Circle central', 'Middle line', 'Side line bottom']
    >>> run, = lines["Middle line"]
    >>> np.round(run[[0, -1]], 2).tolist()  # enters at the top border, ends at the bottom touch line
    [[480.0, 0.0], [480.0, 269.68]]
    """
    if mode not in _MODES:
        raise ValueError(f"mode must be one of {_MODES}, got {mode!r}")
    width, height = _check_size(width, height)
    if not (dist > 0 and dist_circles > 0):
        raise ValueError(f"dist and dist_circles must be positive metres, got {dist!r}, {dist_circles!r}")
    points, slices = _stacked_pitch(float(dist), float(dist_circles))
    if mode == "evaluator":
        uv, valid = _project_like_evaluator(camera, points)
    else:
        uv, valid = camera.project(points)
    out: dict[str, list[np.ndarray]] = {}
    if mode == "evaluator":
        class_ids = np.repeat(np.arange(len(slices)), [e - s for _, s, e in slices])
        poly, ids = _evaluator_polylines(uv, valid, class_ids, width, height)
        bounds = np.searchsorted(ids, np.arange(len(slices) + 1))
        for k, (cls, _, _) in enumerate(slices):
            if bounds[k + 1] > bounds[k]:
                out[cls] = [poly[bounds[k]:bounds[k + 1]]]
        return out
    runs, polyline = _clip_runs(uv, valid, width, height, tuple(s for _, s, _ in slices))
    for run, k in zip(runs, polyline.tolist(), strict=True):
        out.setdefault(slices[k][0], []).append(run)
    return out
