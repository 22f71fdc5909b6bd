"""The authentication layer: who sends each request, put on ``request.state.principal``
(:class:`app.api.auth.Principal`, read by ``current_principal`` and ``require_role``).

Two ways in, resolved once per request by :class:`AuthenticationMiddleware`:

* ``Authorization: Bearer <token>``: an API token (``app.services.accounts.users``: only its SHA-256 is stored),
  for scripts. A request with this header is judged by it alone (a wrong token is anonymous).
* the browser's session cookie ``v3d_session`` (Starlette's ``SessionMiddleware``: JSON signed with
  itsdangerous by the key of ``app.services.accounts.users.session_secret``; ``HttpOnly``, ``SameSite=Strict``,
  ``Secure`` with ``V3D_SECURE_COOKIES``; it ends ``V3D_SESSION_MAX_AGE_S`` after the login itself (the
  login time is signed into the cookie: re-signing it on every answer does not extend it), at logout and
  when the user is disabled). It holds the user id, the user's session generation, the login time and
  the session's CSRF token.

Every path under ``/api`` but :data:`PUBLIC_API_PATHS` needs a principal: without one the answer is
401 before anything else is looked at (body, CSRF header, role). A write (POST, PUT, PATCH, DELETE)
authenticated by the session cookie must carry the session's CSRF token (synchronizer token pattern) in
the :data:`CSRF_HEADER` header, else 403 naming the header; token requests need none (a browser never
adds an ``Authorization`` header by itself). Pages, static files, ``/docs`` and ``/openapi.json`` are
public (the pages then ask the API, and send the person to the login page on 401).
"""
from __future__ import annotations

import secrets
import time
from typing import Any, Callable, Optional

from fastapi import Depends, Security
from fastapi.security import APIKeyCookie, HTTPBearer
from starlette.concurrency import run_in_threadpool
from starlette.middleware.sessions import SessionMiddleware
from starlette.requests import HTTPConnection
from starlette.responses import JSONResponse
from starlette.types import ASGIApp, Receive, Scope, Send

from app.api.auth import Principal, current_principal
from app.db.session import reads_on_their_own
from app.services.accounts import users

#: The session cookie's name.
SESSION_COOKIE = "v3d_session"
#: The header a session-authenticated write must carry, with the value ``GET /api/auth/me`` answers.
CSRF_HEADER = "X-CSRF-Token"
#: Methods that change nothing (no CSRF token needed).
SAFE_METHODS = frozenset({"GET", "HEAD", "OPTIONS", "TRACE"})
#: API paths answered without a principal: logging in, whether a demo account exists, the liveness probe.
PUBLIC_API_PATHS = frozenset({"/api/auth/login", "/api/auth/demo", "/api/health"})
#: Paths whose answers never depend on who asks (no database look-up for them).
_STATIC_PREFIXES = ("/static/", "/docs-assets/")
UNAUTHENTICATED = "log in, or send Authorization: Bearer <token>"


def is_protected(path: str) -> bool:
    """True for the paths that need a principal: ``/api`` and below, but :data:`PUBLIC_API_PATHS`.

    >>> is_protected("/api/systems"), is_protected("/api/auth/login"), is_protected("/static/js/api.js")
    (True, False, False)
    """
    return (path == "/api" or path.startswith("/api/")) and path not in PUBLIC_API_PATHS


def new_csrf_token() -> str:
    """A fresh synchronizer token for a session (256 random bits, URL-safe)."""
    return secrets.token_urlsafe(32)


def start_session(cookie_session: dict[str, Any], user_id: int, generation: int,
                  now: Optional[float] = None) -> str:
    """Fill a fresh browser session for the user (after a login: its time, Unix seconds, is ``now`` or
    the clock's) and return its CSRF token."""
    cookie_session.clear()
    csrf = new_csrf_token()
    cookie_session.update({"uid": user_id, "gen": generation, "csrf": csrf,
                           "at": int(time.time() if now is None else now)})
    return csrf


def resolve_principal(session_factory: Callable[[], Any], authorization: Optional[str],
                      cookie_session: dict[str, Any], max_age_s: Optional[float] = None,
                      now: Optional[float] = None) -> Optional[Principal]:
    """The principal of a request from its ``Authorization`` header, else its session cookie's
    contents; None when neither names an enabled user. Touches the database only when one is present.
    A session whose user is gone, disabled or logged out, that has no login time, or whose login is more
    than ``max_age_s`` seconds before ``now`` (the clock's), is emptied (the cookie is then cleared)."""
    if authorization is not None:
        scheme, _, token = authorization.partition(" ")
        if scheme.lower() != "bearer" or not token.strip():
            return None
        with session_factory() as db:
            reads_on_their_own(db)  # one lookup: no transaction around it
            found = users.token_user(db, token.strip())
            return Principal(*found, "token") if found else None
    uid, gen, at = cookie_session.get("uid"), cookie_session.get("gen"), cookie_session.get("at")
    if not isinstance(uid, int) or not isinstance(gen, int):
        return None
    if max_age_s is not None and (not isinstance(at, int)
                                  or (time.time() if now is None else now) - at > max_age_s):
        cookie_session.clear()
        return None
    with session_factory() as db:
        reads_on_their_own(db)
        user = users.resolve_session_user(db, uid, gen)
        if user is None:
            cookie_session.clear()
            return None
        return Principal(user.id, user.name, user.role.value, "session")


def csrf_ok(cookie_session: dict[str, Any], sent: Optional[str]) -> bool:
    """True when ``sent`` (the request's :data:`CSRF_HEADER`) is the session's token (constant time)."""
    expected = cookie_session.get("csrf")
    if not isinstance(expected, str) or not sent:
        return False
    return secrets.compare_digest(sent.encode("utf-8"), expected.encode("utf-8"))


class AuthenticationMiddleware:
    """Resolves the principal of every HTTP request (``scope["state"]["principal"]``) and refuses,
    under ``/api``, anonymous requests (401) and session writes without the CSRF token (403). Sessions end
    ``max_age_s`` seconds after their login (None: only the cookie's own age limits them).
    Must run inside :class:`SessionCookieMiddleware` (it reads ``scope["session"]``); the database is
    the app's ``state.session_factory``, read per request (tests replace it)."""

    def __init__(self, app: ASGIApp, max_age_s: Optional[float] = None) -> None:
        self.app = app
        self.max_age_s = max_age_s

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] != "http" or scope["path"].startswith(_STATIC_PREFIXES):
            await self.app(scope, receive, send)
            return
        conn = HTTPConnection(scope)
        cookie_session = scope.get("session", {})
        principal = await run_in_threadpool(
            resolve_principal, scope["app"].state.session_factory, conn.headers.get("authorization"), cookie_session,
            self.max_age_s)
        scope.setdefault("state", {})["principal"] = principal
        if is_protected(scope["path"]):
            answer = None
            if principal is None:
                answer = JSONResponse({"detail": UNAUTHENTICATED}, status_code=401,
                                      headers={"WWW-Authenticate": "Bearer"})
            elif (principal.via == "session" and scope["method"] not in SAFE_METHODS
                  and not csrf_ok(cookie_session, conn.headers.get(CSRF_HEADER))):
                answer = JSONResponse({"detail": f"missing or wrong {CSRF_HEADER} header: send the csrf_token "
                                                 "of GET /api/auth/me with every write"}, status_code=403)
            if answer is not None:
                await answer(scope, receive, send)
                return
        await self.app(scope, receive, send)


class SessionCookieMiddleware(SessionMiddleware):
    """Starlette's ``SessionMiddleware`` whose key is looked up when the app's middleware is built (its
    first request or lifespan start), not when the app is made: ``secret()`` may read the database."""

    def __init__(self, app: ASGIApp, *, secret: Callable[[], str], max_age: int, https_only: bool) -> None:
        super().__init__(app, secret_key=secret(), session_cookie=SESSION_COOKIE, max_age=max_age,
                         same_site="strict", https_only=https_only)


# ----- OpenAPI: the two ways in, declared on every protected operation (they check nothing themselves:
# the middleware has already resolved the principal) so that /docs and schemathesis can authenticate.
bearer_scheme = HTTPBearer(scheme_name="bearer", auto_error=False,
                           description="An API token of `v3d users add` / `v3d users token`.")
session_scheme = APIKeyCookie(name=SESSION_COOKIE, scheme_name="session", auto_error=False,
                              description=f"The browser session of POST /api/auth/login; writes also need the "
                                          f"{CSRF_HEADER} header (csrf_token of GET /api/auth/me).")

#: Dependencies of every protected router: the two schemes (documentation) and the principal (401).
PROTECTED = [Security(bearer_scheme), Security(session_scheme), Depends(current_principal)]
