"""``/api/auth``: browser login and logout, who is logged in, and whether a demo account exists.

``POST /api/auth/login`` and ``GET /api/auth/demo`` are public (``PUBLIC_API_PATHS``); ``/me`` and
``/logout`` need a principal like every other API route (``app.api.authentication``).
"""
from __future__ import annotations

from typing import Literal, Optional

from fastapi import APIRouter, HTTPException, Request, Response, status
from pydantic import BaseModel, Field

from app.api.auth import PrincipalDep, held_roles
from app.api.authentication import start_session
from app.api.deps import SessionDep
from app.api.schemas import ErrorOut, _In
from app.services.accounts import users

public_router = APIRouter(prefix="/auth", tags=["auth"])
router = APIRouter(prefix="/auth", tags=["auth"])

#: One answer for a wrong name and a wrong password alike (it must not tell which).
WRONG_CREDENTIALS = "wrong name or password"


class LoginIn(_In):
    name: str = Field(max_length=100)
    password: str = Field(max_length=1024)


class MeOut(BaseModel):
    """Who is logged in. ``csrf_token`` is the value of the ``X-CSRF-Token`` header every write of
    this browser session must carry (null for an API token, whose writes need none)."""

    name: str
    role: Literal["annotator", "reviewer", "admin"]
    roles: list[Literal["annotator", "reviewer", "admin"]] = Field(
        description="Every role whose routes this user may call: its own and the less trusted ones (the ranking "
        "of app.api.auth.ROLES; the UI offers only what the user may do).")
    via: Literal["session", "token"]
    csrf_token: Optional[str]


class DemoAccountOut(BaseModel):
    name: str
    password: str


class DemoOut(BaseModel):
    """The demo account of ``v3d serve --demo`` (its password is public), or null when there is none."""

    account: Optional[DemoAccountOut]


@public_router.post("/login", response_model=MeOut,
                    responses={401: {"model": ErrorOut, "description": "Wrong name or password (not saying which)."}})
def login(request: Request, session: SessionDep, body: LoginIn) -> MeOut:
    """Start a browser session (the ``v3d_session`` cookie) for the user whose name and password
    these are; answers who is logged in and the session's CSRF token. A disabled user cannot log in."""
    user = users.authenticate_password(session, body.name, body.password)
    if user is None:
        request.session.clear()
        raise HTTPException(status_code=status.HTTP_401_UNAUTHORIZED, detail=WRONG_CREDENTIALS)
    csrf = start_session(request.session, user.id, user.session_generation)
    return MeOut(name=user.name, role=user.role.value, roles=held_roles(user.role.value),
                 via="session", csrf_token=csrf)


@public_router.get("/demo", response_model=DemoOut)
def demo(session: SessionDep) -> DemoOut:
    """The demo account's name and public password when ``v3d serve --demo`` made one (and it is
    enabled), for the login page's hint; ``{"account": null}`` otherwise."""
    user = users.demo_account(session)
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
