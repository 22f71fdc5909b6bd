"""Request bodies are bounded before they are parsed, and while they stream (issue 15).

:class:`BodyLimitMiddleware` is a pure ASGI middleware in front of every route: a multipart body (an
upload: ``POST /api/imports``, ``POST /api/evaluations/monocular``) may carry up to ``V3D_MAX_UPLOAD_MB``,
any other body (JSON) up to ``V3D_MAX_JSON_KB``. A ``Content-Length`` above the limit is answered 413 at
once, before a byte of the body is read; a body without one (chunked) or lying about it is counted as it
streams and answered 413 as soon as it passes the limit, so that no route (FastAPI's JSON parsing, the
multipart parser's spooling to disk) ever holds more than the limit. :data:`TOO_LARGE` is the OpenAPI
answer of every route.
"""
from __future__ import annotations

from typing import Any

from fastapi import HTTPException
from starlette.responses import JSONResponse
from starlette.types import ASGIApp, Message, Receive, Scope, Send

from app.api.schemas import ErrorOut

#: The OpenAPI ``responses`` entry of every route (``app.api.main``).
TOO_LARGE: dict[int | str, dict[str, Any]] = {
    413: {"model": ErrorOut, "description": "The body is larger than V3D_MAX_JSON_KB (JSON) or V3D_MAX_UPLOAD_MB "
                                            "(an upload): refused before it is parsed."},
}


class BodyTooLarge(HTTPException):
    """Raised from ``receive`` when the streamed body passes the limit: an HTTP 413 wherever it surfaces
    (FastAPI re-raises HTTP exceptions met while parsing a body instead of turning them into 400)."""

    def __init__(self, limit: int, setting: str) -> None:
        size = f"{limit / 1024:g} KB" if setting == "V3D_MAX_JSON_KB" else f"{limit / 2**20:g} MB"
        super().__init__(status_code=413, detail=f"the request body is larger than {size} ({setting})",
                         headers={"Connection": "close"})


def body_limit(content_type: str, max_json_bytes: int, max_upload_bytes: int) -> tuple[int, str]:
    """The limit (bytes) and the setting naming it for a request of ``content_type``.

    >>> body_limit("multipart/form-data; boundary=x", 1024, 10)
    (10, 'V3D_MAX_UPLOAD_MB')
    >>> body_limit("application/json", 1024, 10)
    (1024, 'V3D_MAX_JSON_KB')
    """
    if content_type.lower().startswith("multipart/"):
        return max_upload_bytes, "V3D_MAX_UPLOAD_MB"
    return max_json_bytes, "V3D_MAX_JSON_KB"


class BodyLimitMiddleware:
    """413 for an HTTP request body above its limit (:func:`body_limit`), declared or streamed."""

    def __init__(self, app: ASGIApp, *, max_json_bytes: int, max_upload_bytes: int) -> None:
        self.app = app
        self.max_json_bytes = max_json_bytes
        self.max_upload_bytes = max_upload_bytes

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] != "http":
            await self.app(scope, receive, send)
            return
        headers = {k.decode("latin-1").lower(): v.decode("latin-1") for k, v in scope.get("headers", [])}
        limit, setting = body_limit(headers.get("content-type", ""), self.max_json_bytes, self.max_upload_bytes)
        declared = headers.get("content-length", "")
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
