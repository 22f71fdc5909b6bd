"""The segmentation of a sequence's labels into pieces under one motion model each (``flight`` / ``roll``).

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
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import numpy as np

from app.geometry.motion import (
    GRAVITY_M_S2,
    KINDS,
    linear_fits,
    robust_cost,
)
from app.geometry.motion import (
    LabelTable as _Labels,
)
from app.geometry.motion import (
    determined as _determined,
)
from app.geometry.motion import (
    plausible as _plausible,
)
from app.geometry.motion import (
    position_prior as _position_prior,
)
from app.geometry.motion import (
    positions as _positions,
)
from app.geometry.motion import (
    refine as _refine,
)
from app.geometry.motion import (
    shifted as _shifted,
)
from app.geometry.motion import (
    stop_time as _stop_time,
)

#: Defaults (pixels on a 1920-px-wide image). Label noise is about 1 px; a wrong label is tens to
#: hundreds of px off. ``flag_px`` flags a label against the fitted trajectory; ``break_px`` ends a
#: piece when three consecutive frames are all further than that from its prediction.
DEFAULT_FLAG_PX = 15.0


DEFAULT_BREAK_PX = 10.0


_MIN_FRAMES = 4


#: A one-camera flight's position at a break is tied to its neighbour's this tightly (m): a kick changes
#: the velocity, not the position, and the break lies within half a frame of the midpoint (at 30 m/s,
#: 0.6 m); the depth it fixes is otherwise tens of metres loose. Neighbours further than
#: ``_ANCHOR_GAP`` frames away (frames without labels between) do not tie it.
ANCHOR_SIGMA_M = 0.5


_ANCHOR_GAP = 3


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

    def position(self, frames: np.ndarray | Sequence[float], fps: float) -> np.ndarray:
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
    x0 = start if start is not None else linear
    assert x0 is not None  # without a start, linear is the linear fit (made above when not given)
    q = _refine(sub, kind, x0, t)
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
    fits = dict(zip(missing, linear_fits(L, [(idx, kind, first) for kind in missing], fps), strict=True))
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
        for (key, kind), fit in zip(owners, linear_fits(self.L, jobs, self.fps), strict=True):
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
            ordered = sorted(cuts)
            split += list(zip(ordered[:-1], ordered[1:], strict=True))
        if len(split) == len(bounds):
            break
        bounds = _shift_bounds(L, by_frame, frames, fps, split, best)
    bounds = [(a, b) for a, b in bounds if b > a]
    pieces = [_best_piece(L, by_frame, frames[a:b], fps, refine=True,
                          start=_overlapping(previous, frames[a], frames[b - 1]),
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
    ok = [_acceptable(p, b - a, fps, alone) for (a, b), p in zip(bounds, pieces, strict=False)]
    out: list[Piece | None] = [p if good else None for p, good in zip(pieces, ok, strict=False)]
    for end, (i, j) in zip(ends, ((0, 1), (len(pieces) - 1, len(pieces) - 2)), strict=True):
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


def _group(L: _Labels) -> dict[int, np.ndarray]:
    by_frame: dict[int, list[int]] = {}
    for i, f in enumerate(L.frame):
        by_frame.setdefault(int(f), []).append(i)
    return {f: np.array(v) for f, v in by_frame.items()}


def _bad_frames(L: _Labels, by_frame, piece: Piece, frames: Sequence[int], fps: float,
                break_px: float) -> tuple[np.ndarray, np.ndarray]:
    """For each of ``frames``: every label further than ``break_px`` from ``piece`` (all bad), and
    some label further (one bad): :func:`_frame_bad` without and with ``worst``, for many frames."""
    idx = np.concatenate([by_frame[f] for f in frames])
    e = np.linalg.norm(L.residuals(idx, piece.position(L.frame[idx], fps)), axis=1)
    counts = np.array([len(by_frame[f]) for f in frames])
    starts = np.concatenate([[0], np.cumsum(counts)[:-1]])
    return np.minimum.reduceat(e, starts) > break_px, np.maximum.reduceat(e, starts) > break_px
