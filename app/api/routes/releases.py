"""``/api/releases``: named, immutable snapshots of the accepted systems (``app.services.releases``). Making one
needs the admin role (403 otherwise; 409 for a name taken); reading them and their diff, any logged-in user."""
from __future__ import annotations

from datetime import datetime
from typing import Annotated, Any, Literal, Optional

from fastapi import APIRouter, Depends, Path, Query, status
from fastapi.concurrency import run_in_threadpool
from fastapi.responses import Response
from pydantic import BaseModel, Field

from app.api.auth import Principal, require_role
from app.api.deps import SessionDep
from app.api.schemas import INVALID, NOT_FOUND, ErrorOut, _In, readable_name
from app.services.releases import content, diff

router = APIRouter(prefix="/releases", tags=["releases"])

ReleaseName = Annotated[str, Path(min_length=1, max_length=content.NAME_MAX, description="The release's name.")]


class ReleaseIn(_In):
    name: Annotated[str, readable_name(content.NAME_MAX, "a release name")] = Field(
        min_length=1, max_length=content.NAME_MAX,
        description="Unique, also by its NFKC case-folded form (409); no leading or trailing space, '/', '\\', "
                    "control or format character (Unicode Cc, Cf), not dots alone; stored in NFC.")
    note: str = Field("", max_length=10_000, description="Free text kept with the release.")


class ReleaseOut(BaseModel):
    """A release: the accepted systems as they were when it was made, immutably."""

    name: str
    note: str
    created_at: datetime
    created_by: str
    systems: int = Field(description="Accepted systems it holds.")
    views: int = Field(description="Their views (frames).")
    hash: str = Field(description="SHA-256 (hex) of its canonical content (docs/exports.md gives the recipe).")


class ReleasesOut(BaseModel):
    items: list[ReleaseOut]


class DiffEnd(BaseModel):
    name: str
    hash: str


class DiffSystem(BaseModel):
    system_id: int
    name: str
    game: str = Field(description="league/season/match")


class DiffView(BaseModel):
    frame_id: int
    view: str = Field(description="The frame's name.")
    changes: list[Literal["label", "lines", "calibration", "decision", "added", "removed"]]


class DiffChanged(DiffSystem):
    ball3d_moved_m: Optional[float] = Field(description="How far the 3D ball moved (world m); null when either "
                                                        "release's system has none.")
    views: list[DiffView]


class DiffOut(BaseModel):
    from_: DiffEnd = Field(alias="from")
    to: DiffEnd
    added: list[DiffSystem]
    removed: list[DiffSystem]
    changed: list[DiffChanged]
    unchanged: int


def _out(release: Any) -> ReleaseOut:
    return ReleaseOut.model_validate(content.release_summary(release))


@router.post("", response_model=ReleaseOut, status_code=status.HTTP_201_CREATED,
             responses={409: {"model": ErrorOut, "description": "The name is taken."}, **INVALID})
async def create_release(session: SessionDep, body: ReleaseIn,
                         principal: Annotated[Principal, Depends(require_role("admin"))]) -> ReleaseOut:
    """Make a release of the accepted systems as they are now (their labels, lines, calibrations, decisions, 3D
    results and the settings those were computed with); audited (``release.create``). Later edits, recomputes and
    imports never change it."""
    release = await run_in_threadpool(content.create_release, session, body.name, body.note, principal.name)
    return _out(release)


@router.get("", response_model=ReleasesOut)
def list_releases(session: SessionDep) -> ReleasesOut:
    """Every release, oldest first."""
    return ReleasesOut(items=[_out(r) for r in content.list_releases(session)])


@router.get("/{name}", response_model=ReleaseOut, responses=NOT_FOUND)
def show_release(session: SessionDep, name: ReleaseName) -> ReleaseOut:
    """One release."""
    return _out(content.get_release(session, name))


@router.get("/{a}/diff/{b}", response_model=DiffOut, response_model_by_alias=True,
            responses={**NOT_FOUND, 200: {"content": {"text/csv": {}}}})
def diff_releases(session: SessionDep, a: ReleaseName, b: ReleaseName,
                  format: Annotated[Literal["json", "csv"], Query(description="json (default) or csv.")] = "json",
                  ) -> Any:
    """What changed from release ``a`` to release ``b``: systems added, removed and changed (with how far the 3D
    ball moved and, per view, what changed: label, lines, calibration, decision); ``?format=csv`` as CSV
    (``app.services.releases.diff.DIFF_CSV_COLUMNS``)."""
    result = diff.diff_releases(session, a, b)
    if format == "csv":
        return Response(diff.diff_csv(result), media_type="text/csv; charset=utf-8",
                        headers={"Content-Disposition": 'attachment; filename="diff.csv"'})
    return result.as_dict()
