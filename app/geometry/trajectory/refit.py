"""The re-fit after an edit: only the pieces the edit touches are fitted again (a fast path that moves one
break, else the pieces around the edit segmented again), and only the frames whose place on the trajectory
can have changed are answered, as a window of the fit.
"""
from __future__ import annotations

from typing import Sequence

import numpy as np

from app.geometry.camera import Camera
from app.geometry.motion import (
    LabelTable as _Labels,
)
from app.geometry.trajectory.fit import TrajectoryFit, _assemble, _check_inputs
from app.geometry.trajectory.segmentation import (
    _CONFIRM,
    _SHIFT,
    DEFAULT_BREAK_PX,
    DEFAULT_FLAG_PX,
    Piece,
    _acceptable,
    _anchored,
    _bad_frames,
    _bad_run,
    _Best,
    _best_piece,
    _group,
    _segment,
    _shift_bounds,
)

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
    bounds = list(zip(cuts[:-1], cuts[1:], strict=True))
    if any(b - a < 1 for a, b in bounds):
        return None
    best = _Best(L, by_frame, fps)
    bounds = _shift_bounds(L, by_frame, frames, fps, bounds, best)
    for (a, b), p in zip(bounds, old, strict=True):
        check = best(frames[a:b])
        if check.kind != p.kind:
            return None
        bad, off = _bad_frames(L, by_frame, check, frames[a:b], fps, break_px)
        if bad[0] or bad[-1] or _bad_run(list(off)) is not None:
            return None
    # refined as :func:`_segment` does, each model's refinement started from the piece before the edit
    new = [_best_piece(L, by_frame, frames[a:b], fps, refine=True, start=p, linear=best.linear(frames[a:b]))
           for (a, b), p in zip(bounds, old, strict=True)]
    new = _anchored(L, by_frame, fps, list(pieces[:lo]) + new + list(pieces[hi + 1:]),
                    range(lo, lo + len(new)))[lo:lo + len(new)]
    if not all(_acceptable(p, b - a, fps, len(pieces) == 1) for (a, b), p in zip(bounds, new, strict=True)):
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
                break_px: float = DEFAULT_BREAK_PX, tau_px: float, rule: str,
                min_baseline_m: float, min_parallax_deg: float) -> TrajectoryFit | None:
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
                     rule=rule, min_baseline_m=min_baseline_m, min_parallax_deg=min_parallax_deg, previous=fit,
                     edited=(first_frame, last_frame))


def refit_window(fit: TrajectoryFit, points: np.ndarray, cameras: Sequence[Camera | None], widths: Sequence[float],
                 first_frame: int, last_frame: int, *, flag_px: float = DEFAULT_FLAG_PX,
                 break_px: float = DEFAULT_BREAK_PX, tau_px: float, rule: str, min_baseline_m: float,
                 min_parallax_deg: float, fast_path: bool = True) -> TrajectoryFit:
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
        cameras, widths, flag_px, break_px, tau_px, rule, min_baseline_m, min_parallax_deg: as
        in :func:`fit_trajectory`.
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
                     rule=rule, min_baseline_m=min_baseline_m, min_parallax_deg=min_parallax_deg, previous=fit,
                     edited=(first_frame, last_frame))
