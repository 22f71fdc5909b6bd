"""A new curator's walk through the pages (Playwright, Chromium, the real server over the demo dataset): each
test is one thing the walk found wrong, named after what the user now sees. The database is shared by the
module: a test that decides or edits systems uses its own, or puts back what it changed."""
from __future__ import annotations

import re

import pytest

from tests.browser.support import api_json as _api
from tests.browser.support import api_write, tid, wait_for_steady_layout

pytestmark = pytest.mark.browser

#: Makes the page's pass visits (POST /api/passes/{id}/visits) answer 0.8 s late, so that whatever the top bar says
#: before the server's answer stays long enough to be read; and records every text the bar shows with the address
#: it was shown at (each change of the page's DOM, and every 5 ms for a change of address alone). ``__visitAnswered``:
#: the address whose visit was last answered; ``__barWrites``: the writes of the bar since (the bar's text is set
#: anew, a mutation even when the text is the same, once the page has read the answer).
_SLOW_VISITS_AND_BAR_LOG = """
  const realFetch = window.fetch.bind(window);
  window.__visitAnswered = null;
  window.__barWrites = 0;
  window.fetch = async (url, init) => {
    if (!String(url).includes('/visits')) return realFetch(url, init);
    await new Promise((r) => setTimeout(r, 800));
    const answer = await realFetch(url, init);
    window.__visitAnswered = location.pathname;
    window.__barWrites = 0;
    return answer;
  };
  window.__bar = [];
  const look = () => {
    const text = document.querySelector('[data-testid=pass-progress]')?.textContent || '';
    const last = window.__bar[window.__bar.length - 1];
    if (!last || last[0] !== location.pathname || last[1] !== text) window.__bar.push([location.pathname, text]);
  };
  new MutationObserver((records) => {
    if (records.some((r) => r.target.closest?.('[data-testid=pass-progress]'))) window.__barWrites += 1;
    look();
  }).observe(document, { subtree: true, childList: true, characterData: true });
  setInterval(look, 5);
"""


def _system_id(page) -> int:
    return int(re.search(r"/systems/(\d+)", page.url).group(1))


def _arrive(page, system_id: int, bar: str) -> None:
    """Wait until the page shows ``system_id`` with its views and the top bar reads ``bar``."""
    page.wait_for_function(
        """([id, bar]) => location.pathname === `/systems/${id}` && !document.body.classList.contains('loading')
          && document.querySelectorAll('[data-testid=view]').length > 0
          && document.querySelector('[data-testid=pass-progress]')?.textContent === bar""",
        arg=[system_id, bar])


def test_a_resumed_pass_comes_back_to_the_systems_left_pending_before_its_resume_point(page, artifacts):
    order = [s["id"] for s in _api(page, "/api/systems?limit=100")["items"]]
    n = len(order)
    assert n >= 6
    # an older pass, resumed late: everything but the first two and the last two already decided elsewhere
    made = api_write(page, "POST", "/api/passes", data={"filter": {}, "sort": "-doubts", "system_id": order[-2],
                                                         "fresh": True})
    assert made.ok, made.text()
    pass_id = made.json()["id"]
    assert made.json()["systems"] == order
    for sid in order[2:-2]:
        etag = page.request.get(f"/api/systems/{sid}").headers["etag"]
        assert api_write(page, "POST", f"/api/systems/{sid}/review", data={"status": "rejected"},
                         headers={"If-Match": etag}).ok

    page.add_init_script(_SLOW_VISITS_AND_BAR_LOG)
    page.goto(f"/systems/{order[-2]}?pass={pass_id}")
    _arrive(page, order[-2], f"pass {n - 1} of {n} · 4 pending")

    # r on the second to last: the last, whose place reads right from the moment it is shown
    page.keyboard.press("r")
    _arrive(page, order[-1], f"pass {n} of {n} · 3 pending")
    # the visit's late answer, read and written into the bar
    page.wait_for_function("(path) => window.__visitAnswered === path && window.__barWrites > 0",
                           arg=f"/systems/{order[-1]}")
    shown = [text for path, text in page.evaluate("window.__bar") if path == f"/systems/{order[-1]}"]
    assert shown and all(not re.match(r"pass \d+ of", t) or t.startswith(f"pass {n} of {n}") for t in shown), shown

    # r on the last: not the end of the pass, the two pending systems before the resume point, in the pass's order
    page.keyboard.press("r")
    _arrive(page, order[0], f"pass 1 of {n} · 2 pending")
    assert page.locator(tid("pass-finished")).is_hidden()
    page.keyboard.press("r")
    _arrive(page, order[1], f"pass 2 of {n} · 1 pending")
    page.keyboard.press("r")
    page.locator(tid("pass-finished")).wait_for()
    assert page.locator(tid("toast")).inner_text().endswith("Nothing pending is left in this pass.")
    assert page.locator(tid("pass-counts")).inner_text() == f"0 accepted · {n} rejected · 0 needs fix · 0 skipped"
    statuses = {s["id"]: s["review"]["status"] for s in _api(page, "/api/systems?limit=100")["items"]}
    assert set(statuses.values()) == {"rejected"}, statuses
    # put the queue back for the module's other tests
    for sid in order:
        etag = page.request.get(f"/api/systems/{sid}").headers["etag"]
        assert api_write(page, "POST", f"/api/systems/{sid}/review", data={"status": "pending"},
                         headers={"If-Match": etag}).ok


def test_s_with_no_view_selected_snaps_and_never_mirrors(page):
    """The README gives ``s`` to snap a label and ``m`` to mirror: ``s`` on a system whose only fix is a mirror
    says which key mirrors, and writes nothing."""
    system = next(s for s in (_api(page, f"/api/systems/{i['id']}") for i in
                              _api(page, "/api/systems?doubt=mirrored_labels&limit=100")["items"])
                  if {d["suggestion"]["action"] for d in s["doubts"] if d.get("suggestion")} == {"mirror_labels"})
    writes: list[str] = []
    page.on("request", lambda r: writes.append(f"{r.method} {r.url}") if r.method in ("PATCH", "POST", "PUT")
            and "/api/frames" in r.url else None)
    page.goto(f"/systems/{system['id']}")
    page.locator(tid("view")).first.wait_for()
    page.wait_for_function("() => !document.body.classList.contains('loading')")
    page.keyboard.press("s")
    toast = page.locator(tid("toast"))
    # the toast is the key's answer: its entry said why it could not snap, so nothing of the key was sent
    toast.filter(has_text="m").wait_for()
    assert "press m" in toast.inner_text() and "mirror" in toast.inner_text(), toast.inner_text()
    assert writes == []
    after = _api(page, f"/api/systems/{system['id']}")
    assert [v["ball"] for v in after["views"]] == [v["ball"] for v in system["views"]]


def _covered_or_cut(page, selector: str) -> list[str]:
    """The texts of the elements of ``selector`` that are not wholly seen: cut by their container's edge (or the
    window's), or with another element drawn over their left end, middle or right end."""
    return page.evaluate("""(selector) => [...document.querySelectorAll(selector)].filter((e) => {
      const r = e.getBoundingClientRect();
      if (r.width === 0) return false;
      if (r.left < 0 || r.top < 0 || r.right > innerWidth || r.bottom > innerHeight) return true;
      for (let p = e.parentElement; p && p !== document.body; p = p.parentElement) {
        const c = p.getBoundingClientRect(), style = getComputedStyle(p);
        if (style.overflowX !== 'visible' && (r.left < c.left - 0.5 || r.right > c.right + 0.5)) return true;
      }
      const y = (r.top + r.bottom) / 2, ends = [[r.left + 4, y], [(r.left + r.right) / 2, y], [r.right - 4, y]];
      return ends.some(([x, y]) => { const hit = document.elementFromPoint(x, y); return hit && !e.contains(hit); });
    }).map((e) => e.textContent)""", selector)


@pytest.mark.parametrize("size", [(1366, 768), (1920, 1080)], ids=["1366x768", "1920x1080"])
def test_the_doubt_chips_and_log_out_are_wholly_seen_at_common_screen_sizes(page, artifacts, size):
    width, height = size
    page.set_viewport_size({"width": width, "height": height})
    doubtful = max(_api(page, "/api/systems?limit=100")["items"],
                   key=lambda s: len(_api(page, f"/api/systems/{s['id']}")["doubts"]))
    page.goto(f"/systems/{doubtful['id']}")
    page.locator(f"{tid('system-doubts')} .chip").first.wait_for()
    page.wait_for_function("() => !document.body.classList.contains('loading')")
    page.screenshot(path=str(artifacts / f"walk/system-{width}x{height}.png"))
    chips = page.locator(f"{tid('system-doubts')} .chip")
    assert chips.count() >= 2
    assert _covered_or_cut(page, f"{tid('system-doubts')} .chip") == []
    assert _covered_or_cut(page, ".topbar button") == []

    # the queue with a pass to resume: the link, the user's name and Log out all in the window
    order = [s["id"] for s in _api(page, "/api/systems?limit=100")["items"]]
    made = api_write(page, "POST", "/api/passes", data={"filter": {}, "sort": "-doubts", "system_id": order[3],
                                                         "fresh": True})
    assert made.ok
    page.goto("/")
    page.locator(tid("resume-pass")).wait_for()
    page.screenshot(path=str(artifacts / f"walk/queue-{width}x{height}.png"))
    assert _covered_or_cut(page, f".topbar a, .topbar button, {tid('resume-pass')}") == []


def test_the_views_of_an_accepted_system_read_accepted_with_the_system_not_pending(page):
    system = next(s for s in (_api(page, f"/api/systems/{i['id']}")
                              for i in _api(page, "/api/systems?sort=name&limit=100")["items"]) if len(s["views"]) >= 3)
    etag = page.request.get(f"/api/systems/{system['id']}").headers["etag"]
    assert api_write(page, "POST", f"/api/systems/{system['id']}/review", data={"status": "accepted"},
                     headers={"If-Match": etag}).ok
    try:
        page.goto(f"/systems/{system['id']}")
        page.locator(tid("view-decisions")).first.wait_for()
        badges = page.locator(f"{tid('view-decision-status')}, {tid('calibration-decision-status')}")
        texts = [badges.nth(i).inner_text() for i in range(badges.count())]
        assert len(texts) == 2 * len(system["views"])
        assert all(t == "accepted with the system" for t in texts), texts
        # a view's own decision reads as its own; the system's stands for the parts not decided
        page.keyboard.press("1")
        with page.expect_response(lambda r: "/calibration-review" in r.url) as answer:
            page.keyboard.press("Shift+N")
        assert answer.value.ok
        first = page.locator(tid("view-decisions")).first
        first.locator(tid("calibration-decision-status")).filter(has_text=re.compile("^needs fix$")).wait_for()
        assert first.locator(tid("view-decision-status")).inner_text() == "accepted with the system"
    finally:
        etag = page.request.get(f"/api/systems/{system['id']}").headers["etag"]
        assert api_write(page, "POST", f"/api/systems/{system['id']}/review", data={"status": "pending"},
                         headers={"If-Match": etag}).ok


def _view_with_box(system: dict) -> int:
    return next(k for k, v in enumerate(system["views"]) if v["ball"].get("box"))


def test_a_conflict_with_the_users_own_change_says_it_was_theirs(page, browser, server_url, accounts):
    """A 412 whose changes since the page read the view were all the same user's (another tab, a script with their
    session) says so; another person's change names them."""
    from tests.browser.support import log_in

    listing = _api(page, "/api/systems?sort=name&limit=100")["items"]
    system = next(s for s in (_api(page, f"/api/systems/{i['id']}") for i in listing[len(listing) // 2:])
                  if any(v["ball"].get("box") for v in s["views"]))
    k = _view_with_box(system)
    view = system["views"][k]
    fid, box = view["frame_id"], view["ball"]["box"]
    page.goto(f"/systems/{system['id']}")
    page.locator(tid("view")).nth(k).locator(tid("ball-hit")).wait_for()

    # the same user moves the box from elsewhere (their other tab) while this page shows the old version
    moved = api_write(page, "PATCH", f"/api/frames/{fid}/ball", data={"box": [box[0], box[1] + 4, box[2], box[3] + 4]},
                      headers={"If-Match": view["etag"]})
    assert moved.ok, moved.text()
    page.keyboard.press(str(k + 1))
    with page.expect_response(lambda r: r.request.method == "PATCH") as answer:
        page.keyboard.press("ArrowRight")
    assert answer.value.status == 412
    notice = page.locator(tid("conflict"))
    notice.locator("strong").filter(has_text="Conflict").wait_for()
    heading = notice.locator("strong").inner_text()
    assert "someone else" not in heading and "by you" in heading, heading
    page.locator(tid("conflict-keep")).click()

    # another person's change names them
    other = browser.new_context(base_url=server_url)
    try:
        theirs = other.new_page()
        theirs.goto("/login")
        log_in(theirs, accounts["annotator"])
        theirs.wait_for_url(f"{server_url}/")
        etag = theirs.request.get(f"/api/frames/{fid}").headers["etag"]
        assert api_write(theirs, "PATCH", f"/api/frames/{fid}/ball", data={"box": box}, headers={"If-Match": etag}).ok
    finally:
        other.close()
    with page.expect_response(lambda r: r.request.method == "PATCH") as answer:
        page.keyboard.press("ArrowLeft")
    assert answer.value.status == 412
    notice.locator("strong").filter(has_text=accounts["annotator"].name).wait_for()
    assert "by you" not in notice.locator("strong").inner_text()


def test_reverting_an_older_entry_asks_in_words_not_json(page):
    listing = _api(page, "/api/systems?sort=name&limit=100")["items"]
    system = next(s for s in (_api(page, f"/api/systems/{i['id']}") for i in reversed(listing))
                  if any(v["ball"].get("box") for v in s["views"]))
    k = _view_with_box(system)
    fid, box = system["views"][k]["frame_id"], system["views"][k]["ball"]["box"]
    for dy in (3, 6):  # two edits: the older one cannot be reverted without overwriting the newer
        etag = page.request.get(f"/api/frames/{fid}").headers["etag"]
        assert api_write(page, "PATCH", f"/api/frames/{fid}/ball",
                         data={"box": [box[0], box[1] + dy, box[2], box[3] + dy]}, headers={"If-Match": etag}).ok
    page.goto(f"/systems/{system['id']}")
    page.wait_for_function("() => document.querySelectorAll('[data-testid=history-entry]').length >= 2")
    asked: list[str] = []

    def answer(dialog):
        asked.append(dialog.message)
        dialog.dismiss()

    page.on("dialog", answer)
    older = page.locator(f"{tid('history-entry')}[data-action='ball.edit']").nth(1)
    with page.expect_event("dialog"), page.expect_response(lambda r: "/revert" in r.url) as refused:
        older.locator(tid("history-revert")).click()
    assert refused.value.status == 409
    assert len(asked) == 1, asked
    assert "{" not in asked[0] and '"' not in asked[0], asked[0]
    assert f"box [{box[0]:g}, {box[1] + 6:g}" in asked[0] and "Revert anyway" in asked[0], asked[0]
    etag = page.request.get(f"/api/frames/{fid}").headers["etag"]
    assert api_write(page, "PATCH", f"/api/frames/{fid}/ball", data={"box": box}, headers={"If-Match": etag}).ok


def test_the_sort_select_names_every_order_the_column_headers_give(page):
    page.goto("/")
    page.locator(tid("queue-row")).first.wait_for()
    headers = page.locator("th.sortable")
    for i in range(headers.count()):
        for _ in range(2):  # each header's first click and its flip
            before = page.url
            headers.nth(i).click()
            page.wait_for_function("(u) => location.href !== u", arg=before)
            page.locator(tid("queue-row")).first.wait_for()
            sort = re.search(r"[?&]sort=([^&]+)", page.url)
            wanted = sort.group(1) if sort else "-severity"  # the default order, left out of the address
            chosen = page.eval_on_selector(tid("sort"), "(s) => [s.value, s.selectedIndex, s.selectedOptions[0]?.text]")
            assert chosen[0] == wanted and chosen[1] >= 0 and chosen[2], (headers.nth(i).inner_text(), wanted, chosen)


def test_the_chip_legend_gives_each_fact_one_chip_in_the_tables_colour(page):
    page.goto("/")
    page.locator(tid("queue-row")).first.wait_for()
    legend = page.eval_on_selector_all(f"{tid('queue-legend')} {tid('chip-legend-entry')}", """(entries) =>
      entries.map((e) => { const c = e.querySelector('.chip'), s = getComputedStyle(c);
        return [c.textContent, e.textContent.slice(c.textContent.length).trim(), s.color, s.backgroundColor]; })""")
    assert len(legend) >= 10
    meanings = [m for _, m, _, _ in legend]
    assert len(set(meanings)) == len(meanings), [e for e in legend if meanings.count(e[1]) > 1]
    chips = {c: (colour, background) for c, _, colour, background in legend}
    assert not {"not admitted", "labels mirrored?"} & set(chips), sorted(chips)
    shown = page.eval_on_selector_all(f"{tid('row-doubts')} .chip", """(cs) => cs.map((c) => {
      const s = getComputedStyle(c); return [c.textContent.replace(/^\\d+ /, ''), s.color, s.backgroundColor]; })""")
    assert shown
    for words, colour, background in shown:
        assert words in chips, (words, sorted(chips))
        assert chips[words] == (colour, background), (words, chips[words], (colour, background))
    reds = {c for c, (colour, _) in chips.items() if colour == "rgb(255, 155, 149)"}
    assert {"mirrored labels", "error > τ"} <= reds


def test_enter_with_nothing_to_confirm_speaks_of_placements_first(page):
    system = _api(page, "/api/systems?sort=name&limit=100")["items"][1]
    page.goto(f"/systems/{system['id']}")
    page.locator(tid("view")).first.wait_for()
    page.wait_for_function("() => !document.body.classList.contains('loading')")
    page.keyboard.press("Enter")
    toast = page.locator(tid("toast"))
    toast.filter(has_text="nothing to confirm").wait_for()
    said = toast.inner_text()
    assert said.startswith("nothing to confirm: no label placed from a doubt's fix"), said


def _frame_boxes(page) -> list[tuple[float, float]]:
    """Where each view's frame is in the window (left, top), in the views' V order."""
    return page.eval_on_selector_all(f"{tid('view')} .frame", "(fs) => fs.map((f) => { const r = "
                                     "f.getBoundingClientRect(); return [Math.round(r.left), Math.round(r.top)]; })")


def test_a_dragged_box_and_a_confirmed_snap_leave_the_views_where_they_were(page, artifacts):
    """A drag released far from the other views' ball raises a doubt above that frame (and a chip in the line under
    the header); the frame stays under the pointer and no card is re-sorted. Snapping it back and confirming clears
    the doubt; no card changes column."""
    page.set_viewport_size({"width": 1366, "height": 768})
    items = _api(page, "/api/systems?sort=name&limit=100")["items"]
    system = next(s for s in (_api(page, f"/api/systems/{i['id']}") for i in items if i["views_total"] == 4)
                  if not s["doubts"] and all(v["ball"].get("box") for v in s["views"]))
    k = 1
    box = system["views"][k]["ball"]["box"]
    page.goto(f"/systems/{system['id']}")
    card = page.locator(tid("view")).nth(k)
    card.locator(tid("ball-hit")).wait_for()
    page.wait_for_function("() => !document.body.classList.contains('loading')")
    card.scroll_into_view_if_needed()
    before = _frame_boxes(page)
    m = card.locator(tid("view-svg")).evaluate(
        "(s) => { const m = s.getScreenCTM(); return [m.a, m.b, m.c, m.d, m.e, m.f]; }")

    def screen(px, py):
        return (m[0] * px + m[2] * py + m[4], m[1] * px + m[3] * py + m[5])

    cx, cy = (box[0] + box[2]) / 2, (box[1] + box[3]) / 2
    page.mouse.move(*screen(cx, cy))
    page.mouse.down()
    page.mouse.move(*screen(cx + 90, cy + 40), steps=8)
    with page.expect_response(lambda r: r.request.method == "PATCH" and "/ball" in r.url) as moved:
        page.mouse.up()
    assert moved.value.ok
    card.locator(tid("view-doubts")).wait_for()  # the doubt the drag raised, above the frame
    wait_for_steady_layout(page, f"{tid('view')} .frame")
    page.screenshot(path=str(artifacts / "walk/drag-released-1366x768.png"))
    after = _frame_boxes(page)
    # the browser's scroll anchoring keeps the frame where it was to within a few pixels (the node it anchors to is
    # not the frame itself; Chromium 156 leaves it 2 px off): still under the pointer, far from a bar's height
    assert after[k][0] == before[k][0] and abs(after[k][1] - before[k][1]) <= 4, \
        ("the frame moved under the pointer when the drag was released", before, after)
    assert [x for x, _ in after] == [x for x, _ in before], ("a card changed column", before, after)

    # snap it back to where the other views agree, confirm: the doubt clears, no card moves
    page.keyboard.press(str(k + 1))
    with page.expect_response(lambda r: r.request.method == "PATCH" and "/ball" in r.url) as snapped:
        page.keyboard.press("s")
    assert snapped.value.ok
    with page.expect_response(lambda r: r.request.method == "PATCH" and "/ball" in r.url) as confirmed:
        page.keyboard.press("Enter")
    assert confirmed.value.ok
    card.locator(tid("view-doubts")).wait_for(state="detached")
    wait_for_steady_layout(page, f"{tid('view')} .frame")
    after = _frame_boxes(page)
    assert [x for x, _ in after] == [x for x, _ in before], (before, after)
    etag = page.request.get(f"/api/frames/{system['views'][k]['frame_id']}").headers["etag"]
    assert api_write(page, "PATCH", f"/api/frames/{system['views'][k]['frame_id']}/ball", data={"box": box},
                     headers={"If-Match": etag}).ok


def test_ctrl_z_after_a_reload_undoes_the_users_last_edit_from_the_history(page):
    items = _api(page, "/api/systems?sort=-name&limit=100")["items"]
    system = next(s for s in (_api(page, f"/api/systems/{i['id']}") for i in items if i["views_total"] >= 3)
                  if s["views"][0]["ball"].get("box"))
    fid, box = system["views"][0]["frame_id"], system["views"][0]["ball"]["box"]
    page.goto(f"/systems/{system['id']}")
    page.locator(tid("view")).first.locator(tid("ball-hit")).wait_for()
    page.wait_for_function("() => !document.body.classList.contains('loading')")
    page.keyboard.press("1")
    with page.expect_response(lambda r: r.request.method == "PATCH" and "/ball" in r.url) as nudged:
        page.keyboard.press("ArrowRight")
    assert nudged.value.ok
    assert _api(page, f"/api/frames/{fid}")["ball"]["box"] == pytest.approx([box[0] + 1, box[1], box[2] + 1, box[3]])

    page.reload()
    page.locator(tid("history-entry")).first.wait_for()
    with page.expect_response(lambda r: r.request.method == "POST" and "/undo" in r.url) as undone:
        page.keyboard.press("Control+z")
    assert undone.value.ok, undone.value.text()
    page.locator(tid("toast")).filter(has_text="Undone").wait_for()
    assert _api(page, f"/api/frames/{fid}")["ball"]["box"] == pytest.approx(box)
    with page.expect_response(lambda r: r.request.method == "POST" and "/undo" in r.url) as redone:
        page.keyboard.press("Control+Shift+Z")
    assert redone.value.ok
    assert _api(page, f"/api/frames/{fid}")["ball"]["box"] == pytest.approx([box[0] + 1, box[1], box[2] + 1, box[3]])
    # after the undo and its redo, another reload: the redone edit is the user's last one again
    page.reload()
    page.locator(tid("history-entry")).first.wait_for()
    with page.expect_response(lambda r: r.request.method == "POST" and "/undo" in r.url) as again:
        page.keyboard.press("Control+z")
    assert again.value.ok, again.value.text()
    assert _api(page, f"/api/frames/{fid}")["ball"]["box"] == pytest.approx(box)


def test_the_queue_opened_logged_out_goes_to_the_login_after_one_question(browser, server_url):
    context = browser.new_context(base_url=server_url)
    try:
        p = context.new_page()
        refused: list[str] = []
        asked: list[str] = []
        p.on("response", lambda r: refused.append(r.url) if r.status == 401 else None)
        p.on("request", lambda r: asked.append(r.url) if "/api/" in r.url else None)
        # the login page's own first call (its demo hint) is asked once the queue's page is gone: whatever that page
        # asked, it asked before it
        with p.expect_response(lambda r: r.url.endswith("/api/auth/demo")):
            p.goto("/")
        p.wait_for_url(f"{server_url}/login?next=%2F")
        p.locator(tid("login-form")).wait_for()
        assert asked == [f"{server_url}/api/auth/me", f"{server_url}/api/auth/demo"], asked
        assert refused == [f"{server_url}/api/auth/me"], refused
    finally:
        context.close()
