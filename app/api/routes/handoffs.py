"""The hand-off of systems marked needs fix (``app.services.curation.handoff``), as the pages read it.

* ``GET /api/handoffs/mine``: what waits for the caller: ``to_fix`` (systems returned to them, and ``to_fix_ids``,
  the list in order) and ``to_re_review`` (systems they returned that came back fixed): the queue page's **To fix**
  and **To re-review** counts, and the system page's next system to fix.
* ``GET /api/systems/{id}/handoff``: the system's newest hand-off in words, and whether the caller may send it back
  as fixed (``POST /api/systems/{id}/review`` ``{"status": "fixed"}``).
"""
from __future__ import annotations

from typing import Optional

from fastapi import APIRouter

from app.api.auth import PrincipalDep
from app.api.deps import SessionDep, SystemDep
from app.api.handoff_schemas import HandOffOut, MyWorkOut
from app.api.schemas import NOT_FOUND
from app.services.curation import handoff

router = APIRouter(tags=["assignments"])


@router.get("/handoffs/mine", response_model=MyWorkOut)
def my_work(session: SessionDep, principal: PrincipalDep) -> MyWorkOut:
    """The caller's **To fix** and **To re-review** counts (0 when nothing waits)."""
    work = handoff.my_work(session, principal.user_id)
    return MyWorkOut(to_fix=work.to_fix, to_re_review=work.to_re_review, to_fix_ids=list(work.to_fix_ids))


@router.get("/systems/{system_id}/handoff", response_model=Optional[HandOffOut], responses=NOT_FOUND)
def system_handoff(session: SessionDep, principal: PrincipalDep, system: SystemDep) -> Optional[HandOffOut]:
    """The system's newest hand-off, or null when it was never marked needs fix."""
    made = handoff.latest_handoff(session, system.id)
    if made is None:
        return None
    return HandOffOut(returned_to=made.returned_to, returned_by=made.returned_by, fixed=made.fixed, open=made.open,
                      words=made.words,
                      may_send_fixed=handoff.returned_to_user(session, system.id, principal.user_id))
