"""``/api/users`` (admin): the users, a new user with its first API token, another token."""
from __future__ import annotations

from datetime import datetime
from typing import Annotated, Literal

from fastapi import APIRouter, Depends, Path, status
from pydantic import BaseModel, Field

from app.api.auth import require_role
from app.api.deps import SessionDep
from app.api.schemas import INVALID, NOT_FOUND, _In
from app.services.accounts import users

router = APIRouter(prefix="/users", tags=["users"], dependencies=[Depends(require_role("admin"))])
RoleName = Literal["annotator", "reviewer", "admin"]


class UserOut(BaseModel):
    name: str
    role: RoleName
    created_at: datetime
    tokens: int
    disabled: bool
    demo: bool


class UserIn(_In):
    name: str = Field(max_length=100)
    role: RoleName
    password: str = Field(min_length=1, max_length=1024)


class TokenOut(BaseModel):
    """An API token, shown this once (only its SHA-256 is stored)."""

    name: str
    token: str


@router.get("", response_model=list[UserOut])
def list_users(session: SessionDep) -> list[UserOut]:
    """Every user by name, with the number of API tokens."""
    return [UserOut.model_validate(u, from_attributes=True) for u in users.list_users(session)]


@router.post("", response_model=TokenOut, status_code=status.HTTP_201_CREATED, responses=INVALID)
def create_user(session: SessionDep, body: UserIn) -> TokenOut:
    """A new user (422 naming ``name`` when it is taken) and its first API token."""
    user, token = users.create_user(session, body.name, body.role, body.password)
    return TokenOut(name=user.name, token=token)


@router.post("/{name}/tokens", response_model=TokenOut, status_code=status.HTTP_201_CREATED,
             responses={**NOT_FOUND, **INVALID})
def issue_token(session: SessionDep,
                name: Annotated[str, Path(description="The user's name.", max_length=100, pattern=r"^[^\x00]+$")],
                ) -> TokenOut:
    """Another API token for the user ``name`` (the others keep working)."""
    return TokenOut(name=name, token=users.issue_token(session, name))
