"""``/api/systems``: the review queue, the system view, and system review decisions.

The system view answers the ETag of the system's review decision (its ``etag`` field too; each view
carries its frame's ``etag``); a decision is a conditional write on it (``app.api.conditional``) and
needs the reviewer role."""
from __future__ import annotations

from typing import Annotated

from fastapi import APIRouter, Query, Response

from app.api.answers import json_answer
from app.api.assignment_schemas import AssignmentOut, PresenceOut
from app.api.auth import AnnotatorDep, PrincipalDep
from app.api.conditional import PRECONDITIONS, IfMatchDep, with_etag
from app.api.deps import EditDep, SessionDep, SystemDep, SystemIdPath
from app.api.handoff_schemas import DecisionOut, SystemReviewIn
from app.api.queue_schemas import SystemPageOut, SystemSummaryOut
from app.api.routes.frames import name_entry
from app.api.schemas import INVALID, NOT_FOUND, QueueQuery, SystemListQuery
from app.api.view_schemas import ReviewOut, SystemView
from app.db.models import ReviewStatus, UserRole
from app.db.types import utcnow
from app.services.curation import assignment, decisions, handoff, presence, queue, writing
from app.services.curation.system_page import system_page
from app.services.curation.versions import expected_versions, system_etag

router = APIRouter(prefix="/systems", tags=["systems"])


@router.get("", response_model=SystemPageOut, responses=INVALID)
def list_systems(session: SessionDep, principal: PrincipalDep,
                 query: Annotated[SystemListQuery, Query()], response: Response) -> Response:
    """One page of the review queue, filtered and sorted, with the progress per review status; by
    ``offset`` or by cursor (``after`` / ``before``: a page's ``next_cursor`` / ``prev_cursor``; 422
    naming the field for a cursor of another sort or both at once). ``assignee=NAME|me|none``: the systems
    assigned to that user, to the caller, or to nobody (an unknown name answers as a user with no system does: the
    queue tells no one which accounts exist). Each row carries its ``assignment`` and who has it open now
    (``open_by``). Serialised here (``app.api.answers``): a page of 50 rows validated a second time by FastAPI cost
    as much again as shaping it."""
    filters = query.filters(me=principal.name)
    page = queue.list_system_rows(session, filters, query.sort, query.limit, query.offset, query.after,
                                  query.before)
    cursor = query.after is not None or query.before is not None
    ids = [row["id"] for row in page.items]
    assigned, now = assignment.assignments_of(session, ids), utcnow()
    present = presence.open_on(session, ids, now)
    items = [SystemSummaryOut.of_row(row, AssignmentOut.of(assigned.get(row["id"])),
                                     [PresenceOut.of(p, now) for p in present.get(row["id"], [])])
             for row in page.items]
    return json_answer(SystemPageOut(items=items, total=page.total, limit=query.limit,
                                     offset=None if cursor else query.offset, counts=page.counts,
                                     next_cursor=page.next_cursor, prev_cursor=page.prev_cursor), response)


@router.get("/{system_id}", response_model=SystemView, responses=NOT_FOUND)
def read_system(session: SessionDep, principal: PrincipalDep, system_id: SystemIdPath,
                query: Annotated[QueueQuery, Query()], response: Response) -> Response:
    """The system view (``docs/api.md``); ``prev_id`` / ``next_id`` follow the queue given by
    the query parameters (by default the whole queue, largest error first; ``assignee=me`` is the caller).
    ``assignment`` and ``open_by`` say who it is assigned to and who has it open. ``ETag``: the system's
    version (``etag``), what a decision's ``If-Match`` sends. 404 naming the id when there is none (the page's own
    load finds it: no lookup before)."""
    out = SystemView.of(system_page(session, system_id, query.filters(me=principal.name), query.sort))
    with_etag(response, out.etag)
    return json_answer(out, response)


@router.post("/{system_id}/review", response_model=DecisionOut, responses={**NOT_FOUND, **INVALID, **PRECONDITIONS})
def review_system(session: SessionDep, principal: AnnotatorDep, if_match: IfMatchDep, system: SystemDep,
                  body: SystemReviewIn, response: Response, edit: EditDep) -> DecisionOut:
    """Record the reviewer's decision on the whole system (``If-Match``: the system view's ``etag``, which every
    write of the system's labels, lines, exclusions, calibrations and decision changes: 412 once anything the page
    showed has changed); the system's new ETag in the header, its audit entry in ``X-V3D-Audit-Entry`` (what an undo
    names). ``needs_fix`` returns the system to the person the body's ``assignee`` names, else to the person who last
    edited its labels, else its assignee (the answer's ``returned_to`` and ``handoff`` say to whom); with none of them
    it is refused, 400 naming ``assignee`` (never returned to nobody); ``fixed`` is sent by that person alone (any role)
    and gives it back to the reviewer who asked (``app.services.curation.handoff``). Reviewers send any status; an
    annotator only ``fixed`` on a system returned to them (403 otherwise, before the ``If-Match`` is compared). A
    ``fixed`` whose hand-off another decision closed after that check is refused 409 (checked again in the write,
    under the lock): it never undoes a decision it did not see, ``If-Match`` or not."""
    handoff.check_fixed_allowed(session, system.id, user_id=principal.user_id, role=UserRole(principal.role),
                                status=body.status)
    decision = decisions.decide_review(session, system_id=system.id, status=body.status, comment=body.comment,
                                       actor=principal.name, expected=expected_versions(if_match, "system", system.id),
                                       edit=edit, fixed_by=principal.user_id, return_to=body.assignee)
    name_entry(edit, response)
    with_etag(response, system_etag(writing.get_system(session, system.id)))
    out = DecisionOut.model_validate(ReviewOut.of(decision).model_dump())
    if body.status in (ReviewStatus.NEEDS_FIX, ReviewStatus.FIXED):
        made = handoff.latest_handoff(session, system.id)
        if made is not None:
            out.returned_to = made.returned_to if not made.fixed else made.returned_by
            out.handoff = made.words
    return out
