"""A multi-view system's 3D ball from its labelled views: which views take part, each view's pixel sigma, and the
rule that makes the ball from their pairs (``settings.ball_rule``: by class, or by evidence), what
:mod:`app.services.derivation.recompute` stores and the doubts' placements ask again.

Under the rule by evidence (the default, :func:`app.geometry.evidence.judge_by_evidence`) every view whose camera
fits most of its own lines takes part (:func:`takes_part`), each pair is weighed by its two views' pixel sigmas
(:func:`view_sigmas_px`), and a pair whose two cameras place the players both views see apart is left out
(:func:`players_disagree`); under the rule by class (``weights``) the admitted views only, by the calibration weights,
the parallax filter and the play volume. World frame: SoccerNet (metres, origin at the centre spot, z down); pixels
at 1920 width where a sigma is stated.
"""
from __future__ import annotations

import math
from typing import Any, Callable, Mapping, Sequence, cast

import numpy as np

from app.core.config import Settings
from app.db.models import CalibrationStatus, Frame, System
from app.geometry.ball_evidence import (
    BallFacts,
    OtherView,
    ViewFacts,
    agreeing_views,
    copied_detection,
    depth_shift_px,
    detection_at_ball,
    detection_at_label,
)
from app.geometry.calibration.players import LINES_CONTRADICTED_SIGMA
from app.geometry.camera import Camera
from app.geometry.doubts.detected import CENTRE_NOISE, MIN_SIGMA_PX
from app.geometry.doubts.detections import Detection
from app.geometry.evidence import LONE_PAIR_MAX_ERROR_TAU, judge_by_evidence, kept_pairs_sigma_m, view_sigma_px
from app.geometry.pair_error import REFERENCE_WIDTH_PX
from app.geometry.pitch import distance_to_play_volume, within_play_volume
from app.geometry.triangulation import BallObservation, PairGeometry, TriangulationResult, triangulate_ball
from app.geometry.weighting import fits_own_lines
from app.services.calibration.players import frame_feet
from app.services.derivation import cameras as shared
from app.services.derivation.cameras import PairPlayersMemo
from app.services.derivation.doubts import (
    WeighedViews,
    calibration_weights,
    doubt_settings,
    fitted_frames,
    is_excluded,
    stored_detections,
)


def judged_by_evidence(settings: Settings, weighs_calibrations: bool) -> bool:
    """Whether a system's 3D ball is judged by evidence (``settings.ball_rule`` "evidence", for a kind that weighs its
    calibrations: :func:`system_ball`), else by class."""
    return settings.ball_rule == "evidence" and weighs_calibrations


def takes_part(frame: Frame, by_evidence: bool) -> bool:
    """Whether ``frame``'s view may join its system's 3D ball, its label aside: calibrated, not excluded by a person
    (``is_excluded``), and admitted (``Calibration.admitted``: JaC@gamma above ``admit_jac_min``, the paper's rule); or,
    when the ball is judged by evidence (``by_evidence``, :func:`judged_by_evidence`), below admission while its
    camera still fits most of its own lines (``app.geometry.weighting.fits_own_lines``, JaC@0.5 %, as for the doubts'
    votes). Such a view's ray is then weighed by its uncertainty like any other's: a JaC threshold is a rule by class,
    and a camera fitted to two or three line classes fits them exactly yet scores a coarse JaC (2 of 3 lines, 0.67)
    whatever its pose."""
    cal = frame.calibration
    if cal is None or cal.status is not CalibrationStatus.CALIBRATED or cal.camera is None or is_excluded(frame):
        return False
    return bool(cal.admitted) or (by_evidence and fits_own_lines(cal.jac_0005))


def players_disagree(system: System, cameras: Mapping[Any, Camera],
                     memo: PairPlayersMemo | None = None) -> Callable[[Any, Any], bool]:
    """View ids ``(a, b)`` of ``system``'s ``observations`` -> whether their cameras put the players both views see
    (class and ID, ``Frame.players``) farther apart than ``LINES_CONTRADICTED_SIGMA`` standard deviations
    (:func:`players_disagreement`), what :func:`app.geometry.evidence.judge_by_evidence` leaves a pair out for."""
    figure = players_disagreement(system, cameras, memo)

    def disagree(a: Any, b: Any) -> bool:
        got = figure(a, b)
        return got is not None and got > LINES_CONTRADICTED_SIGMA

    return disagree


def players_disagreement(system: System, cameras: Mapping[Any, Camera],
                         memo: PairPlayersMemo | None = None) -> Callable[[Any, Any], float | None]:
    """View ids ``(a, b)`` of ``system`` -> how far apart their cameras put the players both views see (class and
    ID, ``Frame.players``), in standard deviations (``app.geometry.calibration.players.pair_players_disagreement``),
    None with fewer than three shared players. ``cameras``: view id -> its camera, for every view asked about;
    ``memo``: where each pair's figure comes from (None: the process's, ``cameras.PAIR_PLAYERS``, which answers the
    pairs an edit left as they were). Each view's foot points are read once, on the first pair that asks."""
    ask = memo if memo is not None else shared.PAIR_PLAYERS
    frames = {f.id: f for f in system.frames}
    feet: dict[Any, dict] = {}

    def feet_of_view(view_id: Any) -> dict:
        if view_id not in feet:
            feet[view_id] = frame_feet(frames[view_id])
        return feet[view_id]

    def figure(a: Any, b: Any) -> float | None:
        fa, fb = feet_of_view(a), feet_of_view(b)
        fr_a, fr_b = frames[a], frames[b]
        return ask(cameras[a], fa, (fr_a.width, fr_a.height), cameras[b], fb, (fr_b.width, fr_b.height))

    return figure


def view_sigmas_px(system: System, observations: Sequence[BallObservation], settings: Settings,
                   weighed: WeighedViews, boxes: dict[int, Sequence[float]] | None = None) -> dict[int, float]:
    """Frame id -> the pixel sigma (px at 1920 width) of each observation's view
    (:func:`app.geometry.evidence.view_sigma_px`): its label's centre noise (``CENTRE_NOISE`` of its box's diameter)
    and its calibration's pixel sigma (``weighed``; 0 for a camera not fitted to the view's lines, which
    :func:`calibration_weights` counts full; at least ``consensus_tau_px`` for a camera fitted to fewer than
    ``min_line_classes`` line classes) in quadrature, at least ``MIN_SIGMA_PX``. ``boxes``: frame id -> a ball box
    (px) standing for that view's stored label."""
    fitted = fitted_frames(system)
    s = doubt_settings(settings)
    lines = {v.view_id: v.line_classes for v in weighed.views}
    frames = {f.id: f for f in system.frames}
    out: dict[int, float] = {}
    for o in observations:
        fid = cast(int, o.view_id)
        f = frames[fid]
        box = (boxes or {}).get(fid) or (f.ball_label.box if f.ball_label is not None else None)
        d = None if box is None else (abs(box[2] - box[0]) + abs(box[3] - box[1])) / 2 * REFERENCE_WIDTH_PX / f.width
        cal_sigma = weighed.weighed[fid][1] if fid in fitted and fid in weighed.weighed else 0.0
        if fid in fitted and lines.get(fid, 0) < s.min_line_classes:
            # a camera fitted to fewer classes than fix it fits them exactly: no residual speaks for its stated
            # uncertainty, so it is known only to the consensus tolerance, what a ball the others agree on allows
            cal_sigma = max(cal_sigma, s.consensus_tau_px)
        out[fid] = view_sigma_px(d, cal_sigma, CENTRE_NOISE, MIN_SIGMA_PX)
    return out


def system_ball(system: System, observations: Sequence[BallObservation], settings: Settings, weighed: WeighedViews,
                geometry: Callable[[BallObservation, BallObservation], PairGeometry], *,
                weighs_calibrations: bool, boxes: dict[int, Sequence[float]] | None = None,
                players: PairPlayersMemo | None = None) -> tuple[TriangulationResult, float | None]:
    """The system's 3D ball and its sigma (metres along its least certain direction, None without a ball).

    Under ``settings.ball_rule`` "weights" (or a kind that weighs no calibration) the pairs are judged by class: tau,
    the baseline, the parallax setting, the play volume on each pair's point and, when ``weighs_calibrations``, the
    calibration weights (:func:`calibration_weights`: a few-lined or unsure camera neither makes nor moves a ball
    alone); the ball's sigma is then that of the views of the kept pairs at their pixel sigmas
    (:func:`view_sigmas_px`, :func:`app.geometry.evidence.kept_pairs_sigma_m`), shown, never a reason.
    Under "evidence" (a kind that weighs calibrations) the pairs kept by tau and the baseline alone are judged by
    their uncertainty (:func:`app.geometry.evidence.judge_by_evidence`: the pairs with a view outside the largest
    consensus of views left out, then information-weighted, pairs beyond their joint
    sigma left out, the bound ``settings.ball_max_sigma_m``, the play volume within the ball's uncertainty, a ball
    resting on one pair whose rays meet only at the edge of tau, ``LONE_PAIR_MAX_ERROR_TAU``).
    ``boxes``: frame id -> a ball box (px) standing for that view's stored label (a label not yet confirmed);
    ``players``: where the players' disagreement of a pair comes from (:func:`players_disagree`; None: the
    process's memo)."""
    sigmas = view_sigmas_px(system, observations, settings, weighed, boxes)
    if judged_by_evidence(settings, weighs_calibrations):
        # a camera the fit leaves undetermined (an infinite sigma) tells nothing of where its ray runs: it makes no pair
        observations = [o for o in observations if math.isfinite(sigmas[cast(int, o.view_id)])]
        paper = triangulate_ball(observations, tau_px=settings.triangulation_tau_px, rule=settings.pair_error_rule,
                                 min_baseline_m=settings.min_baseline_m, min_parallax_deg=0.0, geometry=geometry)
        disagree = players_disagree(system, {o.view_id: o.camera for o in observations}, players)
        judged = judge_by_evidence(observations, paper, sigmas, max_sigma_m=settings.ball_max_sigma_m,
                                   distance_to_volume_m=distance_to_play_volume, players_disagree=disagree,
                                   lone_pair_max_error_tau=LONE_PAIR_MAX_ERROR_TAU, consensus=True)
        return judged.result, judged.sigma_m
    weights = calibration_weights(system, settings, weighed=weighed) if weighs_calibrations else None
    result = triangulate_ball(observations, tau_px=settings.triangulation_tau_px, rule=settings.pair_error_rule,
                              min_baseline_m=settings.min_baseline_m, min_parallax_deg=settings.min_parallax_deg,
                              play_volume=lambda p: bool(within_play_volume(p)[0]),  # pitch.PLAY_VOLUME
                              view_weights=weights, geometry=geometry)
    if result.point is None:
        return result, None
    return result, kept_pairs_sigma_m(observations, result.pairs, result.point, sigmas)


def ball_facts(system: System, ball: Sequence[float] | np.ndarray | None, kept_pairs: Sequence[tuple[int, int]],
               sigma_m: float | None, cameras: Mapping[int, Camera], settings: Settings,
               players: PairPlayersMemo | None = None, pair_error_tau: float | None = None,
               detections: dict[int, list[Detection]] | None = None) -> BallFacts:
    """The evidence behind ``system``'s 3D ball ``ball`` ((3,) world metres, None without one; made of the frame id
    pairs ``kept_pairs``; its sigma ``sigma_m``, metres), what :func:`app.geometry.ball_evidence.ball_evidence`
    reads: the views of its kept pairs (named ``V1``, ``V2`` ... by their place in the system), each with whether an
    imported detection confirms its label (its size at the ball's depth is left out: measured, it does not separate
    right balls from wrong ones, ``benchmarks/VOUCH.md``); each other calibrated view with predictions, and each
    other view with a person-placed box (not excluded), with its box against the ball's projection
    (``detection_at_ball``) and how far it sees the ball move 1 m along the pairs' rays (``depth_shift_px``); the
    names of those views a stored label doubt names (a doubt naming no view names them all: read after the doubts are
    written); how many kept pairs' cameras agree on their players (:func:`players_disagreement` at most
    ``LINES_CONTRADICTED_SIGMA``; counted only where the detector confirms every label, 0 elsewhere); the sigma;
    ``pair_error_tau``: its kept pairs' largest error over tau. ``cameras``: frame id -> its camera; ``players``: the
    players' memo (None: the process's); ``detections``: the system's ``stored_detections``, when read already."""
    if ball is None:
        return BallFacts(has_ball=False)
    point = np.asarray(ball, dtype=float)
    used = {v for pair in kept_pairs for v in pair}
    names = {f.id: f"V{i + 1}" for i, f in enumerate(system.frames)}
    if detections is None:
        detections = stored_detections(system, settings.max_predictions_per_frame)
    views, others, labelled = [], [], []
    centres = [cameras[fid].C for fid in used if fid in cameras]
    for f in system.frames:
        if f.id not in used:
            if f.id not in cameras:
                continue
            near = (None if f.id not in detections else detection_at_ball(
                cameras[f.id], point, [d.box for d in detections[f.id]], settings.ball_diameter_m, f.width))
            label = f.ball_label
            at = (detection_at_ball(cameras[f.id], point, [label.box], settings.ball_diameter_m, f.width)
                  if label is not None and label.box is not None and not label.suggested and not is_excluded(f)
                  else None)
            if near is not None or at is not None:
                depth = depth_shift_px(cameras[f.id], point, centres, f.width)
                others += [OtherView(names[f.id], *near, depth_1920=depth)] if near is not None else []
                labelled += [OtherView(names[f.id], *at, depth_1920=depth)] if at is not None else []
            continue
        label = f.ball_label
        box = label.box if label is not None else None
        found = detections.get(f.id)
        # a label the fix key copied from a detection is that detection's own box: it confirms nothing there
        original = label.original_box if label is not None else None
        own = [d.box for d in found or () if box is None or not copied_detection(box, original, d.box)]
        detected = None if not found or box is None else detection_at_label(box, own)
        views.append(ViewFacts(name=names[f.id], detected=detected))
    accused = [d.frame_id for d in system.doubts if d.accuses_label]
    named = used if None in accused else {fid for fid in accused if fid in used}
    doubted = [names[f.id] for f in system.frames if f.id in named]
    agree = 0
    if views and all(v.detected for v in views):
        # the rule reads the players only where the detector confirms every label (its rule 3), and reading each
        # view's players is most of what the evidence costs (benchmarks/VOUCH.md): counted there only
        figure = players_disagreement(system, cameras, players)
        agree = sum(1 for a, b in kept_pairs if (got := figure(a, b)) is not None and got <= LINES_CONTRADICTED_SIGMA)
    return BallFacts(has_ball=True, views=tuple(views), doubted=tuple(doubted), players_pairs=agree, sigma_m=sigma_m,
                     others=tuple(others), pair_error_tau=pair_error_tau, agreeing=agreeing_views(kept_pairs),
                     labelled_others=tuple(labelled), tau_px=settings.triangulation_tau_px)
