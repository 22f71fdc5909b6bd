"""What the browser tests share: the ``data-testid`` selector, reading and writing the API from the page
(its session cookie; writes with the session's CSRF token, as ``static/js/api.js`` sends it) and
logging in through the login page."""
from __future__ import annotations

TESTID = "[data-testid={}]"


def tid(name: str) -> str:
    """The CSS selector of the element whose ``data-testid`` is ``name``."""
    return TESTID.format(name)


def api_json(page, path: str):
    """GET ``path`` on the page's server (its cookies and base URL) and answer the JSON; fails the test
    on a non-2xx answer, naming the path and the status."""
    response = page.request.get(path)
    assert response.ok, f"GET {path}: {response.status} {response.text()}"
    return response.json()


def api_write(page, method: str, path: str, data=None, headers: dict | None = None):
    """``method`` ``path`` with the JSON ``data`` on the page's server as its logged-in session: the
    CSRF token of ``GET /api/auth/me`` in ``X-CSRF-Token``, and ``headers`` (e.g. ``If-Match``). Answers
    Playwright's response."""
    csrf = api_json(page, "/api/auth/me")["csrf_token"]
    return page.request.fetch(path, method=method, data=data, headers={"X-CSRF-Token": csrf, **(headers or {})})


def log_in(page, account) -> None:
    """Fill and send the login page the page is on with the account's name and password."""
    page.locator(tid("login-form")).wait_for()
    page.fill(tid("login-name"), account.name)
    page.fill(tid("login-password"), account.password)
    page.click(tid("login-submit"))
