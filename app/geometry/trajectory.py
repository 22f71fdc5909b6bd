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
is then moved by up to three frames to the place with the lowest total cost. A piece no ball could
follow (:func:`app.geometry.motion.plausible`: faster than 45 m/s, under the grass, far off the pitch) or
shorter than four labelled frames between two others (most often a wrong label at a kick that a piece of
its own explains) is left out: the trajectory crosses its frames by a cubic Hermite curve between the
neighbouring pieces, against which their labels are judged; there the frame's own consensus of two or
more labels on a ball near the curve keeps those labels.

Each piece is fitted by iteratively reweighted linear least squares on the algebraic residual
``(r_1 - x r_3) . (p - C)``, ``(r_2 - y r_3) . (p - C)`` (``r_i`` rows of R, ``(x, y)`` the
undistorted normalised label), reweighted by the depth so that it equals the pixel error, with
Cauchy weights, then refined by a robust (Cauchy) least squares of the pixel residuals themselves;
both fits live in :mod:`app.geometry.motion` (the models, the batched linear fit the segmentation's
candidate cuts share, the Levenberg-Marquardt refinement with the analytic Jacobian). Residuals are
expressed on a 1920-px-wide image (:data:`app.geometry.triangulation.REFERENCE_WIDTH_PX`).

Outputs per frame (:class:`TrajectoryFit`): the trajectory's position, its source
(``triangulated``: the frame has its own triangulation from two or more kept labels; ``fitted``: one
kept label, position from the fit; ``interpolated``: no kept label, inside or between pieces), the
per-label residual and outlier flag (frame, camera) and the frame's own triangulation
(:func:`triangulate_frame`, the paper's pairwise method made robust to one wrong camera) from the
labels the trajectory keeps. :func:`refit_window` re-fits only the pieces an edit touches and answers
only the frames whose place on the trajectory can have changed, re-triangulating only those whose
kept labels changed (:func:`refit_local`, its fast path, reads only the pieces around the edit).

World: SoccerNet metres, origin at the centre spot, z down. Image: continuous pixels, origin at
the top-left corner. Pure: numpy only. (About 830 lines: the segmentation, the per-frame assembly and
the re-fit after an edit, which replays the segmentation's own tests on a few pieces, share the
segmentation's helpers; split apart they would import each other's private parts.)
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Hashable, Sequence

import numpy as np

from app.geometry.camera import Camera
from app.geometry.consensus import ball_consensus
from app.geometry.motion import (
    BALL_RADIUS_M, GRAVITY_M_S2, KINDS, LabelTable as _Labels, linear_fits, positions as _positions, refine as _refine,
    determined as _determined, plausible as _plausible, position_prior as _position_prior, robust_cost, shifted as _shifted, stop_time as _stop_time,
)
from app.geometry.triangulation import BallObservation, reprojection_error_px, triangulate_ball

SOURCES = ("triangulated", "fitted", "interpolated")

#: Defaults (pixels on a 1920-px-wide image). Label noise is about 1 px; a wrong label is tens to
#: hundreds of px off. ``flag_px`` flags a label against the fitted trajectory; ``break_px`` ends a
#: piece when three consecutive frames are all further than that from its prediction.
DEFAULT_FLAG_PX = 15.0
DEFAULT_BREAK_PX = 10.0
DEFAULT_TAU_PX = 20.0
_MIN_FRAMES = 4
#: A one-camera flight's position at a break is tied to its neighbour's this tightly (m): a kick changes
#: the velocity, not the position, and the break lies within half a frame of the midpoint (at 30 m/s,
#: 0.6 m); the depth it fixes is otherwise tens of metres loose. Neighbours further than
#: ``_ANCHOR_GAP`` frames away (frames without labels between) do not tie it.
ANCHOR_SIGMA_M = 0.5
_ANCHOR_GAP = 3
#: Between pieces (a Hermite gap) the frame's own consensus keeps its labels when its point lies within
#: this many metres of the curve (the curve is off by tenths of a metre across a short kick or bounce).
GAP_CONSENSUS_M = 2.0
#: A roll is chosen over a flight unless the flight's robust cost is lower by more than this per label (px^2):
#: label noise alone costs about 1 px^2 per label, so smaller gains are noise.
_ROLL_PREFERENCE_PX2 = 1.0
_CONFIRM = 3
_SHIFT = 3
#: The segmentation grows a piece one frame at a time; the fits of its next lengths are made together
#: (:meth:`_Best.prefetch`), this many first, twice as many each time up to ``_GROWTH_BATCH_MAX`` (the
#: lengths it does not reach are fitted for nothing: a cost, never a different result).
_GROWTH_BATCH = 4
_GROWTH_BATCH_MAX = 16


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
        alternative: (6,) the params of the other model fitted to the same labels (``None`` when it was
            not fitted, e.g. fewer than three frames): where that model's refinement starts after an
            edit of the piece (the two models' costs choose the kind).
    """

    kind: str
    first_frame: int
    last_frame: int
    params: np.ndarray
    cost: float
    alternative: np.ndarray | None = None

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


def _fit(L: _Labels, idx: np.ndarray, kind: str, first: int, fps: float, refine: bool,
         start: np.ndarray | None = None, linear: np.ndarray | None = None) -> tuple[np.ndarray, float]:
    """Fit one model to labels ``idx`` (``t = 0`` at frame ``first``); returns (params (6,), robust cost).
    Unrefined: the reweighted linear fit (:func:`app.geometry.motion.linear_fits`). Refined: the robust
    fit of the pixel residuals (:func:`app.geometry.motion.refine`) from ``start`` (the params of a fit of
    nearly the same labels, e.g. before an edit: the same minimum, in fewer iterations), else from the
    linear solution (``linear`` when the caller has it). A minimum from ``start`` that the labels do not
    determine (:func:`app.geometry.motion.determined`: a piece of a few labels of one camera, say) is
    replaced by the one from the linear solution, as a fit from scratch finds it."""
    if not refine or (start is None and linear is None):
        q, cost = linear_fits(L, [(idx, kind, first)], fps)[0]
        if not refine:
            return q, cost
        linear = q
    sub = L.take(idx)
    t = (sub.frame - first) / fps
    q = _refine(sub, kind, start if start is not None else linear, t)
    if start is not None and not _determined(sub, kind, q, t):
        if linear is None:
            linear = linear_fits(L, [(idx, kind, first)], fps)[0][0]
        q = _refine(sub, kind, linear, t)
    return q, robust_cost(sub.residuals(slice(None), _positions(kind, q, t)))


def _best_piece(L: _Labels, by_frame: dict[int, np.ndarray], frames: Sequence[int], fps: float,
                refine: bool = False, start: Piece | None = None,
                linear: dict[str, np.ndarray] | None = None) -> Piece:
    """The piece of the better model for ``frames`` (a roll unless a flight is clearly better); ``start``:
    a piece fitted to nearly the same frames (before an edit) whose params, and those of its other model
    (``alternative``), re-expressed at ``frames[0]`` (:func:`app.geometry.motion.shifted`), start the
    refinement of each model (:func:`_fit`); ``linear``: the reweighted linear solution of each model for
    these ``frames`` (:meth:`_Best.linear`), where the refinement of a model without a start begins (it
    would compute the same solution first)."""
    fits = _model_fits(L, by_frame, frames, fps, refine, start, linear)
    return _choose(frames, fits, sum(len(by_frame[f]) for f in frames))


def _model_fits(L: _Labels, by_frame, frames: Sequence[int], fps: float, refine: bool, start: Piece | None = None,
                linear: dict[str, np.ndarray] | None = None) -> dict[str, tuple[np.ndarray, float]]:
    """Each model's (params, robust cost) for ``frames`` (:func:`_best_piece`'s arguments)."""
    idx = np.concatenate([by_frame[f] for f in frames])
    first = int(frames[0])
    kinds = KINDS if len(frames) >= 3 else ("flight",)
    lin = dict(linear or {}) if refine else {}
    warm: dict[str, np.ndarray] = {}
    if refine and start is not None:  # re-expressed at this first frame when the piece's start moved
        dt = (first - start.first_frame) / fps
        warm[start.kind] = _shifted(start.kind, start.params, dt) if dt else start.params
        if start.alternative is not None:
            other = _other(start.kind)
            warm[other] = _shifted(other, start.alternative, dt) if dt else start.alternative
    missing = [kind for kind in kinds if kind not in lin and (not refine or kind not in warm)]
    fits = dict(zip(missing, linear_fits(L, [(idx, kind, first) for kind in missing], fps)))
    if not refine:
        return fits
    lin.update({kind: q for kind, (q, _) in fits.items()})
    return {kind: _fit(L, idx, kind, first, fps, True, warm.get(kind), lin.get(kind)) for kind in kinds}


def _other(kind: str) -> str:
    return KINDS[1 - KINDS.index(kind)]


def _choose(frames: Sequence[int], fits: dict[str, tuple[np.ndarray, float]], labels: int) -> Piece:
    """The piece of the better of ``fits`` (:func:`_model_fits`, ``labels`` labels): a roll unless a flight
    is clearly better."""
    kind = min(fits, key=lambda k: fits[k][1])
    if "roll" in fits and fits["roll"][1] <= fits["flight"][1] + _ROLL_PREFERENCE_PX2 * labels:
        kind = "roll"  # within noise of each other (e.g. one camera): the ball on the grass, the common case
    other = fits.get(_other(kind))
    return Piece(kind, int(frames[0]), int(frames[-1]), fits[kind][0], fits[kind][1],
                 other[0] if other is not None else None)


class _Best:
    """:func:`_best_piece` (unrefined) of frame lists, each computed once: the segmentation and the
    re-fit ask for the same frames again (a boundary's best cut, then the piece on each side of it)."""

    def __init__(self, L: _Labels, by_frame: dict[int, np.ndarray], fps: float):
        self.L, self.by_frame, self.fps = L, by_frame, fps
        self._done: dict[tuple[int, ...], tuple[Piece, dict[str, tuple[np.ndarray, float]]]] = {}

    def _get(self, frames: Sequence[int]) -> tuple[Piece, dict[str, tuple[np.ndarray, float]]]:
        key = tuple(frames)
        done = self._done.get(key)
        if done is None:
            self.prefetch([key])
            done = self._done[key]
        return done

    def prefetch(self, lists: Sequence[Sequence[int]]) -> None:
        """Fit the frame lists not fitted yet, all at once (:func:`app.geometry.motion.linear_fits`: the
        same result as one by one)."""
        todo = list(dict.fromkeys(tuple(f) for f in lists if f and tuple(f) not in self._done))
        jobs, owners = [], []
        for key in todo:
            idx = np.concatenate([self.by_frame[f] for f in key])
            for kind in (KINDS if len(key) >= 3 else ("flight",)):
                jobs.append((idx, kind, int(key[0])))
                owners.append((key, kind))
        fits: dict[tuple[int, ...], dict[str, tuple[np.ndarray, float]]] = {key: {} for key in todo}
        for (key, kind), fit in zip(owners, linear_fits(self.L, jobs, self.fps)):
            fits[key][kind] = fit
        for key in todo:
            self._done[key] = (_choose(key, fits[key], sum(len(self.by_frame[f]) for f in key)), fits[key])

    def __call__(self, frames: Sequence[int]) -> Piece:
        return self._get(frames)[0]

    def has(self, frames: Sequence[int]) -> bool:
        """``frames`` is fitted already."""
        return tuple(frames) in self._done

    def linear(self, frames: Sequence[int]) -> dict[str, np.ndarray]:
        """Each model's reweighted linear solution for ``frames`` (the ``linear`` of :func:`_best_piece`)."""
        return {kind: q for kind, (q, _) in self._get(frames)[1].items()}


def _frame_bad(L: _Labels, by_frame, piece: Piece, frame: int, fps: float, break_px: float,
               worst: bool = False) -> bool:
    """Every label of ``frame`` (or, with ``worst``, any label) is further than ``break_px`` from ``piece``."""
    idx = by_frame[frame]
    pos = np.repeat(piece.position([frame], fps), len(idx), axis=0)
    e = np.linalg.norm(L.residuals(idx, pos), axis=1)
    return bool((np.max(e) if worst else np.min(e)) > break_px)


def _segment(L: _Labels, by_frame: dict[int, np.ndarray], frames: Sequence[int], fps: float,
             break_px: float = DEFAULT_BREAK_PX, previous: Sequence[Piece] = (),
             ends: tuple[bool, bool] = (True, True)) -> list[Piece]:
    """Split labelled ``frames`` (sorted) into pieces (module docstring); each piece refined, from the
    params of the piece of ``previous`` (the pieces before an edit) it overlaps most when there is one,
    re-expressed at its first frame (:func:`_fit`: the same minimum, in fewer iterations); pieces no ball
    could follow are left out (:func:`_plausible_pieces`; ``ends``: ``frames`` starts / ends the sequence)."""
    previous = sorted(previous, key=lambda p: p.first_frame)
    frames = list(frames)
    n = len(frames)
    best = _Best(L, by_frame, fps)
    bounds: list[tuple[int, int]] = []
    i = 0
    while i < n:
        j = min(i + _MIN_FRAMES, n)
        piece = best(frames[i:j])
        while j - i > 1 and any(_frame_bad(L, by_frame, piece, f, fps, break_px) for f in frames[i:j]):
            j -= 1  # the opening frames straddle a break: a shorter piece
            piece = best(frames[i:j])
        batch = _GROWTH_BATCH
        while j - i >= _MIN_FRAMES and j < n:
            ahead = frames[j:j + _CONFIRM]
            if len(ahead) == _CONFIRM and _bad_frames(L, by_frame, piece, ahead, fps, break_px)[0].all():
                break
            j += 1
            if not best.has(frames[i:j]):  # the next few lengths at once: fitted together, used if it grows
                best.prefetch([frames[i:k] for k in range(j, min(j + batch, n) + 1)])
                batch = min(2 * batch, _GROWTH_BATCH_MAX)
            piece = best(frames[i:j])
        bounds.append((i, j))
        i = j
    bounds = _shift_bounds(L, by_frame, frames, fps, bounds, best)
    for _ in range(3):  # frames at a piece's ends that it does not explain form their own piece
        split = []
        for a, b in bounds:
            piece = best(frames[a:b])
            bad_all, bad_one = _bad_frames(L, by_frame, piece, frames[a:b], fps, break_px)
            bad, off = bad_all.tolist(), bad_one.tolist()
            head = next((i for i, x in enumerate(bad) if not x), len(bad))
            tail = next((i for i, x in enumerate(bad[::-1]) if not x), len(bad))
            cuts = {a, b, *(c for c in (a + head, b - tail) if a < c < b)}
            # inside: three frames in a row each with a label off the model (one wrong label is alone)
            run = _bad_run(off[head:len(off) - tail])
            if run is not None:  # a kick the growth missed (a small change of velocity): best cut near it
                r0 = a + head + run
                options = range(max(a + 2, r0 - 2 * _SHIFT), min(b - 2, r0 + _SHIFT) + 1)
                best.prefetch([frames[a:c] for c in options] + [frames[c:b] for c in options])
                costs = [(best(frames[a:c]).cost + best(frames[c:b]).cost, c) for c in options]
                if costs:
                    cuts.add(min(costs)[1])
            cuts = sorted(cuts)
            split += list(zip(cuts[:-1], cuts[1:]))
        if len(split) == len(bounds):
            break
        bounds = _shift_bounds(L, by_frame, frames, fps, split, best)
    bounds = [(a, b) for a, b in bounds if b > a]
    pieces = [_best_piece(L, by_frame, frames[a:b], fps, refine=True, start=_overlapping(previous, frames[a], frames[b - 1]),
                          linear=best.linear(frames[a:b])) for a, b in bounds]
    pieces = _anchored(L, by_frame, fps, pieces, range(len(pieces)))
    return _plausible_pieces(L, by_frame, frames, fps, bounds, pieces, ends)


def _one_camera_flight(L: _Labels, by_frame, piece: Piece) -> bool:
    """``piece`` is a flight all of whose labels come from one camera: the labels fix the ball's direction
    from that camera, its depth only through gravity's curvature (tens of metres off over a second)."""
    if piece.kind != "flight":
        return False
    idx = _piece_labels(by_frame, piece)
    return len(idx) > 0 and len(np.unique(L.cam[idx])) == 1


def _piece_labels(by_frame, piece: Piece) -> np.ndarray:
    """Indices of the labels of ``piece``'s frames (those ``by_frame`` holds), frame order."""
    idx = [by_frame[f] for f in range(piece.first_frame, piece.last_frame + 1) if f in by_frame]
    return np.concatenate(idx) if idx else np.zeros(0, int)


def _anchored(L: _Labels, by_frame, fps: float, pieces: Sequence[Piece], which: range) -> list[Piece]:
    """``pieces`` with those of ``which`` that are one-camera flights (:func:`_one_camera_flight`) fitted
    again with their ends tied to their neighbours: the ball does not jump at a kick, a bounce or a wall,
    so at the break (half-way between the two pieces' frames, when at most :data:`_ANCHOR_GAP` frames
    apart) the flight's position is pulled towards the neighbour's (:func:`app.geometry.motion.position_prior`,
    :data:`ANCHOR_SIGMA_M`), unless the neighbour is a one-camera flight itself; kept when the tied flight
    is :func:`~app.geometry.motion.plausible`."""
    out = list(pieces)
    weak: dict[int, bool] = {}  # piece index -> one-camera flight, each decided once

    def one_camera(i: int) -> bool:
        if i not in weak:
            weak[i] = _one_camera_flight(L, by_frame, pieces[i])
        return weak[i]

    for i in which:
        p = pieces[i]
        if not one_camera(i):
            continue
        times, targets = [], []
        for j in (i - 1, i + 1):
            if not 0 <= j < len(pieces) or one_camera(j):
                continue
            n = pieces[j]
            gap = p.first_frame - n.last_frame if j < i else n.first_frame - p.last_frame
            if gap > _ANCHOR_GAP:
                continue
            tb = (n.last_frame + p.first_frame) / 2 if j < i else (p.last_frame + n.first_frame) / 2
            times.append((tb - p.first_frame) / fps)
            targets.append(n.position([tb], fps)[0])
        if not times:
            continue
        sub = L.take(_piece_labels(by_frame, p))
        t = (sub.frame - p.first_frame) / fps
        q = _refine(sub, "flight", p.params, t, prior=_position_prior(times, np.array(targets), ANCHOR_SIGMA_M))
        if not _plausible("flight", q, (p.last_frame - p.first_frame) / fps):
            continue  # tied, the labels need a motion no ball makes (a wall or a bounce inside the piece)
        out[i] = Piece("flight", p.first_frame, p.last_frame, q,
                       robust_cost(sub.residuals(slice(None), _positions("flight", q, t))), p.alternative)
    return out


def _acceptable(piece: Piece, labelled: int, fps: float, alone: bool) -> bool:
    """``piece`` (``labelled`` labelled frames) can be the ball's motion: :func:`app.geometry.motion.plausible`
    over its frames, and, unless it is ``alone`` (the only piece), at least ``_MIN_FRAMES`` labelled frames:
    a shorter piece between two others is most often the segmentation fitting a wrong label at a break."""
    if not alone and labelled < _MIN_FRAMES:
        return False
    return _plausible(piece.kind, piece.params, (piece.last_frame - piece.first_frame) / fps)


def _plausible_pieces(L: _Labels, by_frame, frames: Sequence[int], fps: float, bounds: Sequence[tuple[int, int]],
                      pieces: Sequence[Piece], ends: tuple[bool, bool]) -> list[Piece]:
    """``pieces`` (of ``frames[a:b]`` for ``bounds``) without those that are not :func:`_acceptable`: their
    frames become a gap the trajectory crosses by a Hermite curve between the neighbours (:func:`_assemble`),
    so their labels are judged against the motion around them and a wrong one is flagged. A piece at an end
    of the sequence (``ends``: ``frames`` starts / ends the sequence) has no neighbour on that side: it is
    fitted together with its neighbour instead (kept when that is acceptable; the labels it does not
    explain are flagged), or dropped."""
    alone = len(pieces) == 1
    ok = [_acceptable(p, b - a, fps, alone) for (a, b), p in zip(bounds, pieces)]
    out: list[Piece | None] = [p if good else None for p, good in zip(pieces, ok)]
    for end, (i, j) in zip(ends, ((0, 1), (len(pieces) - 1, len(pieces) - 2))):
        if not end or len(pieces) < 2 or ok[i] or not ok[j]:
            continue
        (a, b) = (bounds[i][0], bounds[j][1]) if i < j else (bounds[j][0], bounds[i][1])
        merged = _best_piece(L, by_frame, frames[a:b], fps, refine=True, start=pieces[j])
        if _acceptable(merged, b - a, fps, True):
            out[i], out[j] = None, merged
    return [p for p in out if p is not None]


def _overlapping(pieces: Sequence[Piece], first: int, last: int) -> Piece | None:
    """The piece of ``pieces`` sharing the most frames with ``first..last`` (None if none does)."""
    overlap = [(min(p.last_frame, last) - max(p.first_frame, first), -i) for i, p in enumerate(pieces)]
    if not overlap or max(overlap)[0] < 0:
        return None
    return pieces[-max(overlap)[1]]


def _bad_run(bad: list[bool]) -> int | None:
    """Index of the first run of ``_CONFIRM`` consecutive bad frames, or ``None``."""
    count = 0
    for i, x in enumerate(bad):
        count = count + 1 if x else 0
        if count == _CONFIRM:
            return i - _CONFIRM + 1
    return None


def _shift_bounds(L, by_frame, frames, fps, bounds, best: _Best | None = None):
    """Move each boundary between consecutive pieces by up to ``_SHIFT`` frames to the lowest cost
    (``best``: the caller's :class:`_Best`, which keeps the pieces fitted here)."""
    best = best if best is not None else _Best(L, by_frame, fps)
    bounds = list(bounds)
    for b in range(1, len(bounds)):
        (a0, a1), (_, b1) = bounds[b - 1], bounds[b]
        lowest = None
        cuts = range(max(a0 + 1, a1 - _SHIFT), min(b1 - 1, a1 + _SHIFT) + 1)
        best.prefetch([frames[a0:cut] for cut in cuts] + [frames[cut:b1] for cut in cuts])
        for cut in cuts:
            cost = best(frames[a0:cut]).cost + best(frames[cut:b1]).cost
            if lowest is None or cost < lowest[0] - 1e-9:
                lowest = (cost, cut)
        if lowest is not None:
            bounds[b - 1], bounds[b] = (a0, lowest[1]), (lowest[1], b1)
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
        :class:`TrajectoryFit` of the whole sequence (``first_frame = 0``, F rows).

    Raises:
        ValueError: shapes that disagree, non-positive fps.
    """
    pts, use = _check_inputs(points, cameras, widths, fps)
    L = _Labels(pts, cameras, widths, use)
    by_frame = _group(L)
    pieces = _segment(L, by_frame, sorted(by_frame), fps, break_px)
    return _assemble(pts, 0, cameras, widths, fps, L, pieces, flag_px, tau_px, 0, len(pts) - 1)


#: The fast path of :func:`refit_window` re-fits the pieces around an edit alone when the edit lies at least
#: this many labelled frames inside them: beyond the frames a break may move by (``_SHIFT``) and the frames
#: that confirm a break (``_CONFIRM``).
_MARGIN = _SHIFT + _CONFIRM
#: The re-fit after an edit (:func:`refit_window`, :func:`refit_local`, :func:`refit_span`,
#: :func:`local_span`) reads only the pieces holding the edit (between pieces: the two around it) and
#: up to this many on each side: the neighbours it may fit again and, beyond them, the pieces whose
#: ends bound the Hermite gaps it fills. A caller may pass just those pieces (``TrajectoryFit.pieces``).
REFIT_REACH = 2


def _stretch(pieces: Sequence[Piece], first_frame: int, last_frame: int) -> tuple[int, int]:
    """Indices (lo, hi) of the pieces the segmentation of :func:`refit_window` replaces: those that
    overlap ``first_frame..last_frame`` and one neighbour on each side (the breaks to them can move);
    when the window lies between pieces (a gap), the two around it (the breaks beyond them are as far
    from the edit as the pieces are long)."""
    hit = [i for i, p in enumerate(pieces) if p.last_frame >= first_frame and p.first_frame <= last_frame]
    if not hit:  # the window lies between pieces (or outside): its neighbours
        around = [i for i, p in enumerate(pieces) if p.last_frame < first_frame][-1:] + \
                 [i for i, p in enumerate(pieces) if p.first_frame > last_frame][:1]
        return min(around), max(around)
    return max(min(hit) - 1, 0), min(max(hit) + 1, len(pieces) - 1)


def _span(pieces: Sequence[Piece], lo: int, hi: int, first_frame: int, last_frame: int) -> tuple[int, int]:
    """Frames (inclusive) whose place on the trajectory changes when pieces ``lo..hi`` are replaced by
    pieces inside their frames after an edit of ``first_frame..last_frame``: from the frame after the
    kept piece before them (its Hermite gap changes) to the frame before the kept piece after them."""
    if not pieces:
        return first_frame, last_frame
    a = pieces[lo - 1].last_frame + 1 if lo > 0 else pieces[0].first_frame
    b = pieces[hi + 1].first_frame - 1 if hi + 1 < len(pieces) else pieces[-1].last_frame
    return min(a, first_frame), max(b, last_frame)


def refit_span(pieces: Sequence[Piece], first_frame: int, last_frame: int) -> tuple[int, int]:
    """The frames (first, last; inclusive, sequence indices) :func:`refit_window` reads and may change
    after an edit of ``first_frame..last_frame``: the caller needs the labels and the previous fit of
    these frames only (with no pieces, the edited frames alone: they hold every label there is)."""
    if not pieces:
        return first_frame, last_frame
    return _span(pieces, *_stretch(pieces, first_frame, last_frame), first_frame, last_frame)


def _bad_frames(L: _Labels, by_frame, piece: Piece, frames: Sequence[int], fps: float,
                break_px: float) -> tuple[np.ndarray, np.ndarray]:
    """For each of ``frames``: every label further than ``break_px`` from ``piece`` (all bad), and
    some label further (one bad): :func:`_frame_bad` without and with ``worst``, for many frames."""
    idx = np.concatenate([by_frame[f] for f in frames])
    e = np.linalg.norm(L.residuals(idx, piece.position(L.frame[idx], fps)), axis=1)
    counts = np.array([len(by_frame[f]) for f in frames])
    starts = np.concatenate([[0], np.cumsum(counts)[:-1]])
    return np.minimum.reduceat(e, starts) > break_px, np.maximum.reduceat(e, starts) > break_px


def _local_stretch(pieces: Sequence[Piece], first_frame: int, last_frame: int) -> tuple[int, int] | None:
    """Indices (lo, hi) of the pieces :func:`_refit_local` fits again: those holding the edited frames and,
    where an edited frame lies within ``_MARGIN`` frames of a break, the piece across it; ``None`` when
    an edited frame lies outside every piece."""
    hit = [i for i, p in enumerate(pieces) if p.last_frame >= first_frame and p.first_frame <= last_frame]
    if not hit or any(not any(p.first_frame <= f <= p.last_frame for p in pieces) for f in (first_frame, last_frame)):
        return None
    lo, hi = min(hit), max(hit)
    if lo > 0 and first_frame - pieces[lo].first_frame < _MARGIN and not _gap_between(pieces[lo - 1], pieces[lo]):
        lo -= 1
    if hi + 1 < len(pieces) and pieces[hi].last_frame - last_frame < _MARGIN and \
            not _gap_between(pieces[hi], pieces[hi + 1]):
        hi += 1
    return lo, hi


def _gap_between(a: Piece, b: Piece) -> bool:
    """Frames lie between consecutive pieces ``a`` and ``b`` (a piece left out there, or frames without
    labels): the break between them cannot move, the Hermite curve crosses the frames between."""
    return b.first_frame > a.last_frame + 1


def _refit_local(L: _Labels, by_frame, pieces: Sequence[Piece], first_frame: int, last_frame: int, fps: float,
                 break_px: float) -> tuple[int, int, list[Piece]] | None:
    """The fast path of :func:`refit_window`: (lo, hi, the pieces replacing ``pieces[lo..hi]``) or ``None``.

    Pieces ``lo..hi`` (:func:`_local_stretch`) keep their outer ends, the breaks between them are moved
    to the lowest cost as :func:`_segment` does (:func:`_shift_bounds`), and each is fitted again.
    This applies when the edit lies at least ``_MARGIN`` labelled frames inside the stretch (beyond
    the frames a break may move by and those that confirm one) and every piece, fitted again, still
    explains its frames as :func:`_segment` requires of a piece (the same model as before, its first
    and last frame within ``break_px``, no ``_CONFIRM`` frames in a row with a label off it, and
    :func:`_acceptable`)."""
    stretch = _local_stretch(pieces, first_frame, last_frame)
    if stretch is None:
        return None
    lo, hi = stretch
    old = pieces[lo:hi + 1]
    frames = [f for f in sorted(by_frame) if old[0].first_frame <= f <= old[-1].last_frame]
    if not frames or frames[0] != old[0].first_frame or frames[-1] != old[-1].last_frame:
        return None
    # the stretch's outer ends stay: a break the edit lies near could move, a gap's edge cannot
    if (sum(f < first_frame for f in frames) < _MARGIN and not (lo > 0 and _gap_between(pieces[lo - 1], old[0]))) or \
            (sum(f > last_frame for f in frames) < _MARGIN and
             not (hi + 1 < len(pieces) and _gap_between(old[-1], pieces[hi + 1]))):
        return None
    cuts = [sum(f < p.first_frame for f in frames) for p in old] + [len(frames)]
    bounds = list(zip(cuts[:-1], cuts[1:]))
    if any(b - a < 1 for a, b in bounds):
        return None
    best = _Best(L, by_frame, fps)
    bounds = _shift_bounds(L, by_frame, frames, fps, bounds, best)
    for (a, b), p in zip(bounds, old):
        check = best(frames[a:b])
        if check.kind != p.kind:
            return None
        bad, off = _bad_frames(L, by_frame, check, frames[a:b], fps, break_px)
        if bad[0] or bad[-1] or _bad_run(list(off)) is not None:
            return None
    # refined as :func:`_segment` does, each model's refinement started from the piece before the edit
    new = [_best_piece(L, by_frame, frames[a:b], fps, refine=True, start=p, linear=best.linear(frames[a:b]))
           for (a, b), p in zip(bounds, old)]
    new = _anchored(L, by_frame, fps, list(pieces[:lo]) + new + list(pieces[hi + 1:]),
                    range(lo, lo + len(new)))[lo:lo + len(new)]
    if not all(_acceptable(p, b - a, fps, len(pieces) == 1) for (a, b), p in zip(bounds, new)):
        return None  # the segmentation would leave it out (:func:`_plausible_pieces`)
    return lo, hi, new


def local_span(pieces: Sequence[Piece], first_frame: int, last_frame: int) -> tuple[int, int] | None:
    """The frames (first, last; inclusive) :func:`refit_local` reads and may change after an edit of
    ``first_frame..last_frame``: the pieces it fits again (the one holding the edit and, near a break,
    the one across it) and the Hermite gaps to their neighbours; ``None`` when the edit lies outside
    every piece."""
    stretch = _local_stretch(pieces, first_frame, last_frame)
    return _span(pieces, *stretch, first_frame, last_frame) if stretch is not None else None


def _window_labels(fit: TrajectoryFit, points, cameras, widths, need: tuple[int, int]):
    pts, use = _check_inputs(points, cameras, widths, fit.fps)
    if len(pts) != len(fit.positions) or fit.residuals_px.shape[1:] != pts.shape[1:2]:
        raise ValueError(f"points must hold the {len(fit.positions)} frames of fit, got shape {pts.shape}")
    if not (fit.first_frame <= need[0] and need[1] < fit.first_frame + len(pts)):
        raise ValueError(f"the re-fit needs frames {need[0]}..{need[1]}; fit and points hold "
                         f"{fit.first_frame}..{fit.first_frame + len(pts) - 1}")
    L = _Labels(pts, cameras, widths, use, fit.first_frame)
    return pts, L, _group(L)


def refit_local(fit: TrajectoryFit, points: np.ndarray, cameras: Sequence[Camera | None], widths: Sequence[float],
                first_frame: int, last_frame: int, *, flag_px: float = DEFAULT_FLAG_PX,
                break_px: float = DEFAULT_BREAK_PX, tau_px: float = DEFAULT_TAU_PX) -> TrajectoryFit | None:
    """The fast path of :func:`refit_window` alone, for a window holding only ``local_span(fit.pieces,
    first_frame, last_frame)``: the same result when it applies, ``None`` when it does not (the edit
    outside every piece or too near the stretch's ends, or a piece that no longer explains its frames):
    then call :func:`refit_window` with the frames of :func:`refit_span`. Arguments as
    :func:`refit_window`.

    Raises:
        ValueError: shapes that disagree, or ``fit`` does not hold the frames of :func:`local_span`.
    """
    need = local_span(fit.pieces, first_frame, last_frame)
    if need is None:
        return None
    pts, L, by_frame = _window_labels(fit, points, cameras, widths, need)
    fast = _refit_local(L, by_frame, fit.pieces, first_frame, last_frame, fit.fps, break_px)
    if fast is None:
        return None
    lo, hi, new = fast
    pieces = list(fit.pieces[:lo]) + new + list(fit.pieces[hi + 1:])
    return _assemble(pts, fit.first_frame, cameras, widths, fit.fps, L, pieces, flag_px, tau_px, *need,
                     previous=fit, edited=(first_frame, last_frame))


def refit_window(fit: TrajectoryFit, points: np.ndarray, cameras: Sequence[Camera | None], widths: Sequence[float],
                 first_frame: int, last_frame: int, *, flag_px: float = DEFAULT_FLAG_PX,
                 break_px: float = DEFAULT_BREAK_PX, tau_px: float = DEFAULT_TAU_PX,
                 fast_path: bool = True) -> TrajectoryFit:
    """Re-fit after labels changed in frames ``first_frame..last_frame`` (inclusive; sequence indices).

    Fast path (:func:`refit_local`): the piece holding the edit (and, when the edit lies within
    ``_MARGIN`` frames of a break, the piece across it) keeps its outer ends, the break between the two
    moves to the lowest cost as in :func:`_segment`, and each is fitted again, when the edit lies at least
    ``_MARGIN`` labelled frames inside that stretch and every piece still explains its frames as the
    segmentation requires (same model, first and last frame within ``break_px``, no ``_CONFIRM`` frames
    in a row with a label off it). Otherwise the pieces that overlap the
    window, and one neighbour on each side, are segmented and fitted again (:func:`_segment`). The
    other pieces are kept. Then only the frames whose place on the trajectory can have changed are
    assembled again (the pieces replaced and the Hermite gaps to the kept ones); of those, a frame
    outside the window whose kept labels are the same as in ``fit`` keeps its own triangulation
    (``ball_3d``, ``cam_lists``) from ``fit`` (same labels, same cameras), the others are
    triangulated again.

    Args:
        fit: the fit before the edit, of the whole sequence or of a window of it (``fit.first_frame``)
            that holds at least the frames of ``refit_span(fit.pieces, first_frame, last_frame)``;
            made with the same ``cameras`` (a camera change needs :func:`fit_trajectory`). Its pieces
            may be only those within :data:`REFIT_REACH` of the edit (a run of consecutive pieces).
        points: (len(fit.positions), K, 2) labels of the frames ``fit.frames`` with the edit applied.
        cameras, widths, flag_px, break_px, tau_px: as in :func:`fit_trajectory`.
        fast_path: False when the caller knows the fast path does not apply (:func:`refit_local` answered
            ``None`` for the same edit): the pieces are segmented again without trying it a second time.

    Returns:
        A windowed :class:`TrajectoryFit`: all pieces of the sequence, per-frame rows for the frames
        whose place can have changed only (``first_frame`` the first of them).

    Raises:
        ValueError: shapes that disagree, or ``fit`` does not hold the frames the re-fit needs.
    """
    pts, L, by_frame = _window_labels(fit, points, cameras, widths, refit_span(fit.pieces, first_frame, last_frame))
    pieces = list(fit.pieces)
    fast = _refit_local(L, by_frame, pieces, first_frame, last_frame, fit.fps, break_px) \
        if pieces and fast_path else None
    if fast is not None:
        lo, hi, new = fast
    elif pieces:
        lo, hi = _stretch(pieces, first_frame, last_frame)
        start = min(first_frame, pieces[lo].first_frame)
        end = max(last_frame, pieces[hi].last_frame)
        frames = [f for f in sorted(by_frame) if start <= f <= end]
        new = _segment(L, by_frame, frames, fit.fps, break_px, pieces[lo:hi + 1],
                       ends=(lo == 0, hi == len(pieces) - 1)) if frames else []
    else:
        lo, hi = 0, -1
        new = _segment(L, by_frame, sorted(by_frame), fit.fps, break_px) if by_frame else []
    a, b = _span(pieces, lo, hi, first_frame, last_frame)
    pieces = pieces[:lo] + new + pieces[hi + 1:]
    return _assemble(pts, fit.first_frame, cameras, widths, fit.fps, L, pieces, flag_px, tau_px, a, b,
                     previous=fit, edited=(first_frame, last_frame))


def _group(L: _Labels) -> dict[int, np.ndarray]:
    by_frame: dict[int, list[int]] = {}
    for i, f in enumerate(L.frame):
        by_frame.setdefault(int(f), []).append(i)
    return {f: np.array(v) for f, v in by_frame.items()}


def _assemble(pts, pts_first, cameras, widths, fps, L, pieces, flag_px, tau_px, a, b, *,
              previous: TrajectoryFit | None = None, edited: tuple[int, int] | None = None) -> TrajectoryFit:
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
    for r in np.flatnonzero(~covered & (np.isfinite(residuals).sum(axis=1) >= 2) & outliers.any(axis=1)):
        row = a + r - pts_first
        tri = triangulate_frame([BallObservation(int(k), cameras[k], pts[row, k], widths[k])
                                 for k in np.flatnonzero(np.isfinite(residuals[r]))], tau_px=tau_px)
        if tri.point is not None and np.linalg.norm(tri.point - positions[r]) <= GAP_CONSENSUS_M:
            outliers[r, list(tri.kept)] = False
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
    placed = np.isfinite(positions).all(axis=1).tolist()
    for r in range(n):
        keep = tuple(np.flatnonzero(keep_mask[r]).tolist())
        if same[r]:
            old = a + r - previous.first_frame  # type: ignore[union-attr]
            point = previous.ball_3d[old] if np.all(np.isfinite(previous.ball_3d[old])) else None  # type: ignore[union-attr]
            kept = tuple(previous.cam_lists[old])  # type: ignore[union-attr]
        else:
            row = a + r - pts_first
            tri = triangulate_frame([BallObservation(k, cameras[k], pts[row, k], widths[k]) for k in keep],
                                    tau_px=tau_px) if len(keep) >= 2 else FrameTriangulation(None, (), {})
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


__all__ = ["GRAVITY_M_S2", "BALL_RADIUS_M", "KINDS", "SOURCES", "REFIT_REACH", "FrameTriangulation", "triangulate_frame", "Piece",
           "TrajectoryFit", "fit_trajectory", "local_span", "refit_local", "refit_span", "refit_window"]
