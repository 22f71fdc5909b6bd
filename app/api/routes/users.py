"""``/api/users`` (admin): the users, a new user with its first API token, a role change, disabling and
enabling, and each user's API tokens (list, issue with a label and an expiry, revoke one). Every change is
audited (``app.services.accounts.users``); no answer is cached (``Cache-Control: no-store``)."""
from __future__ import annotations

from typing import Annotated, Optional

from fastapi import APIRouter, Depends, Path, status

from app.api.account_schemas import TokenIn, TokenOut, TokenSummaryOut, UserIn, UserOut, UserPatch
from app.api.auth import PrincipalDep, require_role
from app.api.deps import SessionDep
from app.api.schemas import INVALID, NOT_FOUND, DbInt
from app.api.security import no_store
from app.services.accounts import users

router = APIRouter(prefix="/users", tags=["users"],
                   dependencies=[Depends(require_role("admin")), Depends(no_store)])


UserName = Annotated[str, Path(description="The user's name.", max_length=100, pattern=r"^[^\x00]+$")]


@router.get("", response_model=list[UserOut])
def list_users(session: SessionDep) -> list[UserOut]:
    """Every user by name, with the number of API tokens that work."""
    return [UserOut.model_validate(u, from_attributes=True) for u in users.list_users(session)]


@router.post("", response_model=TokenOut, status_code=status.HTTP_201_CREATED, responses=INVALID)
def create_user(session: SessionDep, principal: PrincipalDep, body: UserIn) -> TokenOut:
    """A new user (422 naming ``name`` when it is taken) and its first API token; audited."""
    user, token = users.create_user(session, body.name, body.role, body.password, actor=principal.name)
    first = users.list_tokens(session, user.name)[0]
    return TokenOut(name=user.name, token=token, id=first.id, label=first.label, expires_at=first.expires_at)


@router.patch("/{name}", response_model=UserOut, responses={**NOT_FOUND, **INVALID})
def patch_user(session: SessionDep, principal: PrincipalDep, name: UserName, body: UserPatch) -> UserOut:
    """Change the user's role and/or disable or enable it; each change audited."""
    users.get_user(session, name)  # 404 before anything changes
    if body.role is not None:
        users.set_role(session, name, body.role, actor=principal.name)
    if body.disabled is not None:
        users.set_disabled(session, name, body.disabled, actor=principal.name)
    return next(UserOut.model_validate(u, from_attributes=True) for u in users.list_users(session) if u.name == name)


@router.get("/{name}/tokens", response_model=list[TokenSummaryOut], responses=NOT_FOUND)
def list_tokens(session: SessionDep, name: UserName) -> list[TokenSummaryOut]:
    """Every API token of the user, oldest first: id, label, times, state (never the token)."""
    return [TokenSummaryOut.model_validate(t) for t in users.list_tokens(session, name)]


@router.post("/{name}/tokens", response_model=TokenOut, status_code=status.HTTP_201_CREATED,
             responses={**NOT_FOUND, **INVALID})
def issue_token(session: SessionDep, principal: PrincipalDep, name: UserName,
                body: Optional[TokenIn] = None) -> TokenOut:
    """Another API token for the user ``name`` (the others keep working), with an optional label and
    expiry; audited."""
    body = body or TokenIn()
    issued = users.issue_token(session, name, label=body.label, expires_days=body.expires_days, actor=principal.name)
    return TokenOut(name=name, token=issued.token, id=issued.id, label=issued.label, expires_at=issued.expires_at)


@router.delete("/{name}/tokens/{token_id}", response_model=TokenSummaryOut, responses=NOT_FOUND)
def revoke_token(session: SessionDep, principal: PrincipalDep, name: UserName, token_id: DbInt) -> TokenSummaryOut:
    """Revoke one API token of the user: it stops working at once, for good; audited. Answers the token
    as now listed (state ``revoked``)."""
    return TokenSummaryOut.model_validate(users.revoke_token(session, name, token_id, actor=principal.name))
