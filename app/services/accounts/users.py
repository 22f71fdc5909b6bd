"""Users, passwords, API tokens and the session-signing key (issue 7).

* Passwords are hashed with argon2id through pwdlib (``PasswordHash.recommended()``); only the PHC
  string (``$argon2id$v=19$m=...``) is stored. A login for an unknown name still verifies a dummy hash,
  so that the answer takes as long whether the name or the password was wrong.
* API tokens are ``secrets.token_urlsafe(32)`` (256 random bits) prefixed ``v3d_``; only their SHA-256
  (hex) is stored, which suffices for a secret of that entropy (no slow hash needed) and lets a request
  find its token by an indexed equality. The token is shown once, when issued.
* The key that signs session cookies is ``V3D_SESSION_SECRET`` when set, else the ``session`` row of
  ``server_secrets`` (made by migration 0005; made again here if missing), so that several uvicorn
  workers and restarts share it.

Functions change the session and commit where the docstring says so (the CLI and the login route call
them with a session of their own).
"""
from __future__ import annotations

import hashlib
import re
import secrets
import threading
from dataclasses import dataclass
from datetime import datetime, timedelta
from typing import Optional

import sqlalchemy as sa
from pwdlib import PasswordHash
from sqlalchemy.exc import IntegrityError
from sqlalchemy.orm import Session

from app.db.models import ApiToken, ServerSecret, User, UserRole
from app.db.types import utcnow
from app.core.errors import InvalidInputError, NotFoundError

#: argon2id with pwdlib's recommended parameters.
PASSWORDS = PasswordHash.recommended()
#: Verified when the name is unknown, so both failures cost the same.
_DUMMY_HASH = PASSWORDS.hash("v3d: no such user")
#: Every issued token starts with this (tells a v3d token in a log or a leaked file).
TOKEN_PREFIX = "v3d_"
#: ``last_used_at`` is written at most this often per token (a write per request would serialise reads).
TOKEN_USE_RESOLUTION = timedelta(minutes=1)
#: The demo account of ``v3d serve --demo``: a public name and password, shown on the login page.
DEMO_NAME = "demo"
DEMO_PASSWORD = "demo"
#: At most this many argon2 computations at once (each takes 64 MiB and ~0.1-1 s of CPU), so a burst of
#: logins queues instead of exhausting the server's memory.
_HASHING = threading.BoundedSemaphore(2)
_NAME = re.compile(r"^[A-Za-z0-9][A-Za-z0-9._@-]{0,99}$")


@dataclass(frozen=True)
class UserSummary:
    """One line of ``v3d users list`` and ``GET /api/users``."""

    name: str
    role: str
    created_at: datetime
    tokens: int
    disabled: bool
    demo: bool


def hash_token(token: str) -> str:
    """SHA-256 of an API token, hex (64 characters): what ``api_tokens.token_hash`` stores.

    >>> hash_token("v3d_abc") == hashlib.sha256(b"v3d_abc").hexdigest()
    True
    """
    return hashlib.sha256(token.encode("utf-8")).hexdigest()


def _role(role: str) -> UserRole:
    try:
        return UserRole(role)
    except ValueError:
        raise InvalidInputError(f"unknown role {role!r}; one of {', '.join(r.value for r in UserRole)}",
                                field="role") from None


def _check_name(name: str) -> str:
    if not _NAME.match(name or ""):
        raise InvalidInputError("1 to 100 characters: letters, digits and . _ @ - (not first)", field="name")
    return name


def _check_password(password: str) -> str:
    if not password:
        raise InvalidInputError("the password is empty", field="password")
    if len(password) > 1024:
        raise InvalidInputError("the password is longer than 1024 characters", field="password")
    return password


def get_user(session: Session, name: str) -> User:
    """The user called ``name``; :class:`NotFoundError` when there is none."""
    user = session.scalar(sa.select(User).where(User.name == name))
    if user is None:
        raise NotFoundError("user", name)
    return user


def check_new_user(session: Session, name: str, role: str) -> None:
    """Raise the :class:`InvalidInputError` :func:`create_user` would for ``name`` (malformed or taken)
    or ``role``, before anyone types a password."""
    _check_name(name)
    _role(role)
    if session.scalar(sa.select(User.id).where(User.name == name)) is not None:
        raise InvalidInputError(f"a user named {name!r} already exists", field="name")


def create_user(session: Session, name: str, role: str, password: str, *, demo: bool = False) -> tuple[User, str]:
    """Store a new user with an argon2 hash of ``password`` and issue its first API token; commits.

    Returns:
        The user and its API token (the only time the token is seen).

    Raises:
        InvalidInputError: ``name`` malformed or taken (field ``name``), ``role`` not one of
            annotator / reviewer / admin (field ``role``), an empty password (field ``password``).
    """
    _check_name(name), _role(role), _check_password(password)
    with _HASHING:
        password_hash = PASSWORDS.hash(password)
    user = User(name=name, role=_role(role), password_hash=password_hash, demo=demo)
    session.add(user)
    try:
        session.flush()
    except IntegrityError:
        session.rollback()
        raise InvalidInputError(f"a user named {name!r} already exists", field="name") from None
    token = _add_token(session, user)
    session.commit()
    return user, token


def _add_token(session: Session, user: User) -> str:
    token = TOKEN_PREFIX + secrets.token_urlsafe(32)
    session.add(ApiToken(user_id=user.id, token_hash=hash_token(token)))
    session.flush()
    return token


def issue_token(session: Session, name: str) -> str:
    """Issue another API token to the user ``name`` (its other tokens keep working); commits.

    Raises:
        NotFoundError: no such user.
    """
    token = _add_token(session, get_user(session, name))
    session.commit()
    return token


def set_disabled(session: Session, name: str, disabled: bool = True) -> User:
    """Disable (or enable again) the user ``name``: a disabled user cannot log in, and its sessions and
    tokens stop working at their next request; commits. Raises :class:`NotFoundError`."""
    user = get_user(session, name)
    user.disabled = disabled
    user.session_generation += 1
    session.commit()
    return user


def authenticate_password(session: Session, name: str, password: str) -> Optional[User]:
    """The enabled user ``name`` when ``password`` is theirs, else None (same cost either way).
    A hash made with older parameters is replaced by pwdlib's current one (commits then)."""
    user = session.scalar(sa.select(User).where(User.name == name))
    with _HASHING:
        if user is None:
            PASSWORDS.verify(password, _DUMMY_HASH)
            return None
        valid, new_hash = PASSWORDS.verify_and_update(password, user.password_hash)
    if not valid or user.disabled:
        return None
    if new_hash is not None:
        user.password_hash = new_hash
        session.commit()
    return user


def resolve_token(session: Session, token: str) -> Optional[User]:
    """The enabled user owning the API token ``token``, else None. Refreshes the token's
    ``last_used_at`` when older than :data:`TOKEN_USE_RESOLUTION` (commits then; best effort: when the
    database's write lock is busy the refresh waits for a later request)."""
    if not token.startswith(TOKEN_PREFIX) or len(token) > 200:
        return None
    row = session.execute(
        sa.select(ApiToken, User).join(User, ApiToken.user_id == User.id)
        .where(ApiToken.token_hash == hash_token(token), User.disabled.is_(False))
    ).first()
    if row is None:
        return None
    api_token, user = row
    now = utcnow()
    if api_token.last_used_at is None or now - api_token.last_used_at > TOKEN_USE_RESOLUTION:
        api_token.last_used_at = now
        user_id = user.id
        try:
            session.commit()
        except sa.exc.OperationalError:
            # SQLite's write lock is another writer's (an edit of another worker): the request must not
            # fail for a timestamp, which the next request refreshes. Read the user again after the rollback.
            session.rollback()
            user = session.get(User, user_id)
    return user


def resolve_session_user(session: Session, user_id: int, generation: int) -> Optional[User]:
    """The enabled user of a session cookie (its ``user_id`` and ``session_generation``), else None:
    a session outlives neither a logout nor a disable (both raise the generation)."""
    user = session.get(User, user_id)
    if user is None or user.disabled or user.session_generation != generation:
        return None
    return user


def end_sessions(session: Session, user_id: int) -> None:
    """End every browser session of the user (logout); commits."""
    session.execute(sa.update(User).where(User.id == user_id)
                    .values(session_generation=User.session_generation + 1))
    session.commit()


def list_users(session: Session) -> list[UserSummary]:
    """Every user by name, with the number of API tokens."""
    counts = (sa.select(ApiToken.user_id, sa.func.count(ApiToken.id).label("n"))
              .group_by(ApiToken.user_id).subquery())
    rows = session.execute(
        sa.select(User, sa.func.coalesce(counts.c.n, 0)).outerjoin(counts, counts.c.user_id == User.id)
        .order_by(User.name)
    ).all()
    return [UserSummary(u.name, u.role.value, u.created_at, int(n), u.disabled, u.demo) for u, n in rows]


def demo_account(session: Session) -> Optional[User]:
    """The enabled demo account (flagged ``demo``), or None."""
    return session.scalar(sa.select(User).where(User.demo.is_(True), User.disabled.is_(False)).order_by(User.id))


def ensure_demo_account(session: Session) -> str:
    """Create the demo account (``demo`` / ``demo``, role admin, flagged demo) unless it exists; commits.

    Returns:
        A line for the console saying how to log in, or why there is no demo account (a real user
        already has the name).
    """
    existing = session.scalar(sa.select(User).where(User.name == DEMO_NAME))
    if existing is not None and not existing.demo:
        return f"demo account: not made, a user named {DEMO_NAME!r} exists (log in with your own account)"
    if existing is not None and existing.disabled:
        return f"demo account: {DEMO_NAME!r} is disabled (v3d users enable {DEMO_NAME})"
    if existing is None:
        create_user(session, DEMO_NAME, UserRole.ADMIN.value, DEMO_PASSWORD, demo=True)
    return (f"demo account (role admin, for trying v3d only): log in as {DEMO_NAME!r} with password "
            f"{DEMO_PASSWORD!r}; end it with `v3d users disable {DEMO_NAME}`")


def session_secret(session: Session, override: Optional[str] = None) -> str:
    """The key that signs session cookies: ``override`` (``V3D_SESSION_SECRET``) when given, else the
    stored ``session`` secret, made and committed when missing (two workers racing both end up with
    the row that won)."""
    if override:
        return override
    row = session.get(ServerSecret, "session")
    if row is not None:
        return row.value
    session.add(ServerSecret(name="session", value=secrets.token_urlsafe(48)))
    try:
        session.commit()
    except IntegrityError:
        session.rollback()
    return session.get(ServerSecret, "session").value  # type: ignore[union-attr]
