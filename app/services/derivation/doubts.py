"""Doubts of a multi-view system: what the service stores of ``app.geometry.doubts`` (its codes and numbers,
with the sentence ``app.services.wording.doubt_words`` composes).

:func:`update_doubts` runs at the end of every system recomputation (``app.services.derivation.recompute``), so
a system's doubts change in the transaction of the edit that changed them and the queue never
recomputes them: it reads ``System.doubt_counts`` (``{kind: n}``) and ``System.label_doubts`` (how
many accuse a label, the queue's sort key) written here. :func:`doubt_views` is the one adapter from
stored rows to the judge's :class:`~app.geometry.doubts.DoubtView` (the benchmark uses it too);
:func:`doubt_settings` maps the service's settings onto :class:`~app.geometry.doubts.DoubtSettings`.
"""
from __future__ import annotations

import dataclasses
from collections import Counter
from collections.abc import Sequence
from typing import Any, Callable, cast

import numpy as np
import sqlalchemy as sa
from sqlalchemy.orm import Session, object_session, selectinload

from app.core.config import Settings
from app.db.models import CalibrationSource, CalibrationStatus, Doubt, Frame, Game, System
from app.db.types import json_safe
from app.geometry.calibration.result import MIRROR_FLAG, PLAYERS_FLAG, RIG_FLAG
from app.geometry.camera import Camera
from app.geometry.consensus import Consensus
from app.geometry.doubts import DoubtSettings, DoubtView, judge_system, label_severity
from app.geometry.doubts.detections import Detection, check_detections
from app.geometry.doubts.judge import consensus_without, consensuses_without
from app.geometry.doubts.pairings import ON_GRASS_M
from app.geometry.pair_error import REFERENCE_WIDTH_PX, scaled_error_px
from app.geometry.pitch import PLAY_VOLUME
from app.geometry.triangulation import (
    BallObservation,
    PairGeometry,
    TriangulationResult,
    pair_geometry,
    reprojection_error_px,
)
from app.geometry.weighting import calibration_weight, centre_of, label_centre
from app.services.calibration.players import frame_players
from app.services.derivation.cameras import stored_camera
from app.services.derivation.loading import load_view_players, load_view_predictions
from app.services.derivation.rows import put_values, replace_rows
from app.services.kinds import kind_of
from app.services.wording.doubt_words import doubt_message


def doubt_settings(settings: Settings, weighs_calibrations: bool = True) -> DoubtSettings:
    """The judge's settings, every one from ``settings``: the triangulation's tau, rule, baseline, parallax and
    ball diameter, the ``doubt_*`` thresholds (``V3D_DOUBT_*``), the play volume
    (``app.geometry.pitch.PLAY_VOLUME``, its height ``doubt_max_ball_height_m``), and whether the 3D ball lets views
    below admission take part (the rule by evidence, for a kind that weighs its calibrations,
    ``weighs_calibrations``: ``app.services.derivation.ball.takes_part``)."""
    return DoubtSettings(
        triangulation_tau_px=settings.triangulation_tau_px, pair_error_rule=settings.pair_error_rule,
        min_baseline_m=settings.min_baseline_m, min_parallax_deg=settings.min_parallax_deg,
        ball_diameter_m=settings.ball_diameter_m, consensus_tau_px=settings.doubt_consensus_tau_px,
        near_duplicate_max_deg=settings.doubt_near_duplicate_max_deg, inside_margin_px=settings.doubt_inside_margin_px,
        ground_box_tolerance=settings.doubt_ground_box_tolerance,
        play_volume=dataclasses.replace(PLAY_VOLUME, max_height_m=settings.doubt_max_ball_height_m),
        mirror_rig_near_m=settings.doubt_mirror_rig_near_m, mirror_rig_gap_m=settings.doubt_mirror_rig_gap_m,
        min_line_classes=settings.doubt_min_line_classes,
        below_admission_takes_part=settings.ball_rule == "evidence" and weighs_calibrations)


def is_excluded(frame: Frame) -> bool:
    """True when a reviewer excluded the view from its system's triangulation."""
    return frame.review is not None and bool(frame.review.excluded)


def doubt_view(frame: Frame, camera: Camera | None = None) -> DoubtView:
    """One stored frame as the doubt judge sees it (its camera is rebuilt from the stored JSON unless
    given)."""
    cal = frame.calibration
    calibrated = cal is not None and cal.status is CalibrationStatus.CALIBRATED and cal.camera is not None
    if camera is None and cal is not None and cal.camera is not None and calibrated:
        camera = stored_camera(cal.camera)
    label = frame.ball_label
    box = np.asarray(label.box, float) if label is not None and label.box is not None else None
    point = np.asarray(label.point, float) if label is not None and label.point is not None else None
    lines = frame.field_lines.lines if frame.field_lines is not None else {}
    flags = list(cal.flags or []) if cal is not None else []
    return DoubtView(
        view_id=frame.id, name=frame.name, role=frame.role.value, width=frame.width, height=frame.height,
        camera=camera if calibrated else None, admitted=bool(calibrated and cal.admitted),  # type: ignore[union-attr]  # calibrated: cal is set
        jac=cal.jac_0005 if cal is not None else None,
        line_classes=sum(1 for polys in lines.values() if polys), box=box, point=point,
        excluded=is_excluded(frame), mirror_flagged=MIRROR_FLAG in flags,
        mirror_evidence=cal.mirror_evidence if cal is not None else None,
        calibration_reason=cal.reason if cal is not None and cal.status is CalibrationStatus.REFUSED else None,
        rig_assisted=RIG_FLAG in flags, player_assisted=PLAYERS_FLAG in flags,
        uncertainty=cal.uncertainty if calibrated else None,  # type: ignore[union-attr]  # calibrated: cal is set
        suggested=label is not None and label.suggested,
    )


def doubt_views(system: System, cameras: dict[int, Camera] | None = None) -> list[DoubtView]:
    """Every view of ``system`` as a :class:`DoubtView`, in the system's order (``cameras``: frame
    id -> camera already built by the caller, to spare rebuilding it)."""
    cameras = cameras or {}
    return [doubt_view(f, cameras.get(f.id)) for f in system.frames]


@dataclasses.dataclass(frozen=True)
class WeighedViews:
    """A system's views as the doubt judge sees them (:func:`doubt_views`) and, per calibrated view, what its
    calibration is worth (``app.geometry.weighting.calibration_weight`` with the judge's settings: weight and pixel
    sigma at 1920 px), made once per recomputation for the triangulation's weights and the judge
    (:func:`weighed_views`)."""

    views: list[DoubtView]
    weighed: dict[int, tuple[float, float]]


def weighed_views(system: System, settings: Settings, cameras: dict[int, Camera] | None = None) -> WeighedViews:
    """:class:`WeighedViews` of ``system`` as its rows are now (admission and mirror flags as set on them)."""
    s = doubt_settings(settings)
    views = doubt_views(system, cameras)
    # a stored view's id is its frame's id
    return WeighedViews(views, {cast(int, v.view_id): calibration_weight(v, s) for v in views if v.camera is not None})


def calibration_weights(system: System, settings: Settings, cameras: dict[int, Camera] | None = None,
                        weighed: WeighedViews | None = None) -> dict[int, float]:
    """Frame id -> what its calibration is worth as evidence of the ball (``app.geometry.weighting.calibration_weight``
    with the judge's settings: 1, 0.5 or 0), for every calibrated frame of ``system``; what the triangulation
    weighs views by (``app.geometry.triangulation.triangulate_ball`` ``view_weights``), so that it trusts the
    views the judge trusts. Cameras known to be fitted to the view's lines are weighed: computed by v3d, or
    imported with the fit's standard deviations (v3d's own export carries them, so a round trip gives the same
    balls). A camera a person set (source "edited") or one imported without them (a release's camera, how it
    was made unknown) counts full (1): the number of lines it shows says nothing of it.
    Reads the frames' admission as set on them (``weighed``: :func:`weighed_views` of them, when made already)."""
    weighed = weighed or weighed_views(system, settings, cameras)
    fitted = fitted_frames(system)
    return {fid: w if fid in fitted else 1.0 for fid, (w, _) in weighed.weighed.items()}


def fitted_frames(system: System) -> set[int]:
    """Ids of ``system``'s frames whose camera is known to be fitted to the view's lines (computed by v3d, or imported
    with the fit's standard deviations): those whose calibration uncertainty speaks for the camera
    (:func:`calibration_weights`)."""
    return {f.id for f in system.frames if f.calibration is not None and (
        f.calibration.source is CalibrationSource.COMPUTED
        or (f.calibration.source is CalibrationSource.IMPORTED and f.calibration.uncertainty is not None))}


def update_doubts(system: System, settings: Settings, cameras: dict[int, Camera] | None = None,
                  geometry: Callable[[BallObservation, BallObservation], PairGeometry] = pair_geometry,
                  weighed: WeighedViews | None = None,
                  after_confirming: ConfirmedError | None = None,
                  detections: dict[int, list[Detection]] | None = None,
                  once_confirmed: ConfirmedBall | None = None) -> list[Doubt]:
    """Judge the system (``app.geometry.doubts.judge_system``; ``geometry``: the recomputation's pair geometry, shared
    with its triangulation; ``weighed``: its :func:`weighed_views`, when made already; ``detections``: its
    :func:`stored_detections`, when read already) and replace its stored doubts and counts.
    ``after_confirming(frame, centre)``: the recomputation's error (px of the view) of a label centred at ``centre``
    (2,) px once a person confirmed it; given, a detector's box and a placement waiting for its confirmation say that
    number (:func:`with_confirmed_error`), the one the view shows once confirmed. ``once_confirmed(boxes)``: the
    recomputation's triangulation once a person confirmed each box of ``boxes`` (frame id -> box, px); given, boxes
    placed together from one labelled ray keep their key only where that ball's rule keeps their agreement
    (:func:`without_unbacked_fixes`). Changes the session only; the caller commits (with the edit that caused it)."""
    weighed = weighed or weighed_views(system, settings, cameras)
    judged = doubt_settings(settings, kind_of(system).weighs_calibrations)
    found = judge_system(weighed.views, judged, geometry, weighed.weighed)
    found = kind_of(system).judge_doubts(system, found, cameras)
    if detections is None:
        detections = stored_detections(system, settings.max_predictions_per_frame)
    if detections:  # a detector's predictions, checked against the other views (none: the doubts as they were)
        found = check_detections(with_players(system, weighed.views, detections), found, detections, judged,
                                 settings.doubt_detection_size_tolerance, geometry, weighed.weighed)
    found = without_unbacked_fixes(system, found, once_confirmed)
    if after_confirming is not None:
        found = with_confirmed_error(system, found, after_confirming)
    names = {f.id: f.name for f in system.frames}
    replace_rows(system.doubts, Doubt, [  # in place: a doubt the edit leaves as it was writes nothing
        dict(frame_id=d.view_id, kind=d.kind, accuses_label=d.accuses_label, message=doubt_message(d, names),
             evidence=json_safe({**d.evidence, "code": d.code}),
             suggestion=json_safe(d.suggestion) if d.suggestion else None)
        for d in found
    ])
    put_values(system, {"doubt_counts": dict(Counter(d.kind for d in found)),
                        "label_doubts": sum(1 for d in found if d.accuses_label),
                        "label_severity": label_severity(d.kind for d in found)})
    return list(system.doubts)


#: The fixes that place a ball label where other views put the ball (a detector's box, or a box at their ball's
#: projection): the actions a box of theirs may make a 3D ball with.
PLACING_ACTIONS = ("snap_box", "snap_point")


#: ``once_confirmed(boxes)``: the triangulation (its fused ball and every pair, kept or refused) the recomputation would
#: make once a person confirmed a ball box on each frame of ``boxes`` (frame id -> ``[x1, y1, x2, y2]`` px).
ConfirmedBall = Callable[[dict[int, Sequence[float]]], TriangulationResult]


def without_unbacked_fixes(system: System, doubts: list[Any], once_confirmed: ConfirmedBall | None = None
                           ) -> list[Any]:
    """``doubts`` with no one-key fix where, in a system without a 3D ball, the fix would place a label that the
    ball's rule has no label of a person to check against:

    * placed from the agreement of two or more labelled views (``evidence["agreeing_views"]``) from whose labels the
      ball's rule keeps no ball (it refused their pairs: beyond their joint sigma, a sigma above the bound, players
      that disagree ...): the doubts' votes weigh views by class and the ball by its uncertainty, so the two may
      disagree about such a pair; a box placed where the votes put the ball copies that agreement, and once
      confirmed it pairs with those very labels into a ball the rule refused from them (``evidence["no_key"]``
      ``"agreeing"``);
    * placed from detections alone (code ``detections_agree``: no labelled view takes part): two such boxes,
      confirmed, make a ball of the detector's boxes alone, which its confirmations of those same boxes would then
      vouch for (``"detections"``);
    * placed from one labelled ray and one detection (code ``one_ray``) whose ball lies in the air (more than
      :data:`app.geometry.doubts.pairings.ON_GRASS_M` above the grass) where no third view sees it (its
      ``agreeing_views`` are the ray's view alone): the box alone then says where along the ray the ball is, over a
      stretch of metres a ball in the air may occupy, and a false box that lies on the ray's band at a ball's size
      says it as well; confirmed, the two views make the ball with nothing to check its depth (the ball's rule
      vouches for a depth only by a third view). On the grass the ground is that check: the pairing puts the ball
      where the labelled ray meets the grass, the one spot of the ray a ball on the ground can be, which a random
      box rarely hits (``"one_ray"``);
    * placed from one labelled ray and two (or more) detected views whose rays meet it at one ball (code
      ``one_view``), where the ball's rule, once every box of that pairing is confirmed (``once_confirmed``),
      leaves out a pair of the pairing's views because their rays disagree (or keeps no ball): the pairing accepts
      rays that meet within the doubts' wide tau, the ball keeps a pair only within the triangulation's tau and its
      views' joint sigma, so a false box that meets the ray and the other box within the wider tolerance passes the
      pairing, and once confirmed the ball's rule keeps a ball from the pairs it does not refuse, with nothing
      checking where it put it (the third view was that check, and it disagreed); where the rule refuses none of
      their pairs for disagreeing, the third view checks the other two as it does for three labels
      (``"one_view"``). Without ``once_confirmed`` (a caller that does not triangulate) such fixes are left as they
      are.

    Such a doubt keeps its numbers, the box the key would have placed among them (``evidence["box"]``, px).
    On made copies of the shared detector sets these made balls 1.0-20 m off in systems that had none
    (``benchmarks/VOUCH.md``, 2026-11-29 later and evening), every one a box filled into a view without a label of a
    person's. The doubt stays with its numbers (its words say why there is no key): a person places the label by
    eye. A fix placed from one labelled ray with a detection that a third view confirms or whose ball is on the
    grass, a snap of a view's own label of a person's (moved off by a slip of the hand: the other views agreeing
    where it was is what a person expects the key to restore), and every fix in a system with a 3D ball (whose rule
    checks the box against the views it already pairs), are left as they are."""
    if system.triangulation is not None and system.triangulation.ball3d is not None:
        return doubts
    labelled = {f.id for f in system.frames if f.ball_label is not None and not f.ball_label.suggested
                and f.ball_label.centre is not None}
    refused = _pairings_the_ball_refuses(doubts, labelled, once_confirmed)
    out = []
    for d in doubts:
        if d.suggestion and d.suggestion.get("action") in PLACING_ACTIONS and d.view_id not in labelled:
            agreeing = [v for v in (d.evidence or {}).get("agreeing_views") or [] if v in labelled]
            why = ("agreeing" if len(agreeing) >= 2 else "detections" if d.code == "detections_agree"
                   else "one_ray" if d.code == "one_ray" and _depth_from_box_alone(d.evidence or {})
                   else "one_view" if d.code == "one_view" and d.view_id in refused else None)
            if why is not None:
                # the box stays among its numbers: where the key would have placed it, for a person to judge by eye
                box = {"box": d.suggestion["box"]} if d.suggestion.get("box") is not None else {}
                d = dataclasses.replace(d, suggestion=None, evidence={**d.evidence, **box, "no_key": why})
        out.append(d)
    return out


#: The reasons for which the ball's rule leaves out a pair whose rays it could triangulate because the two views
#: disagree (``app.geometry.triangulation.DROP_REASONS``): the paper's tau, the players both cameras see, the largest
#: consensus of the views and the pairs' joint sigma (``app.geometry.evidence``).
DISAGREEING = ("error_above_tau", "players_disagree", "outside_consensus", "beyond_joint_sigma")


def _pairings_the_ball_refuses(doubts: Sequence[Any], labelled: set[int], once_confirmed: ConfirmedBall | None
                               ) -> set[int]:
    """The views (frame ids) of ``one_view`` fills whose pairing the ball's rule would not keep once its boxes are
    confirmed (:func:`without_unbacked_fixes`): for each such fill, the boxes of every ``one_view`` fill among its
    pairing's views (``evidence["agreeing_views"]`` and its own) placed at once, the fill is refused where the ball
    then made keeps no ball, or leaves out a pair of two of those views because their rays disagree
    (:data:`DISAGREEING`). A pair the rule cannot form at all (two cameras too close to triangulate, a point behind a
    camera: ``baseline_below_min``, ``behind_camera`` ...) says nothing of their agreement and is not asked, nor is a
    view whose camera takes no part in the ball (``ball.takes_part``: it is in no pair). ``labelled``: the frames
    with a label a person placed. Empty without ``once_confirmed``."""
    if once_confirmed is None:
        return set()
    boxes = {d.view_id: d.suggestion["box"] for d in doubts
             if d.code == "one_view" and d.view_id not in labelled and d.suggestion
             and d.suggestion.get("action") == "snap_box" and d.suggestion.get("box") is not None}
    refused: set[int] = set()
    asked: dict[frozenset[int], bool] = {}
    for vid in boxes:
        d = next(x for x in doubts if x.view_id == vid and x.code == "one_view" and x.suggestion)
        views = frozenset({vid, *((d.evidence or {}).get("agreeing_views") or [])})
        if views not in asked:
            result = once_confirmed({v: boxes[v] for v in views if v in boxes})
            asked[views] = result.point is None or any(
                p.reason in DISAGREEING and p.view_a in views and p.view_b in views for p in result.pairs)
        if asked[views]:
            refused.add(vid)
    return refused


def _depth_from_box_alone(evidence: dict[str, Any]) -> bool:
    """Whether a ``one_ray`` fill's box alone fixes where along the labelled ray its ball lies: no view but the ray's
    confirms it (``evidence["agreeing_views"]``: the ray's view and each third view that sees the ball) and its ball
    (``evidence["ball3d"]``, world metres, SoccerNet z down) lies more than
    :data:`app.geometry.doubts.pairings.ON_GRASS_M` above the grass, the bound the pairing's own checks call "on the
    grass" (:func:`app.geometry.doubts.pairings._told_from_players`). False where the evidence lacks the ball."""
    ball = evidence.get("ball3d")
    if not ball or len(ball) != 3:
        return False
    return len(evidence.get("agreeing_views") or []) <= 1 and -float(ball[2]) > ON_GRASS_M


#: ``after_confirming(frame, centre, box)``: how far (px of the view) a label centred at ``centre`` (its box ``box``,
#: [x1, y1, x2, y2] px, or None for a point) would lie from the 3D ball once confirmed; None where there would be none.
ConfirmedError = Callable[[Frame, np.ndarray, Sequence[float] | None], float | None]

#: The doubts whose ball label a person confirms as it is (a detector's box placed by its key, then Enter): each says
#: how far that label will lie from the 3D ball once confirmed.
CONFIRMED_KINDS = ("ball_detected", "suggested_label")


def with_confirmed_error(system: System, doubts: list[Any],
                         after_confirming: ConfirmedError) -> list[Any]:
    """``doubts`` with, on each of :data:`CONFIRMED_KINDS` whose label is known (a ``ball_detected`` suggestion's box,
    a ``suggested_label``'s placed label), ``evidence["confirmed_error_px"]``: its distance (px of the view) from the
    3D ball once confirmed (``after_confirming``), and ``confirmed_error_scaled_px`` in the scale the system's pair
    rule compares with tau (``scaled_error_px``, px at 1920 width for ``max_scaled_1920``): the numbers the view's
    facts show after the fix key and after Enter, from the same computation (None: no 3D ball then)."""
    frames = {f.id: f for f in system.frames}
    rule = system.triangulation.rule if system.triangulation is not None else None
    out = []
    for d in doubts:
        frame = frames.get(d.view_id) if d.kind in CONFIRMED_KINDS else None
        centre, box = None, None
        if frame is not None and d.kind == "ball_detected" and (d.suggestion or {}).get("box"):
            box = d.suggestion["box"]
            x1, y1, x2, y2 = box
            centre = np.array([(x1 + x2) / 2, (y1 + y2) / 2])
        elif frame is not None and d.kind == "suggested_label" and frame.ball_label is not None:
            known = frame.ball_label.centre
            centre = None if known is None else np.asarray(known, dtype=float)
            box = frame.ball_label.box
        if centre is None:
            out.append(d)
            continue
        assert frame is not None  # a centre is read from a frame
        error = after_confirming(frame, centre, box)
        out.append(dataclasses.replace(d, evidence={
            **d.evidence, "confirmed_error_px": None if error is None else round(error, 2),
            "confirmed_error_scaled_px": None if error is None else round(
                cast(float, scaled_error_px(error, frame.width, rule)), 2)}))
    return out


def stored_detections(system: System, per_frame: int) -> dict[int, list[Detection]]:
    """Frame id -> the stored predictions of every detector on that frame of ``system`` (``Frame.predictions``,
    loaded with the system by ``app.services.derivation.loading``: at most ``per_frame``,
    ``V3D_MAX_PREDICTIONS_PER_FRAME``, the best by score; a view the session holds without them has them read so,
    ``loading.load_view_predictions``), highest score first; frames without any left out."""
    session = object_session(system)
    if session is not None:
        load_view_predictions(session, system.frames, per_frame)
    out: dict[int, list[Detection]] = {}
    for f in system.frames:
        for p in sorted(f.predictions, key=lambda p: (-p.score, p.id)):
            out.setdefault(f.id, []).append(Detection(p.source, float(p.score), (p.x1, p.y1, p.x2, p.y2)))
    return out


def with_players(system: System, views: list[DoubtView], detections: dict[int, list[Detection]]) -> list[DoubtView]:
    """``views`` (of ``system``), each view with predictions given its person boxes (``Frame.players``, read in one
    query where the session has not loaded them): the detector's check reads them there (a lone ray's detection on a
    player's head or feet, ``app.geometry.doubts.pairings._told_from_players``)."""
    frames = {f.id: f for f in system.frames if f.id in detections}
    session = object_session(system)
    if session is not None:
        load_view_players(session, list(frames.values()))
    return [dataclasses.replace(v, players=tuple(box for _, _, box in frame_players(frames[v.view_id])))
            if v.view_id in frames else v for v in views]


def distance_to_others(views: list[DoubtView], me: DoubtView, s: DoubtSettings,
                       geometry: Callable[[BallObservation, BallObservation], PairGeometry] = pair_geometry,
                       ) -> tuple[Consensus | None, float | None]:
    """How far view ``me``'s ball label lies from the ball the other views agree on
    (``app.geometry.doubts.judge.consensus_without``: the judge's voters, weights and play volume, ``me`` left out).

    Returns:
        ``(consensus, distance)``: the others' :class:`Consensus` (None without a label on ``me``, a suggested one, or
        no agreed ball, or an ambiguous one) and the distance between ``me``'s labelled centre and that ball's
        projection in px of a 1920-wide image (``REFERENCE_WIDTH_PX``; None without a camera on ``me`` or when the
        ball lies behind it).
    """
    if not _measured(me):
        return None, None
    return _distance(me, consensus_without(views, me.view_id, s, geometry))


def _measured(me: DoubtView) -> bool:
    """Whether ``me``'s label is measured against the others: it has one and nobody's suggestion placed it."""
    return label_centre(me) is not None and not me.suggested


def _distance(me: DoubtView, cons: Consensus) -> tuple[Consensus | None, float | None]:
    """:func:`distance_to_others` given the others' consensus ``cons``."""
    if cons.point is None or cons.ambiguous:
        return None, None
    if me.camera is None:
        return cons, None
    e = reprojection_error_px(me.camera, cons.point, centre_of(me))
    return cons, (None if e is None else float(e) * REFERENCE_WIDTH_PX / me.width)


def update_label_distances(system: System, settings: Settings, weighed: WeighedViews,
                           geometry: Callable[[BallObservation, BallObservation], PairGeometry] = pair_geometry,
                           ) -> None:
    """Store, on each view's reprojection row, how far its ball label lies from the ball the other views agree on
    (:func:`distance_to_others`, px at 1920 width; None when there is none): what the per-annotator figures read
    (``app.services.evaluation.annotators``) instead of judging every system per request. The consensuses come from
    one decision of who votes, with the recomputation's calibration weights (``judge.consensuses_without``). Changes
    the session only."""
    s = doubt_settings(settings)
    by_id = {v.view_id: v for v in weighed.views}
    measured = [v.view_id for v in weighed.views if _measured(v)]
    others = consensuses_without(weighed.views, measured, s, geometry, weighed.weighed)
    for frame in system.frames:
        rep = frame.reprojection
        if rep is None:
            continue
        me, cons = by_id.get(frame.id), others.get(frame.id)
        put_values(rep, {"others_distance_px": _distance(me, cons)[1] if me is not None and cons is not None else None})


def suggestion_request(frame_id: int | None, suggestion: dict[str, Any] | None,
                       provenance: dict[str, Any] | None = None) -> dict[str, Any] | None:
    """The exact request the system page's fix key sends for ``suggestion`` on frame ``frame_id``:
    ``{"method", "path", "body"}`` (body None: no JSON body), or None when the suggestion has no request.

    ``snap_box``: ``PATCH /api/frames/{id}/ball {"box": [x1, y1, x2, y2], "provenance": {...}}`` (pixels rounded
    to integers as the page rounds them; ``provenance`` = ``{"doubt", "code", "from_views"}`` of the doubt, so
    that the label is stored as a suggestion, not independent evidence, until a person places it);
    ``snap_point``: the same with ``{"point": [x, y]}``; ``exclude_view``: ``POST /api/frames/{id}/exclusion
    {"excluded": true}``; ``mirror_labels``: ``POST /api/frames/{id}/field-lines/mirror``. The caller adds the
    frame's ``If-Match`` ETag."""
    if frame_id is None or not suggestion:
        return None
    action = suggestion.get("action")
    base = f"/api/frames/{int(frame_id)}"
    extra = {"provenance": provenance} if provenance else {}
    if action == "snap_box" and suggestion.get("box") is not None:
        return {"method": "PATCH", "path": f"{base}/ball",
                "body": {"box": [round(float(x)) for x in suggestion["box"]], **extra}}
    if action == "snap_point" and suggestion.get("point") is not None:
        return {"method": "PATCH", "path": f"{base}/ball",
                "body": {"point": [round(float(x)) for x in suggestion["point"]], **extra}}
    if action == "exclude_view":
        return {"method": "POST", "path": f"{base}/exclusion", "body": {"excluded": True}}
    if action == "mirror_labels":
        return {"method": "POST", "path": f"{base}/field-lines/mirror", "body": None}
    return None


def doubt_provenance(doubt: Doubt) -> dict[str, Any]:
    """The provenance a label made from ``doubt``'s suggestion keeps: the doubt's kind and code (the code is
    stored in its evidence, ``code``) and the views it came from (``agreeing_views``); for a detector's box
    (``ball_detected``) also the detector's name and score (``detector``, ``score``)."""
    ev = doubt.evidence or {}
    views = [int(v) for v in ev.get("agreeing_views") or [] if isinstance(v, int)]
    out: dict[str, Any] = {"doubt": doubt.kind, "code": ev.get("code"), "from_views": views}
    if isinstance(ev.get("detector"), str):  # a detector's box: which detector, and its score
        out.update(detector=ev["detector"], score=ev.get("score"))
    return out


def suggestion_json(frame_id: int | None, suggestion: dict[str, Any] | None,
                    provenance: dict[str, Any] | None = None) -> dict[str, Any] | None:
    """A stored suggestion as the API sends it: itself plus ``request`` (:func:`suggestion_request`)."""
    if not suggestion:
        return None
    req = suggestion_request(frame_id, suggestion, provenance)
    return {**suggestion, "request": req} if req is not None else dict(suggestion)


def doubt_json(doubt: Doubt, frame_names: dict[int, str]) -> dict[str, Any]:
    """A stored doubt as the API sends it: ``frame`` is the image name (None for the system); the
    suggestion carries the request its fix key sends (:func:`suggestion_json`)."""
    return {
        "kind": doubt.kind, "frame_id": doubt.frame_id,
        "frame": frame_names.get(doubt.frame_id) if doubt.frame_id is not None else None,
        "accuses_label": doubt.accuses_label, "message": doubt.message, "evidence": doubt.evidence,
        "suggestion": suggestion_json(doubt.frame_id, doubt.suggestion, doubt_provenance(doubt)),
    }


def doubts_report(session: Session, batch: int = 500) -> dict[str, Any]:
    """Every system's stored doubts (the JSON of ``v3d doubts --json``)::

        {"systems": [{"game": {"league", "season", "match"}, "system": <action image name>,
                      "doubts": [{"kind", "frame": <image name> | null, "message", "evidence",
                                  "suggestion", ...}]}]}

    Systems in (league, season, match, name) order, read ``batch`` at a time.
    """
    ids = list(session.scalars(
        sa.select(System.id).join(Game, Game.id == System.game_id)
        .order_by(Game.league, Game.season, Game.match, sa.func.length(System.name), System.name, System.id)
    ))
    out = []
    for start in range(0, len(ids), batch):
        chunk = ids[start:start + batch]
        systems = session.scalars(
            sa.select(System).where(System.id.in_(chunk))
            .options(selectinload(System.game), selectinload(System.frames), selectinload(System.doubts))
        ).all()
        by_id = {s.id: s for s in systems}
        for sid in chunk:
            s = by_id[sid]
            names = {f.id: f.name for f in s.frames}
            out.append({
                "game": {"league": s.game.league, "season": s.game.season, "match": s.game.match},
                "system": s.name,
                "doubts": [doubt_json(d, names) for d in s.doubts],
            })
        session.expunge_all()
    return {"systems": out}
