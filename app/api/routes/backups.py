"""``POST /api/backups``: a backup of the whole deployment as a background job (admins only).

The job (``app.services.jobs.work.run_backup``) takes one consistent snapshot of every table and copies the stored
objects it names into one archive, as ``v3d backup`` does; ``GET /api/jobs/{id}`` follows it and, when it is done,
its ``result_url`` (``GET /api/jobs/{id}/result``, admins only) downloads the archive. The archive holds every
password and API token hash: keep it as a secret (docs/deploy.md, "Backups").
"""
from __future__ import annotations

from typing import Annotated, Optional

from fastapi import APIRouter, Body, status
from fastapi.concurrency import run_in_threadpool
from fastapi.responses import JSONResponse

from app.api.auth import AdminDep
from app.api.deps import SessionDep, SettingsDep
from app.api.job_schemas import BackupIn, JobOut
from app.api.routes.jobs import accepted
from app.api.schemas import ErrorOut
from app.core.errors import ConflictError
from app.services.jobs import runner as jobs
from app.services.jobs.work import backup_room_refusal

router = APIRouter(tags=["jobs"])


@router.post("/backups", response_model=JobOut, status_code=status.HTTP_202_ACCEPTED,
             responses={409: {"model": ErrorOut, "description": "The jobs folder's or the folder store's disk has "
                                                               "less room than the last backup took (said in words); "
                                                               "nothing was queued."}})
async def create_backup(session: SessionDep, settings: SettingsDep, principal: AdminDep,
                        body: Annotated[Optional[BackupIn], Body()] = None) -> JSONResponse:
    """Queue a backup of the whole deployment (every table in one snapshot, the stored files it names) into one zip
    with ``manifest.json``; 202 with the job. Its archive is downloaded by an admin from the job's ``result_url``.
    The store keeps the ``V3D_BACKUPS_KEPT`` newest archives (the oldest removed once a new one is complete); 409 when
    the disk lacks room for the last one's size."""
    refusal = await run_in_threadpool(backup_room_refusal, settings)
    if refusal is not None:
        raise ConflictError(refusal)
    params = {"actor": principal.name, "local_files": (body or BackupIn()).local_files}
    return accepted(await run_in_threadpool(jobs.submit, session, "backup", params))
