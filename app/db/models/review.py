"""The review: decisions on systems and views, review passes, who has a system open.
"""
from __future__ import annotations

from datetime import datetime
from typing import TYPE_CHECKING, Any, Optional

import sqlalchemy as sa
from sqlalchemy.orm import Mapped, mapped_column, relationship

from app.db.models.base import Base
from app.db.models.enums import ReviewStatus
from app.db.types import enum_by_value, utcnow

if TYPE_CHECKING:  # the relationships name these; the registry resolves them at run time
    from app.db.models.labels import Frame, System


class ReviewDecision(Base):
    """The current review decision on a system or on a frame (exactly one of the two); a frame's holds two: its
    ball's (``status``, ``comment``) and its calibration's (``calibration_*``). ``reset_reason`` and
    ``calibration_reset_reason`` say why a decision is pending again (an edit recalibrated a view after it was
    decided: ``app.services.curation.resets.reset_decisions_after_recalibration``)."""

    __tablename__ = "review_decisions"
    __table_args__ = (
        sa.CheckConstraint("(system_id IS NULL) <> (frame_id IS NULL)", name="one_subject"),
    )

    id: Mapped[int] = mapped_column(primary_key=True)
    system_id: Mapped[Optional[int]] = mapped_column(
        sa.ForeignKey("systems.id", ondelete="CASCADE"), unique=True
    )
    frame_id: Mapped[Optional[int]] = mapped_column(sa.ForeignKey("frames.id", ondelete="CASCADE"), unique=True)
    status: Mapped[ReviewStatus] = mapped_column(enum_by_value(ReviewStatus, "review_status"),
                                                 default=ReviewStatus.PENDING)
    comment: Mapped[str] = mapped_column(sa.Text, default="")
    decided_at: Mapped[Optional[datetime]]
    #: Frame decisions only: the reviewer excluded this view from its system's triangulation
    #: (reversible; the view keeps its labels and calibration).
    excluded: Mapped[bool] = mapped_column(default=False)
    #: Why ``status`` is pending again (a system's: one of its views was recalibrated after the decision);
    #: None when decided or never reset. Cleared by the next decision.
    reset_reason: Mapped[Optional[str]] = mapped_column(sa.Text)
    #: Frame decisions only: the reviewer's decision on the view's calibration (its field lines and the
    #: camera fitted to them), apart from the decision on its ball (``status``).
    calibration_status: Mapped[ReviewStatus] = mapped_column(
        enum_by_value(ReviewStatus, "calibration_review_status"), default=ReviewStatus.PENDING)
    calibration_comment: Mapped[str] = mapped_column(sa.Text, default="")
    calibration_decided_at: Mapped[Optional[datetime]]
    #: Why ``calibration_status`` is pending again (an edit of the field lines recalibrated the view).
    calibration_reset_reason: Mapped[Optional[str]] = mapped_column(sa.Text)
    #: System decisions only: the batch (:class:`ReviewBatch`) that accepted the system after a sample, None when a
    #: person made the decision (every person's decision clears it). A plain id: batches are never deleted.
    batch_id: Mapped[Optional[int]]

    system: Mapped[Optional[System]] = relationship(back_populates="review", foreign_keys=[system_id])
    frame: Mapped[Optional[Frame]] = relationship(back_populates="review", foreign_keys=[frame_id])


class SystemPresence(Base):
    """A soft claim: ``user_id`` has system ``system_id`` open in a page (``app.services.curation.presence``).

    ``since`` is when the page opened it (kept by every refresh), ``expires_at`` when the claim lapses
    unless refreshed (UTC). A claim past ``expires_at`` counts as absent: readers filter on it, and the next
    claim written by anyone deletes the lapsed rows, so no cleanup job is needed. Written when a page opens a
    system and refreshed at most once per ``presence.REFRESH_AFTER``, never per heartbeat."""

    __tablename__ = "system_presence"

    system_id: Mapped[int] = mapped_column(sa.ForeignKey("systems.id", ondelete="CASCADE"), primary_key=True)
    user_id: Mapped[int] = mapped_column(sa.ForeignKey("users.id", ondelete="CASCADE"), primary_key=True)
    since: Mapped[datetime]
    expires_at: Mapped[datetime] = mapped_column(index=True)


class ReviewPass(Base):
    """A review pass (``app.services.curation.passes``): the frozen list of the systems of a review
    queue (``filters`` as ``app.services.curation.queue.SystemFilters`` fields, ``sort``) in its order as it
    stood when ``user_name`` began it, across all its pages; ``position`` is the index in ``system_ids`` of
    the system the user last opened. Statuses are not copied: they are read from the systems."""

    __tablename__ = "review_passes"
    __table_args__ = (sa.Index("ix_review_passes_user_name_id", "user_name", "id"),)

    id: Mapped[int] = mapped_column(primary_key=True)
    user_name: Mapped[str] = mapped_column(sa.String(200))
    filters: Mapped[dict[str, Any]] = mapped_column(default=dict)
    sort: Mapped[str] = mapped_column(sa.String(20))
    system_ids: Mapped[list[Any]] = mapped_column(default=list)
    position: Mapped[int] = mapped_column(default=0)
    created_at: Mapped[datetime] = mapped_column(default=utcnow)
    visited_at: Mapped[datetime] = mapped_column(default=utcnow)


class ReviewHandoff(Base):
    """One hand-off of a system marked needs fix (``app.services.curation.handoff``): ``returned_by`` (the reviewer,
    a user's name as the audit log names actors) returned it to the user ``returned_to_id`` (None: nobody could be
    found, ``note`` says why) with the decision's comment (``note``) at ``returned_at``. The record, not the system's
    current status, says the system is returned to that user: an edit meanwhile sets its decision back to pending and
    the hand-off stays open. ``fixed_at``: when that user sent it back as fixed; ``closed_at``: when the hand-off
    ended (sent back as fixed, or decided again by a reviewer); open while None."""

    __tablename__ = "review_handoffs"
    __table_args__ = (sa.Index("ix_review_handoffs_returned_to_id_returned_at", "returned_to_id", "returned_at"),)

    id: Mapped[int] = mapped_column(primary_key=True)
    system_id: Mapped[int] = mapped_column(sa.ForeignKey("systems.id", ondelete="CASCADE"), index=True)
    #: A plain id, as ``System.assignee_id``: users are disabled, never deleted.
    returned_to_id: Mapped[Optional[int]]
    returned_by: Mapped[str] = mapped_column(sa.String(200))
    note: Mapped[str] = mapped_column(sa.Text, default="")
    returned_at: Mapped[datetime] = mapped_column(default=utcnow)
    fixed_at: Mapped[Optional[datetime]]
    closed_at: Mapped[Optional[datetime]]


class ReviewComment(Base):
    """A comment pinned on a view (``app.services.curation.comments``): ``point`` ``[x, y]`` in pixels of the frame's
    own image (None: the view as a whole), its ``text``, its ``author`` (a user's name), and whether it is resolved
    (``resolved_by`` / ``resolved_at`` of the last resolution; cleared when reopened)."""

    __tablename__ = "review_comments"

    id: Mapped[int] = mapped_column(primary_key=True)
    system_id: Mapped[int] = mapped_column(sa.ForeignKey("systems.id", ondelete="CASCADE"), index=True)
    frame_id: Mapped[int] = mapped_column(sa.ForeignKey("frames.id", ondelete="CASCADE"))
    point: Mapped[Optional[list[float]]]
    text: Mapped[str] = mapped_column(sa.Text)
    author: Mapped[str] = mapped_column(sa.String(200))
    created_at: Mapped[datetime] = mapped_column(default=utcnow)
    resolved: Mapped[bool] = mapped_column(default=False)
    resolved_by: Mapped[Optional[str]] = mapped_column(sa.String(200))
    resolved_at: Mapped[Optional[datetime]]


class ReviewBatch(Base):
    """A batch of vouched systems accepted after a random sample (``app.services.curation.batches``).

    ``created_by`` made it at ``created_at`` from the queue ``filters`` (``SystemFilters`` fields) with the sampling
    plan's ``confidence`` and ``max_wrong_share`` (fractions); ``system_ids`` are the pending vouched systems the
    filters selected then, in id order, ``versions`` their ``System.version`` then (same order), ``sample_ids`` the
    random subset a person reviews. ``state``: ``open``, ``accepted`` (``accepted_ids``: the systems it accepted, by
    ``decided_by`` at ``decided_at``), ``refused`` (``refusal``: the words naming each system that stopped it; a
    batch refused once stays refused) or ``undone`` (its acceptances put back to pending, ``undone_at``)."""

    __tablename__ = "review_batches"

    id: Mapped[int] = mapped_column(primary_key=True)
    created_by: Mapped[str] = mapped_column(sa.String(200))
    created_at: Mapped[datetime] = mapped_column(default=utcnow)
    filters: Mapped[dict[str, Any]] = mapped_column(default=dict)
    confidence: Mapped[float]
    max_wrong_share: Mapped[float]
    system_ids: Mapped[list[Any]] = mapped_column(default=list)
    versions: Mapped[list[Any]] = mapped_column(default=list)
    sample_ids: Mapped[list[Any]] = mapped_column(default=list)
    state: Mapped[str] = mapped_column(sa.String(20), default="open")
    refusal: Mapped[Optional[str]] = mapped_column(sa.Text)
    decided_by: Mapped[Optional[str]] = mapped_column(sa.String(200))
    decided_at: Mapped[Optional[datetime]]
    accepted_ids: Mapped[Optional[list[Any]]]
    undone_at: Mapped[Optional[datetime]]
