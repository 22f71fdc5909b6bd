"""The trajectory fit of a whole sequence and its per-frame assembly: positions, sources
(``triangulated`` / ``fitted`` / ``interpolated``), per-label residuals and outlier flags, the frames' own
triangulations from the labels kept, the Hermite curve across the gaps between pieces (package docstring:
the models and the method).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import numpy as np

from app.geometry.camera import Camera
from app.geometry.motion import (
    LabelTable as _Labels,
)
from app.geometry.trajectory.frames import FrameTriangulation, triangulate_frame
from app.geometry.trajectory.segmentation import DEFAULT_BREAK_PX, DEFAULT_FLAG_PX, Piece, _group, _segment
from app.geometry.triangulation import BallObservation

SOURCES = ("triangulated", "fitted", "interpolated")


#: Between pieces (a Hermite gap) the frame's own consensus keeps its labels when its point lies within
#: this many metres of the curve (the curve is off by tenths of a metre across a short kick or bounce).
GAP_CONSENSUS_M = 2.0


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
        first_frame: the sequence frame index of row 0 of the per-frame arrays. A fit of the whole
            sequence has ``first_frame = 0`` and F rows; :func:`refit_window` answers a *window*: rows
            ``first_frame .. first_frame + len(positions) - 1`` (the frames the re-fit may have changed),
            while ``pieces`` describe the whole sequence (sequence frame indices), or, in a fit given to
            the re-fit after an edit, a run of consecutive pieces holding at least those within
            :data:`REFIT_REACH` of the edit (its answer then holds that run with the pieces it replaced).
    """

    fps: float
    pieces: tuple[Piece, ...]
    positions: np.ndarray
    sources: tuple[str | None, ...]
    residuals_px: np.ndarray
    outliers: np.ndarray
    ball_3d: np.ndarray
    cam_lists: tuple[tuple[int, ...], ...]
    first_frame: int = 0

    @property
    def frames(self) -> range:
        """The sequence frame indices of the per-frame arrays' rows."""
        return range(self.first_frame, self.first_frame + len(self.positions))

    def window(self, first: int, last: int) -> "TrajectoryFit":
        """The rows of frames ``first..last`` (inclusive, sequence indices, inside :attr:`frames`)."""
        if not (self.first_frame <= first <= last < self.first_frame + len(self.positions)):
            raise ValueError(f"frames {first}..{last} are not all in {self.frames}")
        r = slice(first - self.first_frame, last - self.first_frame + 1)
        return TrajectoryFit(self.fps, self.pieces, self.positions[r], self.sources[r], self.residuals_px[r],
                             self.outliers[r], self.ball_3d[r], self.cam_lists[r], first_frame=first)

    def kept_labels(self, row: int) -> tuple[int, ...]:
        """Camera indices of row ``row``'s labels the trajectory keeps (a finite residual, not flagged):
        the input of that frame's own triangulation."""
        return tuple(int(k) for k in np.nonzero(np.isfinite(self.residuals_px[row]) & ~self.outliers[row])[0])


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
                   tau_px: float, rule: str, min_baseline_m: float, min_parallax_deg: float) -> TrajectoryFit:
    """Fit the ball's trajectory to all labels of all cameras at once (module docstring).

    Args:
        points: (F, K, 2) ball labels, pixels of each camera's image; NaN where there is no label.
        cameras: K cameras (``None`` for an uncalibrated camera: its labels are ignored).
        widths: K image widths, px (residuals are scaled to 1920 px).
        fps: frame rate; frame ``i`` is at ``t = i / fps`` seconds.
        flag_px: label residual above which the label is an outlier, px at 1920 width.
        break_px: prediction error that ends a piece (three frames in a row), px at 1920 width.
        tau_px, rule, min_baseline_m, min_parallax_deg: the per-frame triangulation's threshold (px at 1920 width),
            pair-error rule, least baseline (metres) and least parallax (degrees) (:func:`triangulate_frame`; the
            service passes its settings').

    Returns:
        :class:`TrajectoryFit` of the whole sequence (``first_frame = 0``, F rows).

    Raises:
        ValueError: shapes that disagree, non-positive fps.
    """
    pts, use = _check_inputs(points, cameras, widths, fps)
    L = _Labels(pts, cameras, widths, use)
    by_frame = _group(L)
    pieces = _segment(L, by_frame, sorted(by_frame), fps, break_px)
    return _assemble(pts, 0, cameras, widths, fps, L, pieces, flag_px, tau_px, 0, len(pts) - 1, rule=rule,
                     min_baseline_m=min_baseline_m, min_parallax_deg=min_parallax_deg)


def _assemble(pts, pts_first, cameras, widths, fps, L, pieces, flag_px, tau_px, a, b, *, rule: str,
              min_baseline_m: float,
              min_parallax_deg: float, previous: TrajectoryFit | None = None,
              edited: tuple[int, int] | None = None) -> TrajectoryFit:
    """The per-frame rows of frames ``a..b`` (sequence indices; ``pts`` row 0 is frame ``pts_first``)
    from ``pieces``. A frame outside ``edited`` whose kept labels are those of ``previous`` keeps its
    triangulation from ``previous``; the others are triangulated (:func:`triangulate_frame`)."""
    K = pts.shape[1]
    n = b - a + 1
    pieces = sorted(pieces, key=lambda p: p.first_frame)
    positions = np.full((n, 3), np.nan)
    for i, p in enumerate(pieces):
        lo, hi = max(p.first_frame, a), min(p.last_frame, b)
        if lo <= hi:
            fr = np.arange(lo, hi + 1)
            positions[fr - a] = p.position(fr, fps)
        if i + 1 < len(pieces) and pieces[i + 1].first_frame > p.last_frame + 1:
            _hermite_gap(positions, a, p, pieces[i + 1], fps)
    residuals = np.full((n, K), np.nan)
    sel = np.nonzero((L.frame >= a) & (L.frame <= b))[0]
    if len(sel):
        res = np.linalg.norm(L.residuals(sel, positions[L.frame[sel] - a]), axis=1)
        residuals[L.frame[sel] - a, L.cam[sel]] = res
    outliers = np.nan_to_num(residuals, nan=0.0) > flag_px
    # between pieces the trajectory is a Hermite curve, not a fitted motion: there labels that agree among
    # themselves (the frame's own consensus of two or more) on a ball near the curve are kept whatever
    # their pixel distance to it (two labels agree by chance when one lies near the other's epipolar line,
    # but then their point lies metres away along the ray)
    covered = np.zeros(n, bool)
    for p in pieces:
        covered[max(p.first_frame, a) - a:min(p.last_frame, b) - a + 1] = True
    for g in np.flatnonzero(~covered & (np.isfinite(residuals).sum(axis=1) >= 2) & outliers.any(axis=1)):
        row = a + g - pts_first
        tri = triangulate_frame([BallObservation(int(k), cameras[k], pts[row, k], widths[k])
                                 for k in np.flatnonzero(np.isfinite(residuals[g]))], tau_px=tau_px, rule=rule,
                                min_baseline_m=min_baseline_m, min_parallax_deg=min_parallax_deg)
        if tri.point is not None and np.linalg.norm(tri.point - positions[g]) <= GAP_CONSENSUS_M:
            outliers[g, list(tri.kept)] = False
    keep_mask = np.isfinite(residuals) & ~outliers
    # the frames whose kept labels are those of ``previous`` (outside the edit) keep its triangulation
    same = np.zeros(n, bool)
    if previous is not None and edited is not None:
        rows = np.arange(a, b + 1) - previous.first_frame
        inside = (rows >= 0) & (rows < len(previous.positions))
        before = np.isfinite(previous.residuals_px) & ~previous.outliers
        same[inside] = (before[rows[inside]] == keep_mask[inside]).all(axis=1)
        same &= (np.arange(a, b + 1) < edited[0]) | (np.arange(a, b + 1) > edited[1])
    ball = np.full((n, 3), np.nan)
    cam_lists: list[tuple[int, ...]] = []
    sources: list[str | None] = []
    placed: list[bool] = np.all(np.isfinite(positions), axis=1).tolist()
    for r in range(n):
        keep = tuple(np.flatnonzero(keep_mask[r]).tolist())
        if same[r]:
            old = a + r - previous.first_frame  # type: ignore[union-attr]  # same[r] only with a previous fit
            point = previous.ball_3d[old] if np.all(np.isfinite(previous.ball_3d[old])) else None  # type: ignore[union-attr]  # same[r] only with a previous fit
            kept = tuple(previous.cam_lists[old])  # type: ignore[union-attr]  # same[r] only with a previous fit
        else:
            row = a + r - pts_first
            tri = triangulate_frame([BallObservation(k, cameras[k], pts[row, k], widths[k]) for k in keep],
                                    tau_px=tau_px, rule=rule, min_baseline_m=min_baseline_m,
                                    min_parallax_deg=min_parallax_deg) if len(keep) >= 2 \
                else FrameTriangulation(None, (), {})
            point = tri.point
            kept = tuple(sorted(tri.kept)) if tri.point is not None else keep
        if point is not None:
            ball[r] = point
        cam_lists.append(kept)
        if not placed[r]:
            sources.append(None)
        elif point is not None:
            sources.append("triangulated")
        elif keep:
            sources.append("fitted")
        else:
            sources.append("interpolated")
    return TrajectoryFit(fps, tuple(pieces), positions, tuple(sources), residuals, outliers, ball, tuple(cam_lists),
                         first_frame=a)


def _hermite_gap(positions: np.ndarray, first: int, a: Piece, b: Piece, fps: float) -> None:
    """Fill the frames strictly between pieces ``a`` and ``b`` that ``positions`` holds (row 0 is frame
    ``first``), in place, with the cubic Hermite curve joining ``a``'s end (position, velocity) to ``b``'s
    start."""
    f0, f1 = a.last_frame, b.first_frame
    fr = np.arange(max(f0 + 1, first), min(f1, first + len(positions)))
    if not len(fr):
        return
    T = (f1 - f0) / fps
    p0, p1 = a.position([f0], fps)[0], b.position([f1], fps)[0]
    v0, v1 = a.velocity(f0, fps) * T, b.velocity(f1, fps) * T
    s = (fr - f0) / (f1 - f0)
    h = np.stack([2 * s ** 3 - 3 * s ** 2 + 1, s ** 3 - 2 * s ** 2 + s, -2 * s ** 3 + 3 * s ** 2, s ** 3 - s ** 2], 1)
    positions[fr - first] = h @ np.stack([p0, v0, p1, v1])


