"""Work assignment and presence (``app.services.curation.assignment`` and ``presence``).

* ``POST /api/assignments`` (reviewers and admins): assign systems (by id, a whole game, or a queue filter's
  result) to a user, or unassign them; one audit entry (``system.assign``) per system that changed.
* ``GET /api/assignees`` (reviewers and admins): the users systems may be assigned to.
* ``PUT /api/systems/{id}/presence`` (every role): the page's heartbeat while it has the system open: claims it
  and answers who else has it open. It writes the database only when the claim is due (at most once per
  ``presence.REFRESH_AFTER``), never per heartbeat.
* ``DELETE /api/systems/{id}/presence``: the page left the system.

Who a system is assigned to and who has it open are read with the queue (``GET /api/systems``, its
``assignee`` filter) and the system view (``assignment``, ``open_by``).
"""
from __future__ import annotations

from fastapi import APIRouter, Response

from app.api.assignment_schemas import AssignedOut, AssigneeOut, AssignIn, PresenceStateOut
from app.api.auth import AnnotatorDep, ReviewerDep
from app.api.deps import SessionDep, SystemDep
from app.api.schemas import INVALID, NOT_FOUND
from app.db.types import utcnow
from app.services.accounts.users import ASSIGNEE_NONE
from app.services.curation import assignment, presence

router = APIRouter(tags=["assignments"])


@router.post("/assignments", response_model=AssignedOut, responses={**NOT_FOUND, **INVALID})
def assign(session: SessionDep, principal: ReviewerDep, body: AssignIn) -> AssignedOut:
    """Assign systems to ``assignee`` (an enabled user's name), or unassign them (``assignee`` null): the systems
    ``system_ids``, every system of ``game_id``, or every system the queue ``filter`` matches (the query
    parameters of ``GET /api/systems`` as an object, all pages; ``assignee: "me"`` is the caller). Systems
    already assigned to that user are left alone; each one that changes gets an audit entry (action
    ``system.assign``, before / after ``{"assignee": name}``; revertible). 404 for an unknown system or game,
    422 naming ``assignee`` for an unknown or disabled user. Needs the reviewer role."""
    filters = body.filter.filters(me=principal.name) if body.filter is not None else None
    if filters is not None and filters.assignee not in (None, ASSIGNEE_NONE):
        assignment.known_user(session, filters.assignee, "filter.assignee")
    done = assignment.assign(session, assignee=body.assignee, system_ids=body.system_ids, game_id=body.game_id,
                             filters=filters, actor=principal.name)
    return AssignedOut(assignee=done.assignee, matched=done.matched, changed=done.changed, system_ids=done.system_ids)


@router.get("/assignees", response_model=list[AssigneeOut])
def list_assignees(session: SessionDep, principal: ReviewerDep) -> list[AssigneeOut]:
    """The users systems may be assigned to (every enabled user, by name, with their role). Needs the
    reviewer role (the people who assign)."""
    return [AssigneeOut(name=u.name, role=u.role.value) for u in assignment.assignable_users(session)]


@router.put("/systems/{system_id}/presence", response_model=PresenceStateOut, responses=NOT_FOUND)
def claim_presence(session: SessionDep, principal: AnnotatorDep, system: SystemDep) -> PresenceStateOut:
    """The page's heartbeat while the caller has the system open (send it every ``heartbeat_seconds``): a soft
    claim that lapses ``ttl_seconds`` after its last refresh, and the others who have the system open now.
    Writes only when the claim is missing or older than ``presence.REFRESH_AFTER`` (30 s; ``wrote``); any role.
    Not a lock: edits by others are never refused because of it."""
    now = utcnow()
    return PresenceStateOut.of(presence.claim(session, system.id, principal.user_id, now), now)


@router.delete("/systems/{system_id}/presence", status_code=204, responses=NOT_FOUND)
def release_presence(session: SessionDep, principal: AnnotatorDep, system: SystemDep) -> Response:
    """The caller left the system (closed or moved on): their claim ends now instead of lapsing. 204 either way."""
    presence.release(session, system.id, principal.user_id)
    return Response(status_code=204)
