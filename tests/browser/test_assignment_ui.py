"""Work assignment and presence in Chromium (issue 28, item 10), two annotators and an admin at 1366x768:
the admin assigns systems to annotator A from the queue's assign bar (the selected system, then every system a
filter matches), A finds exactly those under "My systems" and opens one; annotator B sees "A has this system
open" in its queue row (B's queue page, already open, refreshes it) and on that system's page; A leaving the
system ends the claim at once."""
from __future__ import annotations

import pytest

from tests.accounts import PASSWORD, Account
from tests.browser.support import api_json, log_in, tid, wait_until

pytestmark = pytest.mark.browser

VIEWPORT = {"width": 1366, "height": 768}


@pytest.fixture(scope="module")
def annotators(seeded_settings) -> dict[str, Account]:
    """Two annotators, "ana" and "ben", in the seeded database."""
    from app.db.session import make_engine, make_session_factory
    from app.services.accounts.users import create_user

    engine = make_engine(seeded_settings.database_url)
    out = {}
    try:
        with make_session_factory(engine)() as session:
            for name in ("ana", "ben"):
                _, token = create_user(session, name, "annotator", PASSWORD)
                out[name] = Account(name, "annotator", PASSWORD, token)
    finally:
        engine.dispose()
    return out


def _browser_of(browser, server_url, account: Account):
    """A new 1366x768 context logged in through the login page as ``account``; JS errors collected. Its timers run
    on Playwright's clock (real time, which the test may move forward: ``p.clock.fast_forward``)."""
    context = browser.new_context(viewport=VIEWPORT, base_url=server_url)
    context.clock.install()
    p = context.new_page()
    p.errors = []
    p.on("pageerror", lambda exc: p.errors.append(str(exc)))
    p.goto("/")
    log_in(p, account)
    p.wait_for_url(f"{server_url}/")
    p.locator(tid("queue-row")).first.wait_for()
    return context, p


def test_admin_assigns_a_sees_my_systems_b_sees_a_present(browser, server_url, page, annotators, artifacts):
    shots = artifacts / "assignment"
    shots.mkdir(exist_ok=True)
    page.set_viewport_size(VIEWPORT)
    # ----- the admin assigns: the first row of the queue, then every system with a label doubt
    page.goto("/?sort=name")
    page.locator(tid("assign-bar")).wait_for()
    page.locator(tid("queue-row")).first.wait_for()
    first = page.locator(tid("queue-row")).first.get_attribute("data-id")
    page.select_option(tid("assign-user"), "ana")
    page.click(tid("assign-selected"))
    page.locator(tid("assign-result")).filter(has_text="assigned to ana").wait_for()
    page.select_option(tid("filter-doubt"), "any")
    page.wait_for_url("**doubt=any**")
    page.locator(tid("queue-row")).first.wait_for()
    doubted = {s["id"] for s in api_json(page, "/api/systems?doubt=any&limit=500")["items"]}
    assert doubted, "the demo has systems with label doubts"
    page.once("dialog", lambda d: d.accept())
    page.click(tid("assign-filter"))
    page.locator(tid("assign-result")).filter(has_text="matching").wait_for()
    page.locator(tid("row-assignee")).first.wait_for()
    page.screenshot(path=str(shots / "1-admin-assigned-1366.png"))
    assigned = {int(first)} | doubted
    listed = {s["id"] for s in api_json(page, "/api/systems?assignee=ana&limit=500")["items"]}
    assert listed == assigned
    history = api_json(page, f"/api/audit?system_id={first}")["items"]
    assert history[0]["action"] == "system.assign" and history[0]["after"] == {"assignee": "ana"}

    a_ctx, a = _browser_of(browser, server_url, annotators["ana"])
    b_ctx, b = _browser_of(browser, server_url, annotators["ben"])
    try:
        # ----- A: "My systems" lists exactly hers; annotators get no assign bar
        assert a.locator(tid("assign-bar")).count() == 0
        a.click(tid("my-systems"))
        a.wait_for_url("**assignee=me**")
        a.wait_for_function("() => document.querySelector('[data-testid=my-systems]').getAttribute('aria-pressed') === "
                            "'true'")
        a.wait_for_function(f"document.querySelectorAll('[data-testid=queue-row]').length === {len(assigned)}")
        rows = {int(r.get_attribute("data-id")) for r in a.locator(tid("queue-row")).all()}
        assert rows == assigned
        assert a.locator(tid("row-assignee")).filter(has_text="yours").count() == len(assigned)
        a.screenshot(path=str(shots / "2-ana-my-systems-1366.png"))
        # she opens the first of them: the page claims it (one write) and says it is hers
        target = int(a.locator(tid("queue-row")).first.get_attribute("data-id"))
        with a.expect_response(lambda r: r.url.endswith(f"/api/systems/{target}/presence")
                               and r.request.method == "PUT") as claim:
            a.locator(tid("system-link")).first.click()
        assert claim.value.json()["wrote"] is True
        a.locator(tid("system-assignee")).filter(has_text="assigned to you").wait_for()
        assert a.locator(tid("presence")).is_hidden()  # nobody else there
        assert "assignee=me" in a.url  # prev / next stay within her systems

        # ----- B: the queue row (B's queue was open before A came: it re-reads its rows' people every 30 s, here
        # moved forward on its clock instead of waited for) and the system page say that A has it open
        row = b.locator(f'{tid("queue-row")}[data-id="{target}"]')
        assert row.locator(tid("row-presence")).count() == 0
        b.clock.fast_forward("00:31")
        row.locator(tid("row-presence")).wait_for()
        assert row.locator(tid("row-presence")).inner_text() == "ana has it open"
        assert row.locator(tid("row-assignee")).inner_text() == "→ ana"
        row.scroll_into_view_if_needed()
        b.screenshot(path=str(shots / "3-ben-queue-sees-ana-1366.png"))
        b.goto(f"/systems/{target}")
        bar = b.locator(tid("presence"))
        bar.wait_for()
        text = bar.inner_text()
        assert text.startswith("ana has this system open (since ") and "your edits may cross theirs" in text
        assert b.locator(tid("system-assignee")).inner_text() == "assigned to ana"
        b.screenshot(path=str(shots / "4-ben-system-sees-ana-1366.png"))
        b.set_viewport_size({"width": 1920, "height": 1080})
        b.screenshot(path=str(shots / "5-ben-system-sees-ana-1920.png"))
        # A sees B in turn at her next heartbeat (sent at once when her tab becomes visible)
        a.evaluate("document.dispatchEvent(new Event('visibilitychange'))")
        a.locator(tid("presence")).filter(has_text="ben has this system open").wait_for()

        # ----- A goes back to the queue: her claim ends now, not in two minutes
        a.goto("/")
        a.locator(tid("queue-row")).first.wait_for()
        # the keepalive DELETE of the page left behind reaches the server shortly
        wait_until(lambda: [p["name"] for p in api_json(b, f"/api/systems/{target}")["open_by"]] == ["ben"])
        assert not a.errors and not b.errors, (a.errors, b.errors)
    finally:
        a_ctx.close()
        b_ctx.close()
