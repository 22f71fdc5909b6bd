"""Test accounts: one user per role, made through ``app.services.accounts.users`` in a migrated database, and
the ways tests authenticate as them (a browser session logged in through ``POST /api/auth/login``, or
an API token). Hashing a password with argon2 takes about a second here, so accounts are made once per
database and logged in once per test session."""
from __future__ import annotations

from dataclasses import dataclass

from fastapi.testclient import TestClient

from app.api.auth import ROLES
from app.api.authentication import CSRF_HEADER, SESSION_COOKIE
from app.core.config import Settings
from app.db.session import make_engine, make_session_factory
from app.main import create_app
from app.services.accounts.users import create_user

#: Every test account's password (the name is ``test-<role>``).
PASSWORD = "correct horse battery staple"


@dataclass
class Account:
    """A user of the test database: its API token and, once logged in, its browser session."""

    name: str
    role: str
    password: str
    token: str
    cookie: str | None = None
    csrf: str | None = None

    @property
    def bearer(self) -> dict[str, str]:
        """The ``Authorization`` header of its API token."""
        return {"Authorization": f"Bearer {self.token}"}


def make_accounts(database_url: str, login: bool = True, roles: tuple[str, ...] = ROLES) -> dict[str, Account]:
    """Commit one user per role of ``roles`` (``test-annotator``, ``test-reviewer``, ``test-admin``) into the
    migrated database at ``database_url`` and, with ``login``, log each in through the real login
    route (its cookie and CSRF token kept: the session-signing key lives in the database, so every app
    on it accepts them)."""
    engine = make_engine(database_url)
    accounts: dict[str, Account] = {}
    try:
        with make_session_factory(engine)() as session:
            for role in roles:
                user, token = create_user(session, f"test-{role}", role, PASSWORD)
                accounts[role] = Account(user.name, role, PASSWORD, token)
    finally:
        engine.dispose()
    if login:
        with TestClient(create_app(Settings(database_url=database_url))) as client:
            for account in accounts.values():
                answer = client.post("/api/auth/login", json={"name": account.name, "password": account.password})
                assert answer.status_code == 200, answer.text
                account.cookie = client.cookies[SESSION_COOKIE]
                account.csrf = answer.json()["csrf_token"]
                client.cookies.clear()
    return accounts


def as_session(client: TestClient, account: Account) -> TestClient:
    """``client`` acting as the account's logged-in browser: its session cookie, and its CSRF token
    on every request (as ``static/js/api.js`` sends it on writes)."""
    client.cookies.set(SESSION_COOKIE, account.cookie or "")
    client.headers[CSRF_HEADER] = account.csrf or ""
    return client


def as_token(client: TestClient, account: Account) -> TestClient:
    """``client`` sending the account's API token (no cookie, no CSRF header)."""
    client.cookies.clear()
    client.headers.pop(CSRF_HEADER, None)
    client.headers.update(account.bearer)
    return client
