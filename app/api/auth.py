"""Who is asking: the authenticated principal of a request and the role each write needs.

Roles are ranked: an ``annotator`` edits labels and field lines and takes per-view decisions; a
``reviewer`` may also take system decisions and revert audited writes; an ``admin`` may also import,
export and manage users. A route states the least role it needs with :func:`require_role`; every
route under ``/api`` (reads included) needs at least an authenticated principal.

The authentication layer (a browser session cookie with CSRF protection, or an
``Authorization: Bearer <token>`` API token) resolves the principal once per request and puts it on
``request.state.principal``; this module only reads it, so routes and services never care how the
person logged in (``Principal.via`` says it, for the rules that differ: a token's write must carry
``If-Match``).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Annotated, Literal

from fastapi import Depends, HTTPException, Request

from app.db.models import UserRole

#: A role's name, as the API takes and answers it (the values of ``UserRole``: one home).
if TYPE_CHECKING:  # mypy cannot build a Literal from values computed at import
    Role = str
else:
    Role = Literal[tuple(r.value for r in UserRole)]

#: The roles from least to most trusted (``UserRole``'s order); a role may do everything a lower one may.
ROLES: tuple[str, ...] = tuple(r.value for r in UserRole)


def held_roles(role: Role) -> list[Role]:
    """The roles whose routes a user of ``role`` may call: its own and every less trusted one.

    >>> held_roles("reviewer")
    ['annotator', 'reviewer']
    """
    return list(ROLES[:ROLES.index(role) + 1])


@dataclass(frozen=True)
class Principal:
    """The authenticated user of one request.

    ``user_id`` and ``name`` identify the user (the audit log records ``name``); ``role`` is one of
    :data:`ROLES`; ``via`` is ``"session"`` for the browser's session cookie and ``"token"`` for an
    API token.
    """

    user_id: int
    name: str
    role: Role
    via: Literal["session", "token"]

    def may(self, role: Role) -> bool:
        """True when this principal's role is ``role`` or a more trusted one.

        >>> ana = Principal(1, "ana", "reviewer", "token")
        >>> ana.may("annotator"), ana.may("admin")
        (True, False)
        """
        return role in held_roles(self.role)


async def current_principal(request: Request) -> Principal:
    """The principal the authentication layer resolved for this request; 401 when there is none."""
    principal = getattr(request.state, "principal", None)
    if principal is None:
        raise HTTPException(status_code=401, detail="log in, or send Authorization: Bearer <token>",
                            headers={"WWW-Authenticate": "Bearer"})
    return principal


PrincipalDep = Annotated[Principal, Depends(current_principal)]


def require_role(role: Role):
    """A dependency answering 403 naming the needed role unless the principal has ``role`` or more;
    it returns the principal (401 first when nobody is authenticated)."""

    async def _check(principal: PrincipalDep) -> Principal:
        if not principal.may(role):
            raise HTTPException(status_code=403, detail=f"this needs the {role} role; you are {principal.role}")
        return principal

    _check.__name__ = f"require_{role}"
    return _check


AnnotatorDep = Annotated[Principal, Depends(require_role("annotator"))]
ReviewerDep = Annotated[Principal, Depends(require_role("reviewer"))]
AdminDep = Annotated[Principal, Depends(require_role("admin"))]
