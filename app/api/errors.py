"""Domain errors to HTTP answers, in one place.

* :class:`~app.core.errors.NotFoundError` and :class:`~app.services.images.serving.ImageUnavailable`: 404
  with the message (it names the missing id or file);
* :class:`~app.core.errors.ForbiddenError`: 403 (e.g. an import path outside the data root);
* :class:`~app.services.transfer.archives.UploadTooLarge`: 413 (an upload above ``V3D_MAX_UPLOAD_MB``);
* :class:`~app.services.jobs.runner.JobNotReady`: 409 (a job's file asked for before it exists);
* :class:`~app.core.errors.DatasetError`: 400, the server-side dataset cannot be imported (the
  message names the file and the field);
* :class:`~app.core.errors.StaleVersionError`: 412 with the resource's current state, its ETag (also
  in the ``ETag`` header) and its newest audit entry, and for a system the entries written since the version the
  ``If-Match`` named, also in words in ``detail`` (``app.api.view_schemas.StaleOut``, shaped from the rows the
  service read after rolling back);
* :class:`~app.core.errors.ConflictError`: 409 with the message and, when known, ``current``;
* :class:`~app.core.errors.InvalidInputError` and
  :class:`~app.geometry.annotations.AnnotationError`: 422 with the message and, when known, ``field``;
* a write that gave up waiting for the database's lock (``sqlalchemy.exc.OperationalError`` that
  ``app.db.session.is_lock_timeout`` recognises: SQLite "database is locked", PostgreSQL ``lock_timeout``,
  after ``V3D_WRITE_LOCK_TIMEOUT_S``): 503 with ``Retry-After`` (:data:`RETRY_AFTER_S`), never 500; nothing was
  written, the same request may be sent again. Any other ``OperationalError`` stays a server error.
* :class:`~app.services.storage.stores.StorageError` (the file store, ``V3D_STORAGE_URL``, unreachable, refusing
  v3d's credentials or not answering within its timeouts): 503 with ``Retry-After`` (:data:`STORE_RETRY_AFTER_S`)
  and the store's words, at once, never a 404 of a missing file or a 500.

Request validation errors keep FastAPI's form (422, ``detail`` a list of ``{loc, msg, type}``), so a
NaN box answers ``loc: ["body", "box", 0]``; an error quotes its ``input`` back only when it is short (at most
:data:`MAX_ECHO_CHARS` as JSON) and holds no secret (:data:`SECRET_FIELDS`: a login without a name does not
answer its password), so that no error answer echoes a body. Every other error's
``detail`` text is cut at :data:`MAX_DETAIL_CHARS`. A body FastAPI cannot read at all (JSON that is not UTF-8, a
broken multipart form), which FastAPI and Starlette answer with an undeclared 400, answers in that form
too: 422, ``loc: ["body"]``, ``type: "body_unparsable"`` (found by ``benchmarks/fuzz.py``).
"""
from __future__ import annotations

import json
from typing import Any

from fastapi import FastAPI, Request, status
from fastapi.encoders import jsonable_encoder
from fastapi.exception_handlers import http_exception_handler
from fastapi.exceptions import RequestValidationError
from fastapi.responses import JSONResponse, Response
from sqlalchemy.exc import OperationalError
from starlette.exceptions import HTTPException as StarletteHTTPException

from app.api.audit_schemas import AuditEntryOut
from app.api.view_schemas import FrameView, StaleOut, SystemStateOut
from app.core.errors import (
    ConflictError,
    DatasetError,
    ForbiddenError,
    InvalidInputError,
    NotFoundError,
    StaleVersionError,
)
from app.db.models import Frame
from app.db.session import is_lock_timeout
from app.geometry.annotations import AnnotationError
from app.services.images.serving import ImageUnavailable
from app.services.jobs.runner import JobNotReady
from app.services.storage.stores import StorageError
from app.services.transfer.archives import UploadTooLarge

#: Longest ``input`` (as JSON, characters) a validation error quotes back; a longer one is left out.
MAX_ECHO_CHARS = 200
#: Longest ``detail`` text of an error answer (characters); the rest is cut (a message never quotes a body whole).
MAX_DETAIL_CHARS = 2000
#: Fields whose values an error never quotes (a login's password, a token, a secret), wherever they appear.
SECRET_FIELDS = frozenset({"password", "token", "secret"})


def shortened(text: str, limit: int = MAX_DETAIL_CHARS) -> str:
    """``text`` cut to ``limit`` characters, saying how much was left out; a lone surrogate a client sent (which no
    UTF-8 answer can hold) written as its escape.

    >>> shortened("abcdef", 3), shortened("a\\ud800")
    ('abc... (3 more characters)', 'a\\\\ud800')
    """
    text = text.encode("utf-8", "backslashreplace").decode("utf-8")
    return text if len(text) <= limit else f"{text[:limit]}... ({len(text) - limit} more characters)"


def _holds_secret(value: Any) -> bool:
    if isinstance(value, dict):
        return any(str(k).lower() in SECRET_FIELDS or _holds_secret(v) for k, v in value.items())
    if isinstance(value, (list, tuple)):
        return any(_holds_secret(v) for v in value)
    return False


def shown_validation_error(error: dict[str, Any]) -> dict[str, Any]:
    """One error of a :class:`RequestValidationError` as the answer shows it: ``type``, ``loc``, ``msg`` (cut at
    :data:`MAX_DETAIL_CHARS`), and ``input`` / ``ctx`` only when each is short
    (at most :data:`MAX_ECHO_CHARS` as JSON) and neither names nor sits at a secret field (:data:`SECRET_FIELDS`).

    >>> shown_validation_error({"type": "missing", "loc": ("body", "name"), "msg": "Field required",
    ...                         "input": {"password": "hunter2"}})
    {'type': 'missing', 'loc': ['body', 'name'], 'msg': 'Field required'}
    >>> shown_validation_error({"type": "int_parsing", "loc": ("query", "limit"), "msg": "m", "input": "x" * 300})
    {'type': 'int_parsing', 'loc': ['query', 'limit'], 'msg': 'm'}
    """
    loc = list(error.get("loc", ()))
    out: dict[str, Any] = {"type": error.get("type"), "loc": loc, "msg": shortened(str(error.get("msg", "")))}
    secret_place = any(str(part).lower() in SECRET_FIELDS for part in loc)
    for key in ("input", "ctx"):
        if key not in error or secret_place or _holds_secret(error[key]) or isinstance(error[key], (bytes, bytearray)):
            continue
        try:
            value = jsonable_encoder(error[key])
            text = json.dumps(value, ensure_ascii=False)
            text.encode("utf-8")  # a lone surrogate cannot be answered (UnicodeEncodeError, a ValueError)
        except (TypeError, ValueError):
            continue
        if len(text) <= MAX_ECHO_CHARS:
            out[key] = value
    return out


async def _validation_error(_: Request, exc: Exception) -> JSONResponse:
    """FastAPI's 422 of a request that fails validation, quoting no long input and no secret
    (:func:`shown_validation_error`)."""
    assert isinstance(exc, RequestValidationError)
    return JSONResponse({"detail": [shown_validation_error(e) for e in exc.errors()]},
                        status_code=status.HTTP_422_UNPROCESSABLE_CONTENT)


def _answer(code: int, exc: Exception, field: str | None = None) -> JSONResponse:
    body: dict[str, object] = {"detail": shortened(str(exc))}
    if field:
        body["field"] = field
    return JSONResponse(body, status_code=code)


async def _not_found(_: Request, exc: Exception) -> JSONResponse:
    return _answer(status.HTTP_404_NOT_FOUND, exc)


async def _forbidden(_: Request, exc: Exception) -> JSONResponse:
    return _answer(status.HTTP_403_FORBIDDEN, exc)


async def _too_large(_: Request, exc: Exception) -> JSONResponse:
    return _answer(status.HTTP_413_CONTENT_TOO_LARGE, exc, getattr(exc, "field", None))


async def _bad_dataset(_: Request, exc: Exception) -> JSONResponse:
    return _answer(status.HTTP_400_BAD_REQUEST, exc, getattr(exc, "field", None))


async def _invalid(_: Request, exc: Exception) -> JSONResponse:
    return _answer(status.HTTP_422_UNPROCESSABLE_CONTENT, exc, getattr(exc, "field", None))


async def _stale(request: Request, exc: Exception) -> JSONResponse:
    assert isinstance(exc, StaleVersionError)
    current = exc.current
    principal = getattr(request.state, "principal", None)
    admin = principal is not None and principal.may("admin")
    changes = [AuditEntryOut.shown(e, admin) for e in exc.changes]
    detail = str(exc)
    if changes:  # what the client did not see, in words: who changed what since the version it named
        detail = shortened(f"{detail}. Since your version: "
                           + "; ".join(f"{c.actor}: {c.summary}" for c in changes))
    body = StaleOut(
        detail=detail, etag=exc.etag,
        current=(FrameView.of_frame(current) if isinstance(current, Frame)
                 else SystemStateOut.of(current) if current is not None else None),  # type: ignore[arg-type]  # current is a Frame or a System: a System here
        last_change=AuditEntryOut.shown(exc.last_change, admin) if exc.last_change is not None else None,
        changes_since=changes,
    )
    return JSONResponse(body.model_dump(mode="json", by_alias=True), status_code=status.HTTP_412_PRECONDITION_FAILED,
                        headers={"ETag": exc.etag, "Cache-Control": "no-cache"})


async def _conflict(_: Request, exc: Exception) -> JSONResponse:
    body = {"detail": str(exc), "current": getattr(exc, "current", None)}
    return JSONResponse(jsonable_encoder(body), status_code=status.HTTP_409_CONFLICT)


#: Seconds a client is asked to wait before sending again a write answered 503 (the database's lock was busy).
RETRY_AFTER_S = 2


async def _database_error(_: Request, exc: Exception) -> JSONResponse:
    """503 + ``Retry-After`` for a lock wait past its timeout; any other operational error re-raised (500)."""
    if not is_lock_timeout(exc):
        raise exc
    return JSONResponse({"detail": "the database is busy with other writes; nothing was changed, send the request "
                                   f"again in {RETRY_AFTER_S} s"},
                        status_code=status.HTTP_503_SERVICE_UNAVAILABLE,
                        headers={"Retry-After": str(RETRY_AFTER_S), "Cache-Control": "no-store"})


#: Seconds a client is asked to wait before sending again a request the file store could not serve (its timeouts and
#: tries, ``app.services.storage.s3``, take about as long).
STORE_RETRY_AFTER_S = 30


async def _store_error(_: Request, exc: Exception) -> JSONResponse:
    """503 + ``Retry-After`` for a store that cannot be used (its words name it and why)."""
    return JSONResponse({"detail": f"{exc}; nothing was changed, send the request again in {STORE_RETRY_AFTER_S} s"},
                        status_code=status.HTTP_503_SERVICE_UNAVAILABLE,
                        headers={"Retry-After": str(STORE_RETRY_AFTER_S), "Cache-Control": "no-store"})


async def _http_error(request: Request, exc: Exception) -> Response:
    """FastAPI's answer to ``HTTPException``, except the 400 that FastAPI and Starlette raise when they
    cannot read a request body ("There was an error parsing the body", "Invalid multipart data."; v3d's
    own code raises no 400 ``HTTPException``): that one becomes the 422 of a malformed body, naming it."""
    if isinstance(exc, StarletteHTTPException) and exc.status_code == status.HTTP_400_BAD_REQUEST:
        cause = exc.__cause__ or exc.__context__
        reason = shortened(f"{exc.detail} ({type(cause).__name__}: {cause})" if cause is not None else str(exc.detail),
                           MAX_ECHO_CHARS)
        return JSONResponse({"detail": [{"type": "body_unparsable", "loc": ["body"],
                                         "msg": f"the body cannot be read: {reason}"}]},
                            status_code=status.HTTP_422_UNPROCESSABLE_CONTENT)
    return await http_exception_handler(request, exc)  # type: ignore[arg-type]  # registered for HTTPException only


def install_error_handlers(app: FastAPI) -> None:
    """Register the mapping of the module docstring on ``app``."""
    app.add_exception_handler(NotFoundError, _not_found)
    app.add_exception_handler(ForbiddenError, _forbidden)
    app.add_exception_handler(ImageUnavailable, _not_found)
    app.add_exception_handler(UploadTooLarge, _too_large)
    app.add_exception_handler(JobNotReady, _conflict)
    app.add_exception_handler(DatasetError, _bad_dataset)
    app.add_exception_handler(InvalidInputError, _invalid)
    app.add_exception_handler(StaleVersionError, _stale)
    app.add_exception_handler(ConflictError, _conflict)
    app.add_exception_handler(AnnotationError, _invalid)
    app.add_exception_handler(StarletteHTTPException, _http_error)
    app.add_exception_handler(OperationalError, _database_error)
    app.add_exception_handler(StorageError, _store_error)
    app.add_exception_handler(RequestValidationError, _validation_error)
