"""Users and roles over HTTP (issue 7): every route of the app, found by walking ``app.routes``, is
public or refuses anonymous requests (401) and the roles below its least role (403), per role and per
way in (API token, browser session); CSRF on session writes; login, logout, disabled users, the session
cookie and its key shared by every app (worker) on one database."""
from __future__ import annotations

import re
from collections.abc import Iterator

import pytest
from fastapi import FastAPI
from fastapi.routing import iter_route_contexts
from fastapi.testclient import TestClient
from pydantic import SecretStr, ValidationError

from app.api.auth import ROLES
from app.api.authentication import CSRF_HEADER, SESSION_COOKIE
from app.core.config import Settings
from app.main import create_app
from app.services.accounts import users
from tests.accounts import Account, as_session, as_token

from .factories import Scene

pytestmark = pytest.mark.engine

#: (method, path) answered without a principal: the pages, the docs, the login and its demo hint.
PUBLIC = {("GET", "/"), ("GET", "/login"), ("GET", "/docs"), ("GET", "/openapi.json"), ("GET", "/systems/{system_id}"),
          ("POST", "/api/auth/login"), ("GET", "/api/auth/demo"), ("GET", "/api/health")}
WRITES = {"POST", "PUT", "PATCH", "DELETE"}


def _least_role(route) -> str | None:
    """The most trusted role named by a ``require_role`` dependency of the route (None: any principal)."""
    found: set[str] = set()

    def walk(dependant) -> None:
        for sub in dependant.dependencies:
            name = getattr(sub.call, "__name__", "")
            if name.startswith("require_") and name.removeprefix("require_") in ROLES:
                found.add(name.removeprefix("require_"))
            walk(sub)

    dependant = getattr(route, "dependant", None)  # plain Starlette routes (openapi.json) have none
    if dependant is not None:
        walk(dependant)
    return max(found, key=ROLES.index) if found else None


def _operations(app: FastAPI) -> list[tuple[str, str, str, object]]:
    """Every (method, path template, concrete path, route) the app answers, HEAD left out; path
    parameters become 999999 (no such row)."""
    ops = []
    for route in iter_route_contexts(app.routes):
        for method in sorted((route.methods or set()) - {"HEAD"}):
            ops.append((method, route.path, re.sub(r"\{[^}]+\}", "999999", route.path), route))
    return ops


@pytest.fixture
def tokens(app: FastAPI) -> Iterator[TestClient]:
    with TestClient(app) as c:
        yield c


def test_the_walk_sees_every_router(app: FastAPI) -> None:
    paths = {p for _, p, _, _ in _operations(app)}
    assert {"/api/frames/{frame_id}/ball", "/api/systems/{system_id}/review", "/api/imports", "/api/exports/yolo",
            "/api/exports/issia-3d", "/api/users", "/api/auth/me", "/"} <= paths
    assert len(paths) >= 25


def test_anonymous_requests_get_401_on_every_route_but_the_public_ones(app: FastAPI, anonymous: TestClient) -> None:
    for method, template, path, _ in _operations(app):
        answer = anonymous.request(method, path)
        if (method, template) in PUBLIC:
            assert answer.status_code not in (401, 403), (method, path, answer.status_code)
        else:
            assert answer.status_code == 401, (method, path, answer.status_code, answer.text)
            assert answer.json()["detail"] == "log in, or send Authorization: Bearer <token>"
            assert answer.headers["www-authenticate"] == "Bearer"
    assert anonymous.get("/static/js/api.js").status_code == 200  # static files are public
    assert anonymous.get("/docs-assets/swagger-ui-bundle.js").status_code == 200


def test_a_wrong_token_or_a_forged_cookie_is_anonymous(anonymous: TestClient, accounts: dict[str, Account]) -> None:
    assert anonymous.get("/api/games", headers={"Authorization": "Bearer v3d_not-a-token"}).status_code == 401
    assert anonymous.get("/api/games", headers={"Authorization": f"Basic {accounts['admin'].token}"}).status_code == 401
    forged = accounts["admin"].cookie.rsplit(".", 1)[0] + ".AAAAAAAAAAAAAAAAAAAAAAAAAAA"
    anonymous.cookies.set(SESSION_COOKIE, forged)
    assert anonymous.get("/api/games").status_code == 401


def test_every_write_route_states_its_least_role(app: FastAPI) -> None:
    unstated = [(m, p) for m, p, _, route in _operations(app)
                if m in WRITES and (m, p) not in PUBLIC and p not in ("/api/auth/logout",)
                and _least_role(route) is None]
    assert unstated == [], "write routes without require_role (app.api.auth)"


EXPECTED_LEAST_ROLE = {
    ("PATCH", "/api/frames/{frame_id}/ball"): "annotator",
    ("PUT", "/api/frames/{frame_id}/field-lines"): "annotator",
    ("POST", "/api/frames/{frame_id}/field-lines/mirror"): "annotator",
    ("POST", "/api/frames/{frame_id}/exclusion"): "annotator",
    ("POST", "/api/frames/{frame_id}/review"): "annotator",
    # any role past the role check: an annotator may send "fixed" on a system returned to them, and nothing else (the
    # route refuses the rest with 403: tests/api/routes/test_team_loop.py)
    ("POST", "/api/systems/{system_id}/review"): "annotator",
    ("GET", "/api/stats/annotators"): "reviewer",
    ("POST", "/api/imports"): "admin",
    ("GET", "/api/exports/soccernet-v3d"): "admin",
    ("GET", "/api/exports/issia-3d"): "admin",
    ("GET", "/api/exports/yolo"): "admin",
    ("GET", "/api/exports/coco"): "admin",
    ("GET", "/api/users"): "admin",
    ("POST", "/api/users"): "admin",
    ("PATCH", "/api/users/{name}"): "admin",
    ("GET", "/api/users/{name}/tokens"): "admin",
    ("DELETE", "/api/users/{name}/tokens/{token_id}"): "admin",
    ("POST", "/api/recompute"): "admin",
    ("POST", "/api/exports/soccernet-v3d"): "admin",
    ("GET", "/api/jobs/{job_id}/result"): "admin",
    ("GET", "/api/jobs"): None,
    ("GET", "/api/jobs/{job_id}"): None,
    ("GET", "/api/systems"): None,
    ("GET", "/api/games"): None,
    ("POST", "/api/passes"): "annotator",  # issue 28: a review pass is a user's own, any role begins one
    ("POST", "/api/passes/{pass_id}/visits"): "annotator",
    ("GET", "/api/passes"): None,
    ("GET", "/api/predictions"): None,
    ("DELETE", "/api/predictions/{source}"): "admin",
    ("POST", "/api/releases"): "admin",
}


def test_the_roles_of_the_issue(app: FastAPI) -> None:
    """annotator: frame edits (and sending back a system returned to them); reviewer: system decisions and the
    per-annotator figures; admin: imports, every export, users; reads: any."""
    found = {(m, p): _least_role(r) for m, p, _, r in _operations(app)}
    assert {k: found.get(k, "missing") for k in EXPECTED_LEAST_ROLE} == EXPECTED_LEAST_ROLE


@pytest.mark.parametrize("via", ["token", "session"])
@pytest.mark.parametrize("role", ROLES)
def test_each_role_gets_403_below_the_least_role_of_every_route(app: FastAPI, tokens: TestClient,
                                                                accounts: dict[str, Account], role: str,
                                                                via: str) -> None:
    """Per role: 403 naming the needed role on every route whose least role is above it, and past the
    role check (no 401 / 403) everywhere else; sessions send their CSRF token."""
    client = as_token(tokens, accounts[role]) if via == "token" else as_session(tokens, accounts[role])
    checked = 0
    for method, template, path, route in _operations(app):
        if (method, template) in PUBLIC or template == "/api/auth/logout":
            continue
        least = _least_role(route)
        answer = client.request(method, path)
        if least is not None and ROLES.index(role) < ROLES.index(least):
            assert answer.status_code == 403, (role, method, path, answer.status_code)
            assert answer.json()["detail"] == f"this needs the {least} role; you are {role}"
        else:
            assert answer.status_code not in (401, 403), (role, method, path, answer.status_code, answer.text)
        checked += 1
    assert checked >= 20


# ----- CSRF -----------------------------------------------------------------------------------------
def test_session_writes_need_the_csrf_token_and_token_writes_do_not(tokens: TestClient, scene: Scene,
                                                                    accounts: dict[str, Account]) -> None:
    url, body = f"/api/systems/{scene.system_id}/review", {"status": "accepted", "comment": "ok"}
    client = as_session(tokens, accounts["reviewer"])
    del client.headers[CSRF_HEADER]
    missing = client.post(url, json=body)
    assert missing.status_code == 403 and CSRF_HEADER in missing.json()["detail"]
    wrong = client.post(url, json=body, headers={CSRF_HEADER: accounts["admin"].csrf})  # another session's token
    assert wrong.status_code == 403 and CSRF_HEADER in wrong.json()["detail"]
    assert client.get(url.removesuffix("/review")).json()["review"]["status"] == "pending"  # nothing stored
    right = client.post(url, json=body, headers={CSRF_HEADER: accounts["reviewer"].csrf})
    assert right.status_code == 200 and right.json()["status"] == "accepted"
    by_token = as_token(client, accounts["reviewer"])
    assert by_token.post(url, json={"status": "rejected"}).status_code == 428  # a token's write names its version
    etag = by_token.get(url.removesuffix("/review")).headers["ETag"]
    answer = by_token.post(url, json={"status": "rejected"}, headers={"If-Match": etag})
    assert answer.status_code == 200 and answer.json()["status"] == "rejected"


def test_401_comes_before_any_csrf_check(anonymous: TestClient, scene: Scene) -> None:
    answer = anonymous.post(f"/api/systems/{scene.system_id}/review", json={"status": "accepted"},
                            headers={CSRF_HEADER: "whatever"})
    assert answer.status_code == 401
    assert anonymous.post(f"/api/systems/{scene.system_id}/review", content=b"{not json").status_code == 401


# ----- login, logout, me ----------------------------------------------------------------------------
def test_login_answers_one_message_for_a_wrong_name_or_password(anonymous: TestClient,
                                                                accounts: dict[str, Account]) -> None:
    wrong_password = anonymous.post("/api/auth/login", json={"name": "test-admin", "password": "nope"})
    wrong_name = anonymous.post("/api/auth/login", json={"name": "nobody", "password": accounts["admin"].password})
    assert wrong_password.status_code == wrong_name.status_code == 401
    assert wrong_password.json() == wrong_name.json() == {"detail": "wrong name or password"}
    assert SESSION_COOKIE not in anonymous.cookies


def test_login_sets_a_strict_httponly_cookie_and_me_answers_the_csrf_token(anonymous: TestClient,
                                                                          accounts: dict[str, Account]) -> None:
    answer = anonymous.post("/api/auth/login",
                            json={"name": "test-annotator", "password": accounts["annotator"].password})
    assert answer.status_code == 200
    body = answer.json()
    assert (body["name"], body["role"], body["roles"], body["via"]) == ("test-annotator", "annotator", ["annotator"],
                                                                        "session")
    cookie = answer.headers["set-cookie"].lower()
    assert cookie.startswith(f"{SESSION_COOKIE}=") and "httponly" in cookie and "samesite=strict" in cookie
    assert "max-age=43200" in cookie and "secure" not in cookie
    me = anonymous.get("/api/auth/me").json()
    assert me == body and len(me["csrf_token"]) >= 40
    assert as_token(anonymous, accounts["admin"]).get("/api/auth/me").json() == {
        "name": "test-admin", "role": "admin", "roles": ["annotator", "reviewer", "admin"], "via": "token",
        "csrf_token": None}


def test_secure_cookies_setting_marks_the_cookie_secure(db_settings: Settings, app: FastAPI,
                                                         accounts: dict[str, Account]) -> None:
    secure = create_app(db_settings.model_copy(update={"secure_cookies": True}))
    secure.state.session_factory = app.state.session_factory
    with TestClient(secure, base_url="https://testserver") as c:
        answer = c.post("/api/auth/login", json={"name": "test-admin", "password": accounts["admin"].password})
    assert "; secure" in answer.headers["set-cookie"].lower()


def test_logout_ends_the_session_and_copies_of_its_cookie(app: FastAPI, accounts: dict[str, Account]) -> None:
    with TestClient(app) as browser, TestClient(app) as thief:
        login = browser.post("/api/auth/login",
                             json={"name": "test-reviewer", "password": accounts["reviewer"].password})
        csrf = login.json()["csrf_token"]
        thief.cookies.set(SESSION_COOKIE, browser.cookies[SESSION_COOKIE])
        assert thief.get("/api/auth/me").status_code == 200
        assert browser.post("/api/auth/logout").status_code == 403  # a write: it needs the CSRF token
        assert browser.post("/api/auth/logout", headers={CSRF_HEADER: csrf}).status_code == 204
        assert browser.get("/api/auth/me").status_code == 401
        assert thief.get("/api/auth/me").status_code == 401
        assert as_token(thief, accounts["reviewer"]).get("/api/auth/me").status_code == 200  # tokens live on


def test_a_disabled_user_can_neither_log_in_nor_use_its_session_or_token(app: FastAPI, tokens: TestClient,
                                                                         accounts: dict[str, Account]) -> None:
    client = as_session(tokens, accounts["annotator"])
    assert client.get("/api/games").status_code == 200
    with app.state.session_factory() as session:
        users.set_disabled(session, "test-annotator")
    assert client.get("/api/games").status_code == 401
    assert as_token(client, accounts["annotator"]).get("/api/games").status_code == 401
    login = client.post("/api/auth/login", json={"name": "test-annotator", "password": accounts["annotator"].password})
    assert login.status_code == 401


def test_every_app_on_the_database_shares_the_session_key_unless_overridden(db_settings: Settings, app: FastAPI,
                                                                            accounts: dict[str, Account]) -> None:
    """The cookie logged in by another app (another uvicorn worker, or before a restart) is accepted;
    with another ``V3D_SESSION_SECRET`` it is not."""
    for secret, expected in ((None, 200), ("another key, long enough to be accepted", 401)):
        worker = create_app(db_settings.model_copy(update={"session_secret": SecretStr(secret) if secret else None}))
        worker.state.session_factory = app.state.session_factory
        with TestClient(worker) as c:
            assert as_session(c, accounts["admin"]).get("/api/games").status_code == expected


def test_a_short_session_secret_is_refused_naming_the_variable(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("V3D_SESSION_SECRET", "x" * 31)
    with pytest.raises(ValidationError, match="V3D_SESSION_SECRET must be at least 32 characters"):
        Settings()
    monkeypatch.setenv("V3D_SESSION_SECRET", "x" * 32)
    assert Settings().session_secret.get_secret_value() == "x" * 32


def test_answers_holding_a_token_or_the_csrf_token_are_never_stored(client: TestClient,
                                                                    anonymous: TestClient,
                                                                    accounts: dict[str, Account]) -> None:
    """Token and CSRF answers carry ``Cache-Control: no-store`` (issue 15): no browser, proxy or disk
    cache keeps a secret."""
    login = anonymous.post("/api/auth/login", json={"name": "test-annotator",
                                                    "password": accounts["annotator"].password})
    made = client.post("/api/users", json={"name": "nora", "role": "annotator", "password": "pw"})
    for answer in (login, anonymous.get("/api/auth/me"), made, client.post("/api/users/nora/tokens"),
                   client.get("/api/users")):
        assert answer.status_code in (200, 201) and answer.headers["cache-control"] == "no-store", answer.url


def test_demo_hint_names_the_demo_account_only_when_it_exists(app: FastAPI) -> None:
    # a browser on this machine: a loopback peer naming a loopback Host (issue 27, item 3)
    with TestClient(app, client=("127.0.0.1", 50000), base_url="http://127.0.0.1:8000") as here:
        assert here.get("/api/auth/demo").json() == {"account": None}
        with app.state.session_factory() as session:
            assert "log in as 'demo' with password 'demo'" in users.ensure_demo_account(session)
        assert here.get("/api/auth/demo").json() == {"account": {"name": "demo", "password": "demo"}}
        answer = here.post("/api/auth/login", json={"name": "demo", "password": "demo"})
        assert answer.status_code == 200 and answer.json()["role"] == "admin"


@pytest.mark.parametrize("peer, headers", [
    (("203.0.113.9", 50000), {}),  # another machine
    (("::ffff:198.51.100.7", 50000), {}),
    (("127.0.0.1", 50000), {"X-Forwarded-For": "203.0.113.9"}),  # a proxy on this machine, declared or not
    (("127.0.0.1", 50000), {"Forwarded": "for=203.0.113.9"}),
    (("::1", 50000), {"X-Real-IP": "203.0.113.9"}),
])
def test_the_demo_account_never_logs_in_over_a_network_nor_through_a_proxy(app: FastAPI, peer, headers) -> None:
    """Was: ``v3d serve --demo`` on 127.0.0.1 behind a reverse proxy (nginx forwarding the network to it) gave
    anyone the demo admin, its password shown by ``GET /api/auth/demo``. The account logs in only from this machine
    without a proxy: 403 saying why (the hint says nothing); a declared proxy is refused by ``v3d serve --demo``."""
    with app.state.session_factory() as session:
        users.ensure_demo_account(session)
    with TestClient(app, client=peer) as there:
        assert there.get("/api/auth/demo", headers=headers).json() == {"account": None}
        answer = there.post("/api/auth/login", json={"name": "demo", "password": "demo"}, headers=headers)
        assert answer.status_code == 403 and "only on the machine that serves v3d" in answer.json()["detail"]
        assert "v3d_session" not in answer.cookies and there.get("/api/auth/me").status_code == 401


def test_users_routes_make_a_user_whose_token_works(client: TestClient, tokens: TestClient) -> None:
    made = client.post("/api/users", json={"name": "ines", "role": "reviewer", "password": "pw"})
    assert made.status_code == 201 and made.json()["token"].startswith("v3d_")
    assert client.post("/api/users", json={"name": "ines", "role": "admin", "password": "x"}).json()["field"] == "name"
    listed = {u["name"]: u for u in client.get("/api/users").json()}
    assert listed["ines"]["role"] == "reviewer" and listed["ines"]["tokens"] == 1
    tokens.headers["Authorization"] = f"Bearer {made.json()['token']}"
    assert tokens.get("/api/auth/me").json()["name"] == "ines"


def test_pages_stay_public_and_say_nothing_about_systems(anonymous: TestClient, client: TestClient) -> None:
    assert anonymous.get("/systems/999999").status_code == 200  # the page; it asks the person to log in
    assert client.get("/systems/999999").status_code == 404  # logged in: the missing-system page
    assert anonymous.get("/login").status_code == 200 and 'src="/static/js/login.js"' in anonymous.get("/login").text


def test_openapi_declares_the_bearer_and_session_schemes(anonymous: TestClient) -> None:
    spec = anonymous.get("/openapi.json").json()
    schemes = spec["components"]["securitySchemes"]
    assert schemes["bearer"] == {"type": "http", "scheme": "bearer", "description": schemes["bearer"]["description"]}
    assert (schemes["session"]["in"], schemes["session"]["name"]) == ("cookie", SESSION_COOKIE)
    assert spec["paths"]["/api/frames/{frame_id}/ball"]["patch"]["security"] == [{"bearer": []}, {"session": []}]
    assert "security" not in spec["paths"]["/api/auth/login"]["post"]


def test_tokens_are_listed_issued_with_a_label_and_expiry_and_revoked_one_by_one(client: TestClient,
                                                                                 tokens: TestClient) -> None:
    made = client.post("/api/users", json={"name": "otto", "role": "annotator", "password": "pw"}).json()
    assert made["label"] == "first token" and made["expires_at"] is None and isinstance(made["id"], int)
    ci = client.post("/api/users/otto/tokens", json={"label": "CI", "expires_days": 7})
    assert ci.status_code == 201 and ci.json()["label"] == "CI" and ci.json()["expires_at"]
    listed = client.get("/api/users/otto/tokens").json()
    assert [(t["id"], t["label"], t["state"]) for t in listed] == [(made["id"], "first token", "active"),
                                                                   (ci.json()["id"], "CI", "active")]
    assert all("token" not in t for t in listed)
    script = as_token(tokens, Account("otto", "annotator", "pw", ci.json()["token"]))
    assert script.get("/api/games").status_code == 200
    gone = client.delete(f"/api/users/otto/tokens/{ci.json()['id']}")
    assert gone.status_code == 200 and gone.json()["state"] == "revoked"
    assert script.get("/api/games").status_code == 401
    first = as_token(tokens, Account("otto", "annotator", "pw", made["token"]))
    assert first.get("/api/games").status_code == 200
    assert client.delete("/api/users/otto/tokens/999999").status_code == 404
    assert client.get("/api/users/nobody/tokens").status_code == 404
    bad = client.post("/api/users/otto/tokens", json={"expires_days": 0})
    assert bad.status_code == 422 and bad.json()["detail"][0]["loc"][-1] == "expires_days"


def test_disable_then_enable_brings_no_token_back(client: TestClient, tokens: TestClient) -> None:
    """The attack of issue 15: ``disable`` then ``enable`` revived every old token."""
    made = client.post("/api/users", json={"name": "pia", "role": "reviewer", "password": "pw"}).json()
    script = as_token(tokens, Account("pia", "reviewer", "pw", made["token"]))
    assert script.get("/api/games").status_code == 200
    assert client.patch("/api/users/pia", json={"disabled": True}).json()["disabled"] is True
    assert script.get("/api/games").status_code == 401
    assert client.patch("/api/users/pia", json={"disabled": False}).json()["disabled"] is False
    assert script.get("/api/games").status_code == 401
    assert [t["state"] for t in client.get("/api/users/pia/tokens").json()] == ["revoked"]
    assert tokens.post("/api/auth/login", json={"name": "pia", "password": "pw"}).status_code == 200


def test_a_role_change_applies_to_the_next_request(client: TestClient, tokens: TestClient) -> None:
    made = client.post("/api/users", json={"name": "quin", "role": "annotator", "password": "pw"}).json()
    script = as_token(tokens, Account("quin", "annotator", "pw", made["token"]))
    assert script.get("/api/users").status_code == 403
    changed = client.patch("/api/users/quin", json={"role": "admin"})
    assert changed.status_code == 200 and changed.json()["role"] == "admin"
    assert script.get("/api/users").status_code == 200
    assert client.patch("/api/users/quin", json={"role": "boss"}).status_code == 422
    assert client.patch("/api/users/nobody", json={}).status_code == 404


def test_admin_actions_are_audited_and_listed_to_admins_only(client: TestClient, tokens: TestClient,
                                                             accounts: dict[str, Account]) -> None:
    made = client.post("/api/users", json={"name": "rex", "role": "annotator", "password": "secret pw"}).json()
    issued = client.post("/api/users/rex/tokens", json={"label": "laptop"}).json()
    client.patch("/api/users/rex", json={"role": "reviewer"})
    client.delete(f"/api/users/rex/tokens/{issued['id']}")
    client.patch("/api/users/rex", json={"disabled": True})
    client.patch("/api/users/rex", json={"disabled": False})
    log = client.get("/api/audit?limit=6").json()
    assert [e["action"] for e in reversed(log["items"])] == [
        "user.create", "token.issue", "user.role", "token.revoke", "user.disable", "user.enable"]
    assert {e["actor"] for e in log["items"]} == {"test-admin"}  # the fixture's own users: cli:<os user>
    assert not any(e["revertible"] for e in log["items"])
    text = repr(log)
    assert made["token"] not in text and issued["token"] not in text and "secret pw" not in text
    reviewer = as_token(tokens, accounts["reviewer"])
    seen = reviewer.get("/api/audit?limit=50").json()
    assert seen["total"] == 0 and not any(e["action"].startswith(("user.", "token.")) for e in seen["items"])
    entry = log["items"][0]["id"]
    refused = client.post(f"/api/audit/{entry}/revert")
    assert refused.status_code == 422 and "changed a user or a token" in refused.json()["detail"]


def test_a_session_ends_twelve_hours_after_the_login_however_busy(app: FastAPI, accounts: dict[str, Account],
                                                                  monkeypatch: pytest.MonkeyPatch) -> None:
    """Starlette re-signs the cookie on every answer, which used to restart its 12 hours; the login time
    is now signed into it and counted from (issue 15)."""
    import app.api.authentication as authentication

    clock = [1_900_000_000.0]
    monkeypatch.setattr(authentication.time, "time", lambda: clock[0])
    with TestClient(app) as browser:
        login = browser.post("/api/auth/login",
                             json={"name": "test-reviewer", "password": accounts["reviewer"].password})
        assert login.status_code == 200
        for hours in (1, 4, 8, 11.9):  # a request every few hours: each re-signs the cookie
            clock[0] = 1_900_000_000.0 + hours * 3600
            assert browser.get("/api/auth/me").status_code == 200, hours
        clock[0] = 1_900_000_000.0 + 12 * 3600 + 1
        assert browser.get("/api/auth/me").status_code == 401


def test_a_session_cookie_without_a_login_time_is_refused() -> None:
    """A cookie signed before the login time was stored (or forged without it) names no principal."""
    from app.api.authentication import resolve_principal

    cookie = {"uid": 1, "gen": 0, "csrf": "x"}
    assert resolve_principal(lambda: None, None, cookie, max_age_s=43200) is None and cookie == {}
