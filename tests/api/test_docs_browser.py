"""The API docs render in Chromium with every request answered by this server: no CDN, no font
service, no schema validator. The real app is served by uvicorn on a free port."""
from __future__ import annotations

from collections.abc import Iterator
from urllib.parse import urlsplit

import pytest

from app.core.config import Settings
from app.main import create_app
from tests.browser.support import pump_until
from tests.live_server import serve_app

pytestmark = pytest.mark.browser


@pytest.fixture(scope="module")
def base_url(db_url: str) -> Iterator[str]:
    """URL of ``create_app`` served by uvicorn in a thread (the docs need no data)."""
    with serve_app(create_app(Settings(database_url=db_url))) as url:
        yield url


#: The request the test has the page make last, once everything it draws has asked for what it needs.
SENTINEL = "/api/health?the-docs-page-is-drawn"

#: In the page: the fonts loaded and two animation frames drawn (the images and fonts of what is drawn are asked for
#: as it is laid out and painted), then the sentinel's request, which the page sends after all of those.
_THEN_SENTINEL = """async (sentinel) => {
  await document.fonts.ready;
  await new Promise((drawn) => requestAnimationFrame(() => requestAnimationFrame(drawn)));
  fetch(sentinel).catch(() => {});
}"""


def test_docs_render_offline(base_url: str, browser) -> None:
    own_host = urlsplit(base_url).netloc
    foreign: list[str] = []
    last: list[str] = []

    def guard(route) -> None:
        if route.request.url.endswith(SENTINEL):
            last.append(route.request.url)
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
        tab.locator(".opblock").first.wait_for()  # the operations are drawn
        # no request to another host can come after the sentinel's, which the page sends once it has drawn them:
        # the requests reach the route in the order the page sends them
        tab.evaluate(_THEN_SENTINEL, SENTINEL)
        pump_until(tab, lambda: last, "the page's request after the drawn docs")
    finally:
        context.close()
    assert foreign == [], f"/docs asked other hosts: {foreign}"
