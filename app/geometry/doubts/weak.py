"""Where cameras take no full part in the votes: a weak label's ray and the one detection near it (``weak_ray``), or a
weak view's one detection where the others' ball projects or along a lone labelled ray (``weak_view``), only for boxes
that cannot make a 3D ball (docs/detectors.md, "The check"); and which views' cameras are weak (:func:`_weak`)."""
from __future__ import annotations

import math
from typing import Any, Hashable, Mapping, Sequence

import numpy as np

from app.geometry.doubts.contract import DoubtSettings, DoubtView
from app.geometry.doubts.detected import CheckedDetection, Detection, _near_ray, size_ratio
from app.geometry.doubts.pairings import (
    MISS,
    _as_labelled,
    _band,
    _found,
    _judged,
    _meet,
    _Member,
    _member,
    _on_epipolar,
    _Pairing,
    _sure,
    _telling,
)
from app.geometry.triangulation import MIN_PAIR_WEIGHT, BallObservation
from app.geometry.weighting import calibration_weight, fits_own_lines, label_centre, project_point, rule_scale


def _triangulation_weight(view: DoubtView, s: DoubtSettings) -> float:
    """What the view's label weighs in the triangulation by class (``app.geometry.triangulation.triangulate_ball``
    ``view_weights``): its calibration's weight (:func:`app.geometry.weighting.calibration_weight`, read where its
    label's ray meets the grass) for a camera with its fit's uncertainty, a full vote for one without (a camera a
    person set or a release's: the recomputation counts it whole); none for a view below admission, which the
    triangulation leaves out."""
    if view.camera is None or not view.admitted:
        return 0.0
    return calibration_weight(view, s)[0] if view.uncertainty else 1.0


def _takes_part(view: DoubtView) -> bool:
    """Whether the view joins the 3D ball judged by evidence (``app.services.derivation.ball.takes_part``): a camera,
    admitted, or below admission while it fits most of its own lines; its ray then weighs by its uncertainty alone,
    whatever its line classes."""
    return view.camera is not None and (view.admitted or fits_own_lines(view.jac))


def _uncounted(fills: Mapping[Hashable, Detection], views: Sequence[DoubtView], s: DoubtSettings,
               placed: Mapping[Hashable, Detection] | None = None) -> bool:
    """Whether placing the boxes ``fills`` (view id -> detection) makes no 3D ball of its own: a wrong box then costs
    a label, never a system's ball. The boxes ``placed`` (boxes other checks already placed, checked as ones that
    may make a ball) count as labels; their views are not asked.

    By class (``s.below_admission_takes_part`` false): no pair of a filled view and another labelled or filled view
    weighs :data:`MIN_PAIR_WEIGHT` in the triangulation (a full vote and at least a half one), so every filled view
    stays out of the ball. By evidence (the default rule): every view that takes part (:func:`_takes_part`) joins the
    ball weighed by its uncertainty, a few-lined or unsure camera too, so a filled view that takes part stays out of
    nothing; its box makes no ball of its own only where at least two other labels that take part are there to make
    the ball it joins (it moves that ball within its uncertainty). A filled view beside one labelled ray would make
    the ball with it alone: with an unsure camera, a ball 1 m off on a made detector set (``benchmarks/VOUCH.md``,
    2026-11-29 later)."""
    boxes = {**(placed or {}), **fills}
    if s.below_admission_takes_part:
        others = [v for v in views if not (v.excluded or v.suggested) and v.view_id not in fills and _takes_part(v)
                  and (v.view_id in boxes or label_centre(v) is not None)]
        return len(others) >= 2 or not any(_takes_part(v) for v in views if v.view_id in fills)
    weights: dict[Hashable, float] = {}
    for v in views:
        if v.excluded or v.suggested:
            continue
        if v.view_id in boxes:
            weights[v.view_id] = _triangulation_weight(_as_labelled(v, boxes[v.view_id]), s)
        elif label_centre(v) is not None:
            weights[v.view_id] = _triangulation_weight(v, s)
    return not any(weights[f] + w >= MIN_PAIR_WEIGHT for f in fills if f in weights
                   for o, w in weights.items() if o != f)


def _weak_ray(rays: Sequence[DoubtView], targets: Sequence[DoubtView], views: Sequence[DoubtView],
              thirds: Sequence[DoubtView], detections: Mapping[Hashable, Sequence[Detection]],
              by_id: Mapping[Hashable, BallObservation], tol: Mapping[Hashable, float],
              sigma: Mapping[Hashable, float], s: DoubtSettings,
              size_tolerance: float) -> dict[Hashable, tuple[CheckedDetection, str, tuple[Hashable, ...]]]:
    """A label whose camera takes no full part in the votes and one detection, where the box cannot make a 3D ball:
    for each target view, the one detection within :data:`MISS` tolerances of a weak ray's epipolar segment (the
    tolerance tau widened by both cameras' pixel sigmas in quadrature, :func:`_on_epipolar`) that meets it
    (:func:`_meet`: in the play volume, within both views' tolerances, a ball's size at that depth) and that no third
    view misses (:func:`_third_views`). Filled only when the boxes placed stay out of the triangulation
    (:func:`_uncounted`): a camera fitted to a few lines may turn its ray by degrees (one such ray in nine projects
    the ball more than tau off on the shared detector sets), so its ray and one detection may fill a label but never
    make a ball; a pairing that would make one needs a third view (:func:`_among_detections`). One of the two
    cameras must be sure (pixel sigma within tau, :func:`_sure`): where both are unsure their band is wide and
    nothing sure sees the ball where they put it (on a made set a label's unsure camera and a view of sigma 52 px
    whose image does not hold the ball met at a false box 20 m from it). Two boxes near the ray, or rays choosing
    different boxes in one view, leave the view alone: an unsure ray has no margin of its own to choose between
    them."""
    chosen: dict[Hashable, _Pairing] = {}
    for v in targets:
        picks: dict[tuple[float, ...], _Pairing] = {}
        for r in rays:
            if not (_sure(r, sigma, s) or _sure(v, sigma, s)):
                continue  # two unsure cameras: nothing sure sees the ball where they put it
            near = _near_ray(r, v, detections.get(v.view_id, ()), MISS * _band(r, v, sigma, s), s)
            if len(near) != 1 or not _on_epipolar(r, v, near[0], sigma, s):
                continue
            p = _meet([_Member(r, by_id[r.view_id], None, size_tolerance), _member(v, near[0], s, size_tolerance)],
                      tol, s)
            if p is None:
                continue
            p = _judged(p, thirds, detections, tol, s, size_tolerance)
            if not p.missed:
                picks[near[0].box] = p
        if len(picks) == 1:
            chosen[v.view_id] = next(iter(picks.values()))
    fills = {vid: next(iter(p.detections().values())) for vid, p in chosen.items()}
    if not fills or not _uncounted(fills, views, s):
        return {}
    found: dict[Hashable, tuple[CheckedDetection, str, tuple[Hashable, ...]]] = {}
    for p in chosen.values():
        found.update(_found(p, 1, None, "weak_ray"))
    return found


def _weak_views(targets: Sequence[DoubtView], ball: np.ndarray, views: Sequence[DoubtView],
                detections: Mapping[Hashable, Sequence[Detection]], sigma: Mapping[Hashable, float],
                agreeing: tuple[Hashable, ...], filled: Mapping[Hashable, Detection], s: DoubtSettings,
                size_tolerance: float) -> dict[Hashable, tuple[CheckedDetection, str, tuple[Hashable, ...]]]:
    """Views whose own camera takes no part in the checks (few lines and an unsure fit, or a sigma beyond tau), where
    the other views place the ball (``ball`` (3,) world metres, z down): the one detection whose centre lies within
    the view's tolerance (its pixel sigma ``sigma``, px at 1920 width, at least tau) of where that ball projects, at a
    ball's size there, with no other detection within :data:`MISS` tolerances (a camera this unsure cannot choose
    between two boxes), fills the view, only where its box stays out of the triangulation (:func:`_uncounted`, with
    the boxes ``filled`` already placed): the detection never moves the ball, which the others placed. A camera
    whose sigma spreads that window over more than :data:`MAX_WINDOW_SHARE` of its image tells nothing
    (:func:`_telling`; the caller keeps those out)."""
    found: dict[Hashable, tuple[CheckedDetection, str, tuple[Hashable, ...]]] = {}
    tau = max(s.consensus_tau_px, s.triangulation_tau_px)
    for v in targets:
        uv = project_point(v, ball)
        dets = detections.get(v.view_id) or ()
        if uv is None or not dets:
            continue
        k, t = rule_scale(v, s), max(tau, float(sigma.get(v.view_id, math.inf)))
        dist = [float(np.linalg.norm(d.centre - uv)) * k for d in dets]
        if sum(dd < MISS * t for dd in dist) != 1:
            continue
        i = int(np.argmin(dist))
        ratio = size_ratio(v, dets[i].box, ball, s.ball_diameter_m)
        if dist[i] >= t or ratio is None or abs(ratio - 1.0) > size_tolerance:
            continue
        if not _uncounted({**{k: c.detection for k, (c, _, _) in found.items()}, v.view_id: dets[i]}, views, s,
                          filled):
            continue
        found[v.view_id] = (CheckedDetection(v.view_id, dets[i], dist[i], np.asarray(ball, float), float(ratio)),
                            "weak_view", agreeing)
    return found


def _placed_by_players_alone(v: DoubtView) -> bool:
    """Whether ``v``'s camera was fitted to its players' foot points with no field line of its own to read a fit from
    (JaC None): its stored uncertainty is the players' fit's (over-determined by at least 3 foot points,
    ``app.geometry.calibration.players``), so a JaC below a half, which marks a failed fit of a camera's own lines,
    says nothing of it. On the detector study sets such cameras (pixel sigmas 10-26 px) projected the true ball 4-12
    px off (``benchmarks/DETECTOR.md``, 2026-11-27, branch vote5)."""
    return v.player_assisted and v.jac is None


def _weak(views: Sequence[DoubtView], vote: Any, checked: Sequence[DoubtView], s: DoubtSettings,
          weighed: Mapping[Any, tuple[float, float]] | None) -> tuple[dict[Hashable, float], dict[Hashable, float]]:
    """The views whose camera takes no full part in the checks yet still tells where the ball lies: labelled ones
    outside the votes' labelled views (a helper's half vote, or none) and unlabelled ones outside ``checked`` (the
    views whose detections are checked) or with a sigma beyond tau, each with its pixel sigma (px at 1920 width).
    Kept only a camera whose fit's uncertainty is stored (else its sigma says nothing), which fits at least half of
    its own lines (JaC@0.5 % >= 0.5: a camera that fits fewer is a failed fit, whatever its sigma; on the shared
    detector sets such cameras put the ball hundreds of px off; a camera its players alone placed has no lines to fit,
    :func:`_placed_by_players_alone`) and whose sigma still tells (:func:`_telling`).
    Returns ``(labelled, unlabelled)``: view id -> sigma."""
    labelled: dict[Hashable, float] = {}
    unlabelled: dict[Hashable, float] = {}
    judged = {v.view_id for v in vote.labelled}
    sure = {v.view_id for v in checked}
    for v in views:
        if v.camera is None or v.excluded or v.mirror_flagged or v.suggested or not v.uncertainty \
                or ((v.jac or 0.0) < 0.5 and not _placed_by_players_alone(v)):
            continue
        known = weighed.get(v.view_id) if weighed is not None else None
        sig = float((known if known is not None else calibration_weight(v, s))[1])
        if not _telling(v, sig, s):
            continue
        if label_centre(v) is not None:
            if v.view_id not in judged:
                labelled[v.view_id] = sig
        elif v.view_id not in sure or sig > max(s.consensus_tau_px, s.triangulation_tau_px):
            unlabelled[v.view_id] = sig
    return labelled, unlabelled


def _weak_on_lone_ray(lone: DoubtView, views: Sequence[DoubtView], vote: Any, unlabelled: Sequence[DoubtView],
                      witnesses: Sequence[DoubtView], detections: Mapping[Hashable, Sequence[Detection]],
                      by_id: Mapping[Hashable, BallObservation], wtol: Mapping[Hashable, float],
                      sigma: dict[Hashable, float], s: DoubtSettings, size_tolerance: float,
                      weighed: Mapping[Any, tuple[float, float]] | None,
                      ) -> tuple[dict[Hashable, tuple[CheckedDetection, str, tuple[Hashable, ...]]],
                                 dict[Hashable, float]]:
    """With one labelled ray and nothing placed: the views whose own camera takes no part in the votes (:func:`_weak`:
    few lines and an unsure fit, or a camera its players alone placed) checked along that ray within their own
    uncertainty (:func:`app.geometry.doubts.weak._weak_ray` with the labelled ray: the one detection within
    :data:`app.geometry.doubts.pairings.MISS` tolerances of its epipolar segment, tau widened by both cameras' pixel
    sigmas in quadrature, meeting it in the play volume at a ball's size, no third view missing it), only where the
    boxes placed stay out of the triangulation (such a view weighs nothing there): a wrong box costs a label, never a
    system's ball. Code ``weak_view``: the view's own camera is the weak one. Returns the checked detections and the
    pixel sigmas with the weak views' own (``sigma``'s and :func:`_weak`'s, px at 1920 width)."""
    _, weak = _weak(views, vote, unlabelled, s, weighed)
    usable = {v.view_id for v in unlabelled}
    targets = [v for v in views if v.view_id in weak and v.view_id not in usable]
    if not targets:
        return {}, sigma
    sigma = {**sigma, **weak}
    found = _weak_ray([lone], targets, views, witnesses, detections, by_id, wtol, sigma, s, size_tolerance)
    return {vid: (c, "weak_view", agreeing) for vid, (c, _, agreeing) in found.items()}, sigma
