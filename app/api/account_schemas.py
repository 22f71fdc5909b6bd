"""Schemas of the accounts: browser login and who is logged in (``app.api.routes.auth``), the users and their API
tokens as the admin manages them (``app.api.routes.users``)."""
from __future__ import annotations

from datetime import datetime
from typing import Annotated, Literal, Optional

from pydantic import BaseModel, ConfigDict, Field

from app.api.auth import Role
from app.api.schemas import _In, readable_name
from app.services.accounts import users


class LoginIn(_In):
    name: str = Field(max_length=100)
    password: str = Field(max_length=1024)


class MeOut(BaseModel):
    """Who is logged in. ``csrf_token`` is the value of the ``X-CSRF-Token`` header every write of
    this browser session must carry (null for an API token, whose writes need none)."""

    name: str
    role: Role
    roles: list[Role] = Field(
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


class UserOut(BaseModel):
    name: str
    role: Role
    created_at: datetime
    tokens: int
    disabled: bool
    demo: bool


class UserIn(_In):
    name: Annotated[str, readable_name(100, "a user name")] = Field(max_length=100)
    role: Role
    password: str = Field(min_length=1, max_length=1024)


class TokenOut(BaseModel):
    """An API token, shown this once (only its SHA-256 is stored), with the id that lists and revokes it."""

    name: str
    token: str
    id: int
    label: Optional[str]
    expires_at: Optional[datetime]


class TokenIn(_In):
    label: Optional[str] = Field(None, min_length=1, max_length=100, description="What the token is for.")
    expires_days: Optional[float] = Field(None, gt=0, le=users.MAX_TOKEN_DAYS,
                                          description="The token stops working this many days from now "
                                                      "(none: until revoked).")


class TokenSummaryOut(BaseModel):
    """An API token as listed (never the token itself)."""

    model_config = ConfigDict(from_attributes=True)

    id: int
    label: Optional[str]
    created_at: datetime
    last_used_at: Optional[datetime]
    expires_at: Optional[datetime]
    revoked_at: Optional[datetime]
    state: Literal["active", "expired", "revoked"]


class UserPatch(_In):
    role: Optional[Role] = Field(None, description="The user's new role.")
    disabled: Optional[bool] = Field(None, description="true: no login, sessions end, every token revoked for "
                                                       "good; false: may log in again (no token comes back).")
