"""The 3D ball judged by its evidence: each pair's point weighed by what its two views know, pairs that disagree
beyond their joint sigma left out, and the fused ball kept only when its own uncertainty is within a bound and it
lies in the play volume within that uncertainty (pure numpy).

The paper averages every pair kept by tau and the baseline; v3d's default rule (``ball_rule`` "weights") adds rules
by class on top (a parallax threshold, a play volume tested on each pair's point, a few-lined or unsure camera that
neither makes nor moves a ball alone). Under ``ball_rule`` "evidence" the pairs the paper keeps are judged by their
uncertainty instead (Hartley and Zisserman, *Multiple View
Geometry*, 2nd ed., sec. 5.2.3 and 12.2; the confidence-weighted triangulation of anipose and Pose2Sim):

0. a kept pair whose two cameras put the players both views see in places that disagree (``players_disagree``,
   :func:`app.geometry.calibration.players.pair_players_disagreement`) is left out (reason ``players_disagree``): with
   two views an error of one camera along the epipolar line (a mirrored or misplaced camera) leaves the ball's rays no
   residual, and the players are a second, independent look at the same two cameras (in a desynchronised replay
   they have moved too);
0b. before anything is weighed, the largest set of views that agree on one ball is chosen (RANSAC's consensus:
   Fischler and Bolles, *Random Sample Consensus*, CACM 24(6), 1981; Hartley and Zisserman sec. 4.7.1, every pair
   a sample): each kept pair's point is a hypothesis, its support the views of the kept pairs whose reprojection
   error there is within tau (the paper's own test of agreement, in the pair rule's units) or within
   :data:`CONSENSUS_SIGMAS` of their own pixel sigma (a camera known only to 80 px cannot refute a point 60 px off
   its label: it supports every hypothesis and decides none); the largest support wins, two of one size ordered by
   the smaller sum of their views' errors over tau. Each pair with a view outside it is left out (reason
   ``outside_consensus``); nothing is when every view is in it.
   Why before the weighing and by count: a replay of another instant whose ray crosses the others' within tau by
   chance makes sharp pairs, and rule 2 weighs them above the right pairs of a few-lined or unsure camera, so the
   gate dropped the right side; a count of agreeing views does not depend on their sigmas. Why the smaller error
   between supports of one size (with three views, two pairs sharing a view): right pairs meet well within tau,
   chance crossings anywhere in it (rule 4);
1. each view has a pixel sigma (px at 1920 width: its label's and its calibration's, in quadrature); each kept pair's
   point ``p_k`` has the information matrix ``I_k = sum_v J_v^T J_v / sigma_v^2`` of its two views
   (:func:`app.geometry.spread.projection_jacobian` at ``p_k``). A low-parallax pair's information is nearly
   singular along its depth, an unsure camera's small: such a pair is not dropped, it only tells what it knows;
2. the ball is the information-weighted mean ``X = (sum I_k)^-1 sum I_k p_k`` of the pairs; a pair whose point lies
   beyond :data:`GATE_CHI2` of ``X`` in its own metric ``(p_k - X)^T I_k (p_k - X)`` (chi-square, 3 degrees of
   freedom, 99 %) disagrees with the others beyond their joint sigma: the worst such pair is dropped (reason
   ``beyond_joint_sigma``) and ``X`` fused again, until every pair agrees;
3. the ball's sigma is the square root of the largest eigenvalue of the least-squares covariance of the views of the
   pairs left (:func:`app.geometry.spread.position_covariance`, metres along its least certain direction); the ball
   stands when that sigma is within ``max_sigma_m`` (else every pair left is dropped with ``sigma_above_bound``) and
   when it lies within :data:`VOLUME_SIGMAS` sigmas of the play volume (else ``outside_play_volume``);
4. a ball left resting on one pair whose rays meet only in the outer part of tau (its error above
   ``lone_pair_max_error_tau`` of tau, :data:`LONE_PAIR_MAX_ERROR_TAU` in the recomputation) is refused (reason
   ``lone_pair_at_tau_edge``): a right pair's rays meet well within tau (every one-pair right ball of the sets that
   chose it within 0.61 tau, 95 % of two-view pairs within 0.26 tau: ``benchmarks/VOUCH.md``), while two rays that
   cross by chance (a replay of another instant, a label on another object along the epipolar band) meet anywhere
   within it; with one pair no other view checks which of the two it is, and the ball such a pair makes is metres
   off when it is the chance crossing.

World frame: SoccerNet (metres, origin at the centre spot, z down). Pixels at 1920 width (``REFERENCE_WIDTH_PX``).
"""
from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Any, Callable, Mapping, Sequence

import numpy as np

from app.geometry.pair_error import scaled_error_px
from app.geometry.spread import position_sigma_m, projection_jacobian
from app.geometry.triangulation import (
    STATUS_NO_PAIR_KEPT,
    STATUS_TRIANGULATED,
    BallObservation,
    PairResult,
    TriangulationResult,
    reprojection_error_px,
)

#: A pair disagrees with the fused ball when its squared Mahalanobis distance in its own information exceeds this: the
#: 99 % quantile of the chi-square law of 3 degrees of freedom (a pair's point has three coordinates).
GATE_CHI2 = 11.345

#: A ball stands when the play volume lies within this many of its sigmas (its least certain direction): a ball
#: placed a little outside by its own uncertainty may be in the volume; one placed farther cannot.
VOLUME_SIGMAS = 3.0

#: A ball resting on one pair is refused when that pair's error is above this fraction of tau (rule 4 of the module
#: docstring). Chosen on the four sets ``benchmarks/VOUCH.md`` names (2026-11-29, late night: dev-large, seed-204,
#: seed-201-s1301, seed-202-s1301): their 453 one-pair right balls meet within 0.61 tau (all but two within 0.5), their
#: two wrong one-pair balls (desynchronised replays, 2.2 and 10.7 m off) at 0.74 and 0.97 tau. On four held-out sets
#: it withheld no wrong ball and two right ones whose pairs meet at 0.71 and 0.74 tau: the margin is thin.
LONE_PAIR_MAX_ERROR_TAU = 0.7

#: A view supports a hypothesised ball within this many of its own pixel sigmas, when that is more than tau (rule 0b
#: of the module docstring): the 99 % radius of a two-dimensional normal pixel error (the square root of the
#: chi-square quantile of 2 degrees of freedom, 9.21), the level of :data:`GATE_CHI2`.
CONSENSUS_SIGMAS = 3.035

# Relative eigenvalue level below which an information matrix fixes no point (a direction it knows nothing of).
_SINGULAR_EPS = 1e-12


@dataclass(frozen=True)
class EvidenceBall:
    """What :func:`judge_by_evidence` gives.

    Attributes:
        result: the triangulation with the pairs judged (reasons ``players_disagree``, ``outside_consensus``,
            ``beyond_joint_sigma``, ``sigma_above_bound``, ``outside_play_volume`` and ``lone_pair_at_tau_edge`` added
            where they apply) and the fused ball, or status ``no_pair_kept``.
        sigma_m: the ball's sigma (metres, one standard deviation along its least certain direction) of the pairs
            left, also when the bound refused the ball (what refused it); None without pairs left or when their
            views fix no point.
    """

    result: TriangulationResult
    sigma_m: float | None


def view_sigma_px(label_diameter_px: float | None, calibration_sigma_px: float, label_noise: float,
                  min_sigma_px: float) -> float:
    """One view's pixel sigma (px at 1920 width): its label's centre noise (``label_noise`` times the label's
    diameter ``label_diameter_px``, px at 1920 width; 0 for a point label) and its calibration's pixel sigma
    (``calibration_sigma_px``, ``app.geometry.weighting.calibration_weight``; ``inf`` for an undetermined camera) in
    quadrature, at least ``min_sigma_px``."""
    label = 0.0 if label_diameter_px is None else label_noise * float(label_diameter_px)
    return max(float(min_sigma_px), math.sqrt(label * label + float(calibration_sigma_px) ** 2))


def _information(obs: Sequence[BallObservation], point: np.ndarray, sigma: Mapping[Any, float]
                 ) -> np.ndarray | None:
    """``sum_v J_v^T J_v / sigma_v^2`` (3, 3), 1/m^2, of ``obs`` at ``point``; None where it lies behind a camera. A
    view of infinite sigma adds nothing."""
    info = np.zeros((3, 3))
    for o in obs:
        s = float(sigma[o.view_id])
        if not math.isfinite(s):
            continue
        J = projection_jacobian(o, point)
        if J is None:
            return None
        info += J.T @ J / (s * s)
    return info


def kept_pairs_sigma_m(observations: Sequence[BallObservation], pairs: Sequence[PairResult], ball: np.ndarray,
                       sigma_px_1920: Mapping[Any, float]) -> float | None:
    """The sigma (metres, one standard deviation along the least certain direction) of ``ball`` ((3,) world metres)
    made from the kept ``pairs`` of ``observations``: :func:`app.geometry.spread.position_sigma_m` of the views of
    those pairs whose pixel sigma (``sigma_px_1920``, px at 1920 width) is finite (a camera known to nothing adds
    nothing); None when no view is left or they fix no point."""
    used = {v for p in pairs if p.kept for v in (p.view_a, p.view_b)}
    views = [o for o in observations if o.view_id in used and math.isfinite(float(sigma_px_1920[o.view_id]))]
    return position_sigma_m(views, ball, sigma_px_1920) if views else None


def _squared_distance(r: np.ndarray, info: np.ndarray) -> float:
    """``r^T I r``: the squared distance (no unit) of an offset ``r`` (3,) metres in the metric of an information
    matrix ``info`` (3, 3), 1/m^2."""
    return float(r @ info @ r)


def _fixes_point(info: np.ndarray) -> bool:
    eig = np.linalg.eigvalsh(info)
    return bool(eig[-1] > 0 and eig[0] > _SINGULAR_EPS * eig[-1])


def _kept_informations(pairs: list[PairResult], by_id: Mapping[Any, BallObservation],
                       sigma_px_1920: Mapping[Any, float],
                       players_disagree: Callable[[Any, Any], bool] | None) -> dict[int, np.ndarray]:
    """The information matrix (3, 3; 1/m^2, world frame) of each kept pair of ``pairs`` (by index) from its two views'
    pixel sigmas (:func:`_information`); a pair whose cameras' players disagree, or whose point lies behind a camera,
    is dropped in ``pairs`` itself (reasons ``players_disagree``, ``behind_camera``) and has none."""
    infos: dict[int, np.ndarray] = {}
    for k, p in enumerate(pairs):
        if not p.kept or p.point is None:
            continue
        if players_disagree is not None and players_disagree(p.view_a, p.view_b):
            pairs[k] = dataclasses.replace(p, kept=False, reason="players_disagree")
            continue
        info = _information((by_id[p.view_a], by_id[p.view_b]), p.point, sigma_px_1920)
        if info is None:  # the pair's point behind a camera: the paper's rules dropped it already
            pairs[k] = dataclasses.replace(p, kept=False, reason="behind_camera")
            continue
        infos[k] = info
    return infos


def _support(point: np.ndarray, views: Sequence[BallObservation], tau_px: float, rule: str,
             sigma_px_1920: Mapping[Any, float]) -> tuple[frozenset, float]:
    """The views of ``views`` that agree with a hypothesised ball ``point`` ((3,) world metres, SoccerNet frame):
    their reprojection error there, in ``rule``'s units (px at 1920 width for the scaled rules,
    :func:`app.geometry.pair_error.scaled_error_px`), within ``tau_px`` or within :data:`CONSENSUS_SIGMAS` of their
    pixel sigma ``sigma_px_1920`` (view id -> px at 1920 width); a view the point lies behind agrees with nothing.
    Returns them and the sum of their errors over tau (no unit)."""
    support, total = [], 0.0
    for o in views:
        e = scaled_error_px(reprojection_error_px(o.camera, point, o.point_px), o.image_width, rule)
        if e is not None and e <= max(tau_px, CONSENSUS_SIGMAS * float(sigma_px_1920[o.view_id])):
            support.append(o.view_id)
            total += e / tau_px
    return frozenset(support), total


def largest_consensus(pairs: Sequence[PairResult], kept: Sequence[int], by_id: Mapping[Any, BallObservation],
                      tau_px: float, rule: str, sigma_px_1920: Mapping[Any, float]) -> frozenset | None:
    """The largest set of views that agree on one ball (rule 0b of the module docstring; RANSAC, Fischler and Bolles
    1981, with every pair as a sample): each pair ``pairs[k]`` of ``kept`` (indices; each with a point, world metres)
    a hypothesis, its support the views of the kept pairs (``by_id``: view id -> observation) within ``tau_px`` of
    it (``rule``'s units, px at 1920 width for the scaled rules) or within :data:`CONSENSUS_SIGMAS` of their pixel
    sigma (``sigma_px_1920``, px at 1920 width); the largest, two of one size ordered by the smaller sum of errors
    over tau, then by the pairs' order.

    Returns:
        Its view ids, or None when ``kept`` is empty or it holds every view of the kept pairs (nothing to leave
        out).

    Raises:
        KeyError: a view of a kept pair without an observation in ``by_id`` or a sigma.
    """
    ids = {v for k in kept for v in (pairs[k].view_a, pairs[k].view_b)}
    views = [o for v, o in by_id.items() if v in ids]
    best: tuple[tuple[int, float], frozenset] | None = None
    for k in kept:
        support, total = _support(np.asarray(pairs[k].point, float), views, tau_px, rule, sigma_px_1920)
        key = (len(support), -total)
        if best is None or key > best[0]:
            best = (key, support)
    if best is None or len(best[1]) == len(ids):
        return None
    return best[1]


def _outside_consensus(pairs: Sequence[PairResult], kept: Sequence[int], by_id: Mapping[Any, BallObservation],
                       triangulated: TriangulationResult, sigma_px_1920: Mapping[Any, float]) -> list[int]:
    """The pairs of ``kept`` (indices into ``pairs``) with a view outside :func:`largest_consensus` of them, at
    ``triangulated``'s tau and rule; none when the consensus leaves nothing out."""
    agree = largest_consensus(pairs, kept, by_id, triangulated.tau_px, triangulated.rule, sigma_px_1920)
    return [] if agree is None else [k for k in kept if not {pairs[k].view_a, pairs[k].view_b} <= agree]


def judge_by_evidence(observations: Sequence[BallObservation], triangulated: TriangulationResult,
                      sigma_px_1920: Mapping[Any, float], *, max_sigma_m: float,
                      distance_to_volume_m: Callable[[np.ndarray], float] | None = None,
                      players_disagree: Callable[[Any, Any], bool] | None = None,
                      lone_pair_max_error_tau: float | None = None, consensus: bool = False) -> EvidenceBall:
    """Judge the pairs the paper's rules kept (``triangulated``: :func:`app.geometry.triangulation.triangulate_ball`
    without weights, play volume or parallax filter) by their uncertainty, and fuse the ball (module docstring).

    Args:
        observations: the labelled views of ``triangulated`` (their cameras, pixels and image widths).
        triangulated: their triangulation by the paper's rules.
        sigma_px_1920: view id -> the view's pixel sigma (px at 1920 width, > 0, ``inf`` for a view whose camera is
            undetermined) for every observation (:func:`view_sigma_px`).
        max_sigma_m: the largest sigma (metres) of a ball that stands; positive.
        distance_to_volume_m: world point (3,) -> its distance (metres) to the play volume, 0 inside
            (``app.geometry.pitch.distance_to_play_volume``); None: no play volume.
        players_disagree: view ids ``(a, b)`` of a kept pair -> whether their cameras disagree on the players both
            views see (asked once per kept pair, before anything else); None: no such evidence.
        lone_pair_max_error_tau: a ball left resting on one pair whose error (``PairResult.error``, the rule's
            units) is above this fraction of ``triangulated.tau_px`` is refused (rule 4); None: no such check.
        consensus: whether the pairs with a view outside the largest consensus of the views are left out before
            the weighing (rule 0b, :func:`largest_consensus`, reason ``outside_consensus``).

    Returns:
        An :class:`EvidenceBall`; ``triangulated`` unchanged (and sigma None) when it has no ball.

    Raises:
        ValueError: ``max_sigma_m`` not positive.
        KeyError: an observation without a sigma.
    """
    if not max_sigma_m > 0:
        raise ValueError(f"max_sigma_m must be positive, got {max_sigma_m!r}")
    if triangulated.point is None:
        return EvidenceBall(triangulated, None)
    pairs = list(triangulated.pairs)
    by_id = {o.view_id: o for o in observations}
    infos = _kept_informations(pairs, by_id, sigma_px_1920, players_disagree)

    def drop(ks, reason: str) -> None:
        for k in ks:
            pairs[k] = dataclasses.replace(pairs[k], kept=False, reason=reason)
            infos.pop(k, None)

    if consensus and len(infos) > 1:
        drop(_outside_consensus(pairs, list(infos), by_id, triangulated, sigma_px_1920), "outside_consensus")

    ball = None
    while infos:
        total = np.sum(list(infos.values()), axis=0)
        if not _fixes_point(total):  # the pairs left know nothing along some direction: the ball is not fixed
            break
        weighted = np.sum([infos[k] @ np.asarray(pairs[k].point, float) for k in infos], axis=0)
        ball = np.linalg.solve(total, weighted)
        d2 = {k: _squared_distance(np.asarray(pairs[k].point) - ball, infos[k]) for k in infos}
        worst = max(d2, key=lambda k: d2[k])
        if d2[worst] <= GATE_CHI2 or len(infos) == 1:
            break
        drop([worst], "beyond_joint_sigma")
        ball = None

    def refused(reason: str, sigma: float | None) -> EvidenceBall:
        drop(list(infos), reason)
        return EvidenceBall(dataclasses.replace(triangulated, status=STATUS_NO_PAIR_KEPT, point=None,
                                                pairs=tuple(pairs), view_errors_px={}), sigma)

    if ball is None:
        return refused("sigma_above_bound", None)
    sigma = kept_pairs_sigma_m(observations, pairs, ball, sigma_px_1920)
    if sigma is None or sigma > max_sigma_m:
        return refused("sigma_above_bound", sigma)
    if distance_to_volume_m is not None and distance_to_volume_m(ball) > VOLUME_SIGMAS * sigma:
        return refused("outside_play_volume", sigma)
    if lone_pair_max_error_tau is not None and len(infos) == 1:
        error = pairs[next(iter(infos))].error
        if error is not None and error > lone_pair_max_error_tau * triangulated.tau_px:
            return refused("lone_pair_at_tau_edge", sigma)
    ball.setflags(write=False)
    errors = {o.view_id: reprojection_error_px(o.camera, ball, o.point_px) for o in observations}
    return EvidenceBall(dataclasses.replace(triangulated, status=STATUS_TRIANGULATED, point=ball, pairs=tuple(pairs),
                                            view_errors_px=errors), sigma)
