"""People and their credentials: users, API tokens (hashed), login rate-limit counters, the server's session
secret.
"""
from __future__ import annotations

from datetime import datetime
from typing import Optional

import sqlalchemy as sa
from sqlalchemy.orm import Mapped, mapped_column, relationship, validates

from app.core.names import name_key
from app.db.models.base import Base
from app.db.models.enums import UserRole
from app.db.types import enum_by_value, utcnow


# ----- people -----------------------------------------------------------------------------------------
class User(Base):
    """A person (or a script's owner) who may log in: ``name`` is unique and is what the audit log records.

    ``password_hash`` is an argon2 PHC string (``app.services.accounts.users``, via pwdlib), never the password;
    ``disabled`` users can neither log in nor use their tokens; ``demo`` marks the account
    ``v3d serve --demo`` made (its password is public: the login page shows it).
    ``session_generation`` is stored in every session cookie; logging out raises it, which ends every
    browser session of the user at once (the cookie itself cannot be recalled).
    """

    __tablename__ = "users"

    id: Mapped[int] = mapped_column(primary_key=True)
    name: Mapped[str] = mapped_column(sa.String(100), unique=True)
    #: ``app.core.names.name_key`` of the name, set with it: names that differ only by case or trailing dots cannot
    #: both be stored (nullable as ``Release.name_key``; every row the model writes has one).
    name_key: Mapped[Optional[str]] = mapped_column(sa.String(120), unique=True, index=True)
    role: Mapped[UserRole] = mapped_column(enum_by_value(UserRole, "user_role"))
    password_hash: Mapped[str] = mapped_column(sa.Text)
    created_at: Mapped[datetime] = mapped_column(default=utcnow)
    disabled: Mapped[bool] = mapped_column(default=False)
    demo: Mapped[bool] = mapped_column(default=False)
    session_generation: Mapped[int] = mapped_column(default=0)

    tokens: Mapped[list[ApiToken]] = relationship(
        back_populates="user", cascade="all, delete-orphan", passive_deletes=True, order_by="ApiToken.id"
    )

    @validates("name")
    def _keyed(self, _: str, name: str) -> str:
        self.name_key = name_key(name)
        return name


class ApiToken(Base):
    """An API token of a user (``Authorization: Bearer <token>``). Only the SHA-256 of the token is
    stored (hex, 64 characters): the token itself is shown once, when it is issued. ``id`` names it in
    listings and revocations; ``label`` says what it is for. ``last_used_at`` is refreshed at most once a
    minute (``app.services.accounts.users.TOKEN_USE_RESOLUTION``). A token works until ``expires_at`` (None:
    no expiry) unless ``revoked_at`` is set (revoked alone, or with every token of a disabled user)."""

    __tablename__ = "api_tokens"

    id: Mapped[int] = mapped_column(primary_key=True)
    user_id: Mapped[int] = mapped_column(sa.ForeignKey("users.id", ondelete="CASCADE"), index=True)
    token_hash: Mapped[str] = mapped_column(sa.String(64), unique=True)
    created_at: Mapped[datetime] = mapped_column(default=utcnow)
    last_used_at: Mapped[Optional[datetime]]
    label: Mapped[Optional[str]] = mapped_column(sa.String(100))
    expires_at: Mapped[Optional[datetime]]
    revoked_at: Mapped[Optional[datetime]]

    user: Mapped[User] = relationship(back_populates="tokens")


class RateLimitCounter(Base):
    """One fixed-window counter of ``app.services.accounts.throttle`` (the storage of the ``limits`` library
    that every server process shares): ``key`` names the limit and who it counts (e.g. failed logins of one
    name from one address), ``hits`` what was counted in the window, which ends at ``expires_at`` (Unix
    seconds); an expired row counts as zero and is reused."""

    __tablename__ = "rate_limit_counters"

    key: Mapped[str] = mapped_column(sa.String(300), primary_key=True)
    hits: Mapped[int] = mapped_column(default=0)
    expires_at: Mapped[float] = mapped_column(sa.Float, index=True)


class ServerSecret(Base):
    """A secret of the server by name, generated once and shared by every worker and restart:
    ``session`` signs the browser's session cookies (``V3D_SESSION_SECRET`` overrides it)."""

    __tablename__ = "server_secrets"

    name: Mapped[str] = mapped_column(sa.String(40), primary_key=True)
    value: Mapped[str] = mapped_column(sa.Text)
    created_at: Mapped[datetime] = mapped_column(default=utcnow)
