"""Comments pinned on a view (``app.services.curation.comments``).

* ``POST /api/systems/{id}/comments`` ``{"frame_id", "point": [x, y] | null, "text"}``: reviewers and admins, and
  the annotator the system is returned to (needs fix); 201 with the comment; 409 once the system holds
  ``V3D_MAX_COMMENTS_PER_SYSTEM`` (resolved ones included).
* ``GET /api/systems/{id}/comments?limit=&offset=``: a page of the system's comments, resolved ones too, oldest first
  (any role), with ``total`` and ``next_offset`` as the audit log's pages.
* ``POST /api/comments/{id}/resolve`` and ``/reopen``: its author, reviewers, or the person the system is returned to.

Every write is audited in words (``comment.add`` / ``comment.resolve`` / ``comment.reopen``); none changes the
system's ETag.
"""
from __future__ import annotations

from typing import Annotated

from fastapi import APIRouter, Path, Query, Response

from app.api.answers import capped_json, json_items
from app.api.auth import AnnotatorDep, PrincipalDep
from app.api.comment_schemas import CommentIn, CommentOut, CommentsPageOut, CommentsQuery
from app.api.deps import SessionDep, SettingsDep, SystemIdPath
from app.api.schemas import INVALID, NOT_FOUND, DbInt, ErrorOut
from app.db.models import UserRole
from app.services.curation import comments

router = APIRouter(tags=["comments"])


CommentIdPath = Annotated[DbInt, Path(description="Comment id.")]


@router.post("/systems/{system_id}/comments", status_code=201, response_model=CommentOut,
             responses={**NOT_FOUND, **INVALID, 409: {"model": ErrorOut, "description": "The system holds "
                                                       "V3D_MAX_COMMENTS_PER_SYSTEM comments already."}})
def add_comment(session: SessionDep, settings: SettingsDep, principal: AnnotatorDep, system_id: SystemIdPath,
                body: CommentIn) -> CommentOut:
    """Pin a comment on a view of the system at ``point`` (or on the whole view). Reviewers and admins; an annotator
    only on a system returned to them (403 otherwise). 422 naming ``frame_id`` (not a view of this system), ``point``
    (outside the image) or ``text``; 409 when the system holds ``V3D_MAX_COMMENTS_PER_SYSTEM`` comments already
    (resolved ones included)."""
    made = comments.add_comment(session, system_id, frame_id=body.frame_id, point=body.point, text=body.text,
                                author=principal.name, user_id=principal.user_id, role=UserRole(principal.role),
                                max_comments=settings.max_comments_per_system)
    return CommentOut.model_validate(made)


@router.get("/systems/{system_id}/comments", response_model=CommentsPageOut, responses=NOT_FOUND)
def list_comments(session: SessionDep, settings: SettingsDep, principal: PrincipalDep, system_id: SystemIdPath,
                  query: Annotated[CommentsQuery, Query()]) -> Response:
    """One page of the system's comments, resolved ones too, oldest first (any logged-in user): at most ``limit``
    from ``offset``, stopping before the comment that would take the page past ``V3D_MAX_ANSWER_KB`` of JSON (it holds
    one at least); ``next_offset`` is where the next page starts (null on the last page), as in ``GET /api/audit``."""
    page = comments.list_comments(session, system_id, limit=query.limit, offset=query.offset)
    total = comments.count_comments(session, system_id)
    items = capped_json([[CommentOut.model_validate(c) for c in page]], settings.max_answer_kb * 1024)
    taken = query.offset + len(items)
    return json_items(items, {"total": total, "limit": query.limit, "offset": query.offset,
                              "next_offset": taken if taken < total else None})


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
