"""The team's loop: a system marked needs fix goes to a person, and comes back to its reviewer once fixed.

* A ``needs_fix`` decision on a system returns it to the user who last edited its labels (the newest audit entry of
  a ball, field lines, mirror or exclusion edit of the system by an enabled user other than the reviewer); failing
  that, to its assignee; or to the person the reviewer names (``return_to``: whoever else would get it). Never to
  nobody: a needs fix with no one to return it to is refused, saying how to choose. The system is assigned to that user
  (``System.assignee_id``: the queue's ``assignee=me`` and **To fix** count find it) and a
  :class:`~app.db.models.ReviewHandoff` records the hand-off.
* The user it was returned to sends ``fixed`` (the only status an annotator may send, :func:`check_fixed_allowed`):
  the system is assigned to the reviewer who asked (their **To re-review**, ``status=fixed``) and the hand-off closes.
* Any other decision on the system closes an open hand-off (the reviewer decided it again).

"Returned to them" is the record, not the system's status: an edit meanwhile sets the decision back to pending
(``app.services.curation.resets``) and the hand-off stays open, so the user may still send ``fixed``. Every hand-off
is an audit entry in words (action ``system.handoff``: "returned to ana by rev: the box sits on the shadow"), written
in the decision's transaction (:func:`after_decision` runs inside the guarded write of
``app.services.curation.decisions.decide_review``).
"""
from __future__ import annotations

from dataclasses import dataclass
from datetime import datetime
from typing import Optional

import sqlalchemy as sa
from sqlalchemy.orm import Session

from app.core.errors import ConflictError, ForbiddenError, InvalidInputError
from app.db.models import AuditEntry, ReviewHandoff, ReviewStatus, System, User, UserRole
from app.db.types import utcnow
from app.services.audit import log as audit
from app.services.audit.summaries import handoff_words

#: The audit action of a hand-off.
ACTION = "system.handoff"
#: The audit actions that edit a system's labels: whose newest author a needs-fix goes back to, and what the
#: per-annotator figures count as edits (``app.services.evaluation.annotators``).
LABEL_ACTIONS = ("ball.edit", "field_lines.replace", "field_lines.mirror", "view.exclusion")


@dataclass(frozen=True)
class HandOff:
    """Where a system's hand-off stands: ``returned_to`` (the user it is returned to, None when nobody), the reviewer
    who returned it (``returned_by``), whether it was sent back ``fixed``, and the hand-off in ``words``."""

    returned_to: Optional[str]
    returned_by: str
    fixed: bool
    open: bool
    words: str


def open_handoff(session: Session, system_id: int) -> Optional[ReviewHandoff]:
    """The system's open hand-off (the newest one not closed), or None."""
    return session.scalar(sa.select(ReviewHandoff).where(ReviewHandoff.system_id == system_id,
                                                         ReviewHandoff.closed_at.is_(None))
                          .order_by(ReviewHandoff.id.desc()).limit(1))


def latest_handoff(session: Session, system_id: int) -> Optional[HandOff]:
    """The system's newest hand-off as shown (the system view, a decision's answer), or None when it never had one."""
    row = session.scalar(sa.select(ReviewHandoff).where(ReviewHandoff.system_id == system_id)
                         .order_by(ReviewHandoff.id.desc()).limit(1))
    if row is None:
        return None
    to = _name(session, row.returned_to_id)
    if row.fixed_at is not None:
        state = {"kind": "fixed", "to": row.returned_by, "by": to, "note": ""}
    else:
        state = {"kind": "returned", "to": to, "by": row.returned_by, "note": row.note,
                 "reason": None if to is not None else "no one had edited its labels and it had no assignee"}
    return HandOff(returned_to=to, returned_by=row.returned_by, fixed=row.fixed_at is not None,
                   open=row.closed_at is None, words=handoff_words(state))


def returned_to_user(session: Session, system_id: int, user_id: int) -> bool:
    """Whether the system is returned to user ``user_id`` now (an open hand-off to them)."""
    row = open_handoff(session, system_id)
    return row is not None and row.returned_to_id == user_id


def check_fixed_allowed(session: Session, system_id: int, *, user_id: int, role: UserRole,
                        status: ReviewStatus) -> None:
    """Refuse a system decision the caller may not send, before anything is read for the write.

    An annotator may send only ``fixed``, and only on a system returned to them; ``fixed`` is the word of the user
    the system is returned to, whatever their role.

    Raises:
        ForbiddenError: an annotator's other status, or ``fixed`` from someone the system is not returned to.
    """
    if role is UserRole.ANNOTATOR and status is not ReviewStatus.FIXED:
        raise ForbiddenError(f"this needs the reviewer role; you are annotator: an annotator sends only 'fixed', on a "
                             f"system returned to them (not {status.value!r})")
    if status is ReviewStatus.FIXED and not returned_to_user(session, system_id, user_id):
        raise ForbiddenError("only the person this system was returned to (marked needs fix) may send it back "
                             "as fixed")


def check_fixed_in_write(session: Session, system: System, user_id: int) -> None:
    """Refuse a ``fixed`` of user ``user_id`` on ``system`` unless the system is still returned to them, read inside
    the decision's write transaction under the write lock (``writing.guarded_write``), so that no decision committed
    between :func:`check_fixed_allowed` and the write is undone by a ``fixed`` that never saw it (a session's
    decision needs no ``If-Match``).

    Raises:
        ConflictError: the hand-off closed since (another decision of the system committed first); nothing is
            written, the message names the system's current status.
    """
    if returned_to_user(session, system.id, user_id):
        return
    current = system.review_status.value if system.review_status is not None else "pending"
    raise ConflictError(f"'fixed' was not applied: the system is no longer returned to you (it was decided since: "
                        f"it is now {current!r}); reload it to see the newest decision", current={"status": current})


def last_label_editor(session: Session, system_id: int, *, other_than: Optional[str]) -> Optional[User]:
    """The enabled user who last edited the system's labels (:data:`LABEL_ACTIONS`, newest audit entry first), not
    ``other_than`` (the reviewer deciding: work is returned to someone else); None when there is none."""
    rows = session.execute(
        sa.select(AuditEntry.actor).where(AuditEntry.system_id == system_id, AuditEntry.action.in_(LABEL_ACTIONS))
        .order_by(AuditEntry.id.desc()).limit(200))
    seen: set[str] = set()
    for (actor,) in rows:
        if actor == other_than or actor in seen:
            continue
        seen.add(actor)
        user = session.scalar(sa.select(User).where(User.name == actor))
        if user is not None and not user.disabled:
            return user
    return None


def _name(session: Session, user_id: Optional[int]) -> Optional[str]:
    if user_id is None:
        return None
    user = session.get(User, user_id)
    return user.name if user is not None else None


def _assign(session: Session, system: System, user: Optional[User], actor: Optional[str], now: datetime) -> None:
    if user is not None and system.assignee_id != user.id:
        system.assignee_id, system.assigned_at, system.assigned_by = user.id, now, audit.public_actor(actor)


#: Why a needs fix found no one, and how to choose: the words of the refusal (``assignee`` names the field).
NOBODY_TO_RETURN_TO = ("nobody edited this system's labels and it has no assignee: choose whom it goes to (send "
                       "'assignee', the name of an enabled user; the system page offers the team's annotators)")


def chosen_person(session: Session, name: str) -> User:
    """The enabled user ``name`` a reviewer chose to return a system to.

    Raises:
        InvalidInputError: no such user, or a disabled one (field ``assignee``).
    """
    user = session.scalar(sa.select(User).where(User.name == name))
    if user is None or user.disabled:
        raise InvalidInputError(f"{name!r} is not {'an enabled' if user is not None else 'a'} user: choose one of the "
                                "team's enabled users", field="assignee")
    return user


def returned_person(session: Session, system: System, *, actor: Optional[str], return_to: Optional[str],
                    required: bool) -> Optional[User]:
    """Whom a needs fix of ``system`` by ``actor`` goes to: ``return_to`` when the reviewer named someone, else the
    last editor of its labels (not the reviewer), else its enabled assignee.

    ``required``: a person's new decision (not an undo or a revert, which restore what the audit holds): a needs fix
    that finds no one is refused rather than sent to nobody.

    Raises:
        InvalidInputError: ``return_to`` is no enabled user, or nobody is found while ``required`` (field
            ``assignee``, the words of :data:`NOBODY_TO_RETURN_TO`); nothing is written.
    """
    if return_to is not None:
        return chosen_person(session, return_to)
    user = last_label_editor(session, system.id, other_than=actor)
    if user is None and system.assignee_id is not None:
        assignee = session.get(User, system.assignee_id)
        user = assignee if assignee is not None and not assignee.disabled else None
    if user is None and required:
        raise InvalidInputError(NOBODY_TO_RETURN_TO, field="assignee")
    return user


def after_decision(session: Session, system: System, status: ReviewStatus, *, actor: Optional[str],
                   note: str, return_to: Optional[str] = None, required: bool = True) -> None:
    """The hand-off a system decision makes (module docstring), in the decision's transaction: needs fix returns the
    system to a person (:func:`returned_person`: ``return_to``, the reviewer's choice, first; ``required``: refused
    when nobody is found), fixed gives it back to the reviewer who asked, any other decision closes an open hand-off.
    Audited (``system.handoff``) for the first two. ``actor``: the decider's name (None: the machine).

    Raises:
        InvalidInputError: ``return_to`` on another status than needs fix, or :func:`returned_person`'s refusals
            (field ``assignee``).
    """
    if return_to is not None and status is not ReviewStatus.NEEDS_FIX:
        raise InvalidInputError(f"'assignee' goes with needs_fix only (whom the system is returned to), not "
                                f"{status.value!r}", field="assignee")
    now = utcnow()
    current = open_handoff(session, system.id)
    by = audit.public_actor(actor)
    if status is ReviewStatus.NEEDS_FIX:
        user = returned_person(session, system, actor=actor, return_to=return_to, required=required)
        if current is not None:
            current.closed_at = now
        before = _name(session, system.assignee_id)
        reason = None if user is not None else "no one had edited its labels and it had no assignee"
        session.add(ReviewHandoff(system_id=system.id, returned_to_id=user.id if user is not None else None,
                                  returned_by=by, note=note, returned_at=now))
        _assign(session, system, user, actor, now)
        state = {"kind": "returned", "to": user.name if user is not None else None, "by": by, "note": note,
                 "reason": reason}
        audit.record(session, actor=actor, action=ACTION, system=system, before={"assignee": before},
                     after={"assignee": _name(session, system.assignee_id), "handoff": state})
    elif status is ReviewStatus.FIXED and current is not None:
        current.fixed_at = current.closed_at = now
        before = _name(session, system.assignee_id)
        reviewer = session.scalar(sa.select(User).where(User.name == current.returned_by))
        reviewer = reviewer if reviewer is not None and not reviewer.disabled else None
        _assign(session, system, reviewer, actor, now)
        state = {"kind": "fixed", "to": reviewer.name if reviewer is not None else None, "by": by, "note": note}
        audit.record(session, actor=actor, action=ACTION, system=system, before={"assignee": before},
                     after={"assignee": _name(session, system.assignee_id), "handoff": state})
    elif current is not None:
        current.closed_at = now


#: How many of a person's **To fix** systems :func:`my_work` names (the page walks them in this order).
TO_FIX_LISTED = 200


@dataclass(frozen=True)
class MyWork:
    """What waits for one user: ``to_fix``, the systems returned to them (open hand-offs, whatever the status their
    edits left), and ``to_re_review``, the systems they returned that came back fixed and are assigned to them.
    ``to_fix_ids``: the ids of the first :data:`TO_FIX_LISTED` systems to fix, the oldest hand-off first: the list
    the person works through, one system after another."""

    to_fix: int
    to_re_review: int
    to_fix_ids: tuple[int, ...] = ()


def my_work(session: Session, user_id: int) -> MyWork:
    """The counts of :class:`MyWork` for user ``user_id`` (two indexed counts) and the first systems to fix."""
    returned = (ReviewHandoff.returned_to_id == user_id, ReviewHandoff.closed_at.is_(None))
    to_fix = session.scalar(sa.select(sa.func.count()).select_from(ReviewHandoff).where(*returned))
    to_re_review = session.scalar(sa.select(sa.func.count()).select_from(System).where(
        System.assignee_id == user_id, System.review_status == ReviewStatus.FIXED))
    ids = session.scalars(sa.select(ReviewHandoff.system_id).where(*returned)
                          .order_by(ReviewHandoff.returned_at, ReviewHandoff.id).limit(TO_FIX_LISTED))
    return MyWork(to_fix=int(to_fix or 0), to_re_review=int(to_re_review or 0), to_fix_ids=tuple(dict.fromkeys(ids)))
