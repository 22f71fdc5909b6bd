"""JSON answers gzip-compressed above a size, never the answers that carry a secret.

:class:`CompressionMiddleware` is Starlette's ``GZipMiddleware`` (answers of at least :data:`MINIMUM_BYTES` to a
client that accepts gzip; images and zips as they are) in front of every route but those whose answers carry a
token or the CSRF token (:data:`SECRET_PATHS`: the login and ``/api/auth/me`` answer ``csrf_token``, user and
token creation answer an API token). Compressing a secret beside text an attacker can choose lets the compressed
length tell the secret (BREACH), so those answers are never compressed; nothing else v3d answers holds a secret.
"""
from __future__ import annotations

from starlette.middleware.gzip import GZipMiddleware
from starlette.types import ASGIApp, Receive, Scope, Send

#: Answers at least this long are compressed (bytes): below it the gzip header and the CPU cost more than they save.
MINIMUM_BYTES = 1024
#: zlib level: 1 compresses the 21 KB system view to 7.3 KB in 0.17 ms of CPU where 6 gives 6.5 KB in 0.31 ms (this
#: machine): on the edits' and pages' path the CPU is what the server is short of, not the kilobyte.
COMPRESS_LEVEL = 1
#: Path prefixes whose answers carry a token or the CSRF token: never compressed.
SECRET_PATHS = ("/api/auth/", "/api/users")


def carries_secret(path: str) -> bool:
    """True for a path whose answers may carry a token or the CSRF token (:data:`SECRET_PATHS`).

    >>> carries_secret("/api/auth/login"), carries_secret("/api/users/ana/tokens"), carries_secret("/api/systems/1")
    (True, True, False)
    """
    return path.startswith(SECRET_PATHS)


class CompressionMiddleware:
    """gzip for HTTP answers of :data:`MINIMUM_BYTES` or more, except those of :func:`carries_secret` paths."""

    def __init__(self, app: ASGIApp) -> None:
        self.app = app
        self.gzip = GZipMiddleware(app, minimum_size=MINIMUM_BYTES, compresslevel=COMPRESS_LEVEL)

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] == "http" and not carries_secret(scope.get("path", "")):
            await self.gzip(scope, receive, send)
        else:
            await self.app(scope, receive, send)
