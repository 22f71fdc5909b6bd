"""The server's edge, in front of every route: how many headers a request may carry, and how an answer leaves.

The HTTP parser bounds the head of a request (its request line and headers together, ``V3D_MAX_HEADER_KB``: uvicorn's
h11 implementation, ``app.cli.serve.server_options``) and closes idle connections between requests
(``V3D_KEEP_ALIVE_S``). :class:`EdgeMiddleware`, the outermost middleware, adds what the server has no option for:

* a request of more than ``V3D_MAX_HEADER_COUNT`` header lines is answered **431** before any route sees it;
* every answer leaves in pieces of at most :data:`PIECE_BYTES`. The server writes a piece only once the client has
  taken the one before (its transport stops accepting writes above its high-water mark, and the next ``send`` waits
  for it to drain), and each wait is bounded by ``V3D_SEND_TIMEOUT_S``: a client that stops reading is disconnected
  then, and until then holds at most about two pieces of the server's memory besides what the kernel buffers. Without
  this an answer was written into the connection whole, and forty clients asking for a 17 MB page of the audit log
  and never reading it held 1.2 GB for as long as they stayed.
"""
from __future__ import annotations

import asyncio
import logging

from starlette.responses import JSONResponse
from starlette.types import ASGIApp, Message, Receive, Scope, Send

#: The largest piece of an answer written at once (bytes): the size of the transport's own high-water mark, so that a
#: client that reads nothing holds about two pieces.
PIECE_BYTES = 64 * 1024

log = logging.getLogger(__name__)


class _ClientNotReading(Exception):
    """The client took no piece of the answer within the send timeout: the answer is abandoned."""


class EdgeMiddleware:
    """Refuse a request of more than ``max_headers`` header lines (431); send every answer in pieces of at most
    :data:`PIECE_BYTES`, each within ``send_timeout_s`` seconds (module docstring)."""

    def __init__(self, app: ASGIApp, *, max_headers: int, send_timeout_s: float) -> None:
        self.app, self.max_headers, self.send_timeout_s = app, max_headers, send_timeout_s

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] != "http":
            await self.app(scope, receive, send)
            return
        if len(scope["headers"]) > self.max_headers:
            refusal = JSONResponse({"detail": f"the request carries {len(scope['headers'])} header lines, more than "
                                              f"{self.max_headers} (V3D_MAX_HEADER_COUNT)"},
                                   status_code=431, headers={"Connection": "close"})
            await refusal(scope, receive, send)
            return

        async def send_in_pieces(message: Message) -> None:
            body = message.get("body", b"") if message["type"] == "http.response.body" else b""
            if len(body) <= PIECE_BYTES:
                await self._send(send, message)
                return
            more = message.get("more_body", False)
            for start in range(0, len(body), PIECE_BYTES):
                last = start + PIECE_BYTES >= len(body)
                await self._send(send, {"type": "http.response.body", "body": body[start:start + PIECE_BYTES],
                                        "more_body": more or not last})

        try:
            await self.app(scope, receive, send_in_pieces)
        except _ClientNotReading:
            # The server closes the connection of an answer left incomplete; nothing more is sent to this client.
            log.warning("%s %s: the client read nothing for %.0f s; its answer is abandoned", scope.get("method"),
                        scope.get("path"), self.send_timeout_s)

    async def _send(self, send: Send, message: Message) -> None:
        try:
            async with asyncio.timeout(self.send_timeout_s):
                await send(message)
        except TimeoutError:
            raise _ClientNotReading() from None
