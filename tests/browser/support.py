"""What the browser tests share: the ``data-testid`` selector, reading and writing the API from the page
(its session cookie; writes with the session's CSRF token, as ``static/js/api.js`` sends it) and
logging in through the login page."""
from __future__ import annotations

import itertools
import json
import re
import subprocess
import sys
import time
from collections.abc import Callable
from contextlib import contextmanager
from pathlib import Path

from tests.conftest import migrate_new_database

TESTID = "[data-testid={}]"
#: The pages' module of words, written from app/services/wording/words.py and the doubts' contract.
WORDS_JS = Path(__file__).resolve().parents[2] / "static" / "js" / "words.js"


def words_js_literal(name: str):
    """The JSON literal ``name`` of ``static/js/words.js`` (``WORDS``, ``LABEL_KINDS``: between ``/*<name>*/`` and
    the next ``/*END*/``), as the pages read it."""
    text = WORDS_JS.read_text(encoding="utf-8")
    return json.loads(text.split(f"/*{name}*/", 1)[1].split("/*END*/", 1)[0])


def import_into_new_database(settings, *datasets, then=None) -> None:
    """Migrate ``settings.database_url`` (a new database) and import each SoccerNet-v3 tree of ``datasets``
    through the importer, as ``v3d import soccernet-v3`` does; ``then(session)``, when given, runs after them
    in the same session (another import, a user). Each import commits on its own."""
    from app.db.session import make_engine, make_session_factory
    from app.services.transfer.importing import import_soccernet_v3

    migrate_new_database(settings.database_url)
    engine = make_engine(settings.database_url)
    try:
        with make_session_factory(engine)() as session:
            for dataset in datasets:
                import_soccernet_v3(session, dataset, settings)
                session.commit()
            if then is not None:
                then(session)
                session.commit()
    finally:
        engine.dispose()


#: The synthetic SoccerNet-v3 dev set (2 games, 40 systems) under ``../shared``.
DEV_SET = ("data", "synthetic", "soccernet-v3-dev")


def seed_dev_set(seeded_databases, shared_dir: Path, into: Path):
    """Settings of a copy in ``into`` of a seeded database (``tests/browser/conftest.py``'s ``SeededDatabases``)
    holding the dev set (:data:`DEV_SET`) imported as a user would, its frames named under the data root
    ``../shared/data``."""
    return seeded_databases.copy("soccernet-v3-dev",
                                 lambda settings: import_into_new_database(settings, shared_dir.joinpath(*DEV_SET)),
                                 into, data_root=shared_dir / "data")


def tid(name: str) -> str:
    """The CSS selector of the element whose ``data-testid`` is ``name``."""
    return TESTID.format(name)


def api_json(page, path: str):
    """GET ``path`` on the page's server (its cookies and base URL) and answer the JSON; fails the test
    on a non-2xx answer, naming the path and the status."""
    response = page.request.get(path)
    assert response.ok, f"GET {path}: {response.status} {response.text()}"
    return response.json()


#: How many times :func:`api_write` sends a write the server answered 503 (``Retry-After``) before it gives up.
WRITE_TRIES = 4


def api_write(page, method: str, path: str, data=None, headers: dict | None = None):
    """``method`` ``path`` with the JSON ``data`` on the page's server as its logged-in session: the
    CSRF token of ``GET /api/auth/me`` in ``X-CSRF-Token``, and ``headers`` (e.g. ``If-Match``). Answers
    Playwright's response.

    A 503 with ``Retry-After`` (the write lock was busy past ``V3D_WRITE_LOCK_TIMEOUT_S``: nothing was changed) is
    sent again after the time it names, up to :data:`WRITE_TRIES` times, as the API asks of every script client:
    the browser tests share two cores with the rest of the suite, where a write can wait past the timeout."""
    for _ in range(WRITE_TRIES):
        csrf = api_json(page, "/api/auth/me")["csrf_token"]
        response = page.request.fetch(path, method=method, data=data,
                                      headers={"X-CSRF-Token": csrf, **(headers or {})})
        wait = response.headers.get("retry-after")
        if response.status != 503 or wait is None:
            return response
        time.sleep(float(wait))
    return response


def wait_until(check, timeout_s: float = 30.0, every_s: float = 0.1):
    """Call ``check()`` until it answers something true, and answer that; the condition a test waits for when no
    element or response of a page says it (a row the server writes after a page has gone, say). Fails the test
    with the last answer after ``timeout_s``: a bound for a machine under load, not a measure of speed."""
    deadline = time.monotonic() + timeout_s
    while not (answer := check()):
        assert time.monotonic() < deadline, f"still {answer!r} after {timeout_s} s"
        time.sleep(every_s)
    return answer


def wait_for_job(page, url: str, timeout_s: float = 300.0) -> dict:
    """The job at ``url`` (its address in the API) once it has ended, done or failed, read through the API until then;
    ``timeout_s``: a bound for a loaded machine."""
    def ended():
        job = api_json(page, url)
        return job if job["state"] in ("done", "failed") else None

    return wait_until(ended, timeout_s=timeout_s, every_s=0.2)


def hold_first(page, url: re.Pattern[str], asks: Callable[[str], bool]) -> list:
    """Route the page's requests to ``url`` and hold the first whose URL ``asks`` says yes to (every other request goes
    on): the list it answers gets that route once the request is sent, for the test to ``continue_()`` when it
    chooses. How the race tests make an earlier answer come back after a later one."""
    held: list = []

    def hold(route) -> None:
        if asks(route.request.url) and not held:
            held.append(route)
        else:
            route.continue_()

    page.route(url, hold)
    return held


def pump_until(page, condition, what: str, timeout_s: float = 30.0) -> None:
    """Let Playwright deliver the page's events (requests, routes, dialogs, console messages) until ``condition()``
    holds; fail naming ``what`` after ``timeout_s``. The sync API hands a test its events only while it is inside a
    Playwright call, so :func:`wait_until`'s plain sleep would never see them: the short ``wait_for_timeout`` here is
    that call, polled on a condition, not a guess at how long something takes. (A ``wait_for_function`` cannot stand
    in for it: it waits for the next document once a navigation is under way.)"""
    deadline = time.monotonic() + timeout_s
    while not condition():
        assert time.monotonic() < deadline, f"waited {timeout_s:.0f} s for {what}"
        page.wait_for_timeout(20)


#: True once the boxes of the elements of a selector are the same in ``frames`` animation frames in a row (their
#: last boxes kept on ``window`` under ``key``, one key per wait).
_STEADY = """([selector, frames, key]) => {
  const boxes = JSON.stringify([...document.querySelectorAll(selector)].map((e) => {
    const r = e.getBoundingClientRect();
    return [r.left, r.top, r.width, r.height];
  }));
  const seen = (window.__steadyLayout ??= {});
  const last = seen[key];
  seen[key] = last && last.boxes === boxes ? { boxes, same: last.same + 1 } : { boxes, same: 0 };
  return document.fonts.status === "loaded" && seen[key].same >= frames;
}"""
_steady_waits = itertools.count()


def wait_for_steady_layout(page, selector: str = "body *", frames: int = 2, timeout_ms: float = 30_000) -> None:
    """Wait until the page's fonts are loaded and the elements of ``selector`` keep their boxes over ``frames``
    animation frames in a row: what a screenshot or a measure of where things are needs (a resize, a redraw or an
    image still moving them would show a layout on its way). A condition on the layout, checked once per frame, not
    a time."""
    page.wait_for_function(_STEADY, arg=[selector, frames, f"w{next(_steady_waits)}"], polling="raf",
                           timeout=timeout_ms)


def log_in(page, account) -> None:
    """Fill and send the login page the page is on with the account's name and password."""
    page.locator(tid("login-form")).wait_for()
    page.fill(tid("login-name"), account.name)
    page.fill(tid("login-password"), account.password)
    page.click(tid("login-submit"))


#: True when the page is working on nothing (``static/js/busy.js``: its body's ``data-busy`` names the work under way:
#: a request, a system loading, a write, an undo, a key typed ahead, a nudge's pause, a frame's image).
_IDLE = "() => document.body !== null && !document.body.hasAttribute('data-busy')"


def settled(page, timeout_ms: float = 30_000) -> None:
    """Wait until the page says it is working on nothing (``data-busy`` absent from its body): what a test waits for
    after an action before the next, so that the next one meets the page as a person would after looking. Fails
    naming the work still under way after ``timeout_ms`` (a bound for a loaded machine, not a measure of speed)."""
    from playwright.sync_api import TimeoutError as PlaywrightTimeoutError

    try:
        page.wait_for_function(_IDLE, timeout=timeout_ms)
    except PlaywrightTimeoutError:
        busy = page.evaluate("() => document.body?.dataset.busy ?? null")
        raise AssertionError(f"the page still says it is busy with {busy!r} after {timeout_ms / 1000:.0f} s") from None


def press(page, *keys: str) -> None:
    """Press each of ``keys`` in turn, each after the page has settled from the one before (:func:`settled`), then
    wait for it to settle again: keys typed as a person who looks at the page between them types them."""
    for key in keys:
        page.keyboard.press(key)
        settled(page)


@contextmanager
def cpu_bound():
    """A Python process spinning on one core until the block ends: the load under which a page's answers arrive late
    and a person's keys arrive while it still works."""
    spinner = subprocess.Popen([sys.executable, "-c", "while True: pass"])
    try:
        yield spinner
    finally:
        spinner.kill()
        spinner.wait()
