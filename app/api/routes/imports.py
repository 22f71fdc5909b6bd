"""``/api/imports``: import a dataset as a background job, from a path under the data root (JSON) or
from an uploaded zip (multipart).

Both answer 202 with the queued job (``Location: /api/jobs/{id}``); the job's progress and report are
read at ``GET /api/jobs/{id}``. What can be checked at once is answered at once: a path outside the data
root (403), a missing path (400), a too large upload (413, counted while it streams to disk), an unsafe
or broken zip (400 naming the member: ``app.services.transfer.archives``). Errors inside the dataset's files fail
the job with a message naming the file and the field. A dataset whose games are stored already is refused
(409 naming them) unless the import names how to merge them (``merge``).
"""
from __future__ import annotations

import secrets
import shutil
import time
from collections.abc import AsyncGenerator, AsyncIterator
from pathlib import Path
from typing import Any

from fastapi import APIRouter, Depends, Request, status
from fastapi.concurrency import run_in_threadpool
from fastapi.exceptions import RequestValidationError
from fastapi.responses import JSONResponse
from pydantic import ValidationError
from sqlalchemy.orm import Session
from starlette.datastructures import UploadFile
from starlette.formparsers import MultiPartException, MultiPartParser

from app.api.auth import AdminDep, require_role
from app.api.deps import SessionDep, SettingsDep
from app.api.job_schemas import ImportIn, ImportOptions, ImportUploadIn, JobOut
from app.api.routes.jobs import accepted
from app.api.schemas import ErrorOut
from app.core.config import Settings, jobs_dir
from app.core.errors import ConflictError, DatasetError, InvalidInputError
from app.datasets.files import refuse_links_out
from app.services.jobs import runner as jobs
from app.services.jobs.work import import_params
from app.services.storage import storage_for
from app.services.storage.datasets import DatasetFiles
from app.services.storage.stores import KeyTooLong
from app.services.transfer.archives import ArchiveLimits, UploadTooLarge, unpack_zip, upload_limit, upload_limit_bytes
from app.services.transfer.data_root import confined_path
from app.services.transfer.import_formats import check_upload_layout, import_format, stored_games_refusal
from app.services.transfer.merging import MERGE_MODES

router = APIRouter(prefix="/imports", tags=["imports"], dependencies=[Depends(require_role("admin"))])

_BODY = {
    "required": True,
    "content": {
        "application/json": {"schema": ImportIn.model_json_schema()},
        "multipart/form-data": {"schema": ImportUploadIn.model_json_schema()},
    },
}


def _body_errors(exc: ValidationError, prefix: tuple[str, ...] = ("body",)) -> RequestValidationError:
    """A pydantic error as FastAPI's 422 (``loc`` starting with ``body``)."""
    return RequestValidationError([{**e, "loc": (*prefix, *e["loc"])} for e in exc.errors(include_url=False)])


async def _limited(stream: AsyncIterator[bytes], limit: int) -> AsyncGenerator[bytes, None]:
    size = 0
    async for chunk in stream:
        size += len(chunk)
        if size > limit:
            raise UploadTooLarge(limit, "file")
        yield chunk


def _upload_folder(settings: Settings) -> Any:
    return jobs_dir(settings) / "uploads" / f"{time.strftime('%Y%m%d-%H%M%S')}-{secrets.token_hex(4)}"


async def _upload_params(request: Request, settings: Settings) -> dict[str, Any]:
    """Receive the multipart form (the body counted against ``V3D_MAX_UPLOAD_MB`` as it arrives; the file
    part spooled to disk beyond 1 MB), check its fields and the file against its format's own limit
    (``ImportFormat.upload_limit``), unpack the zip safely into a folder of its own under the jobs folder, and
    return the import job's params."""
    limit = upload_limit_bytes(settings)
    declared = request.headers.get("content-length")
    if declared is not None and declared.isdigit() and int(declared) > limit:
        raise UploadTooLarge(limit, "file")
    try:
        form = await MultiPartParser(request.headers, _limited(request.stream(), limit), max_files=1,
                                     max_fields=10).parse()
    except MultiPartException as exc:
        raise InvalidInputError(f"malformed multipart body: {exc.message}", field="file") from None
    try:
        upload = form.get("file")
        if not isinstance(upload, UploadFile):
            raise InvalidInputError("a zip file is required in the form field 'file'", field="file")
        fields: dict[str, Any] = {k: v for k, v in form.multi_items() if k != "file"}
        if "flip" in fields:
            fields["flip"] = [c.strip() for c in str(fields["flip"]).split(",") if c.strip()]
        try:
            options = ImportOptions.model_validate(fields)
        except ValidationError as exc:
            raise _body_errors(exc) from None
        limit, setting = upload_limit(settings, import_format(options.kind).upload_limit)
        if (upload.size or 0) > limit:  # a format bounded below the route's limit, which held while it streamed
            raise UploadTooLarge(limit, "file", setting)
        folder = _upload_folder(settings)
        limits = ArchiveLimits.from_settings(settings)
        await run_in_threadpool(unpack_zip, upload.file, folder, limits, where=upload.filename or "upload.zip")
    finally:
        await form.close()
    return import_params(options.kind, folder, width=options.width, height=options.height,
                         from_lines=options.from_lines, flip=options.flip, upload=True, merge=options.merge,
                         source=options.source, name=upload.filename,
                         upload_key=DatasetFiles.from_settings(settings).upload_key(folder))


async def _path_params(request: Request, settings: Settings) -> dict[str, Any]:
    """The JSON body: a path confined to the data root (403 outside it), which must exist (400)."""
    raw = await request.body()
    try:
        body = ImportIn.model_validate_json((raw or b"null").decode("utf-8"))
    except UnicodeDecodeError as exc:
        raise InvalidInputError(f"the body is not UTF-8 JSON ({exc.reason} at byte {exc.start})",
                                field="body") from None
    except ValidationError as exc:
        raise _body_errors(exc) from None
    path = confined_path(body.path, settings.data_root)
    if not path.exists():
        raise DatasetError(body.path, None, "no such file or folder under the data root")
    await run_in_threadpool(refuse_links_out, path)  # a link leading out of the dataset: 400 at once
    return import_params(body.kind, path, width=body.width, height=body.height, from_lines=body.from_lines,
                         flip=body.flip, merge=body.merge, source=body.source)


def _store_upload(settings: Settings, key: str, folder: Path, name: str | None) -> None:
    """Keep the unpacked upload ``folder`` (the zip ``name`` as sent) in the store as ``key``, all or nothing; a
    remote store's upload leaves this node's jobs folder (only scratch then): the node that runs the import fetches
    it. A member whose key the store cannot hold is refused naming it (400); a store that fails answers 503
    (``app.api.errors``); either way the upload is removed and no job is made."""
    storage = storage_for(settings)
    try:
        storage.put_tree(key, folder)  # all or nothing: no object is left of an upload refused here
    except KeyTooLong as exc:
        shutil.rmtree(folder, ignore_errors=True)
        member = exc.key.removeprefix(key.rstrip("/") + "/")
        raise DatasetError(f"{name or 'upload.zip'}!{member}", None,
                           f"its name is too long to be kept in the file store ({exc.size:,} bytes with the "
                           f"folder the upload is kept in; the store holds at most {exc.limit:,}): shorten the "
                           "member's folders or name") from None
    except BaseException:
        shutil.rmtree(folder, ignore_errors=True)  # no job will read it
        raise
    if storage.local_path(key) is None:
        shutil.rmtree(folder, ignore_errors=True)


def _refuse_stored_games(session: Session, params: dict[str, Any], settings: Settings) -> None:
    """409 naming the input's games that are stored already, when the import names no ``merge`` and the input is
    valid (``import_formats.stored_games_refusal``; an upload's folder is removed: no job will read it). An input
    that cannot be imported is left to the job, which fails naming the file and the field, as before."""
    if params.get("merge") is not None:
        return
    try:
        refusal = stored_games_refusal(session, params["kind"], params["path"], params, settings)
    except DatasetError:
        return
    if refusal is not None:
        if params.get("upload"):
            shutil.rmtree(params["path"], ignore_errors=True)
        # the ways to merge, with their words, so that a page offers the choice without a list of its own
        raise ConflictError(refusal[0], current={"games": refusal[1], "merge_modes": MERGE_MODES})


@router.post(
    "", response_model=JobOut, status_code=status.HTTP_202_ACCEPTED, openapi_extra={"requestBody": _BODY},
    responses={400: {"model": ErrorOut, "description": "A missing path, a symbolic link in the dataset leading out of "
                                                       "it, or an unsafe or broken zip (the member named)."},
               403: {"model": ErrorOut, "description": "The path is outside the data root (V3D_DATA_ROOT)."},
               503: {"model": ErrorOut, "description": "The file store (V3D_STORAGE_URL) cannot be used now (said in "
                                                       "words, with Retry-After); nothing was stored."},
               409: {"description": "The dataset's games are stored already and no merge was named: `detail` names "
                                    "them, `current.games` lists them, `current.merge_modes` the ways to merge (in "
                                    "words); nothing was stored."},
               413: {"model": ErrorOut, "description": "The upload is larger than V3D_MAX_UPLOAD_MB."},
               422: {"description": "Invalid fields (named)."}},
)
async def create_import(request: Request, session: SessionDep, settings: SettingsDep,
                        principal: AdminDep) -> JSONResponse:
    """Queue the import of a SoccerNet-v3, SoccerNet-v3D or SoccerNet-calibration tree or an ISSIA folder
    (idempotent: importing the same tree again changes nothing). Answers 202 with the job; its
    ``Location`` is ``/api/jobs/{id}``, which shows the progress and, when done, the import's counts.

    * ``application/json`` ``{"kind", "path", ...}``: ``path`` is absolute or relative to the data root
      (``V3D_DATA_ROOT``); 403 when it lies outside it (or no root is set), without saying whether it
      exists; 400 when a symbolic link inside the dataset leads out of it (the import reads only inside
      its own folder).
    * ``multipart/form-data`` with ``file`` (a zip of the dataset) and ``kind`` (and the options): at
      most ``V3D_MAX_UPLOAD_MB`` (413), unpacked after checking every member (400 naming a member with an
      unsafe name, a link, a file named like an image that is not a PNG or JPEG within V3D_MAX_IMAGE_PIXELS;
      too many members or bytes uncompressed), then kept in the store (``V3D_STORAGE_URL``), from which any
      node's runner reads it.

    A dataset whose games are stored already is refused (409 naming them) unless ``merge`` says how to merge them
    (``keep-newer``: the stored labels and decisions changed after the newest change the file holds are kept;
    ``overwrite``: the file's replace them); a merge writes one audit entry per stored system it changes
    (revertible) and sets a decision from the file only saying so (``app.services.transfer.merging``).

    The import is one audit entry, by the admin who queued it.
    """
    if request.headers.get("content-type", "").startswith("multipart/form-data"):
        params = await _upload_params(request, settings)
        try:  # an upload that is not of its kind is refused now, in words, rather than by a job naming a server folder
            await run_in_threadpool(check_upload_layout, params["kind"], Path(params["path"]),
                                    str(params.get("name") or "upload.zip"))
        except InvalidInputError:
            shutil.rmtree(params["path"], ignore_errors=True)
            raise
    else:
        params = await _path_params(request, settings)
    await run_in_threadpool(_refuse_stored_games, session, params, settings)
    if params.get("upload_key"):  # kept in the store, where the node that runs the job reads it
        await run_in_threadpool(_store_upload, settings, params["upload_key"], Path(params["path"]),
                                params.get("name"))
    params["actor"] = principal.name
    job = await run_in_threadpool(jobs.submit, session, "import", params)
    return accepted(job)

