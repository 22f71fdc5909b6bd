"""Conditional writes: the ``If-Match`` header of every write, and the ETag header of every answer.

A write names the version it was made against with ``If-Match: <ETag>`` (the ETag of
``GET /api/frames/{id}`` or of the system view, or the ``etag`` fields of the system view's JSON). A
stale one is answered 412 with the resource's current state (``app.api.errors``). A write without
``If-Match`` is refused with 428 when it comes with an API token (``Principal.via == "token"``), so
no script overwrites someone's edit by accident; ``If-Match: *`` (any version) does not stand in for an
ETag there. The browser's session writes stay accepted without it (the UI always sends it). The comparison happens in
the write's transaction (``app.services.curation.versions``).
"""
from __future__ import annotations

from typing import Annotated, Any, Optional

from fastapi import Depends, Header, HTTPException, Response

from app.api.auth import PrincipalDep
from app.api.schemas import ErrorOut
from app.api.view_schemas import StaleOut

#: OpenAPI ``responses`` of the guarded writes.
PRECONDITIONS: dict[int | str, dict[str, Any]] = {
    412: {"model": StaleOut, "description": "If-Match names a version that is no longer current: nothing was "
                                            "stored; the body holds the current state, its ETag and its last change."},
    428: {"model": ErrorOut, "description": "A write with an API token must send If-Match with the resource's ETag "
                                          "('*' is not one)."},
}


async def if_match_header(
    principal: PrincipalDep,
    if_match: Annotated[Optional[str], Header(description="The ETag of the resource this write was made against "
                                                          "(required with an API token).")] = None,
) -> Optional[str]:
    """The request's ``If-Match`` header; 428 when a token's write sends none or only ``*``."""
    if principal.via == "token" and (if_match is None or if_match.strip() == "*"):
        raise HTTPException(status_code=428, detail="If-Match is required: send the resource's ETag (from "
                            "GET /api/frames/{id} or the system view; '*' is not one) so that you never "
                            "overwrite someone's edit")
    return if_match


IfMatchDep = Annotated[Optional[str], Depends(if_match_header)]


def with_etag(response: Response, etag: str) -> None:
    """Put the edited (or read) resource's strong ETag on the answer; never cached without revalidation."""
    response.headers["ETag"] = etag
    response.headers["Cache-Control"] = "no-cache"
