"""``/api/exports``: download reviewed labels, streamed in the request (``GET``) or written to a file by
a background job (``POST``, for large exports: the file is then read at ``/api/jobs/{id}/result``)."""
from __future__ import annotations

from collections.abc import Iterator
from typing import Annotated

from fastapi import APIRouter, Body, Depends, Query, Request, status
from fastapi.concurrency import run_in_threadpool
from fastapi.responses import JSONResponse, StreamingResponse

from app.api.auth import require_role
from app.api.deps import SessionDep
from app.api.job_schemas import ExportJobIn, JobOut
from app.api.routes.jobs import accepted
from app.services.transfer import exporting
from app.services.jobs import runner as jobs

router = APIRouter(prefix="/exports", tags=["exports"], dependencies=[Depends(require_role("admin"))])


@router.get(
    "/soccernet-v3d",
    response_class=StreamingResponse,
    responses={200: {"content": {"application/zip": {}},
                     "description": "Labels-v3D.json and Frames-v3.zip per game, and SNv3D.csv."}},
)
def export_soccernet_v3d(
    request: Request,
    include_all: Annotated[bool, Query(alias="all", description="Every system, not only the accepted ones.")] = False,
    images: Annotated[bool, Query(description="Each game's Frames-v3.zip (its images); false leaves them out.")] = True,
) -> StreamingResponse:
    """A zip of the SoccerNet-v3D export (``app.services.transfer.exporting``), streamed while the database is
    read, game by game (nothing of the size of the export is built in memory or on disk).
    ``X-V3D-Systems`` and ``X-V3D-Rows`` give its size. The stream reads through a session of its own,
    closed when the download ends (the request's session closes before a streamed body is sent)."""
    session = request.app.state.session_factory()
    try:
        systems, rows = exporting.export_size(session, include_all)
        chunks = exporting.stream_soccernet_v3d_zip(session, include_all, images=images)
        first = next(chunks)  # a game name that cannot be a folder fails here, before the answer starts
    except BaseException:
        session.close()
        raise

    def body() -> Iterator[bytes]:
        try:
            yield first
            yield from chunks
        finally:
            session.close()

    return StreamingResponse(
        body(), media_type="application/zip",
        headers={"Content-Disposition": 'attachment; filename="soccernet-v3d.zip"',
                 "X-V3D-Systems": str(systems), "X-V3D-Rows": str(rows)},
    )


@router.post("/soccernet-v3d", response_model=JobOut, status_code=status.HTTP_202_ACCEPTED)
async def create_export_job(session: SessionDep,
                            body: Annotated[ExportJobIn, Body(default_factory=ExportJobIn)]) -> JSONResponse:
    """Queue the SoccerNet-v3D export as a background job: the zip (the same archive the ``GET`` streams)
    is written to a file while the database is read, with progress per game; when the job is done its
    ``result_url`` (``/api/jobs/{id}/result``) streams the file."""
    return accepted(await run_in_threadpool(jobs.submit, session, "export", {"format": "soccernet-v3d",
                                                                            "all": body.all, "images": body.images}))
