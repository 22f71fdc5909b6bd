"""The app around the API: offline OpenAPI docs, the UI pages, static files revalidated by ETag."""
from __future__ import annotations

import re

import pytest
from fastapi.testclient import TestClient

from app.core.paths import STATIC_DIR

from .factories import Scene

_REF = re.compile(r"""(?:src|href)\s*=\s*["']([^"']+)["']|url:\s*'([^']+)'""")


def _references(html: str) -> list[str]:
    return [a or b for a, b in _REF.findall(html)]


def test_docs_load_every_asset_from_this_server(client: TestClient) -> None:
    page = "/docs"
    answer = client.get(page)
    assert answer.status_code == 200
    refs = _references(answer.text)
    assert any(r.endswith(".js") for r in refs), refs
    for ref in refs:
        assert ref.startswith("/") and not ref.startswith("//"), f"{page} references an external host: {ref}"
        asset = client.get(ref)
        assert asset.status_code == 200, ref
        assert len(asset.content) > 0
    assert "<script>" not in answer.text  # the start-up is a served file: the CSP allows no inline script
    start_up = client.get("/static/js/docs.js").text
    assert "validatorUrl: null" in start_up  # no schema validation by validator.swagger.io


def test_every_answer_carries_the_security_headers(client: TestClient) -> None:
    """A CSP that allows this server's scripts only (no inline script, no CDN), and the hardening
    headers, on pages, static files, API answers and errors alike."""
    for path in ("/", "/docs", "/static/js/docs.js", "/api/games", "/api/systems/999999", "/openapi.json"):
        headers = client.get(path).headers
        csp = headers["content-security-policy"]
        assert "script-src 'self';" in csp and "unsafe-inline" not in csp.split("script-src")[1].split(";")[0]
        assert "frame-ancestors 'none'" in csp and "default-src 'self'" in csp
        assert headers["x-content-type-options"] == "nosniff" and headers["x-frame-options"] == "DENY"
        assert headers["referrer-policy"] == "same-origin"


def test_redoc_is_not_served(client: TestClient) -> None:
    assert client.get("/redoc").status_code == 404  # its bundle fetches a logo from cdn.redoc.ly


def test_openapi_lists_the_resources(client: TestClient) -> None:
    spec = client.get("/openapi.json").json()
    tags = {t for ops in spec["paths"].values() for op in ops.values() for t in op.get("tags", [])}
    assert {"games", "systems", "frames", "imports", "exports"} <= tags
    assert "/api/frames/{frame_id}/ball" in spec["paths"]


@pytest.mark.skipif(not (STATIC_DIR / "index.html").is_file(), reason="static UI not present")
def test_ui_pages_and_static_files(client: TestClient, scene: Scene) -> None:
    queue = client.get("/")
    assert queue.status_code == 200 and "text/html" in queue.headers["content-type"]
    assert queue.text == (STATIC_DIR / "index.html").read_text(encoding="utf-8")
    system = client.get(f"/systems/{scene.system_id}")
    assert system.text == (STATIC_DIR / "system.html").read_text(encoding="utf-8")
    module = client.get("/static/js/api.js")
    assert module.status_code == 200 and module.headers["cache-control"] == "no-cache"
    assert "javascript" in module.headers["content-type"]
    again = client.get("/static/js/api.js", headers={"If-None-Match": module.headers["etag"]})
    assert again.status_code == 304
    assert client.get("/static/js/nothing-here.js").status_code == 404
