"""A batch of an import's records merged into the session's rows (``app.services.transfer.importing``): each game
upserted, each stored system merged by the import's mode (``app.services.transfer.merging``), its views' lines and
ball labels taken from the file or kept, and what is left once the rows stand (:class:`MergedBatch`: the frames to
calibrate, the imported calibrations, the player boxes, the systems to recompute, the merges to audit). Nothing is
flushed: the write lock is taken after the calibration, by the caller's first write.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from datetime import datetime

from sqlalchemy import select
from sqlalchemy.orm import Session, selectinload, undefer

from app.core.config import Settings
from app.core.progress import Progress
from app.datasets.records import CalibrationFields, FrameRecord, GameRecord, SystemRecord
from app.db.models import BallKind, BallLabel, FieldLineAnnotation, Frame, Game, ReviewDecision, ReviewStatus, System
from app.services.calibration.players import PlayerRow, frame_players
from app.services.derivation.recompute import load_for_recompute
from app.services.transfer.merging import Merge, SystemChange


@dataclass
class MergedBatch:
    """What the merge of a batch's records leaves to do once its frames are calibrated: the games' merges (audited at
    the end), the frames to calibrate (with their records), the imported calibrations, the systems touched and the
    frames' player boxes (stored or new: written in one statement once the frames have ids); and its counts for the
    import's report."""

    merges: list[Merge] = field(default_factory=list)
    to_calibrate: list[Frame] = field(default_factory=list)
    to_calibrate_recs: list[FrameRecord] = field(default_factory=list)
    imported: list[tuple[Frame, CalibrationFields]] = field(default_factory=list)
    touched: list[System] = field(default_factory=list)
    new_players: list[tuple[Frame, tuple[PlayerRow, ...], bool]] = field(default_factory=list)
    systems_new: int = 0
    systems_changed: int = 0
    decisions_from_file: int = 0
    decisions_reset: int = 0


def merge_batch(session: Session, records: list[GameRecord], settings: Settings, progress: Progress | None,
                now: datetime, *, mode: str, source: str, actor: str | None) -> MergedBatch:
    """Upsert ``records`` into the session with no autoflush (nothing is written before calibration), merging stored
    systems by ``mode`` (each change audited as the import of ``source`` by ``actor`` when the batch is written);
    progress ``"merge"`` per system."""
    merged = MergedBatch()
    n_systems = sum(len(g.systems) for g in records)
    done = 0
    with session.no_autoflush:  # nothing is written before calibration: the write lock is taken late
        for grec in records:
            game = _upsert_game(session, grec)
            merge = Merge(mode, grec.as_of, source, actor)
            merged.merges.append(merge)
            systems = {s.name: s for s in game.systems}
            if game.id is not None:  # what the merge compares, loaded at once (not one lazy load per frame)
                load_for_recompute(session, [s.id for s in systems.values()],
                                   predictions=settings.max_predictions_per_frame)
            for srec in grec.systems:
                _merge_system(game, systems, srec, merge, merged, now)
                done += 1
                if progress:
                    progress("merge", done, n_systems)
    return merged


def _upsert_game(session: Session, rec: GameRecord) -> Game:
    game = session.scalars(
        select(Game).where(Game.league == rec.league, Game.season == rec.season, Game.match == rec.match)
        .options(undefer(Game.release), selectinload(Game.systems).selectinload(System.frames).undefer(Frame.release))
    ).one_or_none()
    if game is None:
        game = Game(league=rec.league, season=rec.season, match=rec.match, source_path=rec.source_path,
                    release=rec.release)
        session.add(game)
    game.source_path = rec.source_path
    if game.release != rec.release:
        game.release = rec.release
    if rec.as_of is not None and (game.as_of is None or rec.as_of > game.as_of):
        game.as_of = rec.as_of  # what the file held, as of when: its exports say it again
    return game


def _set_lines(frame: Frame, rec: FrameRecord, now: datetime, merge: Merge, change: SystemChange | None) -> bool:
    """Store the imported lines: the originals as the file gives them, the current ones where the merge takes the
    file's (:meth:`Merge.takes`); returns True when the current lines are new or changed (the frame needs
    recalibration)."""
    original = rec.original_lines if rec.original_lines is not None else rec.lines
    fl = frame.field_lines
    if fl is None:
        frame.field_lines = FieldLineAnnotation(lines=rec.lines, original_lines=original,
                                                edited_at=now if rec.lines != original else None)
        return True
    differs = fl.lines != rec.lines
    taken = merge.takes(fl.edited, fl.edited_at)
    merge.part(change, frame, taken=taken, differs=differs, lines=True)
    fl.original_lines = original  # the dataset's say, whatever the merge keeps
    if taken and differs:
        fl.lines = rec.lines
        fl.edited_at = now if rec.lines != original else None
        return True
    return False


def _set_ball(frame: Frame, rec: FrameRecord, now: datetime, merge: Merge, change: SystemChange | None) -> bool:
    """Store the imported ball label; returns True when the stored label changed.

    Without ``rec.original_ball`` (SoccerNet-v3) the record is the original and the file's current label; with it
    (a v3D export) both are as given. The current label becomes the file's where the merge takes it
    (:meth:`Merge.takes`: a label nobody changed always follows the file).
    """
    kind = BallKind.BOX if rec.ball_box is not None else BallKind.POINT if rec.ball_point is not None else None
    current = (kind, rec.ball_box, rec.ball_point)
    original = rec.original_ball if rec.original_ball is not None else current
    label = frame.ball_label
    if label is None:
        if current[0] is None and original[0] is None:
            return False
        stored_current: tuple = (None, None, None)
        stored_original: tuple = (None, None, None)
        differs = current != stored_current
        taken = merge.takes(False, None)
        label = BallLabel()
        frame.ball_label = label
    else:
        stored_current = (label.kind, label.box, label.point)
        stored_original = (label.original_kind, label.original_box, label.original_point)
        differs = stored_current != current or label.suggested
        if stored_original == original and not differs:
            return False
        taken = merge.takes(label.edited, label.edited_at)
    merge.part(change, frame, taken=taken, differs=differs, lines=False)
    label.original_kind, label.original_box, label.original_point = original
    if taken and differs:
        label.kind, label.box, label.point, label.provenance = (*current, None)
        label.edited_at = now if current != original else None
    if label.kind is None and label.original_kind is None:
        frame.ball_label = None
    return stored_original != original or (taken and differs)


def _merge_system(game: Game, systems: dict[str, System], srec: SystemRecord, merge: Merge, merged: MergedBatch,
                  now: datetime) -> None:
    """Merge one system's record into ``game`` (its stored systems by name: ``systems``); count it and note what its
    frames leave to do in ``merged``."""
    system = systems.get(srec.name)
    new = system is None
    if system is None:
        # Relationships a recomputation reads are set now, so none is lazily loaded after the flush.
        system = System(name=srec.name, kind=srec.kind, triangulation=None, doubts=[])
        game.systems.append(system)
        system.review = ReviewDecision(status=ReviewStatus.PENDING, comment="")
    change = None if new else merge.track(system)
    system.kind = srec.kind
    changed = False
    frames = {f.name: f for f in system.frames}
    for pos, frec in enumerate(srec.frames):
        changed = _merge_frame(system, frames, pos, frec, merge, change, merged, now) or changed
    decided = merge.decide(system, srec.review, change, now)
    merged.decisions_from_file += decided == "file"
    merged.decisions_reset += decided == "reset"
    if new:
        merged.systems_new += 1
    elif changed:
        merged.systems_changed += 1
    if changed or system.triangulation is None:
        merged.touched.append(system)


def _merge_frame(system: System, frames: dict[str, Frame], pos: int, frec: FrameRecord, merge: Merge,
                 change: SystemChange | None, merged: MergedBatch, now: datetime) -> bool:
    """Merge one view's record at ``pos`` of ``system`` (its stored views by name: ``frames``); whether the system
    changed by it."""
    changed = False
    frame = frames.get(frec.name)
    if frame is None:
        frame = Frame(name=frec.name, role=frec.role, position=pos, width=frec.width,
                      height=frec.height, calibration=None, ball_label=None, reprojection=None,
                      optimised_box=None, release=frec.release,
                      predictions=[])  # a new view holds none: no lazy load (it would raise)
        system.frames.append(frame)
        frame.review = ReviewDecision(status=ReviewStatus.PENDING, comment="")
        changed = True
    elif (frame.width, frame.height) != (frec.width, frec.height):
        changed = True
    frame.role, frame.position, frame.width, frame.height = frec.role, pos, frec.width, frec.height
    frame.image_root, frame.image_type = frec.image_root, frec.image_type
    frame.image_zip, frame.image_member = frec.image_zip, frec.image_member
    frame.image_path = frec.image_path
    if frame.release != frec.release:  # what the release carries: kept as it came
        frame.release = frec.release
    if frame.id is None or frame_players(frame) != list(frec.players):
        merged.new_players.append((frame, frec.players, frame.id is not None))
    lines_changed = _set_lines(frame, frec, now, merge, change)
    kept_lines = frame.field_lines is not None and frame.field_lines.lines != frec.lines
    ball_changed = _set_ball(frame, frec, now, merge, change)
    if (lines_changed or ball_changed) and frame.id is not None:
        frame.edit_version += 1  # what people edit changed under them: their ETag goes stale
    if frec.calibration is not None and not kept_lines:  # a kept line edit keeps its camera
        cal = frame.calibration
        fields = frec.calibration.fields
        if (cal is None or cal.camera != fields.camera
                or (cal.jac_0005, cal.jac_001, cal.jac_002) != fields.jac):
            merge.part(change, frame, taken=True, differs=True, lines=True)
            merged.imported.append((frame, fields))
            changed = True
    elif lines_changed or frame.calibration is None:
        merged.to_calibrate.append(frame)
        merged.to_calibrate_recs.append(frec)
        changed = True
    return changed or ball_changed
