"""Domain errors to HTTP answers, in one place.

* :class:`~app.services.errors.NotFoundError` and :class:`~app.services.views.ImageUnavailable`: 404
  with the message (it names the missing id or file);
* :class:`~app.services.errors.ForbiddenError`: 403 (e.g. an import path outside the data root);
* :class:`~app.services.errors.DatasetError`: 400, the server-side dataset cannot be imported (the
  message names the file and the field);
* :class:`~app.services.errors.InvalidInputError` and
  :class:`~app.geometry.annotations.AnnotationError`: 422 with the message and, when known, ``field``.

Request validation errors keep FastAPI's form (422, ``detail`` a list of ``{loc, msg, type}``), so a
NaN box answers ``loc: ["body", "box", 0]``.
"""
from __future__ import annotations

from fastapi import FastAPI, Request, status
from fastapi.responses import JSONResponse

from app.geometry.annotations import AnnotationError
from app.services.errors import DatasetError, ForbiddenError, InvalidInputError, NotFoundError
from app.services.views import ImageUnavailable


def _answer(code: int, exc: Exception, field: str | None = None) -> JSONResponse:
    body: dict[str, object] = {"detail": str(exc)}
    if field:
        body["field"] = field
    return JSONResponse(body, status_code=code)


async def _not_found(_: Request, exc: Exception) -> JSONResponse:
    return _answer(status.HTTP_404_NOT_FOUND, exc)


async def _forbidden(_: Request, exc: Exception) -> JSONResponse:
    return _answer(status.HTTP_403_FORBIDDEN, exc)


async def _bad_dataset(_: Request, exc: Exception) -> JSONResponse:
    return _answer(status.HTTP_400_BAD_REQUEST, exc, getattr(exc, "field", None))


async def _invalid(_: Request, exc: Exception) -> JSONResponse:
    return _answer(status.HTTP_422_UNPROCESSABLE_CONTENT, exc, getattr(exc, "field", None))


def install_error_handlers(app: FastAPI) -> None:
    """Register the mapping of the module docstring on ``app``."""
    app.add_exception_handler(NotFoundError, _not_found)
    app.add_exception_handler(ForbiddenError, _forbidden)
    app.add_exception_handler(ImageUnavailable, _not_found)
    app.add_exception_handler(DatasetError, _bad_dataset)
    app.add_exception_handler(InvalidInputError, _invalid)
    app.add_exception_handler(AnnotationError, _invalid)
