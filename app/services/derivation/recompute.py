"""Recomputation of everything derived from annotations: calibration, admission, triangulation,
reprojections and optimised boxes.

Chain (docs/architecture.md): a frame's field lines -> its calibration (:func:`recompute_frame`) ->
its system's admission and triangulation -> reprojections and optimised boxes of the system's frames
(:func:`recompute_system`). These functions only change the session; the caller commits, so an edit
and its recomputation land in one transaction (``app.services.curation.editing``).

Admission and calibration: ``app.services.calibration.calibrating`` (the frame's calibration, the game rig, the pool).

Derived rows:

* ``Triangulation`` (+ ``TriangulationPair`` per pair of labelled views that take part, ``ball.takes_part``), always
  present after recomputation, with the status of ``app.geometry.triangulation.triangulate_ball``;
* ``BallReprojection`` for every frame with a camera when the system has a 3D ball (the error is
  against the frame's label, None without one);
* ``OptimisedBox`` (paper Eq. min_diametre; drawn by ``settings.optimised_box_method``) for every admitted frame with a
  label when the system has a 3D ball and the ball lies in front of the camera along the labelled ray;
* ``Doubt`` rows and the system's doubt counts (``app.services.derivation.doubts.update_doubts``, last).

A view a reviewer excluded (``ReviewDecision.excluded``) keeps its calibration and labels but takes no
part in the triangulation.

Mirrored labels (``app.geometry.mirror``): after admission, every calibrated frame of the system is
judged from its camera's side, the game's rig and its ball ray against the other views; the verdict
sets the flag :data:`MIRROR_FLAG` and ``Calibration.mirror_evidence``. The flag replaces
``calibrate_frame``'s camera-side flag for calibrated frames, which it reproduces for a frame with no
other evidence (a single frame, a view without a ball). Labels are never changed here.
"""
from __future__ import annotations

from dataclasses import dataclass
from functools import partial
from typing import Any, Callable, Iterable, Sequence, cast

import numpy as np
from sqlalchemy import func, select
from sqlalchemy.orm import Session

from app.core.config import Settings
from app.core.metrics import count_recomputation
from app.core.progress import Progress
from app.datasets.records import CalibrationFields
from app.db import scope
from app.db.models import (
    BallEvidence,
    BallReprojection,
    CalibrationSource,
    CalibrationStatus,
    Frame,
    OptimisedBox,
    System,
    Triangulation,
    TriangulationPair,
    TriangulationStatus,
)
from app.db.types import json_safe, utcnow
from app.db.unit import write_unit
from app.geometry.ball import optimise_box
from app.geometry.ball_evidence import RULE_VERSION, BallFacts, ball_evidence
from app.geometry.calibration.result import MIRROR_FLAG, PLAYERS_FLAG
from app.geometry.calibration.rig import estimate_rig
from app.geometry.camera import Camera
from app.geometry.mirror import MirrorView, mirror_evidence
from app.geometry.pair_error import error_above_tau
from app.geometry.triangulation import (
    BallObservation,
    PairGeometryMemo,
    TriangulationResult,
)
from app.services.audit.log import record_summary
from app.services.calibration.admission import is_admitted
from app.services.calibration.calibrating import apply_calibration, calibrate_lines, calibration_job, expected_side
from app.services.calibration.players import place_frame_by_players, players_mirror_evidence
from app.services.calibration.priors import stored_camera_prior, wants_prior_retry, with_prior_refit
from app.services.calibration.rigs import game_rig, rig_centres, rig_rows, uses_rig, wants_rig_retry, with_rig_retry
from app.services.derivation import cameras as shared
from app.services.derivation.ball import ball_facts, judged_by_evidence, system_ball, takes_part
from app.services.derivation.cameras import PairPlayersMemo, mirrored_camera, stored_camera
from app.services.derivation.doubts import (
    stored_detections,
    update_doubts,
    update_label_distances,
    weighed_views,
)
from app.services.derivation.loading import load_systems
from app.services.derivation.rows import put_values, replace_rows
from app.services.kinds import kind_of
from app.services.wording.doubt_words import with_sentence

#: Version of what :func:`recompute_system` derives (rows and the queue's figures); raise it when that
#: changes, so that stored systems are recomputed before they are served (:func:`refresh_stale_systems`).
DERIVED_VERSION = 15 + RULE_VERSION  # 2: pairs outside the play volume dropped, suggested labels left out; 3: pairs
# weighed;
# 4: each view's distance from the ball the other views agree on (the per-annotator figures)
# by what their calibrations are worth (weak_calibrations, outweighed); 5: each ball's sigma stored (and the rule by
# evidence, settings.ball_rule), a placement's doubts say its error once confirmed, as the view will show it, and a
# players-placed view's label far off the agreed ball is accused; 6: the rule by evidence is the default; 7: under it
# a view below admission that fits most of its own lines takes part, an undetermined camera makes no pair, and a pair
# whose cameras disagree on their players is left out; 8: the doubts' fills count such a view as the ball does (a box
# it would make a ball with is no weak fill), and a box placed from labels the ball keeps no ball from gets no fix key;
# 9: nor a box placed from one labelled ray whose ball is in the air where no third view sees it; 10: nor boxes
# placed from one labelled ray and two detected views whose pairs the ball's rule would not all keep once confirmed;
# 11: a ball resting on one pair whose rays meet only at the edge of tau is refused; 12: the doubts say so of a
# consensus resting on one such pair of full votes beyond their joint sigma (views_disagree, lone_pair); 13: one
# labelled view whose box agrees with the grass calls a view showing that spot missing; 14: before the pairs are
# weighed, those with a view outside the largest consensus of views (within tau of one pair's point) are left out;
# 15: a detection whose rays meet the others' under the grass beyond three of that ball's sigmas fills no view;
# the evidence rule's version 2 (+1): a label the fix key copied from a detection's box is not confirmed by it


def recompute_frame(session: Session, frame: Frame, settings: Settings,
                    rig: Sequence[tuple[int, np.ndarray, bool]] | None = None, *,
                    players: bool = False) -> Triangulation:
    """Recalibrate ``frame`` from its current field lines (:func:`calibrate_frame_lines`), store the
    calibration (source "computed"), then recompute its system. The caller flushes or commits.

    Args:
        rig: the game's rig rows (:func:`rig_rows`) when the caller has read them (an edit reads them with its
            system, ``app.services.curation.writing``): not read again.
        players: then place the frame by its players where they place it
            (``app.services.calibration.players.place_frame_by_players``), as the import did.

    Raises:
        ValueError: the frame has no field lines, or the settings' admission gamma is not stored.
    """
    calibrated = calibrate_frame_lines(session, frame, settings, rig=rig)
    apply_calibration(frame, calibrated.fields, CalibrationSource.COMPUTED)
    if players:
        place_frame_by_players(session, frame, settings, rig)
    sources = calibrated.rig_sources
    if sources is None and rig is not None:
        sources = [(fid, c) for fid, c, _ in rig]
    return recompute_system(session, frame.system, settings, sources)


@dataclass(frozen=True)
class FrameCalibration:
    """What :func:`calibrate_frame_lines` gives: the calibration to store (``fields``), which retry made it
    (``retry``: "rig", "prior" or None: the lines alone) and the game's stored cameras it read for the rig
    (``rig_sources``: ``(frame id, camera centre)``, None when it read none), which
    :func:`recompute_system` takes to spare a query."""

    fields: CalibrationFields
    retry: str | None
    rig_sources: list[tuple[int, np.ndarray]] | None


def calibrate_frame_lines(session: Session, frame: Frame, settings: Settings,
                          lines: dict[str, Any] | None = None, *, refine: bool = True,
                          rig: Sequence[tuple[int, np.ndarray, bool]] | None = None) -> FrameCalibration:
    """The calibration of ``frame`` from its field lines, or from ``lines`` (validated JSON lists,
    ``{class: [[[x, y], ...], ...]}`` px) in their place, as an edit computes it: the one calibration of
    both the commit (:func:`recompute_frame`) and its dry run (``app.services.curation.calibration_preview``).
    Reads the session and writes nothing.

    A frame of a SoccerNet-v3 game that its lines alone cannot calibrate, or calibrate only below
    admission (:func:`wants_rig_retry`), is retried with the game's rig (:func:`game_rig`, the other
    frames' camera positions; :func:`with_rig_retry` keeps the better fit). A frame of a calibration
    dataset whose import learned a camera prior (:func:`stored_camera_prior`) is refitted with it where
    its lines leave the camera open (:func:`wants_prior_retry`), as the import did. The system's kind
    may refine the result (``KindPolicy.refine_calibration``: an ISSIA camera refined with the ball's labels at
    import is refined so again) unless ``refine`` is False (``KindPolicy.calibration_refinement`` says what that
    leaves out). ``rig``: the game's rig rows (:func:`rig_rows`) when the caller has read them.

    Raises:
        ValueError: the frame has no field lines (and no ``lines`` are given).
    """
    fields = calibrate_lines(*calibration_job(frame, lines=lines))
    retry, rig_sources = None, None
    if wants_rig_retry(fields, settings) and uses_rig(frame.system) and frame.system.game_id is not None:
        # read once: the retry's rig and the system's mirror evidence both use the game's stored
        # cameras, and the evidence leaves this system's frames out, so this frame's new row is moot
        stored = list(rig) if rig is not None else rig_rows(session, frame.system.game_id, settings)
        rig_sources = [(fid, c) for fid, c, _ in stored]
        game_rig_now = game_rig(session, frame.system.game_id, settings, exclude_frame_ids=[frame.id], stored=stored)
        if game_rig_now.positions:
            retried = calibrate_lines(*calibration_job(frame, game_rig_now, lines=lines))
            fields = with_rig_retry(fields, retried)
            retry = "rig" if fields is retried else None
    elif (prior := stored_camera_prior(frame.system)) is not None and wants_prior_retry(fields, prior):
        refit = calibrate_lines(*calibration_job(frame, prior, lines=lines))
        fields = with_prior_refit(fields, refit)
        retry = "prior" if fields is refit else None
    if refine:
        fields = kind_of(frame.system).refine_calibration(session, frame, fields, settings)
    return FrameCalibration(fields, retry, rig_sources)


def recompute_system(session: Session, system: System, settings: Settings,
                     rig_sources: Sequence[tuple[int, np.ndarray]] | None = None,
                     geometry: PairGeometryMemo | None = None) -> Triangulation:
    """Admission, mirror evidence, triangulation, reprojections and optimised boxes of one system,
    from its current calibrations and ball labels (see the module docstring). Replaces the previous
    derived rows in the session; the caller flushes or commits. The system's frames must have ids
    (be flushed).

    Args:
        rig_sources: ``(frame id, camera centre)`` feeding the game's rig (:func:`rig_centres`), to spare
            a query per system in bulk; read from the session when None.
        geometry: where the pairs' geometry comes from; None: the process's memo shared by every edit
            (``cameras.PAIR_GEOMETRY``, which keeps the pairs of the views an edit leaves as they were, and
            ``cameras.PAIR_PLAYERS`` for the pairs' players), a memo of its own for a system recomputed in bulk,
            which no later recomputation asks again (and one for its players).

    Returns:
        The system's :class:`Triangulation` row.
    """
    count_recomputation()
    frames = list(system.frames)
    kind = kind_of(system)
    by_evidence = judged_by_evidence(settings, kind.weighs_calibrations)
    cameras, observations = _views_taking_part(frames, settings, by_evidence)
    # each pair's rays (and players) once, for the mirror evidence, the triangulation and the doubts, and the pairs of
    # views an edit left as they were (``cameras`` module docstring); a bulk recomputation's are asked by no later one
    players_memo = shared.PAIR_PLAYERS if geometry is None else PairPlayersMemo(max_entries=shared.PAIRS)
    geometry = shared.PAIR_GEOMETRY if geometry is None else geometry
    if kind.broadcast_priors:
        _update_mirror_flags(session, system, cameras, settings, rig_sources, geometry)
    weighed = weighed_views(system, settings, cameras)  # the judge's views, once for the ball and the doubts

    def ball_of(labelled: list[BallObservation],
                boxes: dict[int, Sequence[float]] | None = None) -> tuple[TriangulationResult, float | None]:
        return system_ball(system, kind.consensus_observations(system, labelled, settings), settings, weighed,
                           geometry, weighs_calibrations=kind.weighs_calibrations, boxes=boxes, players=players_memo)

    result, sigma_m = ball_of(observations)
    after_confirming = partial(_error_once_confirmed, cameras, observations, result,
                               lambda o, boxes: ball_of(o, boxes)[0], by_evidence)
    once_confirmed = partial(_ball_once_confirmed, frames, cameras, observations,
                             lambda o, boxes: ball_of(o, boxes)[0], by_evidence)

    tri = system.triangulation
    if tri is None:
        tri = Triangulation(system=system, status=TriangulationStatus(result.status), tau_px=result.tau_px,
                            rule=result.rule, min_baseline_m=result.min_baseline_m)
        session.add(tri)
    put_values(tri, {"status": TriangulationStatus(result.status),
                     "ball3d": None if result.point is None else [float(v) for v in result.point],
                     "sigma_m": None if result.point is None or sigma_m is None else float(sigma_m),
                     "tau_px": result.tau_px, "rule": result.rule, "min_baseline_m": result.min_baseline_m})
    put_values(tri, {"computed_at": utcnow()})
    replace_rows(tri.pairs, TriangulationPair, [dict(  # in place: a pair the edit leaves as it was writes nothing
        frame_a_id=p.view_a, frame_b_id=p.view_b,
        point=None if p.point is None else [float(v) for v in p.point],
        error_px=json_safe(p.error), parallax_deg=json_safe(p.parallax_deg), baseline_m=float(p.baseline_m),
        kept=bool(p.kept), reason=p.reason,
    ) for p in result.pairs])

    ball = None if result.point is None else np.asarray(result.point, dtype=float)
    for f in frames:
        _update_reprojection(f, cameras.get(f.id), ball)
        admitted = f.calibration is not None and f.calibration.admitted
        _update_optimised_box(f, cameras.get(f.id) if admitted else None, ball, settings)
    # the views' detections read once, for the doubts and the ball's evidence (nothing between changes them)
    detections = stored_detections(system, settings.max_predictions_per_frame)
    update_doubts(system, settings, cameras, geometry, weighed, after_confirming, detections, once_confirmed)
    update_label_distances(system, settings, weighed, geometry)
    kept = [p for p in result.pairs if p.kept]
    errors = [p.error / result.tau_px for p in kept if p.error is not None and result.tau_px]
    pairs = [(cast(int, p.view_a), cast(int, p.view_b)) for p in kept]
    update_summary(system, tri, ball_facts(system, result.point, pairs, sigma_m, cameras, settings, players_memo,
                                           max(errors, default=None), detections))
    put_values(system, {"derived_version": DERIVED_VERSION, "derived_settings": settings.derived_fingerprint()})
    scope.changed(system)  # its derived rows were written: what its next edit compares (``scope``)
    return tri


def _views_taking_part(frames: Sequence[Frame], settings: Settings, by_evidence: bool
                    ) -> tuple[dict[int, Camera], list[BallObservation]]:
    """Each frame's admission set on its calibration (``is_admitted``), the cameras of the calibrated frames by frame
    id, and the ball observations of the frames that take part (``ball.takes_part``) with a label a person placed."""
    cameras: dict[int, Camera] = {}
    observations: list[BallObservation] = []
    for f in frames:
        cal = f.calibration
        if cal is not None:
            put_values(cal, {"admitted": is_admitted(cal, settings)})
            if cal.status is CalibrationStatus.CALIBRATED and cal.camera is not None:
                cameras[f.id] = stored_camera(cal.camera)
        centre = _label_centre(f)
        suggested = f.ball_label is not None and f.ball_label.suggested  # not independent evidence until placed
        if centre is not None and not suggested and takes_part(f, by_evidence):
            observations.append(BallObservation(view_id=f.id, camera=cameras[f.id], point_px=centre,
                                                image_width=f.width))
    return cameras, observations


def _error_once_confirmed(cameras: dict[int, Camera], observations: list[BallObservation],
                          result: TriangulationResult,
                          triangulated: Callable[[list[BallObservation], dict[int, Sequence[float]] | None],
                                                 TriangulationResult], by_evidence: bool,
                          frame: Frame, centre: np.ndarray, box: Sequence[float] | None) -> float | None:
    """How far (px of ``frame``'s image) a label centred at ``centre`` (its box ``box``, px, or None) would lie from
    the 3D ball once a person confirmed it there: the ball ``triangulated`` with it, its box standing for the view's
    label (a label's size is its pixel noise under the rule by evidence), as the recomputation that gave ``result``
    from ``observations`` triangulates (when the view takes part: ``ball.takes_part``), else ``result``'s ball;
    None where there would be none, or no camera."""
    camera = cameras.get(frame.id)
    if camera is None:
        return None
    if not takes_part(frame, by_evidence):
        ball = result.point
    else:
        confirmed = BallObservation(view_id=frame.id, camera=camera, point_px=centre, image_width=frame.width)
        ball = triangulated([*(o for o in observations if o.view_id != frame.id), confirmed],
                            None if box is None else {frame.id: box}).point
    return None if ball is None else _reprojection_error(camera, np.asarray(ball, dtype=float), centre)


def _ball_once_confirmed(frames: Sequence[Frame], cameras: dict[int, Camera], observations: list[BallObservation],
                         triangulated: Callable[[list[BallObservation], dict[int, Sequence[float]] | None],
                                                TriangulationResult], by_evidence: bool,
                         boxes: dict[int, Sequence[float]]) -> TriangulationResult:
    """The 3D ball (its pairs kept and refused) the recomputation would triangulate once a person confirmed a ball
    box on each frame of ``boxes`` (frame id -> ``[x1, y1, x2, y2]`` px of its image): each box's centre stands for
    that view's label, its box for the label's size, beside the labels that take part now (``observations``); a
    frame without a camera, or one that takes no part in the ball (``ball.takes_part``), adds nothing. What
    ``app.services.derivation.doubts.without_unbacked_fixes`` asks of boxes placed together."""
    placed = []
    for f in frames:
        box = boxes.get(f.id)
        if box is None or f.id not in cameras or not takes_part(f, by_evidence):
            continue
        centre = np.array([(box[0] + box[2]) / 2, (box[1] + box[3]) / 2], dtype=float)
        placed.append(BallObservation(view_id=f.id, camera=cameras[f.id], point_px=centre, image_width=f.width))
    ids = {o.view_id for o in placed}
    return triangulated([*(o for o in observations if o.view_id not in ids), *placed],
                        {fid: b for fid, b in boxes.items() if fid in ids})


def system_rig_rows(session: Session, system: System, settings: Settings) -> list[tuple[int, np.ndarray, bool]] | None:
    """The rig rows (:func:`rig_rows`) of ``system``'s game when its kind uses a rig, else None."""
    game_id = rig_game_of(system)
    return rig_rows(session, game_id, settings) if game_id is not None else None


def rig_game_of(system: System) -> int | None:
    """The game whose rig rows ``system``'s recomputation reads (:func:`system_rig_rows`), None when it reads none."""
    return system.game_id if uses_rig(system) and system.game_id is not None else None


def update_summary(system: System, tri: Triangulation, facts: BallFacts | None = None) -> None:
    """Store the review queue's figures of ``system`` (``System.views_total`` ... ``views_above_tau``,
    model docstring) from its current frames and triangulation: aggregates over the **admitted** views,
    ``views_flagged`` over every view, ``views_above_tau`` by ``app.geometry.pair_error.error_above_tau``; and what
    backs its 3D ball (``ball_evidence`` and its reasons, :func:`app.geometry.ball_evidence.ball_evidence` of
    ``facts``; None: left as stored)."""
    frames = list(system.frames)
    cals = [f.calibration for f in frames]
    admitted = [f for f in frames if f.calibration is not None and f.calibration.admitted]
    jacs = [c.jac_0005 for c in cals if c is not None and c.admitted and c.jac_0005 is not None]
    labelled = [(f, rep.error_px) for f in admitted if f.ball_label is not None and f.ball_label.kind is not None
                and (rep := f.reprojection) is not None and rep.error_px is not None]
    put_values(system, {
        "views_total": len(frames),
        "views_calibrated": sum(c is not None and c.status is CalibrationStatus.CALIBRATED for c in cals),
        "views_admitted": len(admitted),
        "views_labelled": sum(f.ball_label is not None and f.ball_label.kind is not None for f in frames),
        "lowest_jac": min(jacs) if jacs else None,
        "worst_error_px": max((error for _, error in labelled), default=None),
        "views_flagged": sum(c is not None and MIRROR_FLAG in (c.flags or []) for c in cals),
        "views_above_tau": sum(error_above_tau(error, f.width, tri.tau_px, tri.rule) for f, error in labelled),
    })
    if facts is not None:
        tier, reasons = ball_evidence(facts)
        put_values(system, {"ball_evidence": BallEvidence(tier), "ball_evidence_reasons": reasons})


def refresh_stale_systems(session: Session, settings: Settings, progress: Progress | None = None) -> int:
    """Recompute (calibrations untouched) every system stored by an older version of the derived rows
    (``System.derived_version < DERIVED_VERSION``, e.g. after a schema upgrade) and commit; returns how
    many. Serving or reporting a database calls it first, so stored doubts and queue figures are current.
    Systems are recomputed and committed :data:`_REFRESH_BATCH` at a time (a crash leaves the rest stale,
    to be refreshed next time), each in a write transaction (``app.db.session.begin_write``), so a
    server running meanwhile never sees half a batch and its edits wait their turn. Each batch is one audit entry
    (action "recompute", by the local user), written in its transaction."""
    ids = list(session.scalars(select(System.id).where(System.derived_version < DERIVED_VERSION).order_by(System.id)))
    _recompute_in_batches(session, ids, settings, progress, {"reason": "stored by an older version",
                                                             "derived_version": DERIVED_VERSION})
    return len(ids)


def systems_computed_otherwise(session: Session, settings: Settings) -> int:
    """How many systems were computed with other settings than ``settings`` (``System.derived_settings`` differs
    from ``settings.derived_fingerprint()``, e.g. after ``V3D_PROFILE`` changed): their stored results are stale until
    ``v3d recompute`` (:func:`recompute_all_systems`). Systems stored before the fingerprint was recorded (None) are
    not counted."""
    return int(session.scalar(select(func.count(System.id)).where(
        System.derived_settings.is_not(None), System.derived_settings != settings.derived_fingerprint())) or 0)


def recompute_all_systems(session: Session, settings: Settings, progress: Progress | None = None,
                          actor: str | None = None) -> tuple[int, int]:
    """The full recompute: every system recomputed with the current settings (calibrations untouched:
    admission, triangulation, reprojections, optimised boxes, mirror flags, doubts and queue figures),
    committed :data:`_REFRESH_BATCH` systems at a time with ``progress("recompute", done, total)``
    after each commit. Idempotent: run again after a crash, it gives the same rows. One audit entry per
    committed batch (action "recompute", by ``actor``; None: the local user), in the batch's transaction.

    Returns:
        ``(systems recomputed, systems triangulated)``.
    """
    ids = list(session.scalars(select(System.id).order_by(System.id)))
    return len(ids), _recompute_in_batches(session, ids, settings, progress, {"reason": "full recompute"}, actor)


def recompute_systems_by_id(session: Session, ids: list[int], settings: Settings, progress: Progress | None,
                            audit_after: dict[str, Any], actor: str | None = None) -> int:
    """Recompute the systems ``ids`` (e.g. those an import of a detector's predictions touched), committed in
    batches as :func:`recompute_all_systems` does (one audit entry per batch with ``audit_after``); returns how many
    were triangulated (0 for no ids)."""
    return _recompute_in_batches(session, ids, settings, progress, audit_after, actor) if ids else 0


def _recompute_in_batches(session: Session, ids: list[int], settings: Settings, progress: Progress | None,
                          audit_after: dict[str, Any], actor: str | None = None) -> int:
    """Recompute the systems ``ids``, committing and releasing :data:`_REFRESH_BATCH` at a time (bounded
    memory), each batch in a write transaction (``app.db.session.begin_write``, so a server running
    meanwhile never sees half a batch and its edits wait their turn), each batch's audit entry ("recompute",
    ``audit_after`` with the counts, ``batch`` of ``batches``) written in its transaction; returns how many were
    triangulated."""
    triangulated = 0
    for start in range(0, len(ids), _REFRESH_BATCH):
        with write_unit(session):  # each batch read and written under the write lock (SQLite: BEGIN IMMEDIATE)
            batch = session.scalars(select(System).where(System.id.in_(ids[start:start + _REFRESH_BATCH]))).all()
            triangulated += recompute_systems(session, batch, settings)
            record_summary(session, "recompute", {"systems": len(ids), **audit_after,
                                                  "batch": start // _REFRESH_BATCH + 1,
                                                  "batches": -(-len(ids) // _REFRESH_BATCH),
                                                  "batch_systems": len(batch)}, actor=actor)
        session.expunge_all()
        if progress:
            progress("recompute", min(start + _REFRESH_BATCH, len(ids)), len(ids))
    return triangulated


def _update_mirror_flags(session: Session, system: System, cameras: dict[int, Camera], settings: Settings,
                         rig_sources: Sequence[tuple[int, np.ndarray]] | None,
                         geometry: PairGeometryMemo | None = None) -> None:
    """Judge every calibrated frame of the system (``app.geometry.mirror.mirror_evidence``: ball rays
    of every calibrated, labelled frame, side prior, the game's rig estimated without this system's
    frames) and set :data:`MIRROR_FLAG` and ``mirror_evidence`` on its calibration. Refused frames
    keep what their rig retry found (:func:`with_rig_retry`).

    Rays of frames below the admission threshold count too: JaC is the same for labels and their
    mirror, so admission says nothing about mirroring, and a rough camera cannot bring two rays
    within tau by chance (it gives no agreement, hence no evidence). Counting them flagged more of
    the dev set's injected mirrored views with no false flag either way; today's figures are in the
    docstring of ``benchmarks/mirror_flags.py`` (73 of 92 flagged). A camera the players placed whose view's
    lines fit it only mirrored keeps the flag with the players' evidence (``players.players_mirror_evidence``), and
    one read from a dataset without its fit's players keeps the flag the dataset gave it."""
    frames = [f for f in system.frames if f.id in cameras]
    if not frames:
        return
    positions = None
    if uses_rig(system) and system.game_id is not None:
        sources = rig_sources if rig_sources is not None else rig_centres(session, system.game_id, settings)
        mine = {f.id for f in system.frames}
        rig = estimate_rig(np.array([c for fid, c in sources if fid not in mine]).reshape(-1, 3))
        positions = np.array([p.centre_m for p in rig.positions]).reshape(-1, 3)
    views = [MirrorView(view_id=f.id, camera=cameras[f.id],
                        ball_px=None if f.ball_label is not None and f.ball_label.suggested else _label_centre(f),
                        image_width=f.width,
                        expected_side=expected_side(f.role), rays=True, name=f.name,
                        mirrored=mirrored_camera(cameras[f.id]))
             for f in frames]
    verdicts = mirror_evidence(views, positions, geometry=geometry or PairGeometryMemo(),
                               tau_px=settings.triangulation_tau_px, rule=settings.pair_error_rule)
    names = {f.id: f.name for f in system.frames}
    # a camera the players placed whose lines fit it only mirrored: its labels are mirrored whatever its camera's
    # verdict (the camera is the players', right where their labels are not)
    by_players = {f.id: ev for f in frames if f.calibration is not None and PLAYERS_FLAG in (f.calibration.flags or [])
                  and (ev := players_mirror_evidence(f.calibration.players, f.calibration.camera)) is not None}
    # such a camera read from a dataset (which keeps its flags but not the fit's players) keeps the flag it came with:
    # the evidence that set it is not in the file, and its camera's own verdict cannot see mirrored labels
    from_file = {f.id for f in frames if f.calibration is not None and not f.calibration.players
                 and PLAYERS_FLAG in (f.calibration.flags or []) and MIRROR_FLAG in (f.calibration.flags or [])}
    flagged = {fid for fid, v in verdicts.items() if v.flagged} | set(by_players) | from_file
    for f in frames:
        cal, verdict = f.calibration, verdicts[f.id]
        assert cal is not None  # a view with a camera has its calibration
        flags = [x for x in (cal.flags or []) if x != MIRROR_FLAG]
        evidence = by_players.get(f.id) or json_safe(with_sentence(verdict.as_dict(), names, flagged))
        put_values(cal, {"flags": [*flags, MIRROR_FLAG] if f.id in flagged else flags, "mirror_evidence": evidence})


def _label_centre(frame: Frame) -> np.ndarray | None:
    """(2,) labelled ball centre in pixels, or None without a current label."""
    centre = frame.ball_label.centre if frame.ball_label is not None else None
    return None if centre is None else np.asarray(centre, dtype=float)


def _projected(camera: Camera, ball: np.ndarray) -> np.ndarray | None:
    """(2,) px where ``camera`` sees the 3D ball ``ball`` (3,) world metres, None behind it."""
    proj, in_front = camera.project(ball.reshape(1, 3))
    return proj[0] if in_front[0] else None


def _reprojection_error(camera: Camera, ball: np.ndarray, centre: np.ndarray) -> float | None:
    """A view's reprojection error as its facts show it: px of its image between the labelled centre ``centre`` (2,)
    and the 3D ball's projection (None behind the camera). The one computation of the stored error and of the error
    a placement would have once confirmed (``recompute_system``'s ``after_confirming``)."""
    return _pixel_error(_projected(camera, ball), centre)


def _pixel_error(uv: np.ndarray | None, centre: np.ndarray) -> float | None:
    """px between the ball's projection ``uv`` (2,) (None: behind the camera) and the labelled centre ``centre``
    (2,): :func:`_reprojection_error` given the projection."""
    return None if uv is None else float(np.linalg.norm(uv - centre))


def _update_reprojection(frame: Frame, camera: Camera | None, ball: np.ndarray | None) -> None:
    uv = _projected(camera, ball) if camera is not None and ball is not None else None
    if uv is None:
        if frame.reprojection is not None:
            frame.reprojection = None
        return
    centre = _label_centre(frame)
    # the stored error from the projection just made (what _reprojection_error would project again)
    error = None if centre is None else _pixel_error(uv, centre)
    rep = frame.reprojection
    if rep is None:
        frame.reprojection = rep = BallReprojection(point=[0.0, 0.0])
    put_values(rep, {"point": [float(uv[0]), float(uv[1])], "error_px": error})


def _update_optimised_box(frame: Frame, camera: Camera | None, ball: np.ndarray | None, settings: Settings) -> None:
    opt = None
    centre = _label_centre(frame)
    if camera is not None and ball is not None and centre is not None:
        r = optimise_box(camera, centre, ball, settings.ball_diameter_m, method=settings.optimised_box_method)
        opt = r if r.status == "ok" else None
    if opt is None:
        if frame.optimised_box is not None:
            frame.optimised_box = None
        return
    assert opt.box is not None and opt.d_px is not None  # an "ok" result has its box and size
    row = frame.optimised_box
    if row is None:
        frame.optimised_box = row = OptimisedBox(box=[], d_opt_px=0.0, error_m=0.0)
    put_values(row, {"box": [float(v) for v in opt.box], "d_opt_px": float(opt.d_px), "error_m": float(opt.error_m)})


#: Systems recomputed per transaction by :func:`refresh_stale_systems`.
_REFRESH_BATCH = 500


def load_for_recompute(session: Session, ids: Sequence[int], *, predictions: int | None,
                       with_game: bool = False) -> dict[int, System]:
    """The systems ``ids`` with what :func:`recompute_system` and ``update_doubts`` read (``scope``), by id, in four
    queries per
    500 systems (``app.services.derivation.loading.load_systems``) instead of one lazy load per attribute and frame
    (systems already in the session get the relations they have not loaded; changed attributes are kept).
    ``with_game``: the system's game joined too (an edit, whose answer names the game and whose recalibration may
    read its learned prior: one lazy load fewer). ``predictions``: the most a view's predictions loaded, the best by
    score (``V3D_MAX_PREDICTIONS_PER_FRAME``; None: none, for a write that recomputes nothing)."""
    return load_systems(session, ids, (*scope.SYSTEM_ROWS, scope.GAME_ROW) if with_game else scope.SYSTEM_ROWS,
                        predictions=predictions)


def preload_systems(session: Session, systems: Sequence[System], settings: Settings) -> None:
    """Flush, then load what recomputing ``systems`` with ``settings`` reads (:func:`load_for_recompute`)."""
    session.flush()
    load_for_recompute(session, [s.id for s in systems], predictions=settings.max_predictions_per_frame)


def recompute_systems(session: Session, systems: Iterable[System], settings: Settings,
                      progress: Progress | None = None, *, preloaded: bool = False) -> int:
    """:func:`recompute_system` for each system, then one flush; returns how many were triangulated.

    The systems' frames and derived rows are loaded in four queries first
    (:func:`preload_systems`; skipped when ``preloaded``: the caller did it), so that recomputing
    thousands of systems does not issue one lazy load per attribute.
    """
    systems = list(systems)
    if preloaded:
        session.flush()
    else:
        preload_systems(session, systems, settings)
    sources = {gid: rig_centres(session, gid, settings)
               for gid in {s.game_id for s in systems if uses_rig(s) and s.game_id is not None}}
    n = 0
    for i, s in enumerate(systems, 1):
        tri = recompute_system(session, s, settings, sources.get(s.game_id), geometry=PairGeometryMemo())
        if tri.status is TriangulationStatus.TRIANGULATED:
            n += 1
        if progress:
            progress("triangulate", i, len(systems))
    session.flush()
    return n
