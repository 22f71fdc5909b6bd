"""A ball detector's predictions, stored as their own rows: never a label.

A prediction names its detector (``source``, e.g. ``yolo-sn-ball``), the frame (view) it was made on, its score and
its box in pixels of the frame's own image (continuous coordinates, origin at the top-left corner, clipped to the
image when imported). Importing a source again replaces all its rows; ``v3d predictions remove SOURCE`` deletes them.
The geometry checks them against the other views (``app.geometry.doubts.detections``); a checked one is offered as
a doubt's fix and becomes a label only when a fix key places it (with its provenance) and a person confirms it.

A frame keeps at most ``V3D_MAX_PREDICTIONS_PER_FRAME`` of them (the import's bound), and every read takes at most so
many per frame, the best by score, through :func:`ranked_predictions`: a frame flooded before the bound existed never
reaches memory whole.
"""
from __future__ import annotations

from datetime import datetime
from typing import Any

import sqlalchemy as sa
from sqlalchemy.orm import Mapped, mapped_column

from app.db.models.base import Base
from app.db.types import utcnow


class Prediction(Base):
    """One detection of the ball by a named detector on one frame (box in px of the frame's image)."""

    __tablename__ = "predictions"
    __table_args__ = (
        sa.Index("ix_predictions_frame_id", "frame_id"),
        sa.Index("ix_predictions_source", "source"),
        sa.CheckConstraint("x2 > x1 AND y2 > y1", name="positive_box"),
    )

    id: Mapped[int] = mapped_column(primary_key=True)
    source: Mapped[str] = mapped_column(sa.String(200))
    frame_id: Mapped[int] = mapped_column(sa.ForeignKey("frames.id", ondelete="CASCADE"))
    score: Mapped[float]
    x1: Mapped[float]
    y1: Mapped[float]
    x2: Mapped[float]
    y2: Mapped[float]
    created_at: Mapped[datetime] = mapped_column(default=utcnow)


def ranked_predictions(*where: Any) -> sa.Subquery:
    """The predictions matching ``where`` (SQL conditions on ``Prediction``), each with its ``rank`` on its frame among
    them: 1 the highest score, ties by id (the first stored). Select ``rank <= N`` from it to read at most N
    predictions a frame, the best, whatever the frame holds (SQL's ``row_number()`` window: one statement on SQLite and
    PostgreSQL)."""
    rank = sa.func.row_number().over(partition_by=Prediction.frame_id,
                                     order_by=(Prediction.score.desc(), Prediction.id)).label("rank")
    return sa.select(Prediction, rank).where(*where).subquery("ranked_predictions")
