"""``/api/releases``: named, immutable snapshots of the accepted systems (``app.services.releases``). Making one
needs the admin role (403 otherwise; 409 for a name taken); reading them and their diff, any logged-in user."""
from __future__ import annotations

from typing import Annotated, Any, Literal

from fastapi import APIRouter, Depends, Path, Query, status
from fastapi.concurrency import run_in_threadpool
from fastapi.responses import Response
from sqlalchemy.orm import Session

from app.api.auth import Principal, PrincipalDep, require_role
from app.api.deps import SessionDep, SettingsDep
from app.api.release_schemas import DiffOut, ReleaseIn, ReleaseOut, ReleasesOut
from app.api.schemas import INVALID, NOT_FOUND, ErrorOut
from app.services.audit.log import actor_words
from app.services.releases import content, diff

router = APIRouter(prefix="/releases", tags=["releases"])

ReleaseName = Annotated[str, Path(min_length=1, max_length=content.NAME_MAX, description="The release's name.")]


def _out(session: Session, release: Any, principal: Principal) -> ReleaseOut:
    return ReleaseOut.model_validate({**content.release_summary(release),
                                      "without_ball3d": content.systems_without_ball(session, release),
                                      "made_by": actor_words(release.created_by, principal.may("admin"))})


@router.post("", response_model=ReleaseOut, status_code=status.HTTP_201_CREATED,
             responses={409: {"model": ErrorOut, "description": "The name is taken."}, **INVALID})
async def create_release(session: SessionDep, settings: SettingsDep, body: ReleaseIn,
                         principal: Annotated[Principal, Depends(require_role("admin"))]) -> ReleaseOut:
    """Make a release of the accepted systems as they are now (their labels, lines, calibrations, decisions, 3D
    results and the settings those were computed with); audited (``release.create``). Later edits, recomputes and
    imports never change it."""
    release = await run_in_threadpool(content.create_release, session, body.name, body.note, principal.name,
                                      settings)
    return _out(session, release, principal)


@router.get("", response_model=ReleasesOut)
def list_releases(session: SessionDep, principal: PrincipalDep) -> ReleasesOut:
    """Every release, oldest first."""
    return ReleasesOut(items=[_out(session, r, principal) for r in content.list_releases(session)])


@router.get("/{name}", response_model=ReleaseOut, responses=NOT_FOUND)
def show_release(session: SessionDep, principal: PrincipalDep, name: ReleaseName) -> ReleaseOut:
    """One release."""
    return _out(session, content.get_release(session, name), principal)


@router.get("/{a}/diff/{b}", response_model=DiffOut, response_model_by_alias=True,
            responses={**NOT_FOUND, 200: {"content": {"text/csv": {}}}})
def diff_releases(session: SessionDep, a: ReleaseName, b: ReleaseName,
                  format: Annotated[Literal["json", "csv"], Query(description="json (default) or csv.")] = "json",
                  ) -> Any:
    """What changed from release ``a`` to release ``b``: systems added, removed and changed (with how far the 3D
    ball moved and, per view, what changed: label, lines, calibration, decision; a removed one, why it left);
    ``?format=csv`` as CSV
    (``app.services.releases.diff.DIFF_CSV_COLUMNS``)."""
    result = diff.diff_releases(session, a, b)
    if format == "csv":
        return Response(diff.diff_csv(result), media_type="text/csv; charset=utf-8",
                        headers={"Content-Disposition": 'attachment; filename="diff.csv"'})
    return result.as_dict()
