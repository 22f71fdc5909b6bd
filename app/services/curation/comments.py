"""Comments pinned on a view: where a reviewer says what is wrong, at the point of the frame it is wrong at.

Who may write: a comment is added by reviewers (and admins), and by the user the system is returned to (an open
hand-off, ``app.services.curation.handoff``); it is resolved or reopened by its author, by reviewers, or by that user.
Anyone logged in reads them. Each write is audited in the write's transaction (``comment.add``, ``comment.resolve``,
``comment.reopen``; the entry names the view, the point and the text in words) and touches no label: the system's
version, and so its ETag, stays as it was (a comment never makes someone else's decision stale).

Bounded: a system holds at most ``V3D_MAX_COMMENTS_PER_SYSTEM`` comments, resolved ones included (one more is refused,
409, naming the cap), and they are read a page at a time (:func:`list_comments`), as the audit log is.
"""
from __future__ import annotations

import math
from typing import Any, Optional

import sqlalchemy as sa
from sqlalchemy.orm import Session

from app.core.errors import ConflictError, ForbiddenError, InvalidInputError, NotFoundError
from app.db.models import Frame, ReviewComment, System, UserRole
from app.db.types import utcnow
from app.db.unit import write_unit
from app.services.audit import log as audit
from app.services.curation.handoff import returned_to_user

#: The longest comment kept (characters); the API refuses a longer one naming ``text``.
MAX_TEXT = 4000


def _may_review(role: UserRole) -> bool:
    return role in (UserRole.REVIEWER, UserRole.ADMIN)


def _state(comment: ReviewComment) -> dict[str, Any]:
    return {"comment": {"id": comment.id, "text": comment.text, "point": comment.point,
                        "resolved": comment.resolved}}


def _check_point(point: Any, frame: Frame) -> Optional[list[float]]:
    """``[x, y]`` in pixels inside the frame's image (``0 <= x <= width``, ``0 <= y <= height``), or None.

    Raises:
        InvalidInputError (field ``point``): not two finite numbers, or outside the image.
    """
    if point is None:
        return None
    if (not isinstance(point, (list, tuple)) or len(point) != 2
            or not all(isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) for v in point)):
        raise InvalidInputError("point must be [x, y] in pixels, or null for the whole view", field="point")
    x, y = float(point[0]), float(point[1])
    if not (0 <= x <= frame.width and 0 <= y <= frame.height):
        raise InvalidInputError(f"point ({x:g}, {y:g}) lies outside the {frame.width}x{frame.height} image",
                                field="point")
    return [x, y]


def count_comments(session: Session, system_id: int) -> int:
    """How many comments the system holds, resolved ones included."""
    return int(session.scalar(sa.select(sa.func.count(ReviewComment.id))
                              .where(ReviewComment.system_id == system_id)) or 0)


def list_comments(session: Session, system_id: int, *, limit: int, offset: int = 0) -> list[ReviewComment]:
    """The system's comments (resolved ones too), oldest first: at most ``limit`` from the ``offset``-th
    (:func:`count_comments` counts them all).

    Raises:
        NotFoundError: no such system.
    """
    if session.get(System, system_id) is None:
        raise NotFoundError("system", system_id)
    return list(session.scalars(sa.select(ReviewComment).where(ReviewComment.system_id == system_id)
                                .order_by(ReviewComment.id).limit(limit).offset(offset)))


def add_comment(session: Session, system_id: int, *, frame_id: Any, point: Any, text: Any, author: str,
                user_id: int, role: UserRole, max_comments: int) -> ReviewComment:
    """Pin a comment on view ``frame_id`` of the system at ``point`` (``[x, y]`` px of the frame's image, None: the
    view as a whole) and commit it with its audit entry; a system holds at most ``max_comments``
    (``V3D_MAX_COMMENTS_PER_SYSTEM``), resolved ones included, counted under the write's lock (on PostgreSQL the
    system's row is locked, so two comments racing for the last place do not both get it).

    Raises:
        ForbiddenError: an annotator on a system not returned to them.
        ConflictError: the system holds ``max_comments`` already (409 naming the cap); nothing stored.
        NotFoundError: no such system.
        InvalidInputError: ``frame_id`` not a view of the system, ``point`` not in its image, ``text`` empty or
            longer than :data:`MAX_TEXT` (each naming its field); nothing stored.
    """
    with write_unit(session):
        system = session.scalar(sa.select(System).where(System.id == system_id).with_for_update())
        if system is None:
            raise NotFoundError("system", system_id)
        if not _may_review(role) and not returned_to_user(session, system_id, user_id):
            raise ForbiddenError("annotators comment only on a system returned to them (marked needs fix)")
        held = count_comments(session, system_id)
        if held >= max_comments:
            raise ConflictError(f"system {system_id} holds {held} comments, the most a system may hold "
                                f"(V3D_MAX_COMMENTS_PER_SYSTEM = {max_comments}, resolved ones included): say it in "
                                "one of them, or ask an administrator to raise the cap")
        frame = session.get(Frame, frame_id) if isinstance(frame_id, int) and not isinstance(frame_id, bool) else None
        if frame is None or frame.system_id != system_id:
            raise InvalidInputError(f"frame {frame_id!r} is not a view of system {system_id}", field="frame_id")
        if not isinstance(text, str) or not text.strip():
            raise InvalidInputError("text must say something", field="text")
        if len(text) > MAX_TEXT:
            raise InvalidInputError(f"text is longer than {MAX_TEXT} characters", field="text")
        comment = ReviewComment(system_id=system_id, frame_id=frame.id, point=_check_point(point, frame),
                                text=text.strip(), author=author, created_at=utcnow(), resolved=False)
        session.add(comment)
        session.flush()
        audit.record(session, actor=author, action="comment.add", frame=frame, before=None, after=_state(comment))
    return comment


def set_resolved(session: Session, comment_id: int, resolved: bool, *, actor: str, user_id: int,
                 role: UserRole) -> ReviewComment:
    """Resolve (``resolved`` True) or reopen a comment and commit it with its audit entry; a comment already so is
    answered as it is (no entry).

    Raises:
        NotFoundError: no such comment.
        ForbiddenError: neither its author, a reviewer, nor the user its system is returned to.
    """
    with write_unit(session):
        comment = session.get(ReviewComment, comment_id)
        if comment is None:
            raise NotFoundError("comment", comment_id)
        if not (comment.author == actor or _may_review(role) or returned_to_user(session, comment.system_id, user_id)):
            raise ForbiddenError("a comment is resolved or reopened by its author, a reviewer, or the person its "
                                 "system is returned to")
        if comment.resolved != resolved:
            before = _state(comment)
            comment.resolved = resolved
            comment.resolved_by, comment.resolved_at = (actor, utcnow()) if resolved else (None, None)
            frame = session.get(Frame, comment.frame_id)
            audit.record(session, actor=actor, action="comment.resolve" if resolved else "comment.reopen",
                         frame=frame, before=before, after=_state(comment))
    return comment
