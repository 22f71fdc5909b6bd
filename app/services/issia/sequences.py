"""ISSIA-3D sequences in the service: import, edits' re-fit, frame images and the export.

* :func:`import_issia`: a folder read by :func:`app.datasets.issia.read_issia` becomes one game
  (league :data:`LEAGUE`, season :data:`SEASON`, match the folder's name), one multi-view system of
  kind ``issia`` per frame index (``System.frame_index``, name the index) and one view per camera
  ("cam<k>", role ``static``). Each static camera is calibrated once
  (:func:`app.services.issia.cameras.sequence_cameras`: ``issia_calibration.json``, or the field lines with
  ``from_lines``) and stored on each of its views' calibrations (JaC against the camera's lines when
  there are lines). Point labels become :class:`~app.db.models.BallLabel` points. Then the sequence's
  trajectory is fitted (``app.services.issia.trajectory``) and every system recomputed (admission,
  triangulation of the labels the trajectory keeps, reprojections, optimised boxes, doubts), and the
  transaction commits. Idempotent by natural keys; a stored sequence is merged
  (``app.services.transfer.merging``: ``keep-newer`` keeps every edited label and line, one audit entry per
  system changed).
* :func:`refined_with_ball`: a view's new calibration from its edited lines, refined again with the
  sequence's ball labels and the other cameras when the import had refined its camera so (flag
  :data:`BALL_BUNDLE_FLAG`): an edit keeps what the ball taught the camera.
* :func:`refit_after_edit`: after an edit of an ISSIA view (in the edit's transaction), the stretch of
  the trajectory it touches is re-fitted (``app.services.issia.refit``) and the systems whose place on
  it changed are recomputed; a new calibration of the view that gives its camera to the sequence
  re-fits the whole sequence.
* a view's image is decoded on demand from its video or frame folder by
  ``app.services.images.serving.read_video_frame``.
* :func:`export_issia3d`: ``ISSIA-3D.csv`` of a stored sequence (:mod:`app.datasets.issia3d`).
"""
from __future__ import annotations

import dataclasses
import time
from pathlib import Path
from typing import Iterable

import numpy as np
import sqlalchemy as sa
from sqlalchemy.orm import Session, selectinload

from app.core.config import Settings
from app.core.progress import Progress
from app.datasets.issia import CAMERA_SET, FPS, IssiaSequence, read_issia
from app.datasets.records import CalibrationFields
from app.db.models import (
    BallKind,
    BallLabel,
    CalibrationSource,
    CalibrationStatus,
    FieldLineAnnotation,
    Frame,
    FrameRole,
    Game,
    System,
    SystemKind,
)
from app.db.session import refresh_statistics
from app.db.types import json_safe, utcnow
from app.db.unit import write_unit
from app.geometry.annotations import lines_from_json_lists, lines_to_json_lists
from app.geometry.calibration.held_out import class_point_distances
from app.geometry.camera import Camera
from app.geometry.jac import JAC_GAMMAS, jac_at_gammas
from app.geometry.trajectory import fit_trajectory
from app.services.audit.log import record_summary
from app.services.calibration.admission import GIVEN_CAMERA_FLAG, admission_args
from app.services.calibration.calibrating import apply_calibration, fit_uncertainty
from app.services.derivation.doubts import update_doubts
from app.services.derivation.recompute import load_for_recompute, recompute_system, recompute_systems
from app.services.issia.cameras import CameraChoice, bundle_refined_cameras, sequence_cameras
from app.services.issia.refit import refit_sequence, sequence_columns
from app.services.issia.trajectory import fit_args, fit_sequence, load_sequence, sequence_arrays
from app.services.kinds.issia import BALL_BUNDLE_FLAG
from app.services.transfer.importing import ImportReport, audit_counts
from app.services.transfer.merging import Merge, SystemChange

LEAGUE, SEASON = "issia", "sequences"
#: Calibration flag of a camera calibrated again from the ball's trajectory of the others.
BALL_ASSISTED_FLAG = "ball_assisted"


def view_name(camera_id: str) -> str:
    """The view name of an ISSIA camera id ("3" -> "cam3")."""
    return f"cam{camera_id}"


def _camera_fields(seq: IssiaSequence, cid: str, choice: CameraChoice) -> CalibrationFields:
    if choice.camera is None:
        return CalibrationFields(CalibrationStatus.REFUSED, None, (None, None, None), reason=choice.reason,
                                 refusal=choice.refusal)
    w, h = seq.image_size
    flags = [BALL_ASSISTED_FLAG] * choice.ball_assisted + [BALL_BUNDLE_FLAG] * choice.bundle_adjusted
    values: tuple[float | None, float | None, float | None]
    if cid in seq.lines:
        jac = jac_at_gammas(choice.camera, seq.lines[cid], w, h, JAC_GAMMAS)
        values = (float(jac[JAC_GAMMAS[0]]), float(jac[JAC_GAMMAS[1]]), float(jac[JAC_GAMMAS[2]]))
    else:
        values, flags = (None, None, None), flags + [GIVEN_CAMERA_FLAG]
    return CalibrationFields(CalibrationStatus.CALIBRATED, json_safe(choice.camera.to_soccernet()), values, flags=flags)


def _set_label(frame: Frame, point: tuple[float, float] | None, merge: Merge, change: SystemChange | None) -> bool:
    """Store the imported point as the original; the current label becomes it where the merge takes the file's (a
    label nobody edited always follows it: :meth:`Merge.takes`). Returns True when the stored label changed."""
    kind = BallKind.POINT if point is not None else None
    new = (kind, None, [float(point[0]), float(point[1])] if point is not None else None)
    label = frame.ball_label
    if label is None:
        if kind is None:
            return False
        label = BallLabel()
        frame.ball_label = label
        current: tuple = (None, None, None)
        same_original, edited, edited_at = False, False, None
    else:
        current = (label.kind, label.box, label.point)
        same_original = (label.original_kind, label.original_box, label.original_point) == new
        edited, edited_at = label.edited, label.edited_at
    differs = current != new
    if same_original and not differs:
        return False
    taken = merge.takes(edited, edited_at)
    merge.part(change, frame, taken=taken, differs=differs, lines=False)
    label.original_kind, label.original_box, label.original_point = new
    if taken and differs:
        label.kind, label.box, label.point, label.provenance = (*new, None)
        label.edited_at = None
    if label.kind is None and label.original_kind is None:
        frame.ball_label = None
    return not same_original or (taken and differs)


def import_issia(session: Session, path: str | Path, settings: Settings, *, from_lines: bool = False,
                 flipped_cameras: Iterable[str] = (), progress: Progress | None = None,
                 actor: str | None = None, source_name: str | None = None,
                 merge: str = "keep-newer") -> ImportReport:
    """Import an ISSIA folder (module docstring) in one transaction.

    Args:
        from_lines: calibrate each camera from ``issia_lines.json`` even when ``issia_calibration.json``
            is present.
        flipped_cameras: camera ids ("1".."6") whose footage is mirrored horizontally (images only).
        actor: who imports, for the import's one audit entry (None: the local user).
        source_name: how the entry names the folder to non-admins (default: its last component).
        merge: how a stored sequence is merged (``app.services.transfer.merging``: an ISSIA folder has no export
            time, so ``keep-newer`` keeps every edited label and line); one audit entry per system it changes.

    Raises:
        DatasetError: invalid folder, files or camera ids (nothing is stored).
    """
    t0 = time.perf_counter()
    report = ImportReport(source=str(path), source_name=source_name or Path(path).name)
    seq = read_issia(path, flipped_cameras=flipped_cameras, max_pixels=settings.max_image_pixels)
    report.read_seconds = time.perf_counter() - t0
    t1 = time.perf_counter()
    choice = sequence_cameras(seq, from_lines=from_lines, **admission_args(settings), pair_rules=fit_args(settings))
    fields = {cid: _camera_fields(seq, cid, choice[cid]) for cid in seq.camera_ids}
    source = CalibrationSource.COMPUTED if from_lines or not seq.cameras else CalibrationSource.IMPORTED
    report.calibration_seconds = time.perf_counter() - t1
    report.games, report.systems, report.frames = 1, len(seq.frames), len(seq.frames) * len(seq.camera_ids)
    for f in fields.values():
        if f.status is CalibrationStatus.CALIBRATED:
            report.calibrated += 1
        else:
            report.refused += 1
            report.refusal_reasons[f.refusal or "unspecified"] += 1
    merging = Merge(merge, None, report.source_name, actor)
    with write_unit(session, lock=False):
        game = _store(session, seq, fields, source, report, merging, settings)
        session.flush()
        fit_sequence(session, game.id, settings)
        systems = [s for s in game.systems if s.kind is SystemKind.ISSIA]
        report.triangulated = recompute_systems(session, systems, settings, progress)
        report.systems_merged = merging.record(session)
        record_summary(session, "import", audit_counts(report), actor=actor, game_id=game.id)
    refresh_statistics(session)  # the edits that follow are planned on the imported rows
    report.seconds = time.perf_counter() - t0
    report.store_seconds = report.seconds - report.read_seconds - report.calibration_seconds
    return report


def _store(session: Session, seq: IssiaSequence, fields: dict[str, CalibrationFields], source: CalibrationSource,
           report: ImportReport, merge: Merge, settings: Settings) -> Game:
    root = seq.root.resolve()
    game = session.scalars(
        sa.select(Game).where(Game.league == LEAGUE, Game.season == SEASON, Game.match == root.name)
        .options(selectinload(Game.systems).selectinload(System.frames).selectinload(Frame.ball_label),
                 selectinload(Game.systems).selectinload(System.frames).selectinload(Frame.calibration),
                 selectinload(Game.systems).selectinload(System.frames).selectinload(Frame.field_lines))
    ).one_or_none()
    if game is None:
        game = Game(league=LEAGUE, season=SEASON, match=root.name, source_path=str(root))
        session.add(game)
    game.source_path = str(root)
    systems = {s.name: s for s in game.systems}
    if systems:  # what the merge compares, loaded at once
        load_for_recompute(session, [s.id for s in systems.values()], predictions=settings.max_predictions_per_frame)
    lines = {cid: lines_to_json_lists(seq.lines[cid]) for cid in seq.lines}
    now = utcnow()
    w, h = seq.image_size
    for index in seq.frames:
        system = systems.get(str(index))
        new = system is None
        if system is None:
            system = System(name=str(index), kind=SystemKind.ISSIA, frame_index=index)
            game.systems.append(system)
            report.systems_new += 1
        change = None if new else merge.track(system)
        system.frame_index = index
        frames = {f.name: f for f in system.frames}
        changed = False
        for k, cid in enumerate(seq.camera_ids):
            name = view_name(cid)
            frame = frames.get(name)
            if frame is None:
                frame = Frame(name=name, role=FrameRole.STATIC, position=k, width=w, height=h,
                              predictions=[])  # a new view holds none: no lazy load (it would raise)
                system.frames.append(frame)
                changed = True
            media = seq.media.get(cid)
            frame.position, frame.width, frame.height = k, w, h
            frame.image_root = str(root) if media is not None else None
            frame.image_path = media.resolve().relative_to(root).as_posix() if media is not None else None
            frame.media_frame = index if media is not None else None
            frame.media_flipped = cid in seq.flipped
            lines_changed = kept_lines = False
            if cid in lines:
                fl = frame.field_lines
                if fl is None:
                    frame.field_lines = FieldLineAnnotation(lines=lines[cid], original_lines=lines[cid])
                elif fl.original_lines != lines[cid] or fl.lines != lines[cid]:
                    taken = merge.takes(fl.edited, fl.edited_at)
                    merge.part(change, frame, taken=taken, differs=fl.lines != lines[cid], lines=True)
                    lines_changed = taken and fl.lines != lines[cid]
                    kept_lines = not taken and fl.lines != lines[cid]
                    if lines_changed:
                        fl.lines, fl.edited_at = lines[cid], None
                    fl.original_lines = lines[cid]
            cal, f = frame.calibration, fields[cid]
            ours = [x for x in (cal.flags or [])
                    if x in (BALL_ASSISTED_FLAG, BALL_BUNDLE_FLAG, GIVEN_CAMERA_FLAG)] if cal else None
            if not kept_lines and (cal is None or (cal.status, cal.camera, ours) != (f.status, f.camera, f.flags)
                                   or cal.source is not source):  # a kept line edit keeps its camera
                merge.part(change, frame, taken=True, differs=cal is not None, lines=True)
                apply_calibration(frame, f, source)
                changed = True
            label_changed = _set_label(frame, seq.point(index, cid), merge, change)
            if (label_changed or lines_changed) and frame.id is not None:
                frame.edit_version += 1  # what people edit changed under them: their ETag goes stale
            changed |= label_changed
        if changed and not new:
            report.systems_changed += 1
        report.decisions_reset += merge.decide(system, None, change, now) == "reset"
    return game


def refined_with_ball(session: Session, frame: Frame,
                      fields: CalibrationFields, settings: Settings) -> CalibrationFields:
    """The calibration of an ISSIA view recalibrated from its edited field lines (``fields``, from the lines
    alone), refined again from its lines and the sequence's ball labels when its stored calibration was so
    refined (flag :data:`BALL_BUNDLE_FLAG`: ``v3d import issia --from-lines``), as the import refined it
    (:func:`app.services.issia.cameras.bundle_refined_cameras`): the other cameras are the sequence's (each camera's
    first admitted view's) with their views' lines, the ball labels those of the stored sequence, the
    trajectory fitted with these cameras. Kept, with the flag, when its JaC at the admission's gamma against the
    view's lines stays above ``admit_jac_min``; ``fields`` otherwise (and for any other view). Changes nothing stored.
    About a second on the 200-frame dev sequence (a trajectory fit and the adjustment)."""
    old = frame.calibration
    if (fields.status is not CalibrationStatus.CALIBRATED or fields.camera is None or old is None
            or BALL_BUNDLE_FLAG not in (old.flags or ()) or frame.field_lines is None
            or frame.system.game_id is None or frame.system.kind is not SystemKind.ISSIA):
        return fields
    arrays = sequence_arrays(load_sequence(session, frame.system.game_id), settings)
    if frame.name not in arrays.camera_names:
        return fields
    k = arrays.camera_names.index(frame.name)
    cameras = list(arrays.cameras)
    cameras[k] = Camera.from_soccernet(fields.camera)
    lines: list = [None] * len(cameras)
    resected = [False] * len(cameras)
    for i in sorted(arrays.systems):
        for f in arrays.systems[i].frames:
            j = arrays.camera_names.index(f.name)
            if lines[j] is None and f.field_lines is not None and f.calibration is not None and f.calibration.admitted:
                lines[j] = lines_from_json_lists(f.field_lines.lines)
                resected[j] = BALL_ASSISTED_FLAG in (f.calibration.flags or ())
    lines[k] = lines_from_json_lists(frame.field_lines.lines)
    resected[k] = False
    fit = fit_trajectory(arrays.points, cameras, arrays.widths, FPS, **fit_args(settings))
    refined = bundle_refined_cameras(cameras, lines, arrays.points, (frame.width, frame.height), fit, resected,
                                     **admission_args(settings))[k]
    if refined is None:
        return fields
    camera = refined[0]
    jac = jac_at_gammas(camera, lines[k], frame.width, frame.height, JAC_GAMMAS)
    flags = [f for f in fields.flags if f != BALL_BUNDLE_FLAG] + [BALL_BUNDLE_FLAG]
    residuals = {c: float(np.max(d)) for c, d in class_point_distances(camera, lines[k]).items() if len(d)}
    return dataclasses.replace(fields, camera=json_safe(camera.to_soccernet()),
                               jac=(float(jac[JAC_GAMMAS[0]]), float(jac[JAC_GAMMAS[1]]), float(jac[JAC_GAMMAS[2]])),
                               flags=flags, residuals_px=residuals,
                               uncertainty=fit_uncertainty(camera, lines[k], tuple(flags)))


def refit_after_edit(session: Session, system: System, settings: Settings, *,
                     recalibrated: Frame | None = None) -> list[System]:
    """After an edit of a view of an ISSIA ``system``, in the edit's transaction (changes the session
    only). Returns the systems touched: ``system`` and every system whose place on the trajectory (its 3D ball)
    changed, recomputed or not (the edit sets their decisions back to pending); a system that is not ISSIA is left
    alone (``[]``).

    * A ball label or exclusion edit (``recalibrated`` None): re-fit the stretch of the sequence around
      the system's frame (:func:`app.services.issia.refit.refit_sequence`), then recompute ``system``
      (once, after the re-fit: its triangulation reads the labels the trajectory keeps) and every other
      system whose kept labels changed, and judge again the doubts of those whose only change is their
      place on the trajectory but that have flagged labels (their evidence names the fitted position).
    * A new calibration of view ``recalibrated`` (field lines; the caller recomputed ``system``): the
      sequence uses the camera of each camera's first admitted view, so when ``recalibrated`` is (or,
      before the edit, may have been) that view the camera changed for every frame and the whole
      sequence is fitted again from scratch (about a second on the 200-frame dev sequence, plus the
      recomputation of the systems whose kept labels changed); otherwise the trajectory's inputs did
      not change and nothing is re-fitted.
    """
    if system.kind is not SystemKind.ISSIA or system.frame_index is None:
        return []
    session.flush()
    if recalibrated is None:
        changed = refit_sequence(session, system.game_id, system.frame_index, system.frame_index, settings)
        recompute_system(session, system, settings)
        touched = [system]
    else:
        columns = sequence_columns(session, system.game_id, settings)
        first = dict(zip(columns.names, columns.first_admitted, strict=False)).get(recalibrated.name)
        if first is not None and system.frame_index > first:
            return []  # an earlier view of this camera gives the camera: the trajectory is unchanged
        changed = fit_sequence(session, system.game_id, settings)
        touched = []
        # what the recomputations below read, for all of them in a few queries (not one per system and relation)
        load_for_recompute(session, [c.system.id for c in changed if c.system is not None and (
            c.labels or c.system.trajectory_point.flagged  # type: ignore[union-attr]  # a re-fitted system has its point
            or c.system.doubt_counts.get("ball_off_consensus"))], predictions=settings.max_predictions_per_frame)
    # systems whose place on the trajectory moved but that the re-fit did not load (one query for all of them): their
    # versions move with their rows written in bulk, and the decided ones go back to pending
    unloaded = [c.system_id for c in changed if c.system is None and c.system_id is not None]
    if unloaded:
        touched += session.scalars(sa.select(System).where(System.id.in_(unloaded))).all()
    for c in changed:
        s = c.system
        if s is None or s in touched:
            continue
        if c.labels:
            recompute_system(session, s, settings)
        elif s.trajectory_point.flagged or s.doubt_counts.get("ball_off_consensus"):  # type: ignore[union-attr]  # a re-fitted system has its point
            update_doubts(s, settings)
        touched.append(s)  # its place on the trajectory (its 3D ball) changed, recomputed or not
    return touched


__all__ = ["LEAGUE", "SEASON", "CAMERA_SET", "FPS", "import_issia", "refit_after_edit", "view_name"]
