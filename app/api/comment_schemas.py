"""Schemas of the comments pinned on a view (``app.api.routes.comments``): a comment to pin, a comment as answered, a
page of a system's comments and the page's query (``limit``, ``offset``; ``next_offset`` names the next page, as
``GET /api/audit``)."""
from __future__ import annotations

from datetime import datetime
from typing import Optional

from pydantic import BaseModel, ConfigDict, Field

from app.api.schemas import DB_INT_MAX, DbInt, _In
from app.services.curation import comments


class CommentOut(BaseModel):
    """A comment pinned on a view."""

    model_config = ConfigDict(from_attributes=True)

    id: int
    system_id: int
    frame_id: int
    point: Optional[list[float]] = Field(description="[x, y] in pixels of the frame's image; null: the whole view.")
    text: str
    author: str
    created_at: datetime
    resolved: bool
    resolved_by: Optional[str] = Field(None, description="Who resolved it last (null while open).")
    resolved_at: Optional[datetime] = None


class CommentsPageOut(BaseModel):
    """A page of a system's comments, oldest first (resolved ones too)."""

    items: list[CommentOut]
    total: int = Field(description="How many comments the system holds (at most V3D_MAX_COMMENTS_PER_SYSTEM).")
    limit: int
    offset: int
    next_offset: Optional[int] = Field(None, description="The offset of the next page, null on the last one. A page "
                                                         "stops before V3D_MAX_ANSWER_KB of JSON, so it may hold fewer "
                                                         "than `limit` comments before the last page.")


class CommentsQuery(BaseModel):
    """The page of ``GET /api/systems/{id}/comments``."""

    limit: int = Field(100, ge=1, le=500, description="Most comments on the page.")
    offset: int = Field(0, ge=0, le=DB_INT_MAX, description="How many comments, oldest first, come before the page.")


class CommentIn(_In):
    """A comment to pin on a view."""

    frame_id: DbInt = Field(description="The view (a frame of the system) the comment is on.")
    point: Optional[list[float]] = Field(None, min_length=2, max_length=2,
                                         description="[x, y] in pixels of the frame's image; null: the whole view.")
    text: str = Field(min_length=1, max_length=comments.MAX_TEXT, description="What the reviewer says.")
