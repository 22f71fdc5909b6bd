"""What the browser tests share: the ``data-testid`` selector and reading the API from the page."""
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
