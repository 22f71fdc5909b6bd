"""The curator's third walk through the imports, the exports, the words of the system page, the Detectors page and
the accessibility of every page (Playwright, Chromium, the real server on this module's copy of the seeded demo
database): each test is one thing the walk found wrong, named after what the user now sees, at 1366x768 (the layout
ones at 1920x1080 too), logged in as the admin."""
from __future__ import annotations

import io
import shlex
import zipfile

import pytest
from playwright.sync_api import expect

from tests.browser.conftest import admin_page
from tests.browser.support import api_json, api_write, pump_until, tid, wait_for_job, wait_for_steady_layout

pytestmark = pytest.mark.browser

SIZES = [(1366, 768), (1920, 1080)]
SIZE_IDS = ["1366x768", "1920x1080"]


@pytest.fixture
def small_page(browser, server_url, admin_state):
    """A 1366x768 page of the logged-in admin (:func:`tests.browser.conftest.admin_page`)."""
    yield from admin_page(browser, server_url, admin_state, 1366, 768)


def _zip(files: dict[str, bytes]) -> bytes:
    out = io.BytesIO()
    with zipfile.ZipFile(out, "w") as z:
        for name, data in files.items():
            z.writestr(name, data)
    return out.getvalue()


def _upload(page, name: str, data: bytes, kind: str) -> None:
    page.locator(tid("import-kind")).select_option(kind)
    page.locator(tid("import-file")).set_input_files({"name": name, "mimeType": "application/zip", "buffer": data})
    page.locator(tid("import-start")).click()


# ----- 11: an ISSIA-3D export of a release without ISSIA sequences ------------------------------------------------
def test_an_issia_export_of_a_release_without_issia_says_nothing_to_export(small_page, artifacts):
    page = small_page
    systems = api_json(page, "/api/systems?limit=1")["items"]
    assert api_write(page, "POST", f"/api/systems/{systems[0]['id']}/review", {"status": "accepted", "comment": ""}).ok
    made = api_write(page, "POST", "/api/releases", {"name": "no-issia", "note": ""})
    assert made.ok, made.text()
    page.goto("/static/releases.html")
    page.locator(tid("export-issia-3d")).click()
    status = page.locator(tid("export-status-issia-3d"))
    status.locator(tid("export-nothing")).wait_for()
    assert "nothing to export: release no-issia holds no frame of an ISSIA sequence" in status.inner_text()
    assert status.locator(tid("export-download")).count() == 0  # no empty zip offered
    page.screenshot(path=str(artifacts / "walk3/releases-issia-nothing-1366x768.png"))
    job = api_json(page, "/api/jobs?kind=export")["items"][0]
    assert job["result_url"] is None and page.request.get(f"{job['url']}/result").status == 409


def test_the_release_exports_wait_for_the_release_list_before_they_can_be_clicked(small_page):
    """The export buttons of the Releases page are disabled while the page reads its releases: clicked before, they
    exported with no release chosen (the database now), and the release's "nothing to export" never came (a
    browser run met it). The list's answer is held here until the buttons are seen disabled: the order is certain."""
    page = small_page
    systems = api_json(page, "/api/systems?limit=1")["items"]
    assert api_write(page, "POST", f"/api/systems/{systems[0]['id']}/review", {"status": "accepted", "comment": ""}).ok
    assert api_write(page, "POST", "/api/releases", {"name": "held", "note": ""}).ok
    held: list = []
    reads = []

    def hold_the_panels_read(route) -> None:  # the page's own table reads the list first, the panel next
        reads.append(route.request.method)
        if route.request.method == "GET" and reads.count("GET") == 2:
            held.append(route)
        else:
            route.continue_()

    page.route("**/api/releases", hold_the_panels_read)
    page.goto("/static/releases.html")
    button = page.locator(tid("export-issia-3d"))
    button.wait_for(state="attached")
    pump_until(page, lambda: bool(held), "the page's read of the releases")
    assert button.is_disabled()  # the list is on its way: no scope chosen yet
    held[0].continue_()
    expect(button).to_be_enabled()
    assert page.locator(tid("export-scope")).input_value() == "release:held"


# ----- 12: re-import from the browser offers the merge ----------------------------------------------------------
def test_a_reimport_from_the_import_panel_offers_keep_newer_or_overwrite(small_page, seeded_databases, artifacts):
    page = small_page
    labels = next((seeded_databases.root / "demo").rglob("Labels-v3.json"))  # the demo's first game, as imported
    game = "/".join(labels.parent.parts[-3:])  # league/season/match
    data = _zip({f"{game}/{f.name}": f.read_bytes() for f in labels.parent.iterdir() if f.is_file()})
    page.goto("/")
    _upload(page, "demo-again.zip", data, "soccernet-v3")
    merge = page.locator(tid("import-merge"))
    merge.wait_for()
    assert "stored already" in merge.locator(tid("import-merge-text")).inner_text()
    modes = [b.get_attribute("data-mode") for b in merge.locator(tid("import-merge-mode")).all()]
    assert modes == ["keep-newer", "overwrite"]
    page.screenshot(path=str(artifacts / "walk3/import-merge-1366x768.png"))
    with page.expect_response(lambda r: r.url.endswith("/api/imports") and r.request.method == "POST") as answer:
        merge.locator('[data-mode="keep-newer"]').click()
    assert answer.value.status == 202
    job = answer.value.json()
    assert job["params"]["merge"] == "keep-newer"
    # the Jobs panel shows the job the words point at
    page.locator(f'{tid("jobs")}:not([hidden]) {tid("job")}[data-id="{job["id"]}"]').wait_for()
    assert "in the Jobs panel, above" in page.locator(tid("import-upload-text")).inner_text()
    assert wait_for_job(page, job["url"])["state"] == "done"


# ----- 13: a wrong upload explained without a server folder ------------------------------------------------------
def test_a_wrong_upload_names_what_it_holds_and_the_layout_wanted_never_a_server_folder(small_page, seeded_settings,
                                                                                        seeded_databases):
    from app.core.config import jobs_dir

    page = small_page
    data = _zip({"notes.txt": b"hello", "pictures/list.csv": b"a,b"})
    page.goto("/")
    _upload(page, "holiday.zip", data, "soccernet-v3")
    error = page.locator(tid("error"))
    error.locator(".msg").filter(has_text="holiday.zip").wait_for()
    words = error.inner_text()
    assert "no Labels-v3.json" in words and "notes.txt" in words and "pictures/list.csv" in words
    assert "<league>/<season>/<match>/" in words and "Frames-v3.zip" in words
    for folder in (str(jobs_dir(seeded_settings)), str(seeded_databases.root), "uploads/"):
        assert folder not in words, words


# ----- 15: curator words on the system page ----------------------------------------------------------------------
def test_the_system_page_labels_each_fit_figure_and_says_a_pinned_camera_is_pinned(small_page):
    page = small_page
    system = next(s for s in (api_json(page, f"/api/systems/{i['id']}")
                              for i in api_json(page, "/api/systems?limit=20")["items"])
                  if any((v["calibration"] or {}).get("jac") for v in s["views"]))
    page.goto(f"/systems/{system['id']}")
    page.locator(tid("view-jac-gamma")).first.wait_for()
    jac = page.locator(tid("view-jac")).first.inner_text()
    assert jac.count(" within ") == 3 and "% within 0.5 %" in jac and "% within 2 %" in jac, jac
    words = page.evaluate("""async () => {
      const { uncertaintyText } = await import('/static/js/viewfacts.js');
      const pinned = uncertaintyText({ position_m: { x: 0, y: 0, z: 0 }, pan_deg: 0.1, tilt_deg: 0.05, roll_deg: 0.02,
                                       focal_px: 12 });
      const fitted = uncertaintyText({ position_m: { x: 0.4, y: 1.2, z: 0.3 }, pan_deg: 0.1, tilt_deg: 0.05,
                                       roll_deg: 0.02, focal_px: 12 });
      return { pinned, fitted };
    }""")
    assert words["pinned"].startswith("where: pinned to a known camera position") and "0.00" not in words["pinned"]
    assert words["fitted"].startswith("where x 0.40, y 1.20, z 0.30 m")


# ----- 16: the Detectors page names real commands ----------------------------------------------------------------
#: The Detectors page once its list of sources is read: a source's row, or the words saying there is none (the table
#: itself is drawn before it is read, and hidden after when the list is empty).
LOADED_SOURCES = f"{tid('source-row')}, {tid('sources-empty')}"


def test_the_detectors_page_names_commands_the_command_line_has(small_page):
    import importlib
    import pkgutil

    import typer.main

    import app.cli
    from app.cli import cli

    for module in pkgutil.iter_modules(app.cli.__path__):  # each registers its commands when imported (as main does)
        importlib.import_module(f"app.cli.{module.name}")

    page = small_page
    page.goto("/static/monocular.html")
    page.locator(LOADED_SOURCES).first.wait_for()
    commands = [c for c in page.locator("code").all_inner_texts() if c.startswith("v3d ")]
    assert "v3d import predictions" in commands
    root = typer.main.get_command(cli)
    for command in commands:
        group = root
        for word in shlex.split(command)[1:]:
            if word.startswith("-") or word.isupper() or not hasattr(group, "commands"):
                break
            assert word in group.commands, f"{command!r}: no {word!r} among {sorted(group.commands)}"
            group = group.commands[word]


# ----- 18: pinning a comment has a key ---------------------------------------------------------------------------
def test_p_pins_a_comment_on_the_system_page(small_page):
    page = small_page
    system = api_json(page, "/api/systems?limit=1")["items"][0]
    page.goto(f"/systems/{system['id']}")
    page.locator(tid("view-svg")).first.wait_for()
    page.locator(tid("comment-pin-start")).wait_for()
    page.keyboard.press("p")
    # a locator, not an expression: Playwright polls a string expression with `new Function` in the page, which
    # the page's CSP (no unsafe-eval) refuses whenever the class is not there at the first look (CI, under load)
    page.locator("body.pinning").wait_for(state="attached")
    svg = page.locator(tid("view-svg")).first
    svg.click(position={"x": 40, "y": 40})
    page.locator(tid("comment-form")).wait_for()
    assert page.locator(tid("comment-where")).inner_text().startswith("on V1")


# ----- 14: users and the audit in the browser ----------------------------------------------------------------------
def _answer_of(page, method: str, path: str):
    """Wait for the page's ``method`` request to the API path ``path`` (query left aside) and answer its response."""
    return page.expect_response(lambda r: r.request.method == method and r.url.split("?")[0].endswith(path))


def test_an_admin_adds_a_user_changes_its_role_issues_and_revokes_a_token_and_disables_it(browser, server_url,
                                                                                          small_page, artifacts):
    page = small_page
    page.goto("/")
    page.locator(tid("link-users")).click()
    page.wait_for_url("**/static/users.html")
    page.locator(f"{tid('user-row')}[data-name='test-admin']").wait_for()
    form = page.locator(tid("user-form"))
    form.locator(tid("user-name-input")).fill("nadia")
    form.locator(tid("user-role-input")).select_option("annotator")
    form.locator(tid("user-password-input")).fill("a long pass phrase")
    with _answer_of(page, "POST", "/api/users") as made:
        form.locator(tid("user-add")).click()
    assert made.value.status == 201
    shown = page.locator(tid("token-shown"))
    shown.wait_for()
    first = shown.locator(tid("token-value")).inner_text()
    assert first.startswith("v3d_") and "shown this once" in shown.inner_text() and "nadia" in shown.inner_text()
    page.screenshot(path=str(artifacts / "walk3/users-token-shown-1366x768.png"))
    assert page.locator(f"{tid('user-row')}[data-name='test-admin'] {tid('user-disable')}").is_hidden()  # not oneself
    outsider = browser.new_context(base_url=server_url)  # no cookie: the token alone
    try:
        assert outsider.request.get("/api/auth/me", headers={"Authorization": f"Bearer {first}"}).json()["role"] == \
            "annotator"
        row = page.locator(f"{tid('user-row')}[data-name='nadia']")
        assert row.locator(tid("user-state")).inner_text() == "active"
        with _answer_of(page, "PATCH", "/api/users/nadia") as changed:
            row.locator(tid("user-role")).select_option("reviewer")
        assert changed.value.status == 200
        assert {u["name"]: u["role"] for u in api_json(page, "/api/users")}["nadia"] == "reviewer"
        # another token, labelled: shown once, listed by its label; revoked after the words say it is for good
        tokens = page.locator(tid("tokens-panel"))
        assert tokens.locator(tid("tokens-heading")).text_content() == "API tokens of nadia"
        tokens.locator(tid("token-label-input")).fill("laptop")
        with _answer_of(page, "POST", "/api/users/nadia/tokens") as issued:
            tokens.locator(tid("token-issue")).click()
        laptop = issued.value.json()
        page.locator(tid("token-value")).filter(has_text=laptop["token"]).wait_for()
        line = tokens.locator(f"{tid('token-row')}[data-id='{laptop['id']}']")
        assert line.locator(tid("token-label")).inner_text() == "laptop"
        assert line.locator(tid("token-state")).inner_text() == "active"
        page.locator(tid("token-shown-close")).click()
        page.locator(tid("token-shown")).wait_for(state="hidden")
        assert page.locator(tid("token-value")).inner_text() == ""
        asked = []
        page.once("dialog", lambda d: (asked.append(d.message), d.accept()))
        with _answer_of(page, "DELETE", f"/api/users/nadia/tokens/{laptop['id']}"):
            line.locator(tid("token-revoke")).click()
        assert "for good" in asked[0]
        tokens.locator(f"{tid('token-row')}[data-id='{laptop['id']}'] {tid('token-state')}").filter(
            has_text="revoked").wait_for()
        bearer = {"Authorization": f"Bearer {laptop['token']}"}
        assert outsider.request.get("/api/auth/me", headers=bearer).status == 401
        # disabled: its sessions end and its first token stops working, for good
        page.once("dialog", lambda d: (asked.append(d.message), d.accept()))
        with _answer_of(page, "PATCH", "/api/users/nadia"):
            row.locator(tid("user-disable")).click()
        assert "revoked for good" in asked[1] and "1 working API token " in asked[1]
        row.locator(tid("user-state")).filter(has_text="disabled").wait_for()
        assert row.locator(tid("user-token-count")).inner_text() == "0"
        assert outsider.request.get("/api/auth/me", headers={"Authorization": f"Bearer {first}"}).status == 401
    finally:
        outsider.close()
    # a name taken is refused, naming the field
    form.locator(tid("user-name-input")).fill("nadia")
    form.locator(tid("user-password-input")).fill("x")
    form.locator(tid("user-add")).click()
    error = page.locator(tid("error")).locator(".msg")
    error.filter(has_text="already exists").wait_for()
    assert "name" in error.inner_text()
    # the tokens shown once are on no page after a reload
    page.reload()
    page.locator(f"{tid('user-row')}[data-name='nadia']").wait_for()
    assert first not in page.content() and laptop["token"] not in page.content()


def test_the_users_and_audit_links_are_an_admins_only(browser, server_url, small_page, accounts):
    small_page.goto("/")
    small_page.locator(tid("logout")).wait_for()
    assert small_page.locator(f"{tid('site-nav')} {tid('link-users')}").count() == 1
    annotator = browser.new_context(base_url=server_url, extra_http_headers=accounts["annotator"].bearer)
    try:
        page = annotator.new_page()
        page.goto("/")
        page.locator(tid("logout")).wait_for()  # put in after the sections, and after the admins' ones
        assert page.locator(f"{tid('site-nav')} a").count() == 4
        assert page.locator(tid("link-users")).count() == 0 and page.locator(tid("link-audit")).count() == 0
        page.goto("/static/users.html")
        page.locator(tid("users-admins-only")).wait_for()
        assert page.locator(tid("users-panel")).is_hidden()
    finally:
        annotator.close()


def _audit_ids(page) -> list[int]:
    return [int(i.removeprefix("#")) for i in page.locator(tid("audit-id")).all_inner_texts()]


def test_the_audit_page_filters_by_user_system_and_day_and_pages_with_each_entrys_number(small_page, artifacts):
    page = small_page
    systems = api_json(page, "/api/systems?limit=3&sort=name&status=pending")["items"]
    for system in systems:
        assert api_write(page, "POST", f"/api/systems/{system['id']}/review",
                         {"status": "rejected", "comment": "seen in the audit"}).ok
    decided = api_json(page, f"/api/audit?system_id={systems[0]['id']}&limit=1")["items"][0]
    undone = api_write(page, "POST", f"/api/audit/{decided['id']}/undo")
    assert undone.ok, undone.text()
    mine = api_json(page, "/api/audit?user=test-admin&limit=500")
    page.goto("/")
    page.locator(tid("link-audit")).click()
    page.wait_for_url("**/static/audit.html")
    page.locator(tid("audit-row")).first.wait_for()
    # by user, two entries a page: the same entries as the API's, newest first, each with its number
    page.goto("/static/audit.html?user=test-admin&limit=2")
    page.locator(tid("audit-count")).filter(has_text=f"{mine['total']} entries match").wait_for()
    assert _audit_ids(page) == [e["id"] for e in mine["items"][:2]]
    assert set(page.locator(tid("audit-actor")).all_inner_texts()) == {"test-admin"}
    assert page.locator(tid("audit-newer")).is_disabled()
    with _answer_of(page, "GET", "/api/audit"):
        page.locator(tid("audit-older")).click()
    page.locator(tid("audit-page")).filter(has_text=f"entries 3–4 of {mine['total']}").wait_for()
    assert _audit_ids(page) == [e["id"] for e in mine["items"][2:4]]
    assert "offset=2" in page.url
    with _answer_of(page, "GET", "/api/audit"):
        page.locator(tid("audit-newer")).click()
    page.locator(tid("audit-page")).filter(has_text="entries 1–2 of").wait_for()
    # by system, typed in the filters: its decision, and the undo naming the entry it undid by the number shown
    page.locator(tid("audit-user")).fill("")
    page.locator(tid("audit-system")).fill(str(systems[0]["id"]))
    with _answer_of(page, "GET", "/api/audit"):
        page.locator(tid("audit-show")).click()
    page.locator(tid("audit-reverts")).first.wait_for()
    ids = _audit_ids(page)
    assert set(page.locator(tid("audit-system-id")).all_inner_texts()) == {str(systems[0]["id"])}
    assert decided["id"] in ids and ids == sorted(ids, reverse=True)
    undo_row = page.locator(f"{tid('audit-row')}[data-id='{undone.headers['x-v3d-audit-entry']}']")
    assert f"entry {decided['id']}" in undo_row.locator(tid("audit-summary")).inner_text()
    assert undo_row.locator(tid("audit-reverts")).get_attribute("href") == f"#entry-{decided['id']}"
    page.screenshot(path=str(artifacts / "walk3/audit-system-1366x768.png"))
    # by the reader's day: today holds them, tomorrow nothing
    today, tomorrow = page.evaluate("() => [0, 1].map((n) => { const d = new Date(); d.setDate(d.getDate() + n); "
                                    "return [d.getFullYear(), d.getMonth() + 1, d.getDate()]"
                                    ".map((v) => String(v).padStart(2, '0')).join('-'); })")
    page.locator(tid("audit-from")).fill(today)
    page.locator(tid("audit-until")).fill(today)
    page.locator(tid("audit-show")).click()
    page.locator(f"{tid('audit')}[data-shown*='since=']").wait_for()
    assert _audit_ids(page) == ids
    page.locator(tid("audit-from")).fill(tomorrow)
    page.locator(tid("audit-until")).fill(tomorrow)
    with _answer_of(page, "GET", "/api/audit"):
        page.locator(tid("audit-show")).click()
    page.locator(tid("audit-empty")).wait_for()
    assert page.locator(tid("audit-row")).count() == 0


@pytest.mark.parametrize("size", SIZES, ids=SIZE_IDS)
def test_the_users_and_audit_pages_fit_the_window(small_page, artifacts, size):
    page = small_page
    page.set_viewport_size({"width": size[0], "height": size[1]})
    for name, ready in (("users", tid("user-row")), ("audit", tid("audit-row"))):
        page.goto(f"/static/{name}.html")
        page.locator(ready).first.wait_for()
        page.locator(tid("logout")).wait_for()
        if name == "users":
            page.locator(f"{tid('user-row')}[data-name='test-admin'] {tid('user-tokens')}").click()
            page.locator(tid("token-row")).first.wait_for()
        wait_for_steady_layout(page)
        assert page.evaluate("document.documentElement.scrollWidth") <= size[0], name  # no sideways scrolling
        page.screenshot(path=str(artifacts / f"walk3/{name}-{size[0]}x{size[1]}.png"))


# ----- 20: no serious or critical accessibility violation on any page ---------------------------------------------
#: What axe-core checks: WCAG 2.0 and 2.1, levels A and AA.
AXE_TAGS = ["wcag2a", "wcag2aa", "wcag21a", "wcag21aa"]


def _axe_violations(page) -> list[str]:
    """The serious and critical violations axe-core finds on the page as it is, each with the elements it names."""
    from axe_playwright_python.sync_playwright import Axe

    found = Axe().run(page, options={"runOnly": {"type": "tag", "values": AXE_TAGS}, "resultTypes": ["violations"]})
    return [f"{v['id']} ({v['impact']}): {v['help']}: {[n['target'] for n in v['nodes']][:4]}"
            for v in found.response["violations"] if v["impact"] in ("serious", "critical")]


def test_every_page_has_no_serious_accessibility_violation(browser, server_url, small_page):
    page = small_page
    system = api_json(page, "/api/systems?limit=1")["items"][0]
    pages = {"/": tid("queue-row"), f"/systems/{system['id']}": tid("view-svg"),
             "/static/stats.html": "svg", "/static/releases.html": f"{tid('diff-form')}",
             "/static/monocular.html": LOADED_SOURCES, "/static/users.html": tid("user-row"),
             "/static/audit.html": tid("audit-row")}
    found = {}
    for path, ready in pages.items():
        page.goto(path)
        page.locator(ready).first.wait_for()
        found[path] = _axe_violations(page)
    anonymous = browser.new_context(viewport={"width": 1366, "height": 768}, base_url=server_url)
    try:
        login = anonymous.new_page()
        login.goto("/login")
        login.locator("form").first.wait_for()
        found["/login"] = _axe_violations(login)
    finally:
        anonymous.close()
    assert not any(found.values()), {p: v for p, v in found.items() if v}


# ----- 19: no "none" comment count above a return note --------------------------------------------------------------
def test_a_system_returned_with_no_comment_shows_its_return_note_not_comments_none(browser, server_url, small_page,
                                                                                    accounts):
    page = small_page
    sid = api_json(page, "/api/systems?limit=1&sort=-name&status=pending")["items"][0]["id"]
    view = next(v for v in api_json(page, f"/api/systems/{sid}")["views"] if (v.get("ball") or {}).get("box"))
    annotator = browser.new_context(base_url=server_url, extra_http_headers=accounts["annotator"].bearer)
    try:  # the annotator moves the view's ball label: the system's needs fix is returned to them
        etag = annotator.request.get(f"/api/frames/{view['frame_id']}").headers["etag"]
        box = view["ball"]["box"]
        moved = annotator.request.patch(f"/api/frames/{view['frame_id']}/ball", headers={"If-Match": etag},
                                        data={"box": [box[0] + 2, box[1], box[2] + 2, box[3]]})
        assert moved.ok, moved.text()
    finally:
        annotator.close()
    decided = api_write(page, "POST", f"/api/systems/{sid}/review",
                        {"status": "needs_fix", "comment": "the box is two pixels off"})
    assert decided.ok, decided.text()
    page.goto(f"/systems/{sid}")
    note = page.locator(tid("handoff"))
    note.wait_for()
    assert note.inner_text().startswith(f"returned to {accounts['annotator'].name}")
    assert page.locator(tid("review-comment")).count() == 0
    assert page.locator(tid("comments-count")).inner_text() == ""  # drawn with the note: never "none" above it


# ----- 19: the queue's game column tells games apart ----------------------------------------------------------------
@pytest.mark.parametrize("size", SIZES, ids=SIZE_IDS)
def test_the_queues_game_column_leads_with_the_teams(small_page, artifacts, size):
    page = small_page
    page.set_viewport_size({"width": size[0], "height": size[1]})
    page.goto("/")
    cell = page.locator(tid("queue-game")).first
    cell.wait_for()
    match = cell.get_attribute("title").split(" / ")[-1]
    date, _, rest = match.partition(" - ")
    shown = cell.inner_text()
    assert shown.startswith(rest.split(" ", 1)[1]) and date in shown, (match, shown)  # teams first, then the date
    page.screenshot(path=str(artifacts / f"walk3/queue-{size[0]}x{size[1]}.png"))
