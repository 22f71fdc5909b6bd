"""A ball agreed on by one pair of viewpoints whose rays meet only at the edge of tau, by more than their cameras'
uncertainty: ``views_disagree`` with code ``lone_pair`` (the judge's rule 3, :func:`app.geometry.doubts.judge_system`).

Why: two rays that are the same ball's meet well within tau, while two rays that cross by chance (a replay of
another instant, a label on another object along the epipolar band) meet anywhere within it; with only two
viewpoints no third view checks which it is. The ball's rule refuses such a ball (``app.geometry.evidence`` rule 4,
reason ``lone_pair_at_tau_edge``, :data:`~app.geometry.evidence.LONE_PAIR_MAX_ERROR_TAU` of the triangulation's tau:
every one-pair right ball of the sets that chose it meets within 0.61 tau, ``benchmarks/VOUCH.md`` 2026-11-29). The
doubts' consensus tolerance is wider (``consensus_tau_px``, 25 px at 1920 width against the triangulation's 20), so
such a pair agreed and the judge said nothing: a desynchronised replay with one other view went unnoticed, its system
without a ball or with one metres off (``benchmarks/DOUBTS.md`` 2026-11-30).

A pair's error at the edge of tau can also be a camera's error: a camera whose own calibration sigma is large (a
view with few lines, an unsure fit) puts a right label that far off. So the doubt is raised only where the cameras'
stated uncertainty does not explain the error: both viewpoints hold a full vote (admitted, sure, with enough line
classes: :func:`app.geometry.weighting.calibration_weight` 1) and the error exceeds their joint pixel sigma (the two
calibrations' sigmas, :func:`app.geometry.weighting.pixel_sigma`, in quadrature). Two views too close to triangulate
(baseline or parallax below the consensus's minimum: a near duplicate) are one viewpoint: their agreement checks
nothing. The doubt names no view (either may be the one of another instant); a third view of the ball, or a check of
the replays' timing, decides; no fix is offered.

Chosen on dev-large and seeds 201-202 (``benchmarks/DOUBTS.md``, 2026-11-30): the four desynchronised replays met at
14.8-21.1 px with joint sigmas of 3.2-11.7 px (1.45-4.7 sigmas); the five clean pairs beyond the edge had a camera
with a half vote (three) or a joint sigma of 22-24 px (two: 0.64 and 0.81 of it). On seeds 203-205, read after, the
clean two-viewpoint pairs of two full votes all met within 12.3 px.
"""
from __future__ import annotations

import math
from itertools import combinations
from typing import Callable, Hashable, Mapping, Sequence

from app.geometry.consensus import Consensus
from app.geometry.doubts.contract import Doubt, DoubtSettings, _r
from app.geometry.evidence import LONE_PAIR_MAX_ERROR_TAU
from app.geometry.triangulation import BallObservation, PairGeometry

#: A full vote (``calibration_weight`` of an admitted, sure view with enough line classes).
FULL_VOTE = 1.0


def viewpoints(ids: Sequence[Hashable], obs: Mapping[Hashable, BallObservation], s: DoubtSettings,
               geometry: Callable[[BallObservation, BallObservation], PairGeometry]) -> list[list[Hashable]]:
    """``ids`` grouped into viewpoints: two views whose pair has too little geometry to triangulate (camera centres
    closer than ``min_baseline_m``, or ball rays meeting at less than ``min_parallax_deg``, the consensus's own test)
    are one viewpoint, transitively. Groups in the order of their first member."""
    parent = {i: i for i in ids}

    def root(i: Hashable) -> Hashable:
        while parent[i] != i:
            i = parent[i]
        return i

    for a, b in combinations(ids, 2):
        g = geometry(obs[a], obs[b])
        if g.baseline_m < s.min_baseline_m or g.parallax_deg < s.min_parallax_deg:
            parent[root(a)] = root(b)
    groups: dict[Hashable, list[Hashable]] = {}
    for i in ids:
        groups.setdefault(root(i), []).append(i)
    return list(groups.values())


def lone_pair_doubts(cons: Consensus, obs: Sequence[BallObservation], labelled: Sequence[Hashable],
                     weight: Mapping[Hashable, float], sigma: Mapping[Hashable, float], s: DoubtSettings,
                     geometry: Callable[[BallObservation, BallObservation], PairGeometry]) -> list[Doubt]:
    """``[views_disagree]`` (code ``lone_pair``) when the consensus ball rests on one pair of viewpoints whose rays
    meet only at the edge of tau by more than their cameras' uncertainty (module docstring), else ``[]``.

    Args:
        cons: the judge's consensus (a ball, not ambiguous; else None is returned).
        obs: the voters' observations (labelled views and helpers), ids as the consensus's.
        labelled: ids of the labelled views that take part (helpers hold no full vote).
        weight: view id -> vote (``calibration_weight``); sigma: view id -> pixel sigma (px at 1920 width).
        s: the judge's thresholds (the triangulation's tau, the minimum baseline and parallax).
        geometry: the pairs' raw geometry (the consensus's).

    Returns:
        The doubt (or none), its evidence: the views, the pair's error (the larger inlier error to the consensus
        ball, px at 1920 width), the edge (``LONE_PAIR_MAX_ERROR_TAU`` of the triangulation's tau) and the joint
        sigma (px at 1920 width).
    """
    if cons.point is None or cons.ambiguous:
        return []
    by_id = {o.view_id: o for o in obs}
    groups = viewpoints([i for i in cons.inliers if i in by_id], by_id, s, geometry)
    if len(groups) != 2:
        return []
    full = [[sigma.get(i, math.inf) for i in g if i in labelled and weight.get(i, 0.0) >= FULL_VOTE] for g in groups]
    if not all(full):
        return []
    errors = [cons.errors_1920.get(i) for g in groups for i in g]
    if any(e is None for e in errors):
        return []
    error = max(e for e in errors if e is not None)
    edge = LONE_PAIR_MAX_ERROR_TAU * s.triangulation_tau_px
    joint = math.hypot(min(full[0]), min(full[1]))
    if not (error > edge and error > joint):
        return []
    return [Doubt("views_disagree", None, "lone_pair",
                 {"views": [i for g in groups for i in g], "best_pair_error_px_1920": _r(error), "edge_px": _r(edge),
                  "tau_px": _r(s.triangulation_tau_px), "joint_sigma_px_1920": _r(joint), "ambiguous": False,
                  "third_view": True})]
