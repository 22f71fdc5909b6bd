"""Failed logins are limited (``app.services.accounts.throttle``, issue 15): 60 wrong passwords for one name
were 60 x 401 with no slowing down. Now 10 failures of one name from one address, or 50 from one address,
within the window answer 429 with Retry-After until it passes (a right password too); the counters are in
the database, shared by every app (worker) on it; X-Forwarded-For counts only from a trusted proxy."""
from __future__ import annotations

import pytest
import sqlalchemy as sa
from fastapi import FastAPI
from fastapi.testclient import TestClient
from pwdlib import PasswordHash
from pwdlib.hashers.argon2 import Argon2Hasher

from app.db.models import RateLimitCounter, User
from app.main import create_app
from app.services.accounts import users
from tests.accounts import Account

pytestmark = pytest.mark.engine

NOW = 1_900_000_000.0
#: argon2id at its lightest parameters. The throttle is these tests' subject, not the hash's cost: a check of the
#: recommended parameters costs about a tenth of a second on a quiet machine (a third under load), and these tests
#: make some 130 of them, each failure as costly as the server's.
LIGHT = PasswordHash((Argon2Hasher(time_cost=1, memory_cost=8, parallelism=1),))


@pytest.fixture(autouse=True)
def _light_hashes(app: FastAPI, accounts: dict[str, Account], monkeypatch: pytest.MonkeyPatch) -> None:
    """The accounts' stored hashes and the unknown name's dummy hash made with :data:`LIGHT`, in the test's own
    transaction (rolled back after it). A login still checks the password with argon2, by the parameters its hash
    names, and a right one is rehashed with the recommended parameters as in service."""
    monkeypatch.setattr(users, "_DUMMY_HASH", LIGHT.hash("v3d: no such user"))
    with app.state.session_factory() as session:
        for account in accounts.values():
            session.execute(sa.update(User).where(User.name == account.name)
                            .values(password_hash=LIGHT.hash(account.password)))
        session.commit()


@pytest.fixture
def clock(app: FastAPI) -> list[float]:
    """The throttle's clock (Unix seconds), moved by the test."""
    now = [NOW]
    app.state.login_throttle.storage.clock = lambda: now[0]
    return now


def _login(client: TestClient, name: str, password: str, **headers: str):
    return client.post("/api/auth/login", json={"name": name, "password": password}, headers=headers)


def test_ten_failures_of_a_name_lock_that_name_from_that_address_until_the_window_passes(
        app: FastAPI, accounts: dict[str, Account], clock: list[float]) -> None:
    admin = accounts["admin"]
    with TestClient(app, client=("198.51.100.7", 40000)) as attacker, \
            TestClient(app, client=("203.0.113.9", 40000)) as colleague:
        assert [_login(attacker, admin.name, f"guess {i}").status_code for i in range(10)] == [401] * 10
        locked = _login(attacker, admin.name, admin.password)  # the right password, too late
        assert locked.status_code == 429 and "too many failed logins" in locked.json()["detail"]
        assert 1 <= int(locked.headers["retry-after"]) <= 300
        assert _login(attacker, accounts["reviewer"].name, accounts["reviewer"].password).status_code == 200
        assert _login(colleague, admin.name, admin.password).status_code == 200  # another address
        clock[0] = NOW + 301
        assert _login(attacker, admin.name, admin.password).status_code == 200


def test_fifty_failures_from_one_address_lock_the_address(app: FastAPI, accounts: dict[str, Account],
                                                          clock: list[float]) -> None:
    with TestClient(app, client=("198.51.100.8", 40000)) as attacker:
        codes = [_login(attacker, f"name{i % 10}", "wrong").status_code for i in range(50)]
        assert codes == [401] * 50
        answer = _login(attacker, accounts["annotator"].name, accounts["annotator"].password)
        assert answer.status_code == 429 and int(answer.headers["retry-after"]) <= 300
        clock[0] = NOW + 400
        assert _login(attacker, accounts["annotator"].name, accounts["annotator"].password).status_code == 200


def test_x_forwarded_for_counts_only_from_a_trusted_proxy(app: FastAPI, db_settings, accounts: dict[str, Account],
                                                          clock: list[float]) -> None:
    admin = accounts["admin"]
    with TestClient(app, client=("198.51.100.9", 40000)) as attacker:  # no trusted proxy: the header is ignored
        for i in range(10):
            assert _login(attacker, admin.name, "x", **{"X-Forwarded-For": f"192.0.2.{i}"}).status_code == 401
        assert _login(attacker, admin.name, "x", **{"X-Forwarded-For": "192.0.2.200"}).status_code == 429
    proxied = create_app(db_settings.model_copy(update={"trusted_proxies": ["10.0.0.0/8"]}))
    proxied.state.session_factory = app.state.session_factory
    proxied.state.login_throttle.storage.clock = lambda: clock[0]
    with TestClient(proxied, client=("10.0.0.2", 40000)) as proxy:
        for _ in range(10):
            assert _login(proxy, admin.name, "x", **{"X-Forwarded-For": "192.0.2.1"}).status_code == 401
        assert _login(proxy, admin.name, admin.password, **{"X-Forwarded-For": "192.0.2.1"}).status_code == 429
        # another client behind the same proxy is not locked out, whatever it writes left of the proxy's entry
        ok = _login(proxy, admin.name, admin.password, **{"X-Forwarded-For": "192.0.2.1, 192.0.2.2"})
        assert ok.status_code == 200


def test_every_app_on_the_database_counts_the_same_failures(app: FastAPI, db_settings,
                                                             accounts: dict[str, Account], clock: list[float]) -> None:
    """Two server processes (two apps on one database) share the counters."""
    other = create_app(db_settings)
    other.state.session_factory = app.state.session_factory
    other.state.login_throttle.storage.clock = lambda: clock[0]
    admin = accounts["admin"]
    with (TestClient(app, client=("198.51.100.10", 1)) as first,
          TestClient(other, client=("198.51.100.10", 2)) as second):
        for i in range(10):
            assert _login(first if i % 2 else second, admin.name, "x").status_code == 401
        assert _login(first, admin.name, admin.password).status_code == 429
        assert _login(second, admin.name, admin.password).status_code == 429


def test_login_declares_429_with_retry_after(app: FastAPI) -> None:
    answer = app.openapi()["paths"]["/api/auth/login"]["post"]["responses"]["429"]
    assert "Retry-After" in answer["headers"]


def _counters(app: FastAPI) -> int:
    with app.state.session_factory() as session:
        return session.scalar(sa.select(sa.func.count()).select_from(RateLimitCounter))


def test_ended_windows_are_deleted_so_the_table_stays_as_small_as_the_live_windows(
        app: FastAPI, accounts: dict[str, Account], clock: list[float]) -> None:
    """A spray of names from many addresses left one row per name and address for ever; now each failure
    deletes ended windows, so after the window only the live counters remain."""
    for a in range(5):
        with TestClient(app, client=(f"198.51.100.{20 + a}", 40000)) as sprayer:
            for i in range(8):
                assert _login(sprayer, f"sprayed{a}-{i}", "x").status_code == 401
    assert _counters(app) == 5 * 8 + 5  # one per name and address, one per address
    clock[0] = NOW + 301
    with TestClient(app, client=("203.0.113.50", 40000)) as later:
        assert _login(later, "someone", "x").status_code == 401
    assert _counters(app) == 2  # the two counters of the live failure
    with TestClient(app, client=("198.51.100.20", 40000)) as sprayer:  # its ended window counts from zero
        assert _login(sprayer, accounts["admin"].name, accounts["admin"].password).status_code == 200


def test_an_ipv6_client_is_its_64_network(app: FastAPI, accounts: dict[str, Account], clock: list[float]) -> None:
    """A host holds a whole /64 and picks its own addresses in it: each guess from a new address of the same /64
    counts against the same client."""
    admin = accounts["admin"]
    for i in range(10):
        with TestClient(app, client=(f"2001:db8:7:1::{i + 1:x}", 40000)) as attacker:
            assert _login(attacker, admin.name, "x").status_code == 401
    with TestClient(app, client=("2001:db8:7:1:ffff::99", 40000)) as same_network:
        assert _login(same_network, admin.name, admin.password).status_code == 429
    with TestClient(app, client=("2001:db8:7:2::1", 40000)) as other_network:
        assert _login(other_network, admin.name, admin.password).status_code == 200
