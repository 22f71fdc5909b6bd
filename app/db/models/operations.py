"""What the service did: the append-only audit log of accepted writes and the background jobs.
"""
from __future__ import annotations

from datetime import datetime
from typing import Any, Optional

import sqlalchemy as sa
from sqlalchemy.orm import Mapped, mapped_column, relationship

from app.db.models.base import Base
from app.db.models.enums import JobState
from app.db.types import decompressed_json, enum_by_value, utcnow


class AuditState(Base):
    """A large state of the edited part (before or after a write) of audit entries, stored once however many
    entries name it: ``digest`` is the SHA-256 of its canonical JSON (``app.db.types.json_digest``), ``body`` that
    JSON compressed (``app.db.types.compressed_json``). A field-line edit's state after is the next edit's state
    before, and an undo's states are the edit's: each is stored once. Append-only, as the entries are."""

    __tablename__ = "audit_states"

    digest: Mapped[str] = mapped_column(sa.String(64), primary_key=True)
    body: Mapped[bytes] = mapped_column(sa.LargeBinary)

    @property
    def value(self) -> Any:
        """The state as it was recorded (a fresh object at each read)."""
        return decompressed_json(self.body)


class AuditEntry(Base):
    """One accepted write (``app.services.audit.log``): who (``actor``, the user's name as text, so the log
    outlives users), when (``at``, UTC), what (``action``: ``ball.edit``, ``field_lines.replace``,
    ``field_lines.mirror``, ``view.exclusion``, ``view.review``, ``view.calibration_review``, ``system.review``,
    ``import``, ``recompute``, ``revert``) and the state of the edited part before and after (JSON; an import or a
    recompute stores its counts in ``after``). ``frame_id`` / ``system_id`` / ``game_id`` are plain indexed
    ids without foreign keys: deleting or re-importing data never deletes its history. Append-only: the
    migration adds triggers refusing UPDATE and DELETE.

    ``before`` and ``after`` read the state wherever it is stored: in the entry's own JSON column (``before_inline``,
    ``after_inline``: small states) or, for a large one, in :class:`AuditState` by its digest
    (``app.services.audit.log.record`` chooses); setting one stores it inline.
    """

    __tablename__ = "audit_entries"
    #: the per-annotator figures (``app.services.evaluation.annotators``) read the edits by action and time
    __table_args__ = (sa.Index("ix_audit_entries_action_at", "action", "at"),)

    id: Mapped[int] = mapped_column(primary_key=True)
    at: Mapped[datetime] = mapped_column(default=utcnow)
    actor: Mapped[str] = mapped_column(sa.String(200), index=True)
    action: Mapped[str] = mapped_column(sa.String(40))
    frame_id: Mapped[Optional[int]] = mapped_column(index=True)
    system_id: Mapped[Optional[int]] = mapped_column(index=True)
    game_id: Mapped[Optional[int]] = mapped_column(index=True)
    before_inline: Mapped[Optional[dict[str, Any]]] = mapped_column("before")
    after_inline: Mapped[Optional[dict[str, Any]]] = mapped_column("after")
    #: A large state's :attr:`AuditState.digest` (no foreign key: states, like entries, are never deleted).
    before_digest: Mapped[Optional[str]] = mapped_column(sa.String(64))
    after_digest: Mapped[Optional[str]] = mapped_column(sa.String(64))
    before_state: Mapped[Optional[AuditState]] = relationship(
        primaryjoin="foreign(AuditEntry.before_digest) == AuditState.digest", lazy="selectin")
    after_state: Mapped[Optional[AuditState]] = relationship(
        primaryjoin="foreign(AuditEntry.after_digest) == AuditState.digest", lazy="selectin")
    #: A revert: the entry it undid.
    reverts_id: Mapped[Optional[int]] = mapped_column(sa.ForeignKey("audit_entries.id"))
    #: The change in one line of words ("ball of V2 moved 12.3 px"; ``app.services.audit.summaries``),
    #: written with the entry; None for entries recorded before the column (computed when read).
    summary: Mapped[Optional[str]] = mapped_column(sa.String(300))
    #: The version the write gave its system (``System.version``: the system's ETag), shared by every entry of one
    #: write; None for entries without a system and entries recorded before the column.
    system_version: Mapped[Optional[int]]

    @property
    def before(self) -> Optional[dict[str, Any]]:
        """The edited part's state before the write (None: an import's or a recompute's entry)."""
        state = self.before_state
        return state.value if state is not None else self.before_inline

    @before.setter
    def before(self, value: Optional[dict[str, Any]]) -> None:
        self.before_inline, self.before_digest, self.before_state = value, None, None

    @property
    def after(self) -> Optional[dict[str, Any]]:
        """The edited part's state after the write (an import's or a recompute's counts)."""
        state = self.after_state
        return state.value if state is not None else self.after_inline

    @after.setter
    def after(self, value: Optional[dict[str, Any]]) -> None:
        self.after_inline, self.after_digest, self.after_state = value, None, None


class Job(Base):
    """A background job (``app.services.jobs.runner``): an import, a full recompute or an export.

    ``params`` is what the job needs to run again from the start (a job interrupted by a killed process
    is resumed by running it again: imports are idempotent); ``stage``, ``done`` and ``total`` are its
    progress (``total`` 0: unknown); ``owner`` names the process running it (``node:pid:token``) and
    ``heartbeat_at`` when that process last showed it was alive; ``attempts`` counts claims (a claim is
    a compare-and-set on it). ``result`` is the job's report (an import's counts, an export's file).
    """

    __tablename__ = "jobs"
    __table_args__ = (sa.Index("ix_jobs_state_id", "state", "id"),)

    id: Mapped[int] = mapped_column(primary_key=True)
    kind: Mapped[str] = mapped_column(sa.String(20))
    params: Mapped[dict[str, Any]] = mapped_column(default=dict)
    state: Mapped[JobState] = mapped_column(enum_by_value(JobState, "job_state"), default=JobState.QUEUED)
    stage: Mapped[Optional[str]] = mapped_column(sa.String(40))
    done: Mapped[int] = mapped_column(default=0)
    total: Mapped[int] = mapped_column(default=0)
    message: Mapped[Optional[str]] = mapped_column(sa.Text)
    result: Mapped[Optional[dict[str, Any]]]
    owner: Mapped[Optional[str]] = mapped_column(sa.String(200))
    attempts: Mapped[int] = mapped_column(default=0)
    created_at: Mapped[datetime] = mapped_column(default=utcnow)
    started_at: Mapped[Optional[datetime]]
    finished_at: Mapped[Optional[datetime]]
    heartbeat_at: Mapped[Optional[datetime]]
