"""``/api/jobs``: background jobs (imports, full recomputes, exports; ``app.services.jobs.runner``), and
``POST /api/recompute`` that queues a full recompute.

A job is created by ``POST /api/imports``, ``POST /api/recompute`` or ``POST /api/exports/{format}``
(202, ``Location: /api/jobs/{id}``) and run by a server process's job runner; ``GET /api/jobs/{id}``
shows its state and progress (``stage``, ``done`` of ``total``), then its result;
``GET /api/jobs/{id}/result`` streams a finished export's file (kept ``V3D_EXPORT_KEEP_HOURS``). Every role may follow
jobs; a full recompute and an export's file need the admin role (as imports and exports do).
"""
from __future__ import annotations

from collections.abc import Iterator
from typing import Annotated, Optional
from urllib.parse import quote

from fastapi import APIRouter, Depends, Path, Query, status
from fastapi.concurrency import run_in_threadpool
from fastapi.responses import FileResponse, JSONResponse, Response, StreamingResponse

from app.api.auth import AdminDep, Principal, PrincipalDep, require_role
from app.api.deps import SessionDep, SettingsDep
from app.api.job_schemas import JobKindName, JobOut, JobPageOut, JobStateName
from app.api.schemas import DB_INT_MAX, NOT_FOUND, DbInt, ErrorOut
from app.core.config import Settings, jobs_dir
from app.core.errors import NotFoundError
from app.db.models import Job, JobState
from app.services.exports.files import prune_stored_exports
from app.services.exports.formats import NOTHING
from app.services.jobs import runner as jobs
from app.services.jobs.progress import read_live
from app.services.jobs.work import RESULT_FILES, without_server_paths
from app.services.storage import storage_for
from app.services.storage.stores import Storage

router = APIRouter(tags=["jobs"])
#: A job id (``DbInt``: beyond the database's integers PostgreSQL refused the query, a 500 found by fuzzing).
JobId = Annotated[DbInt, Path(description="Job id.")]


def job_out(job: Job, principal: Principal | None = None, settings: Settings | None = None) -> JobOut:
    """The API's view of a job row; for an annotator or reviewer (``principal`` below admin) an import's
    path, source and message name the dataset, never a server path (``kinds.without_server_paths``), and the
    process running it (``owner``: node name and process id) is not shown."""
    url = f"/api/jobs/{job.id}"
    # an export that held nothing keeps no file (its result says why in words)
    has_file = job.kind in RESULT_FILES and job.state is JobState.DONE and bool((job.result or {}).get("file"))
    params, result, message, owner = job.params, job.result, job.message, job.owner
    if principal is not None and settings is not None and not principal.may("admin"):
        params, result, message = without_server_paths(job.id, params, result, message, settings)
        owner = None
    progress = {"stage": job.stage, "done": job.done, "total": job.total}
    # the live file is newer than the row's while a batch is open; it is kept on the node running the job (another
    # node's is not here, and one left here by an earlier attempt is stale): the row's progress for those
    if job.state is JobState.RUNNING and settings is not None and jobs.on_this_node(job.owner, settings):
        now = read_live(jobs_dir(settings), job.id)
        if now is not None:
            progress = dict(zip(("stage", "done", "total"), now, strict=True))
    return JobOut.model_validate({
        **{k: getattr(job, k) for k in ("id", "kind", "attempts", "created_at", "started_at", "finished_at",
                                        "heartbeat_at")}, **progress,
        "owner": owner, "params": params, "result": result, "message": message,
        "state": job.state.value, "url": url, "result_url": f"{url}/result" if has_file else None,
    })


def accepted(job: Job) -> JSONResponse:
    """202 with the job and ``Location`` its URL."""
    out = job_out(job)
    return JSONResponse(out.model_dump(mode="json"), status_code=status.HTTP_202_ACCEPTED,
                        headers={"Location": out.url})


@router.get("/jobs", response_model=JobPageOut)
def list_jobs(
    session: SessionDep,
    settings: SettingsDep,
    principal: PrincipalDep,
    state: Annotated[Optional[JobStateName], Query()] = None,
    kind: Annotated[Optional[JobKindName], Query()] = None,
    limit: Annotated[int, Query(ge=1, le=500)] = 50,
    offset: Annotated[int, Query(ge=0, le=DB_INT_MAX)] = 0,
) -> JobPageOut:
    """Jobs, newest first, optionally of one state and kind (annotators and reviewers see an import's
    dataset by name, never its server path)."""
    items, total = jobs.list_jobs(session, JobState(state) if state else None, kind, limit, offset)
    return JobPageOut(items=[job_out(j, principal, settings) for j in items], total=total, limit=limit, offset=offset)


@router.get("/jobs/{job_id}", response_model=JobOut, responses=NOT_FOUND)
def get_job(session: SessionDep, settings: SettingsDep, principal: PrincipalDep, job_id: JobId) -> JobOut:
    """One job: its state, progress and, when done, its result (failed: ``message`` says why). Annotators
    and reviewers see an import's dataset by name (an upload as ``upload <job id>/...``), never a server path."""
    return job_out(jobs.get_job(session, job_id), principal, settings)


@router.get(
    "/jobs/{job_id}/result", response_class=FileResponse, dependencies=[Depends(require_role("admin"))],
    responses={200: {"content": {"application/zip": {}}, "description": "The export's file, or the backup's "
                                                                        "archive."},
               404: {"model": ErrorOut, "description": "No such job, or its file is gone."},
               409: {"model": ErrorOut, "description": "Neither an export nor a backup, or not done yet."}},
)
def job_result(session: SessionDep, settings: SettingsDep, job_id: JobId) -> Response:
    """The file a finished export or backup job wrote, from the store whichever node wrote it (streamed from disk, or
    from a remote store as it is read; only that job's file). An export's is kept ``V3D_EXPORT_KEEP_HOURS`` after it
    was written (older export files are removed here, then 404); a backup's archive until an admin removes it from
    the store. Admins only: a backup holds every password and token hash."""
    job = jobs.get_job(session, job_id)
    if job.kind not in RESULT_FILES or job.state is not JobState.DONE or not job.result:
        raise jobs.JobNotReady(f"job {job_id} is a {job.kind} job in state {job.state.value}: no file to download")
    if not job.result.get("file"):
        raise jobs.JobNotReady(f"job {job_id} wrote no file: {job.result.get(NOTHING) or 'nothing to download'}")
    storage = storage_for(settings)
    if job.kind == "export":
        prune_stored_exports(storage, settings.export_keep_hours)
    key = RESULT_FILES[job.kind](job.result["file"])
    media_type = job.result.get("media_type", "application/octet-stream")
    filename = job.result.get("filename", key.rpartition("/")[2])
    path = storage.local_path(key)
    if path is not None:
        if not path.is_file():
            raise NotFoundError(f"{job.kind} file of job", job_id)
        return FileResponse(path, media_type=media_type, filename=filename)
    try:
        size = storage.stat(key).size
    except FileNotFoundError:
        raise NotFoundError(f"{job.kind} file of job", job_id) from None
    return StreamingResponse(_stored_chunks(storage, key), media_type=media_type,
                             headers={"Content-Length": str(size), "Content-Disposition": _attachment(filename)})


def _stored_chunks(storage: Storage, key: str) -> Iterator[bytes]:
    """The stored file ``key`` in pieces of 1 MiB."""
    with storage.open(key) as stream:
        yield from iter(lambda: stream.read(1 << 20), b"")


def _attachment(filename: str) -> str:
    """``Content-Disposition`` of a download named ``filename`` (as Starlette's ``FileResponse`` writes it)."""
    quoted = quote(filename)
    return f"attachment; filename*=utf-8''{quoted}" if quoted != filename else f'attachment; filename="{filename}"'


@router.post("/recompute", response_model=JobOut, status_code=status.HTTP_202_ACCEPTED)
async def create_recompute(session: SessionDep, principal: AdminDep) -> JSONResponse:
    """Queue a full recompute: every system recomputed with the server's current settings (admission,
    triangulation, reprojections, optimised boxes, doubts and queue figures; calibrations untouched);
    one audit entry, by the admin who queued it."""
    return accepted(await run_in_threadpool(jobs.submit, session, "recompute", {"actor": principal.name}))

