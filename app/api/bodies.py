"""Request bodies are bounded by the route they are sent to, before they are parsed and while they
stream (never by what the client's ``Content-Type`` says, which a client chooses).

:class:`BodyLimitMiddleware` is a pure ASGI middleware in front of every route. It finds the route a
request goes to and the media types that route takes (:func:`route_media_types`: what its OpenAPI request
body declares, derived from the route itself, so that the table cannot drift from the routes):

* a body of a type the route does not take (multipart to a JSON route, ``text/plain``, a body without a
  ``Content-Type`` to a JSON route) is answered **415 before a byte of it is read** (a body: a
  ``Content-Length`` above 0, or chunked); a route that takes no body accepts a JSON one and ignores it;
* a ``multipart/form-data`` body to an **upload route** (one that takes multipart: :func:`upload_routes`,
  today ``POST /api/imports`` and ``POST /api/evaluations/monocular``) may carry up to the route's own limit: the
  setting it declares (:data:`UPLOAD_LIMIT` in its ``openapi_extra``: the monocular benchmark's predictions
  ``V3D_MAX_PREDICTIONS_MB``), never more than ``V3D_MAX_UPLOAD_MB``, which bounds a route that declares none
  (``app.services.transfer.archives.upload_limit``); every other body, whatever its declared type, up to
  ``V3D_MAX_JSON_KB``.

A ``Content-Length`` above the limit is answered 413 at once; a body without one (chunked) or lying about it
is counted as it streams and answered 413 as soon as it passes the limit, so that no route (FastAPI's JSON
parsing, the multipart parser's spooling to disk) ever holds more than the limit. :data:`BODY_REFUSED` is the
OpenAPI answer of every route (413, 415). Refusals close the connection (the unread body is never drained).
"""
from __future__ import annotations

from collections.abc import Sequence
from typing import Any, Optional

from fastapi import HTTPException
from fastapi.routing import APIRoute, RouteContext, iter_route_contexts
from starlette.responses import JSONResponse
from starlette.routing import BaseRoute, Match
from starlette.types import ASGIApp, Message, Receive, Scope, Send

from app.api.schemas import ErrorOut
from app.core.config import Settings
from app.services.transfer.archives import MAX_UPLOAD_SETTING, upload_limit

#: The media type of JSON bodies, and of uploads (the only type that may use ``V3D_MAX_UPLOAD_MB``).
JSON_TYPE, UPLOAD_TYPE = "application/json", "multipart/form-data"

#: The OpenAPI extension by which an upload route declares the setting (MB) bounding its uploads below
#: ``V3D_MAX_UPLOAD_MB``: ``openapi_extra={UPLOAD_LIMIT: "V3D_MAX_PREDICTIONS_MB"}`` (shown in ``/docs`` too).
UPLOAD_LIMIT = "x-v3d-upload-limit"

#: The OpenAPI ``responses`` entries of every route (``app.api.main``).
BODY_REFUSED: dict[int | str, dict[str, Any]] = {
    413: {"model": ErrorOut, "description": "The body is larger than V3D_MAX_JSON_KB (JSON) or the upload route's "
                                            "limit (V3D_MAX_UPLOAD_MB, or the setting named by the operation's "
                                            "x-v3d-upload-limit): refused before it is parsed, or as soon as that "
                                            "much has arrived."},
    415: {"model": ErrorOut, "description": "The body's Content-Type is not one this route takes (e.g. multipart to "
                                            "a JSON route): refused before it is read."},
}


class BodyTooLarge(HTTPException):
    """Raised from ``receive`` when the streamed body passes the limit: an HTTP 413 wherever it surfaces
    (FastAPI re-raises HTTP exceptions met while parsing a body instead of turning them into 400)."""

    def __init__(self, limit: int, setting: str) -> None:
        size = f"{limit / 1024:g} KB" if setting == "V3D_MAX_JSON_KB" else f"{limit / 2**20:g} MB"
        super().__init__(status_code=413, detail=f"the request body is larger than {size} ({setting})",
                         headers={"Connection": "close"})


def media_type(content_type: str) -> str:
    """The media type of a ``Content-Type`` header, lower case, without parameters (``""`` when absent).

    >>> media_type("Multipart/Form-Data; boundary=x"), media_type("")
    ('multipart/form-data', '')
    """
    return content_type.split(";", 1)[0].strip().lower()


def is_json(media: str) -> bool:
    """Whether FastAPI parses a body of ``media`` as JSON (``application/json``, ``application/*+json``).

    >>> is_json("application/json"), is_json("application/merge-patch+json"), is_json("text/plain")
    (True, True, False)
    """
    return media == JSON_TYPE or (media.startswith("application/") and media.endswith("+json"))


def route_media_types(route: BaseRoute | RouteContext) -> frozenset[str]:
    """The media types of the bodies ``route`` takes, as its OpenAPI operation declares them: the
    ``requestBody`` of its ``openapi_extra`` when it states one (a route that reads its body itself, such as
    ``POST /api/imports``), else its body parameters' (FastAPI: a model or ``Body`` is JSON, ``Form``
    ``application/x-www-form-urlencoded``, ``File`` / ``UploadFile`` ``multipart/form-data``); empty for a route
    without a body and for anything that is not an API route (static files, pages). ``route``: a route or
    FastAPI's context of an included one (``fastapi.routing.iter_route_contexts``)."""
    route = getattr(route, "original_route", route)
    if not isinstance(route, APIRoute):
        return frozenset()
    declared = ((route.openapi_extra or {}).get("requestBody") or {}).get("content")
    if declared:
        return frozenset(media_type(m) for m in declared)
    if route.body_field is None:
        return frozenset()
    return frozenset({media_type(getattr(route.body_field.field_info, "media_type", JSON_TYPE))})


def declared_upload_limit(route: BaseRoute | RouteContext) -> str:
    """The setting (its environment name) that bounds the uploads of ``route``: the one its ``openapi_extra``
    declares under :data:`UPLOAD_LIMIT`, else ``V3D_MAX_UPLOAD_MB``."""
    route = getattr(route, "original_route", route)
    declared = (getattr(route, "openapi_extra", None) or {}).get(UPLOAD_LIMIT)
    return str(declared) if declared else MAX_UPLOAD_SETTING


def upload_routes(routes: Sequence[BaseRoute]) -> list[tuple[str, str]]:
    """``(method, path)`` of every route of an app's ``routes`` (included routers walked) that takes an upload
    (multipart), sorted: those whose bodies may reach ``V3D_MAX_UPLOAD_MB``."""
    return sorted((m, str(c.path)) for c in iter_route_contexts(routes) if UPLOAD_TYPE in route_media_types(c)
                  for m in (c.methods or ()))


def route_of(routes: Sequence[BaseRoute], scope: Scope) -> Optional[RouteContext]:
    """The route of an app's ``routes`` (included routers walked) that will answer ``scope``, as the router
    matches: the first full match, else the first whose path matches with another method (405); None: a 404."""
    partial = None
    for route in iter_route_contexts(routes):
        match, _ = route.matches(scope)
        if match is Match.FULL:
            return route
        if match is Match.PARTIAL and partial is None:
            partial = route
    return partial


def body_policy(takes: frozenset[str], content_type: str, max_json_bytes: int,
                upload: tuple[int, str]) -> Optional[tuple[int, str]]:
    """The limit (bytes) and the setting naming it for a body of ``content_type`` sent to a route that takes
    ``takes`` (:func:`route_media_types`) and whose uploads are bounded by ``upload`` (bytes, setting), or None
    when the route does not take that type (415).

    >>> up = (10, "V3D_MAX_UPLOAD_MB")
    >>> body_policy(frozenset({"multipart/form-data"}), "multipart/form-data; boundary=x", 1024, up)
    (10, 'V3D_MAX_UPLOAD_MB')
    >>> body_policy(frozenset({"application/json"}), "multipart/form-data; boundary=x", 1024, up) is None
    True
    >>> body_policy(frozenset(), "application/json", 1024, up), body_policy(frozenset(), "text/plain", 1024, up)
    ((1024, 'V3D_MAX_JSON_KB'), None)
    """
    media = media_type(content_type)
    if media == UPLOAD_TYPE and UPLOAD_TYPE in takes:
        return upload
    if media in takes or (is_json(media) and (not takes or JSON_TYPE in takes)):
        return max_json_bytes, "V3D_MAX_JSON_KB"
    return None


def _refusal(status: int, detail: str) -> JSONResponse:
    return JSONResponse({"detail": detail}, status_code=status, headers={"Connection": "close"})


class BodyLimitMiddleware:
    """415 for a body of a type its route does not take, 413 for one above its route's limit
    (:func:`body_policy`), declared or streamed. ``routes``: the app's route list (read at each request, so
    routes added after the middleware count); ``settings``: the limits (``V3D_MAX_JSON_KB``, ``V3D_MAX_UPLOAD_MB``
    and those the upload routes declare)."""

    def __init__(self, app: ASGIApp, *, routes: Sequence[BaseRoute], settings: Settings) -> None:
        self.app = app
        self.routes = routes
        self.settings = settings
        self.max_json_bytes = int(settings.max_json_kb * 1024)

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] != "http":
            await self.app(scope, receive, send)
            return
        headers = {k.decode("latin-1").lower(): v.decode("latin-1") for k, v in scope.get("headers", [])}
        declared = headers.get("content-length", "").strip()
        has_body = "chunked" in headers.get("transfer-encoding", "").lower() or (declared not in ("", "0"))
        content_type = headers.get("content-type", "")
        route = route_of(self.routes, scope) if has_body else None  # no body: nothing to look up
        takes = route_media_types(route) if route is not None else frozenset()
        upload = upload_limit(self.settings, declared_upload_limit(route) if route is not None else MAX_UPLOAD_SETTING)
        policy = body_policy(takes, content_type, self.max_json_bytes, upload)
        if policy is None:
            if has_body:
                wanted = " or ".join(sorted(takes)) or "no body (or JSON, ignored)"
                shown = media_type(content_type)[:100] or "a body without a Content-Type"
                await _refusal(415, f"this route takes {wanted}, not {shown}")(scope, receive, send)
                return
            policy = self.max_json_bytes, "V3D_MAX_JSON_KB"
        limit, setting = policy
        if declared.isdigit() and int(declared) > limit:
            await self._refuse(scope, receive, send, limit, setting)
            return
        received = 0
        started = False

        async def counted_receive() -> Message:
            nonlocal received
            message = await receive()
            if message["type"] == "http.request":
                received += len(message.get("body", b""))
                if received > limit:
                    raise BodyTooLarge(limit, setting)
            return message

        async def watched_send(message: Message) -> None:
            nonlocal started
            if message["type"] == "http.response.start":
                started = True
            await send(message)

        try:
            await self.app(scope, counted_receive, watched_send)
        except BodyTooLarge:
            if started:  # an answer already began (a route that answers before reading all): cut it short
                raise
            await self._refuse(scope, receive, send, limit, setting)

    @staticmethod
    async def _refuse(scope: Scope, receive: Receive, send: Send, limit: int, setting: str) -> None:
        exc = BodyTooLarge(limit, setting)
        await JSONResponse({"detail": exc.detail}, status_code=413, headers=exc.headers)(scope, receive, send)
