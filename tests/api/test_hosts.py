"""Issue 27, item 3: the ``Host`` check (``app.api.hosts``). Was: nothing looked at ``Host``, so a web page whose
name an attacker rebinds to 127.0.0.1 (DNS rebinding) logged in as the demo admin of a ``--demo`` server and
created an admin of its own with the CSRF token of the login answer.

The apps here are built without the test client's ``testserver`` among their allowed hosts (the other tests'
settings name it, ``tests/conftest.py``): what a served v3d does by default."""
from __future__ import annotations

import pytest
from fastapi import FastAPI
from fastapi.testclient import TestClient

from app.core.config import Settings
from app.services.accounts import users
from tests.accounts import Account


@pytest.fixture
def strict_app(app: FastAPI, db_settings: Settings):
    """``make(allowed_hosts)``: the app on the test's database with only those hosts besides the loopback names."""
    from app.main import create_app

    def make(allowed: list[str] | None = None) -> FastAPI:
        made = create_app(db_settings.model_copy(update={"allowed_hosts": allowed or []}))
        made.state.session_factory = app.state.session_factory
        return made

    return make


def test_the_dns_rebinding_login_as_the_demo_admin_gets_400_and_no_session(strict_app, app: FastAPI) -> None:
    """The attack of issue 27 against a ``v3d serve --demo`` on 127.0.0.1:8000: the browser's page (its name now
    resolving to 127.0.0.1, so the peer is loopback) posts demo / demo naming its own host."""
    with app.state.session_factory() as session:
        users.ensure_demo_account(session)
    served = strict_app()
    with TestClient(served, client=("127.0.0.1", 50000), base_url="http://rebind.attacker.example:8000") as page:
        login = page.post("/api/auth/login", json={"name": "demo", "password": "demo"})
        assert login.status_code == 400 and "v3d_session" not in login.cookies and "csrf" not in login.text
        assert page.get("/api/auth/demo").status_code == 400  # nor is the hint given
        made = page.post("/api/users", json={"name": "rebind-backdoor", "role": "admin", "password": "x" * 12})
        assert made.status_code == 400
    with app.state.session_factory() as session:
        assert "rebind-backdoor" not in {u.name for u in users.list_users(session)}
    # the same browser by a loopback name: the demo account logs in
    for host in ("127.0.0.1:8000", "localhost:8000", "[::1]:8000", "127.0.0.1"):
        with TestClient(served, client=("127.0.0.1", 50000), base_url=f"http://{host}") as here:
            answer = here.post("/api/auth/login", json={"name": "demo", "password": "demo"})
            assert answer.status_code == 200 and answer.json()["role"] == "admin", host


def test_an_allowed_host_works_and_the_demo_still_needs_a_loopback_host(strict_app, app: FastAPI,
                                                                        accounts: dict[str, Account]) -> None:
    """``V3D_ALLOWED_HOSTS`` lets the served name through (any port); even then the demo account, whose password is
    public, logs in only by a loopback name (a rebound name an admin allowed by mistake gets 403)."""
    with app.state.session_factory() as session:
        users.ensure_demo_account(session)
    served = strict_app(["v3d.example.org", "*.lab.example"])
    for host in ("v3d.example.org", "v3d.example.org:8443", "a.lab.example"):
        with TestClient(served, client=("127.0.0.1", 50000), base_url=f"https://{host}") as named:
            assert named.get("/api/health").status_code == 200, host
            own = named.post("/api/auth/login", json={"name": "test-admin", "password": accounts["admin"].password})
            assert own.status_code == 200, host
            demo = named.post("/api/auth/login", json={"name": "demo", "password": "demo"})
            assert demo.status_code == 403 and "v3d_session" not in demo.cookies, host
            assert named.get("/api/auth/demo").json() == {"account": None}
    for host in ("evil.example", "v3d.example.org.evil.example", "lab.example.evil"):
        with TestClient(served, base_url=f"http://{host}") as other:
            assert other.get("/api/health").status_code == 400, host
            assert other.get("/").status_code == 400, host  # pages and static files too


def test_the_test_client_host_is_not_allowed_by_default(strict_app) -> None:
    with TestClient(strict_app()) as default:  # Host: testserver
        assert default.get("/api/health").status_code == 400
    with TestClient(strict_app(), base_url="http://127.0.0.1:8000") as loopback:
        assert loopback.get("/api/health").status_code == 200


def test_allowed_hosts_are_read_comma_separated_and_checked(monkeypatch) -> None:
    monkeypatch.setenv("V3D_ALLOWED_HOSTS", " V3D.example.org, *.lab.example ,::1")
    assert Settings().allowed_hosts == ["v3d.example.org", "*.lab.example", "[::1]"]
    monkeypatch.setenv("V3D_ALLOWED_HOSTS", "")
    assert Settings().allowed_hosts == []
    with pytest.raises(ValueError, match="V3D_ALLOWED_HOSTS"):
        Settings(allowed_hosts="v3d.*.org")
