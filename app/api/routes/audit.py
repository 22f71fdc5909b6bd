"""``/api/audit``: the audit log (every role reads it) and the revert of an entry (reviewers)."""
from __future__ import annotations

from typing import Annotated

from fastapi import APIRouter, Query, Response

from app.api.answers import capped_json, json_answer, json_items
from app.api.audit_schemas import AuditEntryOut, AuditPageOut, AuditQuery
from app.api.auth import AnnotatorDep, PrincipalDep, ReviewerDep
from app.api.conditional import with_etag
from app.api.deps import EditDep, SessionDep, SettingsDep
from app.api.schemas import INVALID, NOT_FOUND, DbInt, ErrorOut, QueueQuery
from app.api.view_schemas import SystemView
from app.db.models import AuditEntry
from app.services.audit import log as audit
from app.services.audit.log import AUDIT_ENTRY_HEADER
from app.services.curation import writing
from app.services.curation.reverting import Reverted, revert_entry, undo_entry
from app.services.curation.system_page import system_page
from app.services.curation.versions import frame_etag, system_etag
from app.services.transfer.data_root import shown_import_counts

router = APIRouter(prefix="/audit", tags=["audit"])


@router.get("", response_model=AuditPageOut, responses=INVALID)
def list_audit(session: SessionDep, settings: SettingsDep, principal: PrincipalDep,
               query: Annotated[AuditQuery, Query()]) -> Response:
    """One page of the audit log, newest first: who changed what, when, and the state before and after.
    ``system_id`` gives the system's decisions and every edit of its views; ``user`` an actor's exact name; ``since``
    and ``until`` when it was written (422 naming ``until`` when it is not after ``since``).
    Changes of users and tokens (``user.*``, ``token.*``) are listed to admins only. An import's ``source`` is
    its server path for admins, the dataset's name for the other roles; work run on the machine is ``cli:<os user>``
    to admins, ``cli`` to the other roles (``user=cli`` lists it). A page holds at most ``limit`` entries and
    stops before the entry that would take it past ``V3D_MAX_ANSWER_KB`` of JSON (it holds one at least);
    ``next_offset`` is where the next page starts (null on the last page)."""
    which = audit.EntryFilter(query.frame_id, query.system_id, query.user, include_admin=principal.may("admin"),
                              since=query.since, until=query.until)
    total = audit.count_entries(session, which)
    batches = audit.entry_batches(session, which, limit=query.limit, offset=query.offset)
    items = capped_json((_shown(session, principal, batch) for batch in batches), settings.max_answer_kb * 1024)
    taken = query.offset + len(items)
    return json_items(items, {"total": total, "limit": query.limit, "offset": query.offset,
                              "next_offset": taken if taken < total else None})


def _shown(session: SessionDep, principal: PrincipalDep, entries: list[AuditEntry]) -> list[AuditEntryOut]:
    """Entries as the caller is shown them: each with its summary (computed for entries older than summaries), an
    import's counts without server paths for non-admins."""
    names = audit.view_names(session, [e for e in entries if not e.summary])
    admin = principal.may("admin")
    items = [AuditEntryOut.shown(e, admin).model_copy(
        update={"summary": audit.entry_summary(e, names.get(e.frame_id) if e.frame_id is not None else None)})
        for e in entries]
    if not admin:
        items = [i.model_copy(update={"after": shown_import_counts(i.after)}) if i.action == "import" else i
                 for i in items]
    return items


@router.post(
    "/{entry_id}/revert", response_model=SystemView,
    responses={**NOT_FOUND, **INVALID,
               409: {"model": ErrorOut, "description": "The resource changed since the entry (send force=true to "
                                                       "revert anyway)."}},
)
def revert(session: SessionDep, settings: SettingsDep, principal: ReviewerDep, entry_id: DbInt,
           query: Annotated[QueueQuery, Query()], response: Response, edit: EditDep,
           force: Annotated[bool, Query(description="Revert even when the resource changed since the entry.")] = False,
           ) -> Response:
    """Restore the entry's ``before`` state through the service of the original edit (the system is
    recomputed), audited as action ``revert``; answers the recomputed system view and the resource's new
    ``ETag``. 409 when the resource changed since the entry (unless ``force``); 422 for an import or a
    recompute, which cannot be reverted. The entry itself is the precondition: no If-Match is needed."""
    done = revert_entry(session, entry_id, settings=settings, actor=principal.name, force=force, edit=edit)
    return _restored(session, done, query, response, principal.name)


@router.post(
    "/{entry_id}/undo", response_model=SystemView,
    responses={**NOT_FOUND, **INVALID,
               403: {"model": ErrorOut, "description": "An annotator undoing a system decision, another's entry, or "
                                                       "an entry someone else's write of the view followed."},
               409: {"model": ErrorOut, "description": "The resource changed since the entry: an undo restores "
                                                       "only what nothing changed since (undo the newer first)."}},
)
def undo(session: SessionDep, settings: SettingsDep, principal: AnnotatorDep, entry_id: DbInt,
         query: Annotated[QueueQuery, Query()], response: Response, edit: EditDep) -> Response:
    """Undo the entry (the system page's Ctrl+Z; its redo, Ctrl+Shift+Z, is the undo of the undo's entry):
    its ``before`` state written back through the service of its edit (the system is recomputed), audited as
    that edit's action with ``reverts_id`` naming the entry; answers the recomputed system view, the resource's
    new ``ETag`` and the new entry's id in ``X-V3D-Audit-Entry``. Labels, camera and 3D ball come back exactly:
    409 when the edited part is no longer what the entry left. Reviewers undo any edit; an annotator their own,
    when no one else wrote the view since (403 otherwise, and for a system decision, a reviewer's edit)."""
    done = undo_entry(session, entry_id, settings=settings, actor=principal.name, may_review=principal.may("reviewer"),
                      edit=edit)
    if edit.entry_id is not None:
        response.headers[AUDIT_ENTRY_HEADER] = str(edit.entry_id)
    return _restored(session, done, query, response, principal.name)


def _restored(session: SessionDep, done: Reverted, query: QueueQuery, response: Response, me: str) -> Response:
    """The recomputed system view after a revert or an undo by ``me`` (whom ``assignee=me`` names), the resource's
    new ETag in the header (serialised here: ``app.api.answers``)."""
    if done.kind == "frame":
        with_etag(response, frame_etag(writing.get_frame(session, done.ident)))
    else:
        with_etag(response, system_etag(writing.get_system(session, done.ident)))
    return json_answer(SystemView.of(system_page(session, done.system_id, query.filters(me=me), query.sort)), response)
