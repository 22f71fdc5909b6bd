"""Robust multi-view consensus of the ball: which labelled views agree on one 3D ball, and which do not.

The paper's fusion (:func:`app.geometry.triangulation.triangulate_ball`) averages every pair whose
error is below tau; one bad view then drops every pair it belongs to and, with two or three views,
leaves no ball at all. Here each pair of views with enough geometry (baseline, parallax, in front of
both cameras) proposes a ball (its DLT point, Hartley and Zisserman 12.2); every view votes for a
proposal when the proposal reprojects within ``tau_px`` of its label (errors scaled to a 1920-px-wide
image, the triangulation's ``max_scaled_1920`` units); the proposal with the most votes wins, ties
broken by the smallest sum of the voters' errors (MSAC, Torr and Zisserman 2000, with the
truncated-quadratic cost replaced by the vote count first). The ball is then re-triangulated from
all voters (DLT over them) and every view's error to it is reported. For V views this costs
V (V - 1) / 2 proposals of V reprojections: nothing for the 2 to 6 views of a broadcast system or
an ISSIA frame.

The consensus is *ambiguous* when a proposal with as many votes as the winner has a voter set
disjoint from the winner's (two camps, e.g. two pairs of views on two different balls): the culprit
cannot be told.

World frame: SoccerNet (metres, origin at the centre spot, z down). Pixels: continuous, origin at the
top-left corner of each view's own image.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from itertools import combinations
from typing import Callable, Hashable, Mapping, Sequence

import numpy as np

from app.geometry.pair_error import REFERENCE_WIDTH_PX
from app.geometry.triangulation import (
    BallObservation,
    PairGeometry,
    pair_geometry,
    reprojection_error_px,
    triangulate_dlt,
    undistort_pixels,
)


@dataclass(frozen=True)
class Consensus:
    """Result of :func:`ball_consensus`.

    Attributes:
        point: (3,) consensus ball centre, world metres (z down), or None (no pair of views with enough
            geometry and an error below tau).
        inliers: ids of the views that agree with ``point`` (input order), empty without one.
        outliers: ids of the labelled views that do not (input order).
        errors_1920: view id -> reprojection error of ``point`` in that view, px scaled to a
            1920-px-wide image (None: behind the camera, or no point).
        ambiguous: another proposal had as many votes with a disjoint voter set.
        best_pair_error_1920: the smallest pair error among the pairs with enough geometry (px at 1920
            width, the larger of the pair's two errors; ``inf`` when every such pair's point lies behind
            one of its cameras), None when no pair had enough geometry.
        support_pairs: number of pairs of views that proposed a ball both of them agree with.
    """

    point: np.ndarray | None
    inliers: tuple[Hashable, ...]
    outliers: tuple[Hashable, ...]
    errors_1920: dict[Hashable, float | None]
    ambiguous: bool
    best_pair_error_1920: float | None
    support_pairs: int


def _scaled_error(o: BallObservation, point: np.ndarray) -> float | None:
    e = reprojection_error_px(o.camera, point, o.point_px)
    return None if e is None else e * REFERENCE_WIDTH_PX / o.image_width


#: A ball one pair proposes: its voters' summed weight, their summed scaled errors (px), the voters (indices of the
#: observations agreeing with it) and the point (world metres).
_Proposal = tuple[float, float, frozenset[int], np.ndarray]


def _proposals(obs: list[BallObservation], w: list[float], tol: list[float], min_baseline_m: float,
               min_parallax_deg: float, plausible: Callable[[np.ndarray], bool] | None,
               geometry: Callable[[BallObservation, BallObservation], PairGeometry]
               ) -> tuple[list[_Proposal], float | None]:
    """Every ball a pair of views proposes that both its views agree with, with its votes (module docstring), and
    the smallest pair error (px at 1920 width; ``inf`` when the only pairs diverge or meet where no ball can be, None
    when no pair is wide enough)."""
    proposals: list[_Proposal] = []
    best_pair: float | None = None
    for i, j in combinations(range(len(obs)), 2):
        g = geometry(obs[i], obs[j])
        if g.baseline_m < min_baseline_m:
            continue
        if g.parallax_deg < min_parallax_deg:
            continue
        h = g.h  # the DLT of the two undistorted pixels
        if abs(h[3]) < 1e-12:
            continue
        point = h[:3] / h[3]
        pair_errors = [_scaled_error(o, point) for o in obs]
        e_i, e_j = pair_errors[i], pair_errors[j]
        if e_i is None or e_j is None:  # the rays diverge: the pair cannot agree
            best_pair = math.inf if best_pair is None else best_pair
            continue
        if plausible is not None and not plausible(point):  # they meet where no ball can be
            best_pair = math.inf if best_pair is None else best_pair
            continue
        pair_e = max(e_i, e_j)
        best_pair = pair_e if best_pair is None else min(best_pair, pair_e)
        if not (e_i < tol[i] and e_j < tol[j]):
            continue
        agreeing = {k: e for k, e in enumerate(pair_errors) if e is not None and e < tol[k]}
        voters = frozenset(agreeing)
        proposals.append((sum(w[k] for k in voters), sum(agreeing[k] for k in voters), voters, point))
    return proposals, best_pair


def _refit(obs: list[BallObservation], undist: list[np.ndarray], tol: list[float], voters: frozenset[int],
           point: np.ndarray) -> np.ndarray:
    """The ball of more than two ``voters`` refitted by the DLT of all their rays when every voter still agrees with
    it (within its tolerance ``tol``), else ``point`` as the pair proposed it."""
    members = sorted(voters)
    h = triangulate_dlt(np.stack([obs[k].camera.projection_matrix for k in members]),
                        np.stack([undist[k] for k in members]))
    if abs(h[3]) > 1e-12:
        refit = h[:3] / h[3]
        errs = [_scaled_error(obs[k], refit) for k in members]
        if all(e is not None and e < tol[k] for e, k in zip(errs, members, strict=True)):
            return refit
    return point


def ball_consensus(observations: Sequence[BallObservation], *, tau_px: float, min_baseline_m: float,
                   min_parallax_deg: float, weights: Mapping[Hashable, float] | None = None,
                   tolerances_px: Mapping[Hashable, float] | None = None,
                   plausible: Callable[[np.ndarray], bool] | None = None,
                   geometry: Callable[[BallObservation, BallObservation], PairGeometry] = pair_geometry) -> Consensus:
    """The ball most labelled views agree on (see the module docstring), for any number of views.

    Args:
        observations: calibrated views with a ball label (unique view ids).
        tau_px: a view agrees with a ball when its reprojection error, scaled to a 1920-px-wide image,
            is below this (px).
        min_baseline_m: pairs whose camera centres are closer do not propose a ball (metres).
        min_parallax_deg: pairs whose rays meet at a smaller angle do not propose a ball (degrees).
        weights: view id -> weight of its vote (default 1): what the view's calibration is worth (the doubt
            judge gives a view of uncertain calibration half a vote). Proposals are ranked by the sum of
            their voters' weights; "ambiguous" compares those sums.
        tolerances_px: view id -> its own tolerance (px at 1920 width, default ``tau_px``): a view whose
            calibration predicts a larger pixel error agrees within that.
        plausible: a test of a proposed ball (world metres -> bool); a pair whose point fails it proposes
            nothing (two rays that meet under the grass or far outside the stadium agree by coincidence).
        geometry: where each pair's baseline, parallax and DLT solution come from
            (``app.geometry.triangulation.pair_geometry``, or the recomputation's ``PairGeometryMemo``).

    Returns:
        A :class:`Consensus`; ``point`` is None when no pair proposes a ball both its views agree with.

    Raises:
        ValueError: duplicate view ids or non-positive ``tau_px``.

    >>> from app.geometry.camera import Camera
    >>> cams = [Camera.from_parameters(focal_px=1500.0, principal_point=(960.0, 540.0), pan_deg=p,
    ...                                tilt_deg=80.0, roll_deg=0.0, position_m=c)
    ...         for p, c in ((0.0, [0, 60, -15]), (90.0, [-70, 0, -15]), (-90.0, [70, 0, -15]))]
    >>> ball = np.array([1.0, 2.0, -0.11])
    >>> obs = [BallObservation(i, c, c.project(ball)[0][0], 1920) for i, c in enumerate(cams)]
    >>> obs[2] = BallObservation(2, cams[2], obs[2].point_px + [200.0, 0.0], 1920)  # a wrong label
    >>> r = ball_consensus(obs, tau_px=20.0, min_baseline_m=1.0, min_parallax_deg=2.0)
    >>> r.inliers, r.outliers, np.round(r.point, 6).tolist()
    ((0, 1), (2,), [1.0, 2.0, -0.11])
    """
    if not tau_px > 0:
        raise ValueError(f"tau_px must be positive, got {tau_px!r}")
    obs = list(observations)
    ids = [o.view_id for o in obs]
    if len(set(ids)) != len(ids):
        raise ValueError(f"observations: view ids must be unique, got {ids!r}")
    undist = [undistort_pixels(o.camera, o.point_px)[0] for o in obs]
    w = [1.0 if weights is None else float(weights.get(o.view_id, 1.0)) for o in obs]
    tol = [tau_px if tolerances_px is None else max(tau_px, float(tolerances_px.get(o.view_id, tau_px))) for o in obs]
    proposals, best_pair = _proposals(obs, w, tol, min_baseline_m, min_parallax_deg, plausible, geometry)
    if not proposals:
        return Consensus(None, (), tuple(ids), {v: None for v in ids}, False, best_pair, 0)
    proposals.sort(key=lambda p: (-p[0], p[1]))
    n_best, _, voters, point = proposals[0]
    ambiguous = any(abs(n - n_best) < 1e-9 and not (v & voters) for n, _, v, _ in proposals[1:])
    if len(voters) > 2:
        point = _refit(obs, undist, tol, voters, point)
    errors = {o.view_id: _scaled_error(o, point) for o in obs}
    inliers = tuple(o.view_id for o, t in zip(obs, tol, strict=True)
                    if (e := errors[o.view_id]) is not None and e < t)
    outliers = tuple(v for v in ids if v not in inliers)
    point = np.asarray(point, float)
    point.setflags(write=False)
    return Consensus(point, inliers, outliers, errors, ambiguous, best_pair, len(proposals))
