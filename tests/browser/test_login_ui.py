"""Logging in through the page, in Chromium: a visitor opening a system's link is sent to the login
page and, once logged in, back to the same link; a wrong password says so without saying which field
was wrong; the header shows who is logged in; a decision above the person's role shows the API's 403;
logging out leads back to the login page. The demo hint appears only once the demo account exists."""
from __future__ import annotations

import re
from contextlib import contextmanager
from urllib.parse import parse_qs, urlsplit

import pytest

from app.db.session import make_engine, make_session_factory
from app.services.accounts.users import ensure_demo_account
from tests.accounts import Account
from tests.browser.support import api_json, log_in, pump_until, tid

pytestmark = pytest.mark.browser


@contextmanager
def _visitor(browser, server_url: str):
    """A page in a new browser context (no session yet); on leaving, the context is closed and any script error the
    page raised fails the test."""
    context = browser.new_context(viewport={"width": 1440, "height": 900}, base_url=server_url)
    errors: list[str] = []
    visitor = context.new_page()
    visitor.on("pageerror", lambda exc: errors.append(str(exc)))
    try:
        yield visitor
    finally:
        context.close()
    assert not errors, errors


def test_a_visitor_logs_in_and_returns_to_the_link_then_logs_out(browser, server_url, accounts, page) -> None:
    sid = api_json(page, "/api/systems?sort=name&limit=1")["items"][0]["id"]  # read as the admin
    with _visitor(browser, server_url) as visitor:
        visitor.goto(f"/systems/{sid}?sort=name")
        visitor.wait_for_url(re.compile(rf"/login\?next=%2Fsystems%2F{sid}%3Fsort%3Dname$"))
        assert visitor.locator(tid("demo-hint")).is_hidden()  # no demo account in this database

        annotator: Account = accounts["annotator"]
        log_in(visitor, Account(annotator.name, annotator.role, "not the password", annotator.token))
        error = visitor.locator(tid("login-error"))
        error.wait_for(state="visible")
        assert error.inner_text() == "Wrong name or password."

        log_in(visitor, annotator)
        visitor.wait_for_url(f"{server_url}/systems/{sid}?sort=name")
        visitor.locator(tid("user-name")).wait_for()
        assert visitor.locator(tid("user")).inner_text() == "test-annotator · annotator"
        visitor.wait_for_function("() => document.querySelector('[data-testid=system-name]')?.textContent !== '…'")

        visitor.keyboard.press("a")  # accepting a system is a reviewer's decision: said in words, nothing sent
        visitor.locator(tid("toast")).filter(has_text="is for reviewers").wait_for()
        assert visitor.locator(tid("error")).is_hidden()

        visitor.click(tid("logout"))
        visitor.wait_for_url(f"{server_url}/login")
        visitor.goto("/")
        visitor.wait_for_url(f"{server_url}/login?next=%2F")


def test_a_call_refused_while_logging_out_leaves_the_person_on_the_plain_login_page(
        browser, server_url, accounts, page) -> None:
    """The page's own calls (the jobs poll, the presence beat) run on while the person logs out; one answered 401
    after the log-out has sent the page to the login page must not turn that into "log in and come back here". The
    timing is made certain here: the page's call is held until the log-out's navigation is under way, and that
    navigation is held until the call has been refused."""
    sid = api_json(page, "/api/systems?sort=name&limit=1")["items"][0]["id"]  # read as the admin
    with _visitor(browser, server_url) as visitor:
        visitor.goto("/login")
        log_in(visitor, accounts["annotator"])
        visitor.wait_for_url(f"{server_url}/")
        visitor.goto(f"/systems/{sid}")
        visitor.locator(tid("logout")).wait_for()

        # what the page's call ended with, as the page logs it (its JS runs on until the login page comes)
        refused: list[str] = []
        visitor.on("console", lambda msg: refused.append(msg.text) if msg.text.startswith("refused") else None)
        held_call: list = []
        held_login: list = []
        visitor.route(re.compile(r"/api/systems\?limit=1&during=logout$"), lambda route: held_call.append(route))
        visitor.route(re.compile(r"/login$"), lambda route: held_login.append(route))
        visitor.evaluate("""() => { import('/static/js/api.js')
          .then((api) => api.send('GET', '/api/systems?limit=1&during=logout'))
          .catch((err) => console.log(`refused ${err.status}`)); }""")
        pump_until(visitor, lambda: held_call, "the page's call to be held")

        # the click does not wait for the navigation it starts: that navigation is the one held here
        visitor.locator(tid("logout")).click(no_wait_after=True)
        pump_until(visitor, lambda: held_login, "the log-out to be answered and the login page asked for")
        held_call[0].continue_()  # the session is over on the server: a real 401
        pump_until(visitor, lambda: refused, "the page's call to be refused")
        assert refused == ["refused 401"]
        held_login[0].continue_()
        visitor.wait_for_load_state()
        visitor.locator(tid("login-submit")).wait_for()
        assert visitor.url == f"{server_url}/login"


def test_the_demo_hint_appears_once_the_demo_account_exists(browser, server_url, seeded_settings) -> None:
    engine = make_engine(seeded_settings.database_url)
    with make_session_factory(engine)() as session:
        ensure_demo_account(session)
    engine.dispose()
    context = browser.new_context(base_url=server_url)
    try:
        visitor = context.new_page()
        visitor.goto("/login")
        visitor.locator(tid("demo-hint")).wait_for(state="visible")
        assert (visitor.locator(tid("demo-name")).inner_text(), visitor.locator(tid("demo-password")).inner_text()) \
            == ("demo", "demo")
        visitor.click(tid("demo-fill"))
        visitor.click(tid("login-submit"))
        visitor.wait_for_url(f"{server_url}/")
        visitor.locator(tid("queue-row")).first.wait_for()
        assert visitor.locator(tid("user")).inner_text() == "demo · admin"
    finally:
        context.close()


@pytest.mark.parametrize("next_param, expected", [
    ("%2Fsystems%2F3%3Fsort%3Dname%23v2", "/systems/3?sort=name#v2"),
    ("%2F%09%2Fevil.example", "/"),          # the browser drops the tab: //evil.example
    ("%2F%0A%2Fevil.example%2Fx", "/"),      # a newline likewise
    ("%2F%5Cevil.example", "/"),             # /\evil.example is read as //evil.example
    ("%2F%5C%5Cevil.example", "/"),
    ("%2F%2Fevil.example", "/"),
    ("https%3A%2F%2Fevil.example%2F", "/"),
    ("javascript%3Aalert(1)", "/"),
    ("%2Flogin%3Fnext%3D%2F", "/"),          # never back to the login page
    ("%2F..%2F%2Fevil.example", "/evil.example"),  # dot segments resolve on this site
])
def test_the_login_page_returns_only_to_a_page_of_this_site(browser, server_url, next_param: str,
                                                            expected: str) -> None:
    """``nextPage`` (static/js/login.js) resolves ``next`` as the browser will when it navigates, and keeps
    it only when it stays on this origin: ``/%09/evil.example`` left the site before (issue 15)."""
    context = browser.new_context(base_url=server_url)
    try:
        visitor = context.new_page()
        visitor.goto(f"/login?next={next_param}")
        visitor.locator(tid("login-form")).wait_for()
        got = visitor.evaluate("async () => (await import('/static/js/login.js')).nextPage()")
        assert got == expected
    finally:
        context.close()


def test_a_login_sent_before_the_page_script_runs_never_puts_the_password_in_the_address(browser, server_url) -> None:
    """The login page's submit button is disabled until login.js handles the submit: with the script held back
    (a slow network, or a quick test), Enter in the password field and a click send nothing, where the form's
    native submit sent a GET with the password in the address and left the login page waiting forever (the
    CI run that failed test_assignment_ui)."""
    context = browser.new_context(base_url=server_url)
    try:
        visitor = context.new_page()
        visitor.route("**/static/js/login.js", lambda route: route.abort())
        visitor.goto("/login")
        # a form sent natively fires its submit event first, in the same task as the key that sends it, and only then
        # plans the navigation: no submit event once the key has been handled means no GET was, or will be, sent
        visitor.evaluate("""() => { window.__submits = 0; document.querySelector('[data-testid=login-form]')
          .addEventListener('submit', () => { window.__submits += 1; }); }""")
        visitor.fill(tid("login-name"), "someone")
        visitor.fill(tid("login-password"), "a secret")
        visitor.press(tid("login-password"), "Enter")  # answered once the page has handled the key
        assert visitor.locator(tid("login-submit")).is_disabled()
        assert visitor.evaluate("() => window.__submits") == 0
        assert visitor.url == f"{server_url}/login"
        assert "secret" not in visitor.url
        visitor.unroute("**/static/js/login.js")
        visitor.reload()
        visitor.locator(tid("login-submit")).wait_for()
        visitor.wait_for_function("() => !document.querySelector('[data-testid=login-submit]').disabled")
    finally:
        context.close()


def test_a_session_that_ends_under_a_typed_comment_says_so_and_gives_the_comment_back(browser, server_url, accounts,
                                                                                       page, artifacts) -> None:
    """Text typed in the decision's box is a draft: leaving the page with it is warned of first (beforeunload); when
    the session ends under it (its cookie gone, as when it expires), the login page says the session ended, returns
    to the same page, and the comment is put back as typed."""
    sid = api_json(page, "/api/systems?sort=name&limit=3")["items"][2]["id"]
    reviewer: Account = accounts["admin"]  # its page's own session: the module's page keeps its own
    typed = "the ball is behind the keeper's glove in V2"
    with _visitor(browser, server_url) as visitor:
        visitor.goto(f"/systems/{sid}?sort=name")
        log_in(visitor, reviewer)
        visitor.wait_for_url(re.compile(rf"/systems/{sid}\?sort=name"))
        visitor.wait_for_function("() => document.querySelector('[data-testid=system-name]')?.textContent !== '…'")
        visitor.fill(tid("comment"), typed)

        dialogs: list[str] = []

        def stay(dialog) -> None:  # the browser asks before leaving a page with a draft; the person stays
            dialogs.append(dialog.type)
            dialog.dismiss()

        visitor.on("dialog", stay)
        visitor.click(tid("queue-link"), no_wait_after=True)
        pump_until(visitor, lambda: dialogs, "the warning before leaving a typed comment")
        assert dialogs == ["beforeunload"]
        visitor.remove_listener("dialog", stay)
        assert visitor.input_value(tid("comment")) == typed  # still on the page, the text as typed

        visitor.context.clear_cookies()  # the session ends under the page
        # its next call is refused (401): to the login page, the comment kept (the page's own polls may come first:
        # then the button is gone, and the click finds nothing)
        visitor.evaluate("() => document.querySelector('[data-testid=next]')?.click()")
        # (the address it returns to may have gained the review pass the page follows)
        visitor.wait_for_url(re.compile(rf"/login\?next=%2Fsystems%2F{sid}%3Fsort%3Dname[^&]*&ended=1&kept=1$"))
        ended = visitor.locator(tid("login-ended"))
        ended.wait_for()
        assert ended.inner_text().startswith("Your session ended")
        back = parse_qs(urlsplit(visitor.url).query)["next"][0]
        assert f"go back to {back};" in ended.inner_text() and "kept and put back" in ended.inner_text()
        for size in ({"width": 1366, "height": 768}, {"width": 1920, "height": 1080}):
            visitor.set_viewport_size(size)
            visitor.screenshot(path=str(artifacts / f"login-session-ended-{size['width']}.png"))

        log_in(visitor, reviewer)
        visitor.wait_for_url(f"{server_url}{back}")
        visitor.locator(tid("toast")).filter(has_text="your decision's comment").wait_for()
        assert visitor.input_value(tid("comment")) == typed
