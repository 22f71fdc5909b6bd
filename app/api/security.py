"""Security headers on every answer: a Content-Security-Policy that allows this server's own scripts
only (no inline script, no CDN), and the usual hardening headers.

Inline ``style`` attributes stay allowed (``style-src 'unsafe-inline'``): the pages and Swagger UI set
element styles, which run no code. Images may be ``data:`` or ``blob:`` URLs (the favicon, canvases).
A pure ASGI middleware, so that streamed answers (image bytes, export zips) pass through untouched.
"""
from __future__ import annotations

from fastapi import Response
from starlette.types import ASGIApp, Message, Receive, Scope, Send

#: The policy: everything from this origin, scripts only from files it serves.
CONTENT_SECURITY_POLICY = (
    "default-src 'self'; script-src 'self'; style-src 'self' 'unsafe-inline'; img-src 'self' data: blob:; "
    "connect-src 'self'; font-src 'self'; object-src 'none'; base-uri 'self'; form-action 'self'; "
    "frame-ancestors 'none'"
)

#: Headers added to every HTTP answer that does not set them itself.
SECURITY_HEADERS: dict[str, str] = {
    "Content-Security-Policy": CONTENT_SECURITY_POLICY,
    "X-Content-Type-Options": "nosniff",
    "X-Frame-Options": "DENY",
    "Referrer-Policy": "same-origin",
    "Cross-Origin-Opener-Policy": "same-origin",
}


class SecurityHeadersMiddleware:
    """Adds :data:`SECURITY_HEADERS` to the start of every HTTP response (existing headers win)."""

    def __init__(self, app: ASGIApp) -> None:
        self.app = app
        self._headers = [(k.lower().encode("latin-1"), v.encode("latin-1")) for k, v in SECURITY_HEADERS.items()]

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] != "http":
            await self.app(scope, receive, send)
            return

        async def send_with_headers(message: Message) -> None:
            if message["type"] == "http.response.start":
                headers = list(message.get("headers", []))
                present = {k.lower() for k, _ in headers}
                headers += [(k, v) for k, v in self._headers if k not in present]
                message = {**message, "headers": headers}
            await send(message)

        await self.app(scope, receive, send_with_headers)


def no_store(response: Response) -> None:
    """Route dependency: the answer carries ``Cache-Control: no-store``, so that no browser, proxy or
    disk cache keeps it. For answers that hold a secret: API tokens (``/api/users``) and the session's
    CSRF token (``/api/auth``)."""
    response.headers["Cache-Control"] = "no-store"
