"""Temporal 3D ball trajectory from synchronised static cameras (ISSIA-3D, issue 9).

The paper triangulates each frame on its own and names temporal tracking as future work. Here the
ball's physics is the check: between kicks and bounces the ball follows one of two models, fitted
to every label of every camera at once (reprojection residuals in pixels, robust loss):

* ``flight``: ``p(t) = p0 + v0 t + (0, 0, g t^2 / 2)``, ``g = 9.81 m/s^2`` (z points down);
* ``roll``: the ball on the grass, centre at ``z = -r`` (:data:`BALL_RADIUS_M`), horizontal
  ``p(t) = p0 + v0 t + a t^2 / 2`` (``a`` the rolling deceleration, fitted) until it stops
  (``t_stop = -(v0 . a) / |a|^2`` when it decelerates), then at rest.

A *piece* is a stretch of frames under one model with its own 6 parameters. Breaks between pieces
are kicks and bounces (a bounce keeps the horizontal velocity and scales the vertical one by the
restitution; the fitted pieces on each side find that without being told). Pieces are found from
the data (``_segment``): a piece grows frame by frame while its model *predicts* the next
labelled frames; when three consecutive labelled frames all disagree with the prediction (every
label of the frame further than ``break_px``), the piece ends and a new one starts; each boundary
is then moved by up to three frames to the place with the lowest total cost.

Each piece is fitted by iteratively reweighted linear least squares on the algebraic residual
``(r_1 - x r_3) . (p - C)``, ``(r_2 - y r_3) . (p - C)`` (``r_i`` rows of R, ``(x, y)`` the
undistorted normalised label), reweighted by the depth so that it equals the pixel error, with
Cauchy weights, then refined by :func:`scipy.optimize.least_squares` (``loss="cauchy"``) on the
pixel residuals themselves. Residuals are expressed on a 1920-px-wide image
(:data:`app.geometry.triangulation.REFERENCE_WIDTH_PX`).

Outputs per frame (:class:`TrajectoryFit`): the trajectory's position, its source
(``triangulated``: the frame has its own triangulation from two or more kept labels; ``fitted``: one
kept label, position from the fit; ``interpolated``: no kept label, inside or between pieces), the
per-label residual and outlier flag (frame, camera) and the frame's own triangulation
(:func:`triangulate_frame`, the paper's pairwise method made robust to one wrong camera) from the
labels the trajectory keeps. :func:`refit_window` re-fits only the pieces an edit touches.

World: SoccerNet metres, origin at the centre spot, z down. Image: continuous pixels, origin at
the top-left corner. Pure: numpy and scipy only. (A little over 400 lines: the model, its
segmentation and the per-frame assembly share the private label table and belong together.)
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Hashable, Sequence

import numpy as np
from scipy.optimize import least_squares

from app.geometry.camera import Camera
from app.geometry.consensus import ball_consensus
from app.geometry.triangulation import REFERENCE_WIDTH_PX, BallObservation, reprojection_error_px, triangulate_ball

GRAVITY_M_S2 = 9.81
BALL_RADIUS_M = 0.11
KINDS = ("flight", "roll")
SOURCES = ("triangulated", "fitted", "interpolated")

#: Defaults (pixels on a 1920-px-wide image). Label noise is about 1 px; a wrong label is tens to
#: hundreds of px off. ``flag_px`` flags a label against the fitted trajectory; ``break_px`` ends a
#: piece when three consecutive frames are all further than that from its prediction.
DEFAULT_FLAG_PX = 15.0
DEFAULT_BREAK_PX = 10.0
DEFAULT_TAU_PX = 20.0
_CAUCHY_PX = 3.0
_MIN_FRAMES = 4
#: A roll is chosen over a flight unless the flight's robust cost is lower by more than this per label (px^2):
#: label noise alone costs about 1 px^2 per label, so smaller gains are noise.
_ROLL_PREFERENCE_PX2 = 1.0
_CONFIRM = 3
_SHIFT = 3


@dataclass(frozen=True)
class FrameTriangulation:
    """One frame's own 3D ball.

    Attributes:
        point: (3,) world metres, or ``None`` with fewer than two consistent labels.
        kept: view ids whose labels produced ``point`` (empty when ``None``), input order.
        errors_px: view id -> reprojection error (px, own image) of ``point`` for every input label.
    """

    point: np.ndarray | None
    kept: tuple[Hashable, ...]
    errors_px: dict[Hashable, float | None]


def triangulate_frame(observations: Sequence[BallObservation], *, tau_px: float = DEFAULT_TAU_PX,
                      rule: str = "max_scaled_1920", min_baseline_m: float = 1.0) -> FrameTriangulation:
    """The paper's pairwise triangulation (method.md section 5) of the labels that agree, robust to
    wrong cameras.

    The labels that agree on one ball are chosen by :func:`app.geometry.consensus.ball_consensus` (the
    ball most views agree on, errors scaled to a 1920-px-wide image); those labels are then fused by
    the paper's method (:func:`app.geometry.triangulation.triangulate_ball`: the mean of the kept
    pairs), so ``point`` is the frame's own triangulation from the cameras it kept. Two labels that
    disagree, or two camps that agree equally (the culprit cannot be told), give no point.

    Args:
        observations: the frame's labels (distinct view ids).
        tau_px: threshold on pair errors and on each kept label's error, px at 1920 width.
        rule, min_baseline_m: as in :func:`~app.geometry.triangulation.triangulate_ball`.

    Returns:
        :class:`FrameTriangulation`.
    """
    obs = list(observations)
    none = FrameTriangulation(None, (), {})
    if len(obs) < 2:
        return none
    consensus = ball_consensus(obs, tau_px=tau_px, min_baseline_m=min_baseline_m)
    if consensus.point is None or consensus.ambiguous or len(consensus.inliers) < 2:
        return none
    kept = [o for o in obs if o.view_id in set(consensus.inliers)]
    res = triangulate_ball(kept, tau_px=tau_px, rule=rule, min_baseline_m=min_baseline_m)
    if res.point is None:
        return none
    errors = {o.view_id: reprojection_error_px(o.camera, res.point, o.point_px) for o in obs}
    return FrameTriangulation(res.point, tuple(o.view_id for o in kept), errors)


@dataclass(frozen=True)
class Piece:
    """A stretch of frames under one motion model.

    Attributes:
        kind: ``"flight"`` or ``"roll"``.
        first_frame, last_frame: labelled frames it spans (inclusive).
        params: (6,) flight ``(p0, v0)``; roll ``(x0, y0, vx, vy, ax, ay)``; metres, seconds, at
            ``t = (frame - first_frame) / fps``.
        cost: robust cost of its labels (Cauchy, px^2 at 1920 width).
    """

    kind: str
    first_frame: int
    last_frame: int
    params: np.ndarray
    cost: float

    def position(self, frames: np.ndarray, fps: float) -> np.ndarray:
        """(N,) frame indices (may lie outside the piece) -> (N, 3) world positions, metres."""
        t = (np.asarray(frames, float) - self.first_frame) / fps
        return _positions(self.kind, self.params, t)

    @property
    def stop_s(self) -> float:
        """Roll: seconds after ``first_frame`` at which the ball stops (``inf`` if it does not)."""
        return _stop_time(self.kind, self.params)

    def velocity(self, frame: float, fps: float) -> np.ndarray:
        """(3,) velocity at ``frame``, m/s."""
        t = (frame - self.first_frame) / fps
        q = self.params
        if self.kind == "flight":
            return np.array([q[3], q[4], q[5] + GRAVITY_M_S2 * t])
        if t >= self.stop_s:
            return np.zeros(3)
        return np.array([q[2] + q[4] * t, q[3] + q[5] * t, 0.0])


def _basis(kind: str, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(N,) seconds -> B (N, 3, 6), c (N, 3) with p = B q + c."""
    n = len(t)
    B = np.zeros((n, 3, 6))
    c = np.zeros((n, 3))
    if kind == "flight":
        for i in range(3):
            B[:, i, i] = 1.0
            B[:, i, 3 + i] = t
        c[:, 2] = 0.5 * GRAVITY_M_S2 * t ** 2
    else:
        for i in range(2):
            B[:, i, i] = 1.0
            B[:, i, 2 + i] = t
            B[:, i, 4 + i] = 0.5 * t ** 2
        c[:, 2] = -BALL_RADIUS_M
    return B, c


def _stop_time(kind: str, q: np.ndarray) -> float:
    """A decelerating roll stops when its speed along ``v0`` vanishes: ``-(v0 . a) / |a|^2``, then stays."""
    va = float(q[2:4] @ q[4:6]) if kind == "roll" else 0.0
    return -va / float(q[4:6] @ q[4:6]) if va < 0 else np.inf


def _positions(kind: str, q: np.ndarray, t: np.ndarray) -> np.ndarray:
    B, c = _basis(kind, np.minimum(np.atleast_1d(t), _stop_time(kind, q)))
    return B @ q + c


class _Labels:
    """Flattened labels: per label its frame, camera, normalised undistorted point and geometry."""

    def __init__(self, points: np.ndarray, cameras: Sequence[Camera | None], widths: Sequence[float],
                 use: np.ndarray):
        frames, cams = np.nonzero(use)
        self.frame, self.cam = frames, cams
        xy = np.zeros((len(frames), 2))
        for k, cam in enumerate(cameras):
            sel = cams == k
            if sel.any():
                xy[sel] = cam.normalise_pixels(points[frames[sel], k], undistort=True)
        self.xy = xy
        self.R = np.stack([cameras[k].R for k in cams]) if len(cams) else np.zeros((0, 3, 3))
        self.C = np.stack([cameras[k].C for k in cams]) if len(cams) else np.zeros((0, 3))
        scale = np.array([0.5 * (cam.K[0, 0] + cam.K[1, 1]) * REFERENCE_WIDTH_PX / w if cam is not None else 1.0
                          for cam, w in zip(cameras, widths)])
        self.scale = scale[cams]  # normalised units -> px at 1920 width

    def residuals(self, idx: np.ndarray, pos: np.ndarray) -> np.ndarray:
        """(n, 2) pixel residuals (1920 width) of labels ``idx`` at world positions ``pos`` (n, 3)."""
        xc = np.einsum("nij,nj->ni", self.R[idx], pos - self.C[idx])
        z = np.where(xc[:, 2] > 1e-6, xc[:, 2], 1e-6)
        return (xc[:, :2] / z[:, None] - self.xy[idx]) * self.scale[idx, None]


def _fit(L: _Labels, idx: np.ndarray, kind: str, first: int, fps: float, refine: bool) -> tuple[np.ndarray, float]:
    """Fit one model to labels ``idx``; returns (params (6,), robust cost)."""
    t = (L.frame[idx] - first) / fps
    rows = L.R[idx][:, :2, :] - L.xy[idx][:, :, None] * L.R[idx][:, 2:3, :]  # (n, 2, 3)
    depth = np.linalg.norm(L.C[idx], axis=1)
    w = np.ones(len(idx))
    q = np.zeros(6)
    for _ in range(6):
        # a roll that stops inside the piece: times after the stop are held at the stop (linear given it)
        B, c = _basis(kind, np.minimum(t, _stop_time(kind, q)))
        A = np.einsum("nrj,njk->nrk", rows, B)  # (n, 2, 6)
        b = np.einsum("nrj,nj->nr", rows, L.C[idx] - c)
        s = (np.sqrt(w) * L.scale[idx] / depth)[:, None]
        q = np.linalg.lstsq((A * s[:, :, None]).reshape(-1, 6), (b * s).reshape(-1), rcond=None)[0]
        pos = _positions(kind, q, t)
        depth = np.maximum(np.einsum("nj,nj->n", L.R[idx][:, 2, :], pos - L.C[idx]), 0.5)
        e = np.linalg.norm(L.residuals(idx, pos), axis=1)
        w = 1.0 / (1.0 + (e / _CAUCHY_PX) ** 2)
    if refine:
        def fun(qq):
            return L.residuals(idx, _positions(kind, qq, t)).reshape(-1)
        q = least_squares(fun, q, loss="cauchy", f_scale=_CAUCHY_PX, method="trf", x_scale="jac").x
    e = np.linalg.norm(L.residuals(idx, _positions(kind, q, t)), axis=1)
    return q, float(np.sum(_CAUCHY_PX ** 2 * np.log1p((e / _CAUCHY_PX) ** 2)))


def _best_piece(L: _Labels, by_frame: dict[int, np.ndarray], frames: Sequence[int], fps: float,
                refine: bool = False) -> Piece:
    idx = np.concatenate([by_frame[f] for f in frames])
    first, last = int(frames[0]), int(frames[-1])
    kinds = KINDS if len(frames) >= 3 else ("flight",)
    fits = {kind: _fit(L, idx, kind, first, fps, refine) for kind in kinds}
    kind = min(fits, key=lambda k: fits[k][1])
    if "roll" in fits and fits["roll"][1] <= fits["flight"][1] + _ROLL_PREFERENCE_PX2 * len(idx):
        kind = "roll"  # within noise of each other (e.g. one camera): the ball on the grass, the common case
    return Piece(kind, first, last, fits[kind][0], fits[kind][1])


def _frame_bad(L: _Labels, by_frame, piece: Piece, frame: int, fps: float, break_px: float,
               worst: bool = False) -> bool:
    """Every label of ``frame`` (or, with ``worst``, any label) is further than ``break_px`` from ``piece``."""
    idx = by_frame[frame]
    pos = np.repeat(piece.position([frame], fps), len(idx), axis=0)
    e = np.linalg.norm(L.residuals(idx, pos), axis=1)
    return bool((np.max(e) if worst else np.min(e)) > break_px)


def _segment(L: _Labels, by_frame: dict[int, np.ndarray], frames: Sequence[int], fps: float,
             break_px: float = DEFAULT_BREAK_PX) -> list[Piece]:
    """Split labelled ``frames`` (sorted) into pieces (module docstring); each piece refined."""
    frames = list(frames)
    n = len(frames)
    bounds: list[tuple[int, int]] = []
    i = 0
    while i < n:
        j = min(i + _MIN_FRAMES, n)
        piece = _best_piece(L, by_frame, frames[i:j], fps)
        while j - i > 1 and any(_frame_bad(L, by_frame, piece, f, fps, break_px) for f in frames[i:j]):
            j -= 1  # the opening frames straddle a break: a shorter piece
            piece = _best_piece(L, by_frame, frames[i:j], fps)
        while j - i >= _MIN_FRAMES and j < n:
            ahead = frames[j:j + _CONFIRM]
            if len(ahead) == _CONFIRM and all(_frame_bad(L, by_frame, piece, f, fps, break_px) for f in ahead):
                break
            j += 1
            piece = _best_piece(L, by_frame, frames[i:j], fps)
        bounds.append((i, j))
        i = j
    bounds = _shift_bounds(L, by_frame, frames, fps, bounds)
    for _ in range(3):  # frames at a piece's ends that it does not explain form their own piece
        split = []
        for a, b in bounds:
            piece = _best_piece(L, by_frame, frames[a:b], fps)
            bad = [_frame_bad(L, by_frame, piece, f, fps, break_px) for f in frames[a:b]]
            head = next((i for i, x in enumerate(bad) if not x), len(bad))
            tail = next((i for i, x in enumerate(bad[::-1]) if not x), len(bad))
            cuts = {a, b, *(c for c in (a + head, b - tail) if a < c < b)}
            # inside: three frames in a row each with a label off the model (one wrong label is alone)
            off = [_frame_bad(L, by_frame, piece, f, fps, break_px, worst=True) for f in frames[a:b]]
            run = _bad_run(off[head:len(off) - tail])
            if run is not None:  # a kick the growth missed (a small change of velocity): best cut near it
                r0 = a + head + run
                options = range(max(a + 2, r0 - 2 * _SHIFT), min(b - 2, r0 + _SHIFT) + 1)
                costs = [(_best_piece(L, by_frame, frames[a:c], fps).cost
                          + _best_piece(L, by_frame, frames[c:b], fps).cost, c) for c in options]
                if costs:
                    cuts.add(min(costs)[1])
            cuts = sorted(cuts)
            split += list(zip(cuts[:-1], cuts[1:]))
        if len(split) == len(bounds):
            break
        bounds = _shift_bounds(L, by_frame, frames, fps, split)
    return [_best_piece(L, by_frame, frames[a:b], fps, refine=True) for a, b in bounds if b > a]


def _bad_run(bad: list[bool]) -> int | None:
    """Index of the first run of ``_CONFIRM`` consecutive bad frames, or ``None``."""
    count = 0
    for i, x in enumerate(bad):
        count = count + 1 if x else 0
        if count == _CONFIRM:
            return i - _CONFIRM + 1
    return None


def _shift_bounds(L, by_frame, frames, fps, bounds):
    """Move each boundary between consecutive pieces by up to ``_SHIFT`` frames to the lowest cost."""
    bounds = list(bounds)
    for b in range(1, len(bounds)):
        (a0, a1), (_, b1) = bounds[b - 1], bounds[b]
        best = None
        for cut in range(max(a0 + 1, a1 - _SHIFT), min(b1 - 1, a1 + _SHIFT) + 1):
            cost = (_best_piece(L, by_frame, frames[a0:cut], fps).cost
                    + _best_piece(L, by_frame, frames[cut:b1], fps).cost)
            if best is None or cost < best[0] - 1e-9:
                best = (cost, cut)
        if best is not None:
            bounds[b - 1], bounds[b] = (a0, best[1]), (best[1], b1)
    return bounds


@dataclass(frozen=True)
class TrajectoryFit:
    """The fitted trajectory of a sequence of F frames seen by K cameras.

    Attributes:
        fps: frames per second.
        pieces: the motion pieces in frame order.
        positions: (F, 3) trajectory position per frame, world metres (NaN outside the labelled span).
        sources: per frame one of :data:`SOURCES`, or ``None`` without a position.
        residuals_px: (F, K) distance of each label to the trajectory's projection, px at 1920 width
            (NaN without a label).
        outliers: (F, K) True for a label whose residual is above ``flag_px`` (it breaks the
            trajectory; a ``ball_off_consensus`` doubt).
        ball_3d: (F, 3) the frame's own triangulation from its kept labels (NaN with fewer than two).
        cam_lists: per frame the camera indices (0-based) of the labels the frame keeps, ascending:
            those of ``ball_3d`` when it exists, else the labels the trajectory does not flag.
    """

    fps: float
    pieces: tuple[Piece, ...]
    positions: np.ndarray
    sources: tuple[str | None, ...]
    residuals_px: np.ndarray
    outliers: np.ndarray
    ball_3d: np.ndarray
    cam_lists: tuple[tuple[int, ...], ...]


def _check_inputs(points, cameras, widths, fps):
    pts = np.asarray(points, float)
    if pts.ndim != 3 or pts.shape[2] != 2:
        raise ValueError(f"points must be (F, K, 2), got shape {pts.shape}")
    if len(cameras) != pts.shape[1] or len(widths) != pts.shape[1]:
        raise ValueError(f"cameras and widths need {pts.shape[1]} entries (one per camera)")
    if not fps > 0:
        raise ValueError(f"fps must be positive, got {fps!r}")
    use = np.all(np.isfinite(pts), axis=2) & np.array([c is not None for c in cameras])[None, :]
    return pts, use


def fit_trajectory(points: np.ndarray, cameras: Sequence[Camera | None], widths: Sequence[float], fps: float, *,
                   flag_px: float = DEFAULT_FLAG_PX, break_px: float = DEFAULT_BREAK_PX,
                   tau_px: float = DEFAULT_TAU_PX) -> TrajectoryFit:
    """Fit the ball's trajectory to all labels of all cameras at once (module docstring).

    Args:
        points: (F, K, 2) ball labels, pixels of each camera's image; NaN where there is no label.
        cameras: K cameras (``None`` for an uncalibrated camera: its labels are ignored).
        widths: K image widths, px (residuals are scaled to 1920 px).
        fps: frame rate; frame ``i`` is at ``t = i / fps`` seconds.
        flag_px: label residual above which the label is an outlier, px at 1920 width.
        break_px: prediction error that ends a piece (three frames in a row), px at 1920 width.
        tau_px: per-frame triangulation threshold (:func:`triangulate_frame`).

    Returns:
        :class:`TrajectoryFit`.

    Raises:
        ValueError: shapes that disagree, non-positive fps.
    """
    pts, use = _check_inputs(points, cameras, widths, fps)
    L = _Labels(pts, cameras, widths, use)
    by_frame = _group(L)
    pieces = _segment(L, by_frame, sorted(by_frame), fps, break_px)
    return _assemble(pts, cameras, widths, fps, L, pieces, flag_px, tau_px)


def refit_window(fit: TrajectoryFit, points: np.ndarray, cameras: Sequence[Camera | None], widths: Sequence[float],
                 first_frame: int, last_frame: int, *, flag_px: float = DEFAULT_FLAG_PX,
                 break_px: float = DEFAULT_BREAK_PX, tau_px: float = DEFAULT_TAU_PX) -> TrajectoryFit:
    """Re-fit after labels changed in frames ``first_frame..last_frame`` (inclusive).

    The pieces that overlap the window, and one neighbour on each side, are segmented and fitted
    again from the current ``points``; the others are kept as they are. Same arguments as
    :func:`fit_trajectory`; ``points`` is the whole sequence with the edit applied.
    """
    pts, use = _check_inputs(points, cameras, widths, fit.fps)
    L = _Labels(pts, cameras, widths, use)
    by_frame = _group(L)
    pieces = list(fit.pieces)
    hit = [i for i, p in enumerate(pieces) if p.last_frame >= first_frame and p.first_frame <= last_frame]
    if not hit:  # the window lies between pieces (or outside): its neighbours
        hit = [i for i, p in enumerate(pieces) if p.last_frame < first_frame][-1:] + \
              [i for i, p in enumerate(pieces) if p.first_frame > last_frame][:1]
    lo = max(min(hit, default=0) - 1, 0)
    hi = min(max(hit, default=len(pieces) - 1) + 1, len(pieces) - 1)
    start = min(first_frame, pieces[lo].first_frame) if pieces else first_frame
    end = max(last_frame, pieces[hi].last_frame) if pieces else last_frame
    frames = [f for f in sorted(by_frame) if start <= f <= end]
    new = _segment(L, by_frame, frames, fit.fps, break_px) if frames else []
    pieces = pieces[:lo] + new + pieces[hi + 1:] if pieces else new
    return _assemble(pts, cameras, widths, fit.fps, L, pieces, flag_px, tau_px)


def _group(L: _Labels) -> dict[int, np.ndarray]:
    by_frame: dict[int, list[int]] = {}
    for i, f in enumerate(L.frame):
        by_frame.setdefault(int(f), []).append(i)
    return {f: np.array(v) for f, v in by_frame.items()}


def _assemble(pts, cameras, widths, fps, L, pieces, flag_px, tau_px) -> TrajectoryFit:
    F, K = pts.shape[:2]
    pieces = sorted(pieces, key=lambda p: p.first_frame)
    positions = np.full((F, 3), np.nan)
    for a, p in enumerate(pieces):
        fr = np.arange(p.first_frame, p.last_frame + 1)
        positions[fr] = p.position(fr, fps)
        if a + 1 < len(pieces) and pieces[a + 1].first_frame > p.last_frame + 1:
            positions = _hermite_gap(positions, p, pieces[a + 1], fps)
    residuals = np.full((F, K), np.nan)
    if len(L.frame):
        res = np.linalg.norm(L.residuals(np.arange(len(L.frame)), positions[L.frame]), axis=1)
        residuals[L.frame, L.cam] = res
    outliers = np.nan_to_num(residuals, nan=0.0) > flag_px
    ball = np.full((F, 3), np.nan)
    cam_lists: list[tuple[int, ...]] = []
    sources: list[str | None] = []
    for f in range(F):
        keep = [k for k in range(K) if np.isfinite(residuals[f, k]) and not outliers[f, k]]
        tri = triangulate_frame([BallObservation(k, cameras[k], pts[f, k], widths[k]) for k in keep],
                                tau_px=tau_px) if len(keep) >= 2 else FrameTriangulation(None, (), {})
        kept = tuple(sorted(tri.kept)) if tri.point is not None else tuple(keep)
        if tri.point is not None:
            ball[f] = tri.point
        cam_lists.append(kept)
        if not np.all(np.isfinite(positions[f])):
            sources.append(None)
        elif tri.point is not None:
            sources.append("triangulated")
        elif keep:
            sources.append("fitted")
        else:
            sources.append("interpolated")
    return TrajectoryFit(fps, tuple(pieces), positions, tuple(sources), residuals, outliers, ball, tuple(cam_lists))


def _hermite_gap(positions: np.ndarray, a: Piece, b: Piece, fps: float) -> np.ndarray:
    """Fill frames strictly between pieces ``a`` and ``b`` with the cubic Hermite curve joining
    ``a``'s end (position, velocity) to ``b``'s start."""
    f0, f1 = a.last_frame, b.first_frame
    T = (f1 - f0) / fps
    p0, p1 = a.position([f0], fps)[0], b.position([f1], fps)[0]
    v0, v1 = a.velocity(f0, fps) * T, b.velocity(f1, fps) * T
    s = (np.arange(f0 + 1, f1) - f0) / (f1 - f0)
    h = np.stack([2 * s ** 3 - 3 * s ** 2 + 1, s ** 3 - 2 * s ** 2 + s, -2 * s ** 3 + 3 * s ** 2, s ** 3 - s ** 2], 1)
    out = positions.copy()
    out[f0 + 1:f1] = h @ np.stack([p0, v0, p1, v1])
    return out


__all__ = ["GRAVITY_M_S2", "BALL_RADIUS_M", "KINDS", "SOURCES", "FrameTriangulation", "triangulate_frame", "Piece",
           "TrajectoryFit", "fit_trajectory", "refit_window"]
