"""Users, passwords, API tokens and the session-signing key.

* Passwords are hashed with argon2id through pwdlib (``PasswordHash.recommended()``); only the PHC
  string (``$argon2id$v=19$m=...``) is stored. A login for an unknown name still verifies a dummy hash,
  so that the answer takes as long whether the name or the password was wrong.
* API tokens are ``secrets.token_urlsafe(32)`` (256 random bits) prefixed ``v3d_``; only their SHA-256
  (hex) is stored, which suffices for a secret of that entropy (no slow hash needed) and lets a request
  find its token by an indexed equality. The token is shown once, when issued. Each has an id, a label,
  its creation and last-use times and an optional expiry; one can be revoked alone, and disabling a user
  revokes all of its tokens for good (enabling it again does not bring them back).
* Every change of a user or a token is audited in its own transaction (``user.create``, ``user.role``,
  ``user.disable``, ``user.enable``, ``token.issue``, ``token.revoke``, ``user.take_over``: who, when, which user
  and token id, never a secret); ``actor`` None is the machine's owner (``cli:<os user>``).
* The key that signs session cookies is ``V3D_SESSION_SECRET`` when set, else the ``session`` row of
  ``server_secrets`` (made by migration 0005; made again here if missing), so that several uvicorn
  workers and restarts share it.

Functions change the session and commit where the docstring says so (the CLI and the login route call
them with a session of their own).
"""
from __future__ import annotations

import contextlib
import functools
import hashlib
import re
import secrets
import threading
from dataclasses import dataclass
from datetime import datetime, timedelta
from typing import Optional, cast

import sqlalchemy as sa
from pwdlib import PasswordHash
from sqlalchemy.engine import CursorResult
from sqlalchemy.exc import IntegrityError
from sqlalchemy.orm import Session

from app.core.errors import InvalidInputError, NotFoundError
from app.core.names import check_name, name_key
from app.db.models import ApiToken, Job, JobState, ServerSecret, User, UserRole
from app.db.types import utcnow
from app.db.unit import write_unit
from app.services.audit import log as audit

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
#: The assignee filter's two words: the caller (``assignee=me``, which the API resolves to the caller's name) and
#: nobody (``assignee=none``: the unassigned systems). No user may be called either, nor a name that differs from one
#: only by case or trailing dots (:data:`RESERVED_NAMES`); the queue's filter reads them here
#: (``app.services.curation.queue``).
ASSIGNEE_ME, ASSIGNEE_NONE = "me", "none"

#: Names no user may have, nor one that differs from them only by case or trailing dots (:func:`name_key`): the
#: assignee filter's words for the caller and for nobody (``GET /api/systems?assignee=me|none``), which a user so
#: called could never be told apart from.
RESERVED_NAMES = (ASSIGNEE_ME, ASSIGNEE_NONE)
#: Longest expiry a token may be given (days).
MAX_TOKEN_DAYS = 3650


@dataclass(frozen=True)
class UserSummary:
    """One line of ``v3d users list`` and ``GET /api/users``."""

    name: str
    role: str
    created_at: datetime
    tokens: int
    disabled: bool
    demo: bool


@dataclass(frozen=True)
class TokenSummary:
    """One API token as ``v3d users tokens`` and ``GET /api/users/{name}/tokens`` list it (never the token)."""

    id: int
    label: Optional[str]
    created_at: datetime
    last_used_at: Optional[datetime]
    expires_at: Optional[datetime]
    revoked_at: Optional[datetime]
    state: str  # "active", "expired" or "revoked"

    @classmethod
    def of(cls, token: ApiToken, now: Optional[datetime] = None) -> "TokenSummary":
        now = now or utcnow()
        state = ("revoked" if token.revoked_at is not None
                 else "expired" if token.expires_at is not None and token.expires_at <= now else "active")
        return cls(token.id, token.label, token.created_at, token.last_used_at, token.expires_at,
                   token.revoked_at, state)


@dataclass(frozen=True)
class IssuedToken:
    """A token just issued: the only time ``token`` itself is seen."""

    id: int
    token: str
    label: Optional[str]
    expires_at: Optional[datetime]


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


def is_reserved_name(name: str) -> bool:
    """Whether ``name`` is one of :data:`RESERVED_NAMES` but for case or trailing dots.

    >>> is_reserved_name("None."), is_reserved_name("Me"), is_reserved_name("menon")
    (True, True, False)
    """
    return name_key(name) in RESERVED_NAMES


def _check_name(name: str, session: Optional[Session] = None) -> str:
    """``name`` when a new user may have it; with ``session``, also unlike every stored name but for case or
    trailing dots. Raises :class:`InvalidInputError` (field ``name``)."""
    check_name(name, "name", max_length=100, what="a user name")  # the rule of every name people read
    if not _NAME.match(name or ""):
        raise InvalidInputError("1 to 100 characters: letters, digits and . _ @ - (not first)", field="name")
    if is_reserved_name(name):
        raise InvalidInputError(f"{name!r} is reserved (the assignee filter's word for "
                                f"{'the caller' if name_key(name) == ASSIGNEE_ME else 'nobody'}); choose another name",
                                field="name")
    if session is not None:
        like = session.scalar(sa.select(User.name).where(User.name_key == name_key(name), User.name != name).limit(1))
        if like is not None:
            raise InvalidInputError(f"a user named {like!r} exists: names that differ only by case or trailing dots "
                                    "are refused", field="name")
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
    """Raise the :class:`InvalidInputError` :func:`create_user` would for ``name`` (malformed, reserved or taken)
    or ``role``, before anyone types a password."""
    _check_name(name, session)
    _role(role)
    if session.scalar(sa.select(User.id).where(User.name == name)) is not None:
        raise InvalidInputError(f"a user named {name!r} already exists", field="name")


def create_user(session: Session, name: str, role: str, password: str, *, demo: bool = False,
                actor: Optional[str] = None) -> tuple[User, str]:
    """Store a new user with an argon2 hash of ``password`` and issue its first API token (label
    ``first token``, no expiry); audited (``user.create``, naming the token's id); commits.

    Returns:
        The user and its API token (the only time the token is seen).

    Raises:
        InvalidInputError: ``name`` malformed, reserved (:data:`RESERVED_NAMES`) or taken, but for case or trailing
            dots too (field ``name``), ``role`` not one of annotator / reviewer / admin (field ``role``), an empty
            password (field ``password``).
    """
    _check_name(name, session), _role(role), _check_password(password)
    with _HASHING:
        password_hash = PASSWORDS.hash(password)
    with write_unit(session, lock=False):
        user = User(name=name, role=_role(role), password_hash=password_hash, demo=demo)
        session.add(user)
        try:
            session.flush()
        except IntegrityError:  # rolled back by the write unit
            raise InvalidInputError(f"a user named {name!r} already exists", field="name") from None
        row, token = _add_token(session, user, "first token", None)
        audit.record(session, actor=actor, action="user.create",
                     after={"user": name, "role": user.role.value, "demo": demo, "token_id": row.id})
    return user, token


def _add_token(session: Session, user: User, label: Optional[str],
               expires_days: Optional[float]) -> tuple[ApiToken, str]:
    if label is not None and not (0 < len(label) <= 100):
        raise InvalidInputError("a token's label has 1 to 100 characters", field="label")
    if expires_days is not None and not (0 < expires_days <= MAX_TOKEN_DAYS):
        raise InvalidInputError(f"a token expires after more than 0 and at most {MAX_TOKEN_DAYS} days",
                                field="expires_days")
    token = TOKEN_PREFIX + secrets.token_urlsafe(32)
    row = ApiToken(user_id=user.id, token_hash=hash_token(token), label=label,
                   expires_at=utcnow() + timedelta(days=expires_days) if expires_days is not None else None)
    session.add(row)
    session.flush()
    return row, token


def issue_token(session: Session, name: str, *, label: Optional[str] = None, expires_days: Optional[float] = None,
                actor: Optional[str] = None) -> IssuedToken:
    """Issue another API token to the user ``name`` (its other tokens keep working), valid for
    ``expires_days`` days (None: until revoked); audited (``token.issue``); commits.

    Raises:
        NotFoundError: no such user.
        InvalidInputError: a label longer than 100 characters (field ``label``), an expiry outside
            (0, :data:`MAX_TOKEN_DAYS`] days (field ``expires_days``), a disabled user (field ``name``: its
            tokens would be revoked anyway).
    """
    user = get_user(session, name)
    if user.disabled:
        raise InvalidInputError(f"{name!r} is disabled: enable it before issuing a token", field="name")
    with write_unit(session, lock=False):
        row, token = _add_token(session, user, label, expires_days)
        audit.record(session, actor=actor, action="token.issue",
                     after={"user": name, "token_id": row.id, "label": label,
                            "expires_at": row.expires_at.isoformat() if row.expires_at else None})
    return IssuedToken(row.id, token, label, row.expires_at)


def list_tokens(session: Session, name: str) -> list[TokenSummary]:
    """Every API token of the user ``name`` (revoked and expired ones included), oldest first.
    Raises :class:`NotFoundError`."""
    user = get_user(session, name)
    now = utcnow()
    rows = session.scalars(sa.select(ApiToken).where(ApiToken.user_id == user.id).order_by(ApiToken.id))
    return [TokenSummary.of(t, now) for t in rows]


def revoke_token(session: Session, name: str, token_id: int, *, actor: Optional[str] = None) -> TokenSummary:
    """Revoke one API token of the user ``name``: it stops working at once, for good; audited
    (``token.revoke``) unless it was revoked already; commits.

    Raises:
        NotFoundError: no such user, or no token ``token_id`` of that user.
    """
    user = get_user(session, name)
    row = session.scalar(sa.select(ApiToken).where(ApiToken.id == token_id, ApiToken.user_id == user.id))
    if row is None:
        raise NotFoundError("token", token_id)
    if row.revoked_at is None:
        with write_unit(session, lock=False):
            row.revoked_at = utcnow()
            audit.record(session, actor=actor, action="token.revoke",
                         after={"user": name, "token_id": row.id, "label": row.label})
    return TokenSummary.of(row)


def set_role(session: Session, name: str, role: str, *, actor: Optional[str] = None) -> User:
    """Give the user ``name`` another role (annotator, reviewer, admin); it applies to the user's next
    request, sessions and tokens alike; audited (``user.role``, before and after) when it changes; commits.

    Raises:
        NotFoundError: no such user.
        InvalidInputError: an unknown role (field ``role``).
    """
    user = get_user(session, name)
    new = _role(role)
    if user.role != new:
        with write_unit(session, lock=False):
            before = user.role.value
            user.role = new
            audit.record(session, actor=actor, action="user.role", before={"user": name, "role": before},
                         after={"user": name, "role": new.value})
    return user


def set_disabled(session: Session, name: str, disabled: bool = True, *, actor: Optional[str] = None) -> User:
    """Disable (or enable again) the user ``name``; audited (``user.disable`` / ``user.enable``); commits.

    A disabled user cannot log in, its sessions end at their next request, and every API token it holds
    is revoked for good: enabling it again lets it log in anew but brings no token back (issue a new one).
    Raises :class:`NotFoundError`.
    """
    user = get_user(session, name)
    with write_unit(session, lock=False):
        revoked = 0
        if disabled:
            revoked = cast(CursorResult, session.execute(
                sa.update(ApiToken).where(ApiToken.user_id == user.id, ApiToken.revoked_at.is_(None))
                .values(revoked_at=utcnow())
            )).rowcount or 0
        user.disabled = disabled
        user.session_generation += 1
        audit.record(session, actor=actor, action="user.disable" if disabled else "user.enable",
                     after={"user": name, **({"tokens_revoked": revoked} if disabled else {})})
    return user


@dataclass
class TakenOver:
    """What :func:`take_over` did: the API ``tokens_revoked``, the ``users_disabled``, the ``admin`` kept (``made``:
    made now, the archive had no such account) and its new API ``token`` (the only one that works)."""

    tokens_revoked: int
    users_disabled: int
    admin: str
    made: bool
    token: str


def take_over(session: Session, admin: str, password: str) -> TakenOver:
    """Make a restored database its restorer's (``v3d restore --new-secrets``, for an archive someone else made): the
    session-signing key dropped (a new one is made at the next start: every cookie of the archive's key is void),
    every API token revoked, every account disabled (until an admin enables it again: ``v3d users enable``) but
    ``admin``, which is an enabled admin with ``password`` and one new API token (made now when the archive has no
    such account). Every account's sessions end. Audited (``user.take_over``, by ``admin``). Commits.

    Raises:
        InvalidInputError: ``admin`` malformed or reserved (field ``name``), an empty password (field ``password``).
    """
    _check_password(password)
    with _HASHING:
        password_hash = PASSWORDS.hash(password)
    existing = session.scalar(sa.select(User).where(User.name == admin))
    if existing is None:
        _check_name(admin, session)
    keep = existing.id if existing is not None else -1
    with write_unit(session, lock=False):
        session.execute(sa.delete(ServerSecret))
        revoked = cast(CursorResult, session.execute(
            sa.update(ApiToken).where(ApiToken.revoked_at.is_(None)).values(revoked_at=utcnow()))).rowcount or 0
        disabled = cast(CursorResult, session.execute(
            sa.update(User).where(User.id != keep, User.disabled.is_(False)).values(disabled=True))).rowcount or 0
        session.execute(sa.update(User).values(session_generation=User.session_generation + 1))
        session.execute(sa.update(User).where(User.id == keep).values(
            role=UserRole.ADMIN, disabled=False, password_hash=password_hash))
        audit.record(session, actor=admin, action="user.take_over",
                     after={"user": admin, "tokens_revoked": revoked, "users_disabled": disabled})
    session.expire_all()
    if existing is None:
        token = create_user(session, admin, "admin", password)[1]
    else:
        token = issue_token(session, admin, label="restore --new-secrets").token
    return TakenOver(tokens_revoked=revoked, users_disabled=disabled, admin=admin, made=existing is None, token=token)


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
        with write_unit(session, lock=False):
            user.password_hash = new_hash
    return user


def _a_job_is_running_on_sqlite(session: Session) -> bool:
    """True when the session's database is SQLite and a job runs on it (any node, any process). On SQLite (WAL) a
    transaction that has read and then writes fails at once ("database is locked") when another connection committed
    in between, and an import's batch reads, calibrates for seconds and only then writes: a bookkeeping write landing
    then would fail the import (``app.services.jobs.runner`` keeps its own heartbeat out of the batches likewise)."""
    if session.get_bind().dialect.name != "sqlite":
        return False
    return session.scalar(sa.select(Job.id).where(Job.state == JobState.RUNNING).limit(1)) is not None


def resolve_token(session: Session, token: str) -> Optional[User]:
    """The enabled user owning the API token ``token`` (neither revoked nor expired), else None. Refreshes the token's
    ``last_used_at`` when older than :data:`TOKEN_USE_RESOLUTION` (commits then). Best effort, never at the cost of
    other work: when the database's write lock is busy, or on SQLite while a job runs
    (:func:`_a_job_is_running_on_sqlite`), the refresh waits for a later request."""
    if not token.startswith(TOKEN_PREFIX) or len(token) > 200:
        return None
    now = utcnow()
    row = session.execute(
        sa.select(ApiToken, User).join(User, ApiToken.user_id == User.id)
        .where(ApiToken.token_hash == hash_token(token), User.disabled.is_(False), ApiToken.revoked_at.is_(None),
               sa.or_(ApiToken.expires_at.is_(None), ApiToken.expires_at > now))
    ).first()
    if row is None:
        return None
    api_token, user = row
    if (api_token.last_used_at is None or now - api_token.last_used_at > TOKEN_USE_RESOLUTION) \
            and not _a_job_is_running_on_sqlite(session):
        user_id = user.id
        try:
            with write_unit(session, lock=False):
                api_token.last_used_at = now
        except sa.exc.OperationalError:
            # SQLite's write lock is another writer's (an edit of another worker): the request must not
            # fail for a timestamp, which the next request refreshes. Read the user again after the rollback.
            return session.get(User, user_id)
    return user


def token_user(session: Session, token: str) -> Optional[tuple[int, str, str]]:
    """``(id, name, role)`` of the user :func:`resolve_token` finds for ``token`` (the same conditions), read by one
    statement of the tables' columns built once: what every request sent with a token asks first, where building and
    loading the two mapped objects was most of its look-up's cost. When the token's ``last_used_at`` is due for its
    refresh, :func:`resolve_token` looks it up again and refreshes it."""
    if not token.startswith(TOKEN_PREFIX) or len(token) > 200:
        return None
    now = utcnow()
    row = session.execute(_token_user_statement(), {"token_hash": hash_token(token), "now": now}).first()
    if row is None:
        return None
    if row.last_used_at is None or now - row.last_used_at > TOKEN_USE_RESOLUTION:
        user = resolve_token(session, token)
        return None if user is None else (user.id, user.name, user.role.value)
    return row.id, row.name, row.role.value


@functools.cache
def _token_user_statement() -> sa.Select:
    """:func:`token_user`'s statement (parameters ``token_hash`` and ``now``): :func:`resolve_token`'s conditions on
    the tables' columns."""
    tokens, users = (cast(sa.Table, m.__table__) for m in (ApiToken, User))
    t, u = tokens.c, users.c
    return (sa.select(u.id, u.name, u.role, t.last_used_at).join_from(tokens, users, t.user_id == u.id)
            .where(t.token_hash == sa.bindparam("token_hash"), u.disabled.is_(False), t.revoked_at.is_(None),
                   sa.or_(t.expires_at.is_(None), t.expires_at > sa.bindparam("now"))))


def resolve_session_user(session: Session, user_id: int, generation: int) -> Optional[User]:
    """The enabled user of a session cookie (its ``user_id`` and ``session_generation``), else None:
    a session outlives neither a logout nor a disable (both raise the generation)."""
    user = session.get(User, user_id)
    if user is None or user.disabled or user.session_generation != generation:
        return None
    return user


def end_sessions(session: Session, user_id: int) -> None:
    """End every browser session of the user (logout); commits."""
    with write_unit(session, lock=False):
        session.execute(sa.update(User).where(User.id == user_id)
                        .values(session_generation=User.session_generation + 1))


def list_users(session: Session) -> list[UserSummary]:
    """Every user by name, with the number of API tokens that work (neither revoked nor expired)."""
    counts = (sa.select(ApiToken.user_id, sa.func.count(ApiToken.id).label("n"))
              .where(ApiToken.revoked_at.is_(None),
                     sa.or_(ApiToken.expires_at.is_(None), ApiToken.expires_at > utcnow()))
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
    with contextlib.suppress(IntegrityError), write_unit(session, lock=False):  # rolled back: another process won
        session.add(ServerSecret(name="session", value=secrets.token_urlsafe(48)))
    return session.get(ServerSecret, "session").value  # type: ignore[union-attr]  # inserted above, or by another process
