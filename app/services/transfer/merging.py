"""How an import merges a dataset into games that are already stored: the modes, and what each keeps.

An import whose games already exist is refused unless it names a mode (``app.services.transfer.import_formats``,
``existing_games``): nothing of curation is ever overwritten by a file that did not ask to. A merge, in either mode:

* compares each stored system's labels with the file's, part by part (each view's ball label, field lines and, for
  a SoccerNet-v3D export, its imported calibration), and takes the file's value or keeps the stored one
  (:meth:`Merge.takes`): ``overwrite`` always takes the file's; ``keep-newer`` keeps a stored value a person changed
  after the newest change the file holds (``GameMetadata.v3d_as_of`` of a SoccerNet-v3D export: its game's newest
  audit entry when it was exported), and any stored change when the file carries no such time (a release, an ISSIA
  folder, an older export: as old as anything stored);
* sets a decision from the file only where the file has one for exactly the labels the system now has (every part
  taken from the file), the file is newer than the stored decision (``keep-newer``) or the merge overwrites, and
  then says so: the decision's comment is "as the import of <source> says" and the system's entry and the
  import's report (``decisions_from_file``) count it (:meth:`Merge.decide`);
* sets back to pending, with the reason, every decision whose labels the merge changed and the file does not vouch
  for (the system's, and the view's ball or calibration decision of each view whose part changed);
* writes one audit entry per stored system it changed (action ``system.import``, the system's state before and
  after, ``app.services.curation.states.system_import_state``), in the batch's transaction, revertible through the
  audit log's revert (``app.services.curation.editing.restore_imported_system``), and bumps the system's version.

Systems new to the game take the file's decision as a new import does, with the same comment and count.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from datetime import datetime
from typing import Any, Optional

from sqlalchemy.orm import Session

from app.db import scope
from app.db.models import Frame, ReviewDecision, ReviewStatus, System
from app.services.audit import log as audit
from app.services.curation.states import same_json, system_import_state

#: The merge modes an import takes (``merge``: the API's form field and JSON key, ``v3d import ... --merge``), with
#: what each does to a stored game.
MERGE_MODES: dict[str, str] = {
    "keep-newer": "the file's labels and decisions replace the stored ones, except those changed after the newest "
                  "change the file holds (every change, for a file that does not say when that was)",
    "overwrite": "the file's labels and decisions replace the stored ones, the edits made since included",
}


@dataclass
class SystemChange:
    """What a merge did to one stored system: its state before (``system_import_state``), whether it changed a
    label (``labels_changed``: a view's current ball, lines or calibration), whether every part is now the file's
    (``as_file``: none kept differs from the file), and the views whose ball or lines/calibration changed."""

    system: System
    before: dict[str, Any]
    labels_changed: bool = False
    as_file: bool = True
    ball_views: set[int] = field(default_factory=set)
    line_views: set[int] = field(default_factory=set)


@dataclass
class Merge:
    """One import's merge (module docstring): ``mode`` (a key of :data:`MERGE_MODES`), the time of the newest change
    the file holds (``as_of``, UTC; None: a file that does not say), and how the entries and comments name the import
    (``source``, ``actor``)."""

    mode: str
    as_of: Optional[datetime]
    source: str
    actor: Optional[str] = None
    changes: list[SystemChange] = field(default_factory=list)

    def __post_init__(self) -> None:
        if self.mode not in MERGE_MODES:
            raise ValueError(f"unknown merge mode {self.mode!r}; choose one of {list(MERGE_MODES)}")

    def track(self, system: System) -> SystemChange:
        """Start following stored ``system`` (loaded with what :func:`system_import_state` reads) before anything of
        it changes."""
        change = SystemChange(system, system_import_state(system))
        self.changes.append(change)
        return change

    def takes(self, edited: bool, edited_at: Optional[datetime]) -> bool:
        """Whether the file's value replaces a stored current value that differs from it: ``edited``, the stored value
        differs from its imported original (a person's change, or an earlier import's curated value), last changed
        at ``edited_at`` (UTC; None: unknown)."""
        if self.mode == "overwrite" or not edited:
            return True
        return self.as_of is not None and edited_at is not None and edited_at <= self.as_of

    def part(self, change: Optional[SystemChange], frame: Frame, *, taken: bool, differs: bool, lines: bool) -> None:
        """Note one part of ``frame`` (its ball, or its lines or calibration when ``lines``) that differed from the
        file's (``differs``): taken from the file (``taken``, the stored label changed) or kept."""
        if change is None or not differs:
            return
        if not taken:
            change.as_file = False
            return
        change.labels_changed = True
        (change.line_views if lines else change.ball_views).add(frame.id)

    def decide(self, system: System, file_status: Optional[ReviewStatus], change: Optional[SystemChange],
               now: datetime) -> Optional[str]:
        """The system's decision after the merge of its labels (module docstring); ``change`` None for a system new
        to its game. Returns "file" when the decision was taken from the file, "reset" when decisions went back to
        pending, None when nothing changed."""
        review = system.review
        stored = review.status if review is not None else ReviewStatus.PENDING
        said = f"as the import of {self.source} says"
        if change is None:
            if file_status is None or file_status is ReviewStatus.PENDING:
                return None
            _decided(system, file_status, said, None, now)
            return "file"
        decided_at = review.decided_at if review is not None else None
        file_newer = (self.mode == "overwrite" or decided_at is None
                      or (self.as_of is not None and decided_at <= self.as_of))
        if (file_newer and change.as_file and file_status is not None
                and (file_status is not stored or change.labels_changed)):
            _decided(system, file_status, said, None, now)
            self._reset_views(change, now)
            return "file"
        if not change.labels_changed:
            return None
        reason = f"the import of {self.source} changed its labels; decide it again"
        reset = self._reset_views(change, now)
        if review is not None and stored is not ReviewStatus.PENDING:
            _decided(system, ReviewStatus.PENDING, review.comment, reason, now)
            reset = True
        return "reset" if reset else None

    def _reset_views(self, change: SystemChange, now: datetime) -> bool:
        """Set back to pending the ball decision of each view whose ball the merge changed, the calibration decision
        of each whose lines or calibration it changed; whether any was decided."""
        reason = f"the import of {self.source} changed this view; decide it again"
        done = False
        for frame in change.system.frames:
            review = frame.review
            if review is None:
                continue
            ball = frame.id in change.ball_views and review.status is not ReviewStatus.PENDING
            calibration = frame.id in change.line_views and review.calibration_status is not ReviewStatus.PENDING
            if ball:
                review.status, review.reset_reason, review.decided_at = ReviewStatus.PENDING, reason, now
            if calibration:
                review.calibration_status, review.calibration_reset_reason = ReviewStatus.PENDING, reason
                review.calibration_decided_at = now
            if ball or calibration:
                frame.edit_version += 1  # the view's decision is in what its ETag covers
                done = True
        if done:
            scope.changed(change.system)
        return done

    def record(self, session: Session) -> int:
        """After the batch's recomputation, one ``system.import`` entry for each followed system whose state changed
        (before and after, the version it gives the system); returns how many."""
        n = 0
        for change in self.changes:
            after = system_import_state(change.system)
            if same_json(change.before, after):
                continue
            audit.record(session, actor=self.actor, action="system.import", system=change.system,
                         before=change.before, after=after, facts={"source": self.source})
            n += 1
        self.changes = []
        return n


def _decided(system: System, status: ReviewStatus, comment: str, reason: Optional[str], now: datetime) -> None:
    review = system.review
    if review is None:
        review = system.review = ReviewDecision(status=ReviewStatus.PENDING, comment="")
    review.status, review.comment, review.reset_reason, review.decided_at = status, comment, reason, now
    scope.changed(system)  # a decision is in what the system's version covers
