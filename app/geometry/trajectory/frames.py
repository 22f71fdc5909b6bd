"""One frame's own 3D ball from static cameras: the paper's pairwise triangulation made robust to one wrong
camera (the views that agree on one ball, ``app.geometry.consensus.ball_consensus``, then ``triangulate_ball``).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Hashable, Sequence

import numpy as np

from app.geometry.consensus import ball_consensus
from app.geometry.triangulation import BallObservation, reprojection_error_px, triangulate_ball


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


def triangulate_frame(observations: Sequence[BallObservation], *, tau_px: float, rule: str,
                      min_baseline_m: float, min_parallax_deg: float) -> FrameTriangulation:
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
        rule, min_baseline_m, min_parallax_deg: as in :func:`~app.geometry.triangulation.triangulate_ball`
            (the baseline and parallax also for the consensus' proposing pairs).

    Returns:
        :class:`FrameTriangulation`.
    """
    obs = list(observations)
    none = FrameTriangulation(None, (), {})
    if len(obs) < 2:
        return none
    consensus = ball_consensus(obs, tau_px=tau_px, min_baseline_m=min_baseline_m, min_parallax_deg=min_parallax_deg)
    if consensus.point is None or consensus.ambiguous or len(consensus.inliers) < 2:
        return none
    kept = [o for o in obs if o.view_id in set(consensus.inliers)]
    res = triangulate_ball(kept, tau_px=tau_px, rule=rule, min_baseline_m=min_baseline_m,
                           min_parallax_deg=min_parallax_deg)
    if res.point is None:
        return none
    errors = {o.view_id: reprojection_error_px(o.camera, res.point, o.point_px) for o in obs}
    return FrameTriangulation(res.point, tuple(o.view_id for o in kept), errors)
