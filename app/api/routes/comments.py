"""Comments pinned on a view (``app.services.curation.comments``).

* ``POST /api/systems/{id}/comments`` ``{"frame_id", "point": [x, y] | null, "text"}``: reviewers and admins, and
  the annotator the system is returned to (needs fix); 201 with the comment.
* ``GET /api/systems/{id}/comments``: every comment of the system, resolved ones too, oldest first (any role).
* ``POST /api/comments/{id}/resolve`` and ``/reopen``: its author, reviewers, or the person the system is returned to.

Every write is audited in words (``comment.add`` / ``comment.resolve`` / ``comment.reopen``); none changes the
system's ETag.
"""
from __future__ import annotations

from datetime import datetime
from typing import Annotated, Optional

from fastapi import APIRouter, Path
from pydantic import BaseModel, ConfigDict, Field

from app.api.auth import AnnotatorDep, PrincipalDep
from app.api.deps import SessionDep, SystemIdPath
from app.api.schemas import INVALID, NOT_FOUND, DbInt, _In
from app.db.models import UserRole
from app.services.curation import comments

router = APIRouter(tags=["comments"])


class CommentIn(_In):
    """A comment to pin on a view."""

    frame_id: DbInt = Field(description="The view (a frame of the system) the comment is on.")
    point: Optional[list[float]] = Field(None, min_length=2, max_length=2,
                                         description="[x, y] in pixels of the frame's image; null: the whole view.")
    text: str = Field(min_length=1, max_length=comments.MAX_TEXT, description="What the reviewer says.")


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


class CommentsOut(BaseModel):
    """A system's comments, oldest first."""

    items: list[CommentOut]


CommentIdPath = Annotated[DbInt, Path(description="Comment id.")]


@router.post("/systems/{system_id}/comments", status_code=201, response_model=CommentOut,
             responses={**NOT_FOUND, **INVALID})
def add_comment(session: SessionDep, principal: AnnotatorDep, system_id: SystemIdPath, body: CommentIn) -> CommentOut:
    """Pin a comment on a view of the system at ``point`` (or on the whole view). Reviewers and admins; an annotator
    only on a system returned to them (403 otherwise). 422 naming ``frame_id`` (not a view of this system), ``point``
    (outside the image) or ``text``."""
    made = comments.add_comment(session, system_id, frame_id=body.frame_id, point=body.point, text=body.text,
                                author=principal.name, user_id=principal.user_id, role=UserRole(principal.role))
    return CommentOut.model_validate(made)


@router.get("/systems/{system_id}/comments", response_model=CommentsOut, responses=NOT_FOUND)
def list_comments(session: SessionDep, principal: PrincipalDep, system_id: SystemIdPath) -> CommentsOut:
    """Every comment of the system, resolved ones too, oldest first (any logged-in user)."""
    return CommentsOut(items=[CommentOut.model_validate(c) for c in comments.list_comments(session, system_id)])


@router.post("/comments/{comment_id}/resolve", response_model=CommentOut, responses=NOT_FOUND)
def resolve_comment(session: SessionDep, principal: AnnotatorDep, comment_id: CommentIdPath) -> CommentOut:
    """Mark the comment resolved (its author, a reviewer, or the person its system is returned to; 403 otherwise)."""
    return CommentOut.model_validate(comments.set_resolved(session, comment_id, True, actor=principal.name,
                                                           user_id=principal.user_id, role=UserRole(principal.role)))


@router.post("/comments/{comment_id}/reopen", response_model=CommentOut, responses=NOT_FOUND)
def reopen_comment(session: SessionDep, principal: AnnotatorDep, comment_id: CommentIdPath) -> CommentOut:
    """Open the comment again (who may: as for resolving)."""
    return CommentOut.model_validate(comments.set_resolved(session, comment_id, False, actor=principal.name,
                                                           user_id=principal.user_id, role=UserRole(principal.role)))
