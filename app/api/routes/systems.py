"""``/api/systems``: the review queue, the system view, and system review decisions."""
from __future__ import annotations

from typing import Annotated, Any

from fastapi import APIRouter, Query

from app.api.deps import SessionDep, SystemDep
from app.api.schemas import (
    INVALID, NOT_FOUND, QueueQuery, ReviewIn, ReviewOut, SystemListQuery, SystemPageOut, SystemView,
)
from app.services import editing, views

router = APIRouter(prefix="/systems", tags=["systems"])


@router.get("", response_model=SystemPageOut)
def list_systems(session: SessionDep, query: Annotated[SystemListQuery, Query()]) -> dict[str, Any]:
    """One page of the review queue, filtered and sorted, with the progress per review status."""
    page = views.list_systems(session, query.filters(), query.sort, query.limit, query.offset)
    return {"items": [s.as_json() for s in page.items], "total": page.total, "limit": query.limit,
            "offset": query.offset, "counts": page.counts}


@router.get("/{system_id}", response_model=SystemView, responses=NOT_FOUND)
def read_system(session: SessionDep, system: SystemDep, query: Annotated[QueueQuery, Query()]) -> dict[str, Any]:
    """The system view (``docs/architecture.md``); ``prev_id`` / ``next_id`` follow the queue given by
    the query parameters (by default the whole queue, largest error first)."""
    return views.system_view(session, system.id, query.filters(), query.sort)


@router.post("/{system_id}/review", response_model=ReviewOut, responses={**NOT_FOUND, **INVALID})
def review_system(session: SessionDep, system: SystemDep, body: ReviewIn) -> ReviewOut:
    """Record the reviewer's decision on the whole system."""
    decision = editing.decide_review(session, system_id=system.id, status=body.status, comment=body.comment)
    return ReviewOut.model_validate(views.review_json(decision))
