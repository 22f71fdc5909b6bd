"""The API docs render in Chromium with every request answered by this server: no CDN, no font
service, no schema validator. The real app is served by uvicorn on a free port."""
from __future__ import annotations

from collections.abc import Iterator
from urllib.parse import urlsplit

import pytest

from app.core.config import Settings
from app.main import create_app
from tests.live_server import serve_app

pytestmark = pytest.mark.browser


@pytest.fixture(scope="module")
def base_url(db_url: str) -> Iterator[str]:
    """URL of ``create_app`` served by uvicorn in a thread (the docs need no data)."""
    with serve_app(create_app(Settings(database_url=db_url))) as url:
        yield url


def test_docs_render_offline(base_url: str, browser) -> None:
    own_host = urlsplit(base_url).netloc
    foreign: list[str] = []

    def guard(route) -> None:
        if urlsplit(route.request.url).netloc == own_host or route.request.url.startswith(("data:", "blob:")):
            route.continue_()
        else:
            foreign.append(route.request.url)
            route.abort()

    context = browser.new_context()
    try:
        tab = context.new_page()
        tab.route("**/*", guard)
        tab.goto(base_url + "/docs")
        tab.locator(".opblock").first.wait_for(timeout=20_000)  # the operations are drawn
        tab.wait_for_load_state("networkidle")
    finally:
        context.close()
    assert foreign == [], f"/docs asked other hosts: {foreign}"
