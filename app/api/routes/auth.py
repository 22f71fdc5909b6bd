"""``/api/auth``: browser login and logout, who is logged in, and whether a demo account exists.

``POST /api/auth/login`` and ``GET /api/auth/demo`` are public (``PUBLIC_API_PATHS``); ``/me`` and
``/logout`` need a principal like every other API route (``app.api.authentication``).
"""
from __future__ import annotations

import asyncio
from concurrent.futures import ThreadPoolExecutor
from typing import Any, Optional

from fastapi import APIRouter, Depends, HTTPException, Request, Response, status
from starlette.concurrency import run_in_threadpool

from app.api.account_schemas import DemoAccountOut, DemoOut, LoginIn, MeOut
from app.api.auth import PrincipalDep, held_roles
from app.api.authentication import start_session
from app.api.deps import SessionDep
from app.api.hosts import loopback_host
from app.api.schemas import ErrorOut
from app.api.security import no_store
from app.services.accounts import users
from app.services.accounts.throttle import client_address, from_this_machine

public_router = APIRouter(prefix="/auth", tags=["auth"], dependencies=[Depends(no_store)])
router = APIRouter(prefix="/auth", tags=["auth"], dependencies=[Depends(no_store)])

#: One answer for a wrong name and a wrong password alike (it must not tell which).
WRONG_CREDENTIALS = "wrong name or password"


#: Password checks run here, two at a time (each argon2 verification takes 64 MiB and ~0.1-1 s of CPU): a flood
#: of logins queues for these threads without holding the request thread pool that every other route needs.
_PASSWORD_CHECKS = ThreadPoolExecutor(max_workers=2, thread_name_prefix="v3d-password-check")


#: Why the demo account does not log in from elsewhere (403).
DEMO_ONLY_HERE = ("the demo account (public password) logs in only on the machine that serves v3d (a loopback address "
                  "such as http://127.0.0.1:8000), not over a network nor through a proxy: "
                  "log in with your own account")


def _check_password(session_factory: Any, name: str, password: str) -> Optional[tuple[int, str, str, int, bool]]:
    """(id, name, role, session generation, demo) of the enabled user ``name`` whose password this is, else None."""
    with session_factory() as session:
        user = users.authenticate_password(session, name, password)
        return None if user is None else (user.id, user.name, user.role.value, user.session_generation, user.demo)


def _here(request: Request) -> bool:
    """The request came straight from this machine (``app.services.accounts.throttle.from_this_machine``: a
    loopback peer, no proxy header) and names it by a loopback ``Host`` (``app.api.hosts.loopback_host``): a page
    of another site whose name was rebound to 127.0.0.1 (DNS rebinding) sends its own name, even with
    ``V3D_ALLOWED_HOSTS`` letting that name through."""
    return (from_this_machine(request.client.host if request.client else None, request.headers)
            and loopback_host(request.headers.get("host")))


@public_router.post("/login", response_model=MeOut, responses={
    401: {"model": ErrorOut, "description": "Wrong name or password (not saying which)."},
    403: {"model": ErrorOut, "description": "The demo account, from another machine or through a proxy (its password "
                                            "is public: it logs in only on the machine that serves v3d)."},
    429: {"model": ErrorOut, "description": "Too many failed logins of this name from this address, or from this "
                                            "address, in the window (V3D_LOGIN_*): Retry-After says when to try again.",
          "headers": {"Retry-After": {"description": "Seconds until a login may be tried again.",
                                      "schema": {"type": "integer"}}}},
})
async def login(request: Request, body: LoginIn) -> MeOut:
    """Start a browser session (the ``v3d_session`` cookie) for the user whose name and password
    these are; answers who is logged in and the session's CSRF token. A disabled user cannot log in.
    Failed logins are limited (``app.services.accounts.throttle``): past the limit every login of the name
    from the client's address (or from the address) gets 429 until the window passes, a right one too. The demo
    account (public password) logs in only from this machine without a proxy: 403 otherwise."""
    state = request.app.state
    address = client_address(request.client.host if request.client else None,
                             request.headers.get("x-forwarded-for"), state.settings.trusted_proxies)
    throttle = state.login_throttle
    wait = await run_in_threadpool(throttle.acquire, body.name, address)
    if wait is not None:
        raise HTTPException(status_code=status.HTTP_429_TOO_MANY_REQUESTS, headers={"Retry-After": str(wait)},
                            detail=f"too many failed logins: try again in {wait} s")
    found = await asyncio.get_running_loop().run_in_executor(
        _PASSWORD_CHECKS, _check_password, state.session_factory, body.name, body.password)
    if found is None:  # the attempt stays counted
        request.session.clear()
        raise HTTPException(status_code=status.HTTP_401_UNAUTHORIZED, detail=WRONG_CREDENTIALS)
    user_id, name, role, generation, is_demo = found
    if is_demo and not _here(request):  # the attempt stays counted
        request.session.clear()
        raise HTTPException(status_code=status.HTTP_403_FORBIDDEN, detail=DEMO_ONLY_HERE)
    await run_in_threadpool(throttle.succeeded, body.name, address)
    csrf = start_session(request.session, user_id, generation)
    return MeOut(name=name, role=role, roles=held_roles(role), via="session", csrf_token=csrf)


@public_router.get("/demo", response_model=DemoOut)
def demo(request: Request, session: SessionDep) -> DemoOut:
    """The demo account's name and public password when ``v3d serve --demo`` made one (and it is
    enabled), for the login page's hint, to a browser on this machine; ``{"account": null}`` otherwise
    (and to anyone else: over a network or through a proxy the demo account cannot log in)."""
    user = users.demo_account(session) if _here(request) else None
    return DemoOut(account=DemoAccountOut(name=user.name, password=users.DEMO_PASSWORD) if user else None)


@router.get("/me", response_model=MeOut)
def me(request: Request, principal: PrincipalDep) -> MeOut:
    """The logged-in user, and the CSRF token of this browser session."""
    csrf = request.session.get("csrf") if principal.via == "session" else None
    return MeOut(name=principal.name, role=principal.role, roles=held_roles(principal.role),
                 via=principal.via, csrf_token=csrf)


@router.post("/logout", status_code=status.HTTP_204_NO_CONTENT)
def logout(request: Request, session: SessionDep, principal: PrincipalDep) -> Response:
    """End the browser session: the cookie is cleared, and every session of the user ends (the
    user's session generation is raised, so a copied cookie stops working too)."""
    if principal.via == "session":
        users.end_sessions(session, principal.user_id)
        request.session.clear()
    return Response(status_code=status.HTTP_204_NO_CONTENT)
