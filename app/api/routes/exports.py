"""``/api/exports``: download reviewed labels, streamed in the request (``GET``) or written to a file by
a background job (``POST``, for large exports and the UI: the file is then read at ``/api/jobs/{id}/result``).

``POST /api/exports/{format}`` queues any export of the registry (``app.services.exports.formats``; written by
``app.services.exports.files``); ``GET /api/exports/cameras`` (as ``GET`` of ``yolo``,
``coco`` and ``issia-3d``, in ``detectors.py`` and ``issia.py``) answers the zip in the request. Every route
needs the admin role."""
from __future__ import annotations

import shutil
import tempfile
from collections.abc import Iterator
from pathlib import Path as FilePath
from typing import TYPE_CHECKING, Annotated, Any, Literal, Optional

from fastapi import APIRouter, Body, Depends, Path, Query, Request, status
from fastapi.concurrency import run_in_threadpool
from fastapi.responses import FileResponse, JSONResponse, StreamingResponse
from starlette.background import BackgroundTask

from app.api.auth import require_role
from app.api.deps import SessionDep, SettingsDep
from app.api.job_schemas import ExportJobIn, JobOut, TreeExportJobIn
from app.api.routes.jobs import accepted
from app.api.schemas import INVALID, ErrorOut, QueryText
from app.core.errors import InvalidInputError
from app.services.exports import files as export_files
from app.services.exports.formats import tree_export_names
from app.services.jobs import runner as jobs
from app.services.jobs.work import export_params
from app.services.releases.content import get_release
from app.services.releases.export import ReleaseSource
from app.services.storage.datasets import DatasetFiles
from app.services.transfer import export_zip, exporting

#: OpenAPI ``responses`` of the routes that take a release by name.
NO_RELEASE: dict[int | str, dict[str, Any]] = {
    404: {"model": ErrorOut, "description": "No release has the name given as ``release``."}}

router = APIRouter(prefix="/exports", tags=["exports"], dependencies=[Depends(require_role("admin"))])


@router.get(
    "/soccernet-v3d",
    response_class=StreamingResponse,
    responses={200: {"content": {"application/zip": {}},
                     "description": "Labels-v3D.json and Frames-v3.zip per game, and SNv3D.csv."},
               **NO_RELEASE, **INVALID},
)
def export_soccernet_v3d(
    request: Request,
    settings: SettingsDep,
    include_all: Annotated[bool, Query(alias="all", description="Every system, not only the accepted ones.")] = False,
    images: Annotated[bool, Query(description="Each game's Frames-v3.zip (its images); false leaves them out.")] = True,
    release: Annotated[Optional[QueryText], Query(min_length=1, max_length=200, description=(
        "A release to export instead of the database now (byte for byte the same each time; not with all)."))] = None,
) -> StreamingResponse:
    """A zip of the SoccerNet-v3D export (``app.services.transfer.exporting``), streamed while the database is
    read, game by game (nothing of the size of the export is built in memory or on disk).
    ``X-V3D-Systems`` and ``X-V3D-Rows`` give its size. The stream reads through a session of its own,
    closed when the download ends (the request's session closes before a streamed body is sent)."""
    if release is not None and include_all:
        raise InvalidInputError("a release holds its accepted systems only: 'all' and 'release' exclude each other",
                                field="all")
    session = request.app.state.session_factory()
    try:
        source = None
        if release is not None:
            chosen = get_release(session, release)
            systems, rows = chosen.systems, chosen.views
            source = ReleaseSource(session, chosen)
        else:
            systems, rows = exporting.export_size(session, include_all)
        chunks = export_zip.stream_soccernet_v3d_zip(session, include_all, images=images, source=source,
                                                     files=DatasetFiles.from_settings(settings))
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


@router.post("/soccernet-v3d", response_model=JobOut, status_code=status.HTTP_202_ACCEPTED,
             responses={**NO_RELEASE, **INVALID})
async def create_export_job(session: SessionDep,
                            body: Annotated[ExportJobIn, Body(default_factory=ExportJobIn)]) -> JSONResponse:
    """Queue the SoccerNet-v3D export as a background job: the zip (the same archive the ``GET`` streams)
    is written to a file while the database is read, with progress per game; when the job is done its
    ``result_url`` (``/api/jobs/{id}/result``) streams the file. ``{"release": name}`` exports that release
    (byte for byte the same whenever asked; its ``Labels-v3D.json`` name it and its hash): 404 for no such release,
    422 beside ``all``."""
    params = export_params("soccernet-v3d", body.all, body.images, body.release)
    if body.release is not None:
        get_release(session, body.release)  # 404 now rather than a failed job
    return accepted(await run_in_threadpool(jobs.submit, session, "export", params))


#: The path parameter's choices: the registry's tree exports (SoccerNet-v3D has its own route above, for its
#: ``images``). A ``Literal`` of the registry's names, built when the module loads, so that the OpenAPI schema lists
#: them and any other name is a 422 before the route runs. A type checker, which cannot read a Literal built at run
#: time, sees the plain string it holds.
if TYPE_CHECKING:
    TreeFormat = str
else:
    TreeFormat = Literal[tree_export_names()]


@router.post("/{export_format}", response_model=JobOut, status_code=status.HTTP_202_ACCEPTED,
             responses={**NO_RELEASE, **INVALID})
async def create_tree_export_job(
    session: SessionDep,
    export_format: Annotated[TreeFormat, Path(description=f"{', '.join(tree_export_names())} (soccernet-v3d: above).")],
    body: Annotated[TreeExportJobIn, Body(default_factory=TreeExportJobIn)],
) -> JSONResponse:
    """Queue an export as a background job: the same tree its ``GET`` answers, written to a file (progress per
    file zipped) kept ``V3D_EXPORT_KEEP_HOURS`` for download at the job's ``result_url``
    (``/api/jobs/{id}/result``). The job's ``result`` holds the export's counts (a YOLO split without images
    in ``empty_splits``)."""
    params = export_params(export_format, body.all, release=body.release)
    if body.release is not None:
        get_release(session, body.release)  # 404 now rather than a failed job
    return accepted(await run_in_threadpool(jobs.submit, session, "export", params))


@router.get(
    "/cameras",
    response_class=FileResponse,
    responses={200: {"content": {"application/zip": {}},
                     "description": "cameras.json and per image size <W>x<H>/ground_truth.zip and predictions.zip."}},
)
def export_cameras(
    session: SessionDep, settings: SettingsDep,
    include_all: Annotated[bool, Query(alias="all", description="Every system, not only the accepted ones.")] = False,
) -> FileResponse:
    """The cameras export (``app.services.transfer.cameras_export``, as ``v3d export cameras``) as a zip: per image
    size the ground truth (``<split>/<name>.json`` field lines) and predictions (``camera_<name>.json``) zips that
    SoccerNet's calibration evaluator reads as they are, and ``cameras.json``. ``X-V3D-Cameras`` gives its size."""
    tmp = FilePath(tempfile.mkdtemp(prefix="v3d-cameras-"))
    try:
        report = export_files.write_export_zip(session, "cameras", tmp / "cameras.zip", include_all, settings)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    return FileResponse(tmp / "cameras.zip", media_type="application/zip", filename="cameras.zip",
                        headers={"X-V3D-Cameras": str(report["cameras"])},
                        background=BackgroundTask(shutil.rmtree, tmp, ignore_errors=True))
