"""The curator's second walk, the review loop's part (Playwright, Chromium, the real server over the demo dataset): each
test is one thing the walk found wrong, named after what the user now sees. The database is shared by the module: a
test that decides or edits systems puts back what it changed. Screenshots go to ``test-artifacts/walk-review/``."""
from __future__ import annotations

import re

import pytest

from app.geometry.doubts import LABEL_KIND_SEVERITY
from tests.accounts import PASSWORD, Account
from tests.browser.support import api_json as _api
from tests.browser.support import api_write, log_in, settled, tid, wait_for_steady_layout, wait_until

pytestmark = pytest.mark.browser

SIZES = [(1366, 768), (1920, 1080)]
SIZE_IDS = ["1366x768", "1920x1080"]


@pytest.fixture(scope="module")
def others(seeded_settings) -> dict[str, Account]:
    """Another reviewer (``walk-rev``) and an annotator (``walk-ana``) of the module's database."""
    from app.db.session import make_engine, make_session_factory
    from app.services.accounts.users import create_user

    engine = make_engine(seeded_settings.database_url)
    out: dict[str, Account] = {}
    try:
        with make_session_factory(engine)() as session:
            for name, role in (("walk-rev", "reviewer"), ("walk-ana", "annotator")):
                _, token = create_user(session, name, role, PASSWORD)
                out[role] = Account(name, role, PASSWORD, token)
            session.commit()
    finally:
        engine.dispose()
    return out


def _context_of(browser, server_url, account: Account, size=(1366, 768)):
    """A browser context logged in as ``account`` through the login page, and its page."""
    context = browser.new_context(viewport={"width": size[0], "height": size[1]}, base_url=server_url)
    p = context.new_page()
    p.goto("/login")
    log_in(p, account)
    p.wait_for_url(f"{server_url}/")
    return context, p


def _loaded(page) -> None:
    page.locator(tid("view")).first.wait_for()
    page.wait_for_function("() => !document.body.classList.contains('loading')")


def _set_status(page, system_id: int, status: str, bearer: dict | None = None) -> None:
    etag = page.request.get(f"/api/systems/{system_id}").headers["etag"]
    headers = {"If-Match": etag, **(bearer or {})}
    if bearer:
        answer = page.request.post(f"/api/systems/{system_id}/review", data={"status": status}, headers=headers)
    else:
        answer = api_write(page, "POST", f"/api/systems/{system_id}/review", data={"status": status}, headers=headers)
    assert answer.ok, answer.text()


def _seen_px(page, card) -> float:
    """How many px of ``card``'s height lie inside the window, below the sticky top bar."""
    return card.evaluate("""(e) => { const r = e.getBoundingClientRect();
      const top = Math.max(0, document.querySelector('.topbar').getBoundingClientRect().bottom);
      return Math.min(r.bottom, innerHeight) - Math.max(r.top, top); }""")


# ----- 1: a view's number key brings it into sight ------------------------------------------------------------------
@pytest.mark.parametrize("size", SIZES, ids=SIZE_IDS)
def test_a_views_number_key_brings_the_selected_view_into_sight(page, artifacts, size):
    page.set_viewport_size({"width": size[0], "height": size[1]})
    system = next(s for s in _api(page, "/api/systems?sort=name&limit=100")["items"] if s["views_total"] >= 4)
    page.goto(f"/systems/{system['id']}")
    _loaded(page)
    views = page.locator(tid("view"))
    n = views.count()
    for key, back_to in ((n, "top"), (1, "bottom")):
        # the window scrolled away from the card (at once: the page scrolls without animation), then its key, which
        # selects and reveals the card as it is handled
        page.evaluate("(where) => window.scrollTo(0, where === 'top' ? 0 : document.body.scrollHeight)", back_to)
        page.keyboard.press(str(key))
        settled(page)  # a key typed while the page still works is applied once it can act
        card = views.nth(key - 1)
        assert card.evaluate("(e) => e.classList.contains('selected')"), key
        wait_for_steady_layout(page, tid("view"))  # whatever else moves the cards (an image drawn) has moved them
        assert _seen_px(page, card) >= 100, (key, back_to, _seen_px(page, card))
    (artifacts / "walk-review").mkdir(exist_ok=True)
    page.keyboard.press(str(n))
    wait_for_steady_layout(page, tid("view"))
    page.screenshot(path=str(artifacts / f"walk-review/view-key-{size[0]}x{size[1]}.png"))


# ----- 2 + 17: the default queue: pending work first, by severity -------------------------------------------------
def _severity(row: dict) -> int:
    return max((LABEL_KIND_SEVERITY.get(k, 0) for k, n in (row.get("doubt_counts") or {}).items() if n), default=0)


def test_the_default_queue_shows_pending_work_first_ranked_by_severity(page, artifacts):
    page.set_viewport_size({"width": 1366, "height": 768})
    page.goto("/")
    page.locator(tid("queue-row")).first.wait_for()
    chosen = page.eval_on_selector(tid("sort"), "(s) => s.selectedOptions[0].text")
    assert "most doubts" not in chosen and "severe" in chosen, chosen
    rows = _api(page, "/api/systems?limit=500")["items"]
    pending = [r for r in rows if (r.get("review") or {}).get("status", "pending") in ("pending", "fixed")]
    severities = [_severity(r) for r in pending]
    assert severities == sorted(severities, reverse=True), severities
    assert severities[0] == 3  # a mirrored system first, whatever the count of chips below it
    first = int(page.locator(tid("queue-row")).first.get_attribute("data-id"))
    try:
        page.keyboard.press("Enter")  # the first row, as a curator opens it
        page.wait_for_url(re.compile(rf".*/systems/{first}\b.*"))
        _loaded(page)
        with page.expect_response(lambda r: r.url.endswith(f"/systems/{first}/review")) as decided:
            page.keyboard.press("r")
        assert decided.value.ok
        page.goto("/")
        page.locator(tid("queue-row")).first.wait_for()
        top = page.locator(tid("queue-row")).first
        assert int(top.get_attribute("data-id")) != first
        assert top.locator(".badge").inner_text() == "pending"
        page.screenshot(path=str(artifacts / "walk-review/queue-after-a-rejection-1366x768.png"))
    finally:
        _set_status(page, first, "pending")


# ----- 3: presence ends with its page and its counter moves -------------------------------------------------------
def test_presence_counts_on_and_ends_when_the_others_page_goes(page, browser, server_url, others):
    system = _api(page, "/api/systems?sort=name&limit=5")["items"][2]
    context, theirs = _context_of(browser, server_url, others["annotator"])
    try:
        theirs.goto(f"/systems/{system['id']}")
        _loaded(theirs)
        # their first heartbeat, as the server keeps it
        wait_until(lambda: any(p["name"] == "walk-ana" for p in _api(page, f"/api/systems/{system['id']}")["open_by"]))
        # this page's timers run on Playwright's clock (real time, moved forward here): its counter and heartbeats
        # (every 10 s) come when the test says, however slow the machine
        page.clock.install()
        page.goto(f"/systems/{system['id']}")
        bar = page.locator(tid("presence"))
        bar.filter(has_text="walk-ana has this system open").wait_for()
        first = bar.inner_text()
        since = int(re.search(r"since (\d+) s", first).group(1))
        page.clock.fast_forward(2000)  # less than a heartbeat: the counter moves by itself between them
        page.wait_for_function("(n) => { const m = /since (\\d+) s/.exec(document.querySelector("
                               "'[data-testid=presence]').textContent); return m && Number(m[1]) >= n + 2; }",
                               arg=since)
        theirs.close(run_before_unload=True)  # their tab goes: its pagehide ends the claim
        # ended by it, on the server: a claim left alone would last 50 s after it was written (at their first
        # heartbeat, seconds ago), longer than this wait's bound
        wait_until(lambda: not any(p["name"] == "walk-ana"
                                   for p in _api(page, f"/api/systems/{system['id']}")["open_by"]), timeout_s=30)
        page.clock.fast_forward("00:11")  # this page's next heartbeat
        bar.wait_for(state="hidden")  # gone at that heartbeat
    finally:
        context.close()


# ----- 9: needs fix says to whom; an annotator's keys get words, not a 403 -----------------------------------------
def test_needs_fix_says_to_whom_and_an_annotator_gets_words_not_a_403(page, browser, server_url, others):
    listing = _api(page, "/api/systems?sort=-name&limit=100")["items"]
    system = next(s for s in (_api(page, f"/api/systems/{i['id']}") for i in listing)
                  if any(v["ball"].get("box") for v in s["views"]))
    view = next(v for v in system["views"] if v["ball"].get("box"))
    box = view["ball"]["box"]
    ana = others["annotator"]
    moved = page.request.patch(f"/api/frames/{view['frame_id']}/ball",
                               data={"box": [box[0] + 2, box[1], box[2] + 2, box[3]]},
                               headers={"If-Match": view["etag"], **ana.bearer})
    assert moved.ok, moved.text()
    try:
        page.goto(f"/systems/{system['id']}")
        _loaded(page)
        toast = page.locator(tid("toast"))
        with page.expect_response(lambda r: r.url.endswith(f"/systems/{system['id']}/review")) as decided:
            page.keyboard.press("f")
        assert decided.value.ok
        toast.filter(has_text=ana.name).wait_for()
        assert f"returned to {ana.name}" in toast.inner_text(), toast.inner_text()

        context, theirs = _context_of(browser, server_url, ana)
        try:
            other = listing[0]["id"]
            theirs.goto(f"/systems/{other}")
            _loaded(theirs)
            theirs.locator(tid("accept")).wait_for(state="hidden")
            assert theirs.locator(tid("review-card")).is_hidden()  # no decision, so no decision's comment
            sent: list[str] = []
            theirs.on("request", lambda r: sent.append(r.url) if r.url.endswith("/review") else None)
            theirs.keyboard.press("a")
            said = theirs.locator(tid("toast"))
            said.filter(has_text="reviewers").wait_for()
            assert "403" not in said.inner_text() and "reviewer role" not in said.inner_text()
            assert theirs.locator(tid("error")).is_hidden()
            assert sent == []
        finally:
            context.close()
    finally:
        _set_status(page, system["id"], "pending")
        etag = page.request.get(f"/api/frames/{view['frame_id']}").headers["etag"]
        assert api_write(page, "PATCH", f"/api/frames/{view['frame_id']}/ball", data={"box": box},
                         headers={"If-Match": etag}).ok


# ----- 10: a pass counts this user's decisions; `a` again writes nothing -------------------------------------------
def test_a_pass_counts_only_your_decisions_and_a_again_writes_no_second_entry(page, others):
    games = _api(page, "/api/games")
    game = min((g for g in games if g["systems"] >= 3), key=lambda g: g["systems"])
    rows = _api(page, f"/api/systems?game_id={game['id']}&sort=name&limit=100")["items"]
    mine = next(r for r in rows if not r["label_doubts"])  # no accept guard in the way
    theirs = [r["id"] for r in rows if r["id"] != mine["id"]]
    rev = others["reviewer"]
    try:
        for sid in theirs:  # another reviewer decides the rest of the game
            _set_status(page, sid, "accepted", bearer=rev.bearer)
        page.goto(f"/systems/{mine['id']}?game={game['id']}&pass=new")
        _loaded(page)
        page.locator(tid("pass-progress")).filter(has_text="pass ").wait_for()
        with page.expect_response(lambda r: r.url.endswith(f"/systems/{mine['id']}/review")) as decided:
            page.keyboard.press("a")
        assert decided.value.ok
        page.locator(tid("pass-finished")).wait_for()
        counts = page.locator(tid("pass-counts")).inner_text()
        assert counts == (f"1 accepted · 0 rejected · 0 needs fix · {len(theirs)} decided by others or before this "
                          "pass · 0 skipped"), counts
        # the page's system reads accepted now: its views' decision bars are drawn again from it
        page.locator(tid("view-decision-status")).filter(has_text="accepted with the system").first.wait_for()
        page.keyboard.press("a")  # again, on the finished last system
        page.locator(tid("toast")).filter(has_text="already accepted").wait_for()
        entries = _api(page, f"/api/audit?system_id={mine['id']}&limit=50")["items"]
        accepted = [e for e in entries if e["action"] == "system.review" and "accepted" in (e.get("summary") or "")]
        assert len(accepted) == 1, [e.get("summary") for e in entries]
    finally:
        for sid in [mine["id"], *theirs]:
            _set_status(page, sid, "pending")


# ----- 12 + 18: z restores and says so; s and Enter say what they did ---------------------------------------------
def test_z_is_logged_as_a_restore_of_the_imported_label(page):
    system = next(s for s in (_api(page, f"/api/systems/{i['id']}")
                              for i in _api(page, "/api/systems?sort=name&limit=100")["items"][3:])
                  if s["views"][0]["ball"].get("box"))
    fid = system["views"][0]["frame_id"]
    page.goto(f"/systems/{system['id']}")
    page.locator(tid("view")).first.locator(tid("ball-hit")).wait_for()
    _loaded(page)
    page.keyboard.press("1")
    with page.expect_response(lambda r: r.request.method == "PATCH" and "/ball" in r.url) as nudged:
        for _ in range(3):
            page.keyboard.press("Shift+ArrowRight")
    assert nudged.value.ok
    page.locator(tid("restore-ball")).first.wait_for()
    with page.expect_response(lambda r: r.request.method == "PATCH" and "/ball" in r.url) as restored:
        page.keyboard.press("z")
    assert restored.value.ok
    page.locator(tid("toast")).filter(has_text="restored to the imported label").wait_for()
    newest = _api(page, f"/api/audit?frame_id={fid}&limit=5")["items"][0]
    assert newest["summary"] == "ball of V1 restored to the imported label", newest["summary"]
    page.locator(tid("history-entry")).filter(has_text="restored to the imported label").first.wait_for()


def test_s_and_its_confirming_enter_each_say_what_they_did(page):
    """Like ``m`` and ``x``: a toast after the snap and after the confirmation."""
    page.set_viewport_size({"width": 1366, "height": 768})
    items = _api(page, "/api/systems?sort=name&limit=100")["items"]
    system = next(s for s in (_api(page, f"/api/systems/{i['id']}") for i in items if i["views_total"] == 4)
                  if not s["doubts"] and all(v["ball"].get("box") for v in s["views"]))
    k, view = 1, system["views"][1]
    box = view["ball"]["box"]
    far = [box[0] + 90, box[1] + 40, box[2] + 90, box[3] + 40]  # a box far off: a doubt that offers a snap
    assert api_write(page, "PATCH", f"/api/frames/{view['frame_id']}/ball", data={"box": far},
                     headers={"If-Match": view["etag"]}).ok
    try:
        page.goto(f"/systems/{system['id']}")
        _loaded(page)
        page.locator(tid("view")).nth(k).locator(tid("view-doubts")).wait_for()
        toast = page.locator(tid("toast"))
        page.keyboard.press(str(k + 1))
        with page.expect_response(lambda r: r.request.method == "PATCH" and "/ball" in r.url) as snapped:
            page.keyboard.press("s")
        assert snapped.value.ok
        toast.filter(has_text="snapped to the suggested box").wait_for()
        assert toast.inner_text().startswith(f"V{k + 1} ("), toast.inner_text()
        with page.expect_response(lambda r: r.request.method == "PATCH" and "/ball" in r.url) as confirmed:
            page.keyboard.press("Enter")
        assert confirmed.value.ok
        toast.filter(has_text="confirmed").wait_for()
    finally:
        etag = page.request.get(f"/api/frames/{view['frame_id']}").headers["etag"]
        assert api_write(page, "PATCH", f"/api/frames/{view['frame_id']}/ball", data={"box": box},
                         headers={"If-Match": etag}).ok


def test_enter_after_apply_opens_the_highlighted_row(page):
    page.goto("/")
    page.locator(tid("queue-row")).first.wait_for()
    page.fill(tid("filter-error-min"), "0")
    before = page.url
    page.click(tid("apply"))
    page.wait_for_function("(u) => location.href !== u", arg=before)
    page.locator(tid("queue-row")).first.wait_for()
    first = page.locator(tid("queue-row")).first.get_attribute("data-id")
    page.keyboard.press("Enter")  # at once: the highlighted row opens, the filter is not applied again
    page.wait_for_url(re.compile(rf".*/systems/{first}\b.*"))


@pytest.mark.parametrize("size", SIZES, ids=SIZE_IDS)
def test_the_login_page_never_breaks_a_command_inside(browser, server_url, artifacts, size):
    context = browser.new_context(viewport={"width": size[0], "height": size[1]}, base_url=server_url)
    try:
        p = context.new_page()
        p.goto("/login")
        p.locator(tid("login-form")).wait_for()
        # the demo's hint as `v3d serve --demo` shows it (this server is not the demo's: its hint is shown here)
        p.evaluate("""() => { document.querySelector('[data-testid=demo-hint]').hidden = false;
          document.querySelector('[data-testid=demo-name]').textContent = 'demo';
          document.querySelector('[data-testid=demo-password]').textContent = 'demo'; }""")
        broken = p.eval_on_selector_all(".card.login .mono", """(cs) => cs.filter((c) => c.textContent.trim()
          && c.getClientRects().length > 1).map((c) => c.textContent)""")
        assert broken == [], broken
        p.screenshot(path=str(artifacts / f"walk-review/login-{size[0]}x{size[1]}.png"))
    finally:
        context.close()


# ----- 16: the system page in a curator's words, the technical term on hover -----------------------------------------
@pytest.mark.parametrize("size", SIZES, ids=SIZE_IDS)
def test_the_system_page_speaks_a_curators_words_with_the_term_on_hover(page, artifacts, size):
    page.set_viewport_size({"width": size[0], "height": size[1]})
    items = _api(page, "/api/systems?sort=name&limit=100")["items"]
    system = next(s for s in (_api(page, f"/api/systems/{i['id']}") for i in items if i["views_total"] >= 3)
                  if any((v["calibration"] or {}).get("uncertainty") for v in s["views"]))
    page.goto(f"/systems/{system['id']}")
    _loaded(page)
    shown = page.eval_on_selector_all(tid("view"), "(vs) => vs.map((v) => v.innerText).join('\\n')")
    for jargon in ("JaC", "Camera ±", "Reproj. error", "rig position", "learned prior", "ball bundle",
                   "only behind a camera"):
        assert jargon not in shown, jargon
    jac = page.locator(tid("term-jac")).first
    assert jac.inner_text() == "Lines fit"
    assert jac.get_attribute("title").startswith("JaC@0.5"), jac.get_attribute("title")
    camera = page.locator(tid("term-camera-sigma")).first
    assert camera.inner_text() == "Camera unsure by" and "Camera ±" in camera.get_attribute("title")
    error = page.locator(tid("term-reprojection-error")).first
    assert error.inner_text() == "Ball off by"
    assert "reprojection error" in error.get_attribute("title") and "τ (tau)" in error.get_attribute("title")
    for flag in page.locator(tid("view-flag")).all():
        assert "_" not in flag.inner_text() and flag.get_attribute("title")
    page.screenshot(path=str(artifacts / f"walk-review/system-words-{size[0]}x{size[1]}.png"))
