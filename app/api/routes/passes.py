"""``/api/passes``: review passes (``app.services.curation.passes``): the frozen list of a review
queue's systems a user reviews once each, stored per user so that it resumes in another browser."""
from __future__ import annotations

from typing import Annotated

from fastapi import APIRouter, Query, status

from app.api.auth import AnnotatorDep, PrincipalDep
from app.api.deps import SessionDep, SettingsDep
from app.api.pass_schemas import PassIn, PassOut, PassPlaceOut, VisitIn
from app.api.schemas import INVALID, NOT_FOUND, DbInt
from app.services.curation import passes

router = APIRouter(prefix="/passes", tags=["passes"])


@router.post("", response_model=PassOut, status_code=status.HTTP_201_CREATED, responses=INVALID)
def start_pass(session: SessionDep, settings: SettingsDep, principal: AnnotatorDep, body: PassIn) -> PassOut:
    """Begin a pass over the queue ``filter`` + ``sort`` (every system of every page, frozen in the queue's
    order now), or continue the caller's newest open pass of that queue holding ``system_id``
    (``fresh``: always a new one). Answers the pass with its ``systems``. A user keeps at most
    ``V3D_MAX_PASSES_PER_USER`` passes (50): a new one drops the least recently visited beyond them."""
    rp = passes.start_pass(session, principal.name, body.filter.filters(), body.sort or body.filter.sort,
                           body.system_id, fresh=body.fresh, keep=settings.max_passes_per_user)
    return PassOut.of(rp, passes.pass_counts(session, rp))


@router.get("", response_model=list[PassOut])
def list_passes(session: SessionDep, principal: PrincipalDep,
                mine: Annotated[bool, Query(description="true (default): the caller's passes; "
                                                        "false: everyone's.")] = True,
                limit: Annotated[int, Query(ge=1, le=100)] = 20) -> list[PassOut]:
    """The newest passes (the caller's by default), each with its counts and position, without its
    ``systems`` list (GET /api/passes/{id} has it): what a person resumes."""
    found = passes.list_passes(session, principal.name if mine else None, limit)
    return [PassOut.of(rp, passes.pass_counts(session, rp), with_systems=False) for rp in found]


@router.get("/{pass_id}", response_model=PassOut, responses=NOT_FOUND)
def read_pass(session: SessionDep, pass_id: DbInt) -> PassOut:
    """A pass with its frozen ``systems`` and the counts of their current statuses."""
    rp = passes.get_pass(session, pass_id)
    return PassOut.of(rp, passes.pass_counts(session, rp))


@router.get("/{pass_id}/place", response_model=PassPlaceOut, responses=NOT_FOUND)
def read_place(session: SessionDep, pass_id: DbInt,
               system_id: Annotated[DbInt, Query(description="The system shown.")]) -> PassPlaceOut:
    """Where ``system_id`` stands in the pass, statuses read now: its neighbours in the pass, the next system
    after it that is still pending (what a decision moves to), the counts, ``finished``."""
    return PassPlaceOut.of(passes.place(session, passes.get_pass(session, pass_id), system_id))


@router.post("/{pass_id}/visits", response_model=PassPlaceOut, responses={**NOT_FOUND, **INVALID})
def visit(session: SessionDep, principal: AnnotatorDep, pass_id: DbInt, body: VisitIn) -> PassPlaceOut:
    """The pass's owner opened ``system_id``: its position moves there (resumed from there later); answers
    the place as GET .../place does. 403 for another user's pass."""
    rp = passes.get_pass(session, pass_id)
    return PassPlaceOut.of(passes.visit(session, rp, body.system_id, principal.name))
