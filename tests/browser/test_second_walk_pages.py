"""The curator's second walk through the queue's jobs, the imports, the releases, the detectors and the statistics
(Playwright, Chromium, the real server): each test is one thing the walk found wrong, named after what the user now
sees. The database is the demo and a labels-only copy of its game, both imported as ``v3d import soccernet-v3``
imports (a job row run by this process, ``app.cli.datasets.run_job_here``) before the server starts; the pages are
used at 1366x768 (the layout ones at 1920x1080 too), logged in through the login page as an admin."""
from __future__ import annotations

import io
import json
import re
import zipfile
from pathlib import Path

import pytest

from tests.browser.support import api_json, api_write, hold_first, log_in, pump_until, settled, tid, wait_for_job
from tests.conftest import migrate_new_database

pytestmark = pytest.mark.browser

SIZES = [(1366, 768), (1920, 1080)]
SIZE_IDS = ["1366x768", "1920x1080"]
#: The labels-only copy's game (the demo's labels under another match name: a game of its own, no image).
LABELS_ONLY_MATCH = "2025-03-22 - 15-00 Northbridge 0 - 0 Westfield"


#: The labels-only copy's view left with one field line and no player: its calibration is refused (a view without a
#: camera: neither its lines nor its players place one).
NO_CAMERA_VIEW = "1_3.png"


def labels_only_tree(demo: Path, out: Path, match: str = LABELS_ONLY_MATCH) -> Path:
    """A SoccerNet-v3 tree holding the demo's ``Labels-v3.json`` under the game ``match``, without its
    ``Frames-v3.zip``: a labels-only dataset; its view :data:`NO_CAMERA_VIEW` keeps one field line and its ball box
    only."""
    labels = next(demo.rglob("Labels-v3.json"))
    game = out / labels.parent.parent.parent.name / labels.parent.parent.name / match
    game.mkdir(parents=True)
    data = json.loads(labels.read_text())
    view = data["replays"][NO_CAMERA_VIEW]
    view["lines"] = view["lines"][:1]
    view["bboxes"] = [b for b in view.get("bboxes", []) if b.get("class") == "Ball"]
    (game / "Labels-v3.json").write_text(json.dumps(data))
    return out


@pytest.fixture(scope="module")
def seeded_settings(tmp_path_factory: pytest.TempPathFactory):
    """The demo and a labels-only game, each imported as ``v3d import soccernet-v3`` does: a job row claimed and
    run by this process (``run_job_here``), finished before the server starts."""
    from app.cli.datasets import run_job_here
    from app.core.config import Settings
    from app.demo import generate_demo_dataset
    from app.services.jobs.work import import_params

    root = tmp_path_factory.mktemp("walk2")
    settings = Settings(database_url=f"sqlite:///{root / 'walk2.sqlite3'}", calibration_workers=1,
                        data_root=tmp_path_factory.getbasetemp())
    migrate_new_database(settings.database_url)
    dataset = generate_demo_dataset(root / "demo")
    for path in (dataset, labels_only_tree(dataset, root / "labels-only")):
        job_id, result = run_job_here(settings, "import", import_params("soccernet-v3", path))
        assert result["systems"] > 0, (job_id, result)
    return settings


@pytest.fixture
def small_page(browser, server_url, accounts):
    """A 1366x768 page logged in through the login page as the admin; a dialog or a JavaScript error fails it."""
    context = browser.new_context(viewport={"width": 1366, "height": 768}, base_url=server_url)
    p = context.new_page()
    errors: list[str] = []
    p.on("pageerror", lambda exc: errors.append(str(exc)))
    p.on("dialog", lambda d: errors.append(f"a dialog: {d.message}"))
    p.goto("/")
    p.wait_for_url(f"{server_url}/login?next=%2F")
    log_in(p, accounts["admin"])
    p.wait_for_url(f"{server_url}/")
    try:
        yield p
    finally:
        context.close()
    assert not errors, f"JavaScript errors or dialogs on the page: {errors}"


def _cut_off(page, selector: str) -> list[str]:
    """Texts of the elements of ``selector`` that are cut by the window's right edge or covered."""
    return page.evaluate("""(selector) => [...document.querySelectorAll(selector)].filter((e) => {
      const r = e.getBoundingClientRect();
      if (r.width === 0) return false;
      if (r.right > window.innerWidth + 0.5) return true;
      const y = (r.top + r.bottom) / 2;
      return [[r.left + 2, y], [r.right - 2, y]].some(([x, y]) => {
        const hit = document.elementFromPoint(x, y); return hit && !e.contains(hit) && !hit.contains(e); });
    }).map((e) => e.textContent)""", selector)


# ----- 4: a finished job's result in words; command-line jobs listed -------------------------------------------
def test_the_jobs_panel_lists_the_command_line_imports_with_what_they_gave_in_numbers(small_page, artifacts):
    page = small_page
    # the two imports `v3d import` ran before the server started (no user queued them)
    jobs = {j["id"]: j for j in api_json(page, "/api/jobs?kind=import")["items"] if not j["params"].get("actor")}
    assert len(jobs) == 2 and all(j["state"] == "done" for j in jobs.values())
    page.wait_for_selector(f"{tid('jobs')}:not([hidden]) {tid('job')}")
    rows = page.locator(f"{tid('jobs')} {tid('job')}")
    assert rows.count() >= 2
    for job_id, job in jobs.items():
        row = page.locator(f'{tid("job")}[data-id="{job_id}"]')
        r = job["result"]
        assert row.get_attribute("data-state") == "done"
        text = row.locator(tid("job-summary")).inner_text()
        # its systems, how many got a 3D ball, how many views no camera: the stored counts, in words
        assert text.startswith(f"{r['systems']} systems: {r['triangulated']} with a 3D ball")
        if r["refused"]:
            assert f"{r['refused']} view{'s' if r['refused'] > 1 else ''} without a camera" in text
        assert "command line" in row.inner_text()
    labels_only = max(jobs)  # imported second
    assert "no images" in page.locator(f'{tid("job")}[data-id="{labels_only}"] {tid("job-summary")}').inner_text()
    assert "no images" not in page.locator(f'{tid("job")}[data-id="{min(jobs)}"] {tid("job-summary")}').inner_text()
    assert jobs[labels_only]["result"]["refused"] >= 1  # the view left with one line
    page.screenshot(path=str(artifacts / "walk2/queue-jobs-1366x768.png"))
    # the words link to the systems they speak of: the queue filtered to the systems with a view without a camera
    link = page.locator(f'{tid("job")}[data-id="{labels_only}"] {tid("job-summary-link")}')
    assert link.inner_text() == f"{jobs[labels_only]['result']['refused']} view without a camera"
    link.click()
    page.wait_for_url("**/?doubt=calibration_refused")
    page.locator(f"{tid('queue')} tbody tr").first.wait_for()
    assert page.locator(tid("filter-doubt")).input_value() == "calibration_refused"
    listed = api_json(page, "/api/systems?doubt=calibration_refused")["items"]
    assert page.locator(f"{tid('queue')} tbody tr").count() == len(listed) >= 1


def test_a_finished_job_shows_no_running_state_and_a_full_bar_never(small_page):
    page = small_page
    bar = page.evaluate("""async () => {
      const { progressBar, jobProgressText } = await import('/static/js/jobs.js');
      const full = progressBar({ state: 'running', stage: 'calibrate', done: 30, total: 30 });
      const half = progressBar({ state: 'running', stage: 'calibrate', done: 15, total: 30 });
      return { fullHasValue: full.hasAttribute('value') && full.position === 1, half: half.value,
               bytes: jobProgressText({ state: 'running', stage: 'predictions', done: 77250, total: 154500 }) };
    }""")
    assert bar == {"fullHasValue": False, "half": 15, "bytes": "reading the predictions 50 %"}


def test_one_size_function_says_50_kb_not_0_0_mb(small_page):
    sizes = small_page.evaluate("""async () => {
      const { fmtBytes } = await import('/static/js/format.js');
      return [812, 50 * 1024, 3.4 * 1048576, 1.5 * 1073741824].map(fmtBytes);
    }""")
    assert sizes == ["812 B", "50 KB", "3.4 MB", "1.5 GB"]


# ----- 7 and 11: a labels-only upload says so, and the message points where the Jobs panel is ------------------
def test_a_labels_only_upload_says_it_has_no_images_and_where_its_job_is(small_page, tmp_path, seeded_settings):
    page = small_page
    tree = labels_only_tree(next(Path(seeded_settings.database_url.removeprefix("sqlite:///")).parent
                                 .glob("demo")), tmp_path / "tree", match="2025-04-01 - 20-00 Upload 1 - 1 Zip")
    archive = tmp_path / "labels-only.zip"
    with zipfile.ZipFile(archive, "w") as zf:
        for f in tree.rglob("*"):
            if f.is_file():
                zf.write(f, f.relative_to(tree).as_posix())
    page.wait_for_selector(f"{tid('import')}:not([hidden])")
    page.set_input_files(tid("import-file"), str(archive))
    page.click(tid("import-start"))
    text = page.locator(tid("import-upload-text"))
    said_now = "(re) => new RegExp(re).test(document.querySelector('[data-testid=import-upload-text]').textContent)"
    page.wait_for_function(said_now, arg="queued")
    said = text.inner_text()
    jobs_y = page.locator(tid("jobs")).bounding_box()["y"]
    import_y = page.locator(tid("import")).bounding_box()["y"]
    assert ("above" in said) == (jobs_y < import_y) and ("below" in said) == (jobs_y > import_y), said
    page.wait_for_function(said_now, arg="imported", timeout=180_000)
    assert "no images" in text.inner_text()


# ----- 5 and 13: releases made, exported and compared on the Releases page ---------------------------------------
def _decide(page, system_id: int, status: str) -> None:
    answer = page.request.get(f"/api/systems/{system_id}")
    done = api_write(page, "POST", f"/api/systems/{system_id}/review", data={"status": status, "comment": ""},
                     headers={"If-Match": answer.headers["etag"]})
    assert done.ok, done.text()


def _create_on_page(page, name: str) -> None:
    page.fill(tid("release-name"), name)
    page.click(tid("release-create"))
    page.wait_for_selector(f"{tid('releases')} tr[data-release='{name}']")


def test_an_admin_types_a_name_and_presses_create_release_and_it_exists(small_page, artifacts):
    page = small_page
    systems = api_json(page, "/api/systems?limit=5&sort=name&status=pending")["items"]
    _decide(page, systems[0]["id"], "accepted")
    _decide(page, systems[1]["id"], "accepted")
    page.goto("/static/releases.html")
    page.get_by_role("button", name="Create release").wait_for()
    _create_on_page(page, "walk-1")
    made = {r["name"]: r for r in api_json(page, "/api/releases")["items"]}
    assert made["walk-1"]["systems"] >= 2
    row = page.locator(f"{tid('releases')} tr[data-release='walk-1']")
    # made: in the reader's words, the full time on hover; by: the person, never "cli:..."
    assert row.locator(tid("release-when")).inner_text() in ("just now", "now") or "second" in row.inner_text()
    assert made["walk-1"]["created_at"][:4] in row.locator(tid("release-when")).get_attribute("title")
    assert row.locator(tid("release-by")).inner_text() == "test-admin"
    audit = api_json(page, "/api/audit?user=test-admin&limit=20")["items"]
    assert any(e["action"] == "release.create" and (e.get("after") or {}).get("name") == "walk-1" for e in audit)

    # the second release after one released system was rejected: the diff names it removed, rejected, linked
    _decide(page, systems[0]["id"], "rejected")
    _create_on_page(page, "walk-2")
    page.select_option(tid("diff-from"), "walk-1")
    page.select_option(tid("diff-to"), "walk-2")
    page.click(tid("diff-show"))
    removed = page.locator(f"{tid('diff-table')} tr[data-change=removed]")
    removed.wait_for()
    assert removed.get_attribute("data-system") == str(systems[0]["id"])
    assert "rejected" in removed.inner_text()
    assert removed.locator(tid("diff-system-link")).get_attribute("href") == f"/systems/{systems[0]['id']}"
    for w, h in SIZES:
        page.set_viewport_size({"width": w, "height": h})
        page.screenshot(path=str(artifacts / f"walk2/releases-{w}x{h}.png"), full_page=True)
        assert page.evaluate("() => document.documentElement.scrollWidth <= window.innerWidth")

    # the Exports panel on the page itself, its scope the releases (the newest chosen)
    scope = page.locator(f"{tid('exports')} {tid('export-scope')}")
    assert scope.input_value() == "release:walk-2"
    scope.select_option("release:walk-1")
    page.click(tid("export-soccernet-v3d-no-images"))
    link = page.locator(f"{tid('export-status-soccernet-v3d-no-images')} {tid('export-download')}")
    link.wait_for(timeout=120_000)
    with page.expect_download() as info:
        link.click()
    with zipfile.ZipFile(io.BytesIO(open(info.value.path(), "rb").read())) as zf:
        labels = [json.loads(zf.read(n)) for n in zf.namelist() if n.endswith("Labels-v3D.json")]
    assert labels and all(x["GameMetadata"]["v3d_release"]["name"] == "walk-1" for x in labels)


def test_one_moved_ball_is_a_dot_named_on_a_sensible_axis_not_a_full_height_bar(small_page, artifacts):
    """Two releases around one edit of a released system (a view's ball box moved 40 px, the system accepted again):
    the diff's one change is one dot named by its system on an axis ending at a round distance above its move."""
    page = small_page
    system = next(s for s in (api_json(page, f"/api/systems/{i['id']}") for i in
                              api_json(page, "/api/systems?limit=50&sort=name&status=pending")["items"])
                  if s["game"]["match"] != LABELS_ONLY_MATCH
                  and sum(1 for v in s["views"] if (v["ball"] or {}).get("box")) >= 3)
    _decide(page, system["id"], "accepted")
    assert api_write(page, "POST", "/api/releases", data={"name": "one-1"}).status == 201
    view = next(v for v in system["views"] if (v["ball"] or {}).get("box"))
    box = view["ball"]["box"]
    moved = api_write(page, "PATCH", f"/api/frames/{view['frame_id']}/ball",
                      data={"box": [box[0] + 40, box[1], box[2] + 40, box[3]]}, headers={"If-Match": view["etag"]})
    assert moved.ok, moved.text()
    _decide(page, system["id"], "accepted")
    assert api_write(page, "POST", "/api/releases", data={"name": "one-2"}).status == 201
    diff = api_json(page, "/api/releases/one-1/diff/one-2")
    changed = [c for c in diff["changed"] if c["system_id"] == system["id"]]
    assert changed and changed[0]["ball3d_moved_m"] > 0
    page.goto("/static/releases.html")
    page.wait_for_selector(f"{tid('releases')} tr[data-release='one-2']")
    page.select_option(tid("diff-from"), "one-1")
    page.select_option(tid("diff-to"), "one-2")
    page.click(tid("diff-show"))
    plot = page.locator(f"{tid('diff-histogram')} svg")
    plot.wait_for()
    assert plot.get_attribute("data-kind") == "dots"
    assert page.locator(f"{tid('diff-histogram')} rect.hist-bar").count() == 0  # no full-height bar
    dots = page.locator(f"{tid('diff-histogram')} circle.move-dot")
    assert dots.count() == len(diff["changed"])
    assert dots.first.get_attribute("data-system") == str(diff["changed"][0]["system_id"])
    assert system["name"] in plot.text_content()
    height = plot.bounding_box()["height"]
    assert height < 140, height  # a short strip, not a 220-px chart for one value
    end = float(plot.locator("text").nth(-2).text_content().removesuffix(" m"))
    moved_m = max(c["ball3d_moved_m"] for c in diff["changed"])
    assert moved_m <= end <= 5 * moved_m  # a round end above the move: 1, 2 or 5 times a power of ten
    row = page.locator(f"{tid('diff-table')} tr[data-change=changed][data-system='{system['id']}']")
    assert row.locator(tid("diff-system-link")).get_attribute("href") == f"/systems/{system['id']}"
    page.screenshot(path=str(artifacts / "walk2/releases-one-change-1366x768.png"), full_page=True)


# ----- 14: one top bar on every page -----------------------------------------------------------------------------
PAGES = {"queue": "/", "system": None, "statistics": "/static/stats.html", "detectors": "/static/monocular.html",
         "releases": "/static/releases.html", "users": "/static/users.html", "audit": "/static/audit.html"}


@pytest.mark.parametrize("size", SIZES, ids=SIZE_IDS)
def test_every_page_has_the_same_top_bar_links_and_log_out_whole(small_page, artifacts, size):
    page = small_page
    w, h = size
    page.set_viewport_size({"width": w, "height": h})
    system = api_json(page, "/api/systems?limit=1&sort=name")["items"][0]["id"]
    seen = {}
    for name, address in PAGES.items():
        page.goto(address or f"/systems/{system}?sort=name")
        page.locator(tid("logout")).wait_for()
        links = page.locator(f".topbar {tid('site-nav')} a")
        seen[name] = [(a.get_attribute("data-testid"), a.inner_text()) for a in links.all()]
        assert page.locator(".topbar a[aria-current=page]").count() == (0 if name == "system" else 1)
        page.screenshot(path=str(artifacts / f"walk2/topbar-{name}-{w}x{h}.png"))
        whole = f".topbar {tid('site-nav')} a, .topbar {tid('logout')}, .topbar {tid('user')}"
        assert _cut_off(page, whole) == [], name
        if name == "system":  # the links leave the system's name room to be read
            page.wait_for_function("() => !document.body.classList.contains('loading')")
            assert page.locator(tid("system-name")).bounding_box()["width"] >= 40
        logout = page.locator(tid("logout")).bounding_box()
        assert logout["x"] + logout["width"] <= w and page.locator(tid("logout")).inner_text() == "Log out"
    assert seen["queue"] == [("link-queue", "Review queue"), ("link-stats", "Statistics"),
                             ("link-monocular", "Detectors"), ("link-releases", "Releases"),
                             ("link-users", "Users"), ("link-audit", "Audit")]  # the last two for admins
    assert all(links == seen["queue"] for links in seen.values()), seen
    # from a system page the queue link keeps the queue's order
    page.goto(f"/systems/{system}?sort=name")
    assert page.locator(f"{tid('site-nav')} {tid('link-queue')}").get_attribute("href") == "/?sort=name"


def test_an_earlier_answer_of_the_figures_coming_back_last_leaves_the_figures_of_the_dates_the_form_says(page):
    """Two dates changed in quick succession ask for the per-annotator figures twice; where the first answer (a window
    in the far future: nobody) comes back after the second's (held here until the second is shown), the table stays
    the second's. (Before, the answer to arrive last was shown: an empty table under an empty "from".)"""
    pending = api_json(page, "/api/systems?limit=1&sort=name&status=pending")["items"]
    _decide(page, pending[0]["id"], "accepted")  # at least one row in every window that holds today
    page.goto("/static/stats.html")
    page.locator(f"{tid('annotator-row')}[data-name='test-admin']").wait_for()
    settled(page)
    held = hold_first(page, re.compile(r"/api/stats/annotators"), lambda url: "since=2999" in url)
    page.fill(tid("annotators-since"), "2999-01-01")
    pump_until(page, lambda: held, "the far window's request to be held")
    page.fill(tid("annotators-since"), "")
    page.locator(f"{tid('annotator-row')}[data-name='test-admin']").wait_for()
    held[0].continue_()
    settled(page)  # the held answer has come back and been taken in
    assert page.locator(f"{tid('annotator-row')}[data-name='test-admin']").count() == 1
    assert page.locator(tid("annotators-empty")).is_hidden()


def test_an_earlier_audit_page_coming_back_last_leaves_the_entries_of_the_filters_the_form_says(page):
    """A filter asked, then cleared at once: where the filtered page (a name nobody has: no entry) comes back after
    the cleared one's (held here until the cleared page is shown), the table stays the cleared page's."""
    pending = api_json(page, "/api/systems?limit=1&sort=name&status=pending")["items"]
    _decide(page, pending[0]["id"], "accepted")  # an entry of this admin's, whatever ran before
    page.goto("/static/audit.html?user=test-admin")
    page.locator(tid("audit-count")).filter(has_text="match the filters").wait_for()
    settled(page)
    held = hold_first(page, re.compile(r"/api/audit\?"), lambda url: "user=nobody-here" in url)
    page.fill(tid("audit-user"), "nobody-here")
    page.press(tid("audit-user"), "Enter")
    pump_until(page, lambda: held, "the filtered page's request to be held")
    page.fill(tid("audit-user"), "")
    page.click(tid("audit-clear"))
    page.locator(f"{tid('audit')}[data-shown]:not([data-shown*='user='])").wait_for(state="attached")
    shown = page.get_attribute(tid("audit"), "data-shown")
    held[0].continue_()
    settled(page)  # the held answer has come back and been taken in
    assert page.get_attribute(tid("audit"), "data-shown") == shown
    assert "in all" in page.inner_text(tid("audit-count"))
    assert page.locator(tid("audit-empty")).is_hidden()


# ----- 15: reviewer figures beside annotators' --------------------------------------------------------------------
@pytest.mark.parametrize("size", SIZES, ids=SIZE_IDS)
def test_the_statistics_page_shows_each_reviewers_decisions_beside_the_annotators_figures(small_page, artifacts, size):
    page = small_page
    w, h = size
    page.set_viewport_size({"width": w, "height": h})
    pending = api_json(page, "/api/systems?limit=50&sort=-name&status=pending")["items"]
    before = {f["name"]: f for f in api_json(page, "/api/stats/annotators")["items"]}.get("test-admin", {})
    _decide(page, pending[0]["id"], "accepted")
    _decide(page, pending[1]["id"], "rejected")
    figures = {f["name"]: f for f in api_json(page, "/api/stats/annotators")["items"]}["test-admin"]
    assert figures["decisions"] == before.get("decisions", 0) + 2
    assert figures["accepted"] == before.get("accepted", 0) + 1
    assert figures["rejected"] == before.get("rejected", 0) + 1
    page.goto("/static/stats.html")
    row = page.locator(f"{tid('annotator-row')}[data-name='test-admin']")
    row.wait_for()
    for key in ("decisions", "accepted", "rejected", "needs_fix", "re_reviews"):
        assert row.locator(f"td[data-key={key}]").inner_text() == str(figures[key]), key
    heading = page.locator(tid("annotators-heading")).inner_text()
    assert "reviewing" in heading.lower() and "(reviewers and admins)" not in heading
    assert "reviewer" in page.locator(tid("group-reviewing")).inner_text().lower()
    page.locator(tid("annotators")).scroll_into_view_if_needed()
    page.screenshot(path=str(artifacts / f"walk2/stats-{w}x{h}.png"), full_page=True)
    assert page.evaluate("() => document.documentElement.scrollWidth <= window.innerWidth")
    last = row.locator("td[data-key=re_reviews]").bounding_box()  # beside the annotator's figures, in the window
    assert last["x"] + last["width"] <= w
    page.locator(tid("evidence-vouched")).wait_for()  # each tier's meaning within its panel, not under the next one
    table, panel = page.locator(tid("evidence")), page.locator(f".panel:has({tid('evidence')})")
    assert table.bounding_box()["x"] + table.bounding_box()["width"] <= (
        panel.bounding_box()["x"] + panel.bounding_box()["width"])
    csv_text = page.request.get("/api/stats/annotators?format=csv").text()
    assert csv_text.splitlines()[0].endswith("decisions,accepted,rejected,needs_fix,re_reviews")


# ----- 6: the Detectors page lists the sources and removes one, in a curator's words -------------------------------
def _predictions_csv(settings, path: Path) -> int:
    """A CSV of a detector's boxes: every labelled ball box of the demo's game, scores 0.5 to 0.95; answers the rows."""
    from sqlalchemy import select

    from app.db.models import BallLabel, Frame, Game, System
    from app.db.session import make_engine, make_session_factory

    engine = make_engine(settings.database_url)
    rows = []
    try:
        with make_session_factory(engine)() as session:
            found = session.execute(select(Game.league, Game.season, Game.match, Frame.name, BallLabel.box)
                                    .join(System, System.game_id == Game.id).join(Frame, Frame.system_id == System.id)
                                    .join(BallLabel, BallLabel.frame_id == Frame.id)
                                    .where(Game.match.not_like("%Westfield%"), BallLabel.box.is_not(None))).all()
    finally:
        engine.dispose()
    for i, (league, season, match, name, box) in enumerate(found):
        conf = 0.5 + 0.45 * i / len(found)
        rows.append(f'{league},{season},"{match}",{name},{box[0]},{box[1]},{box[2]},{box[3]},{conf:.3f}')
    path.write_text("league,season,match,image,x1,y1,x2,y2,score\n" + "\n".join(rows) + "\n")
    return len(rows)


def _old_source(settings, source: str, n: int = 3) -> None:
    """``n`` predictions of ``source`` stored as before their import was recorded: rows without an import entry."""
    from sqlalchemy import select

    from app.db.models import Frame, Prediction
    from app.db.session import make_engine, make_session_factory

    engine = make_engine(settings.database_url)
    try:
        with make_session_factory(engine)() as session:
            frames = session.scalars(select(Frame.id).order_by(Frame.id).limit(n)).all()
            session.add_all([Prediction(source=source, frame_id=f, score=0.7, x1=10, y1=10, x2=30, y2=30)
                             for f in frames])
            session.commit()
    finally:
        engine.dispose()


@pytest.mark.parametrize("size", SIZES, ids=SIZE_IDS)
def test_the_detectors_page_lists_the_imported_sources_and_removes_one_in_words(small_page, seeded_settings,
                                                                               artifacts, size):
    page = small_page
    w, h = size
    page.set_viewport_size({"width": w, "height": h})
    folder = Path(seeded_settings.data_root) / f"detector-{w}"
    folder.mkdir(exist_ok=True)
    n = _predictions_csv(seeded_settings, folder / "boxes.csv")
    source = f"walk-detector-{w}"
    queued = api_write(page, "POST", "/api/imports", data={"kind": "predictions", "path": str(folder / "boxes.csv"),
                                                           "source": source})
    assert queued.status == 202, queued.text()
    url = queued.json()["url"]
    job = wait_for_job(page, url)
    assert job["state"] == "done", job["message"]
    assert job["result"]["summary"]["words"].startswith(f"{n} predictions")  # rows counted, not bytes
    _old_source(seeded_settings, f"old-detector-{w}")

    page.goto("/static/monocular.html")
    row = page.locator(f"{tid('source-row')}[data-source='{source}']")
    row.wait_for()
    assert row.locator("td").nth(1).inner_text() == str(n)
    assert row.locator(tid("source-by")).inner_text() == "test-admin"
    assert row.locator(tid("source-when")).get_attribute("title")  # the full time on hover
    assert row.locator(tid("source-scores")).inner_text().startswith("0.7")  # the median of 0.5 .. 0.95
    old = page.locator(f"{tid('source-row')}[data-source='old-detector-{w}']")
    assert old.locator(tid("source-by")).inner_text() == "unknown"
    # a curator's words: what it measures, the paper's names on hover only
    assert "ball3Destimation" not in page.locator("body").inner_text()
    headings = " ".join(page.locator("h1, h2").all_inner_texts()).lower()
    assert "paper" not in headings and "table 1" not in headings and "monocular" not in headings
    assert page.locator("h1").inner_text() == "Detectors"
    page.screenshot(path=str(artifacts / f"walk2/detectors-{w}x{h}.png"), full_page=True)
    assert page.evaluate("() => document.documentElement.scrollWidth <= window.innerWidth")

    row.locator(tid("source-remove")).click()
    row.locator(tid("source-remove-words")).filter(has_text="labels placed from them stay").wait_for()
    words = row.locator(tid("source-remove-words")).inner_text()
    assert f"Remove the {n} ball boxes of {source}?" in words and "labels placed from them stay" in words
    page.screenshot(path=str(artifacts / f"walk2/detectors-confirm-{w}x{h}.png"))
    row.locator(tid("source-remove-confirm")).click()
    page.wait_for_selector(f"{tid('source-row')}[data-source='{source}']", state="detached")
    assert f"{n} ball boxes of {source} removed" in page.locator(tid("sources-empty")).inner_text()
    assert source not in {s["source"] for s in api_json(page, "/api/predictions")["items"]}


# ----- 7: a view without an image says so; placing and confirming a detector's box there says so too --------------
def test_a_view_without_an_image_says_no_image_and_a_detectors_box_there_says_nobody_can_look(
        small_page, seeded_settings, artifacts):
    page = small_page
    found = None
    for item in api_json(page, "/api/systems?doubt=ball_missing&limit=500")["items"]:
        system = api_json(page, f"/api/systems/{item['id']}")
        if system["game"]["match"] != LABELS_ONLY_MATCH:
            continue
        for d in system["doubts"]:
            if d["kind"] == "ball_missing" and (d["evidence"] or {}).get("code") == "consensus":
                found = system, d
    assert found, "the labels-only copy of the demo has a ball_missing doubt from the other views' consensus"
    system, doubt = found
    k = next(i for i, v in enumerate(system["views"]) if v["frame_id"] == doubt["frame_id"])
    view, box, g = system["views"][k], doubt["suggestion"]["box"], system["game"]
    assert view["image_url"] is None
    path = Path(seeded_settings.data_root) / "labels-only-detector.csv"
    path.write_text("league,season,match,image,x1,y1,x2,y2,score\n"
                    f'{g["league"]},{g["season"]},"{g["match"]}",{view["name"]},{box[0]},{box[1]},{box[2]},{box[3]},0.8\n')
    url = api_write(page, "POST", "/api/imports", data={"kind": "predictions", "path": str(path),
                                                        "source": "blind-yolo"}).json()["url"]
    job = wait_for_job(page, url)
    assert job["state"] == "done", job

    page.goto(f"/systems/{system['id']}")
    shown = page.locator(tid("view")).nth(k)
    shown.locator(tid("no-image")).wait_for()
    assert shown.locator(tid("no-image")).text_content() == "no image"
    assert "labels only" in shown.inner_text() or "labels only" in shown.locator("svg").first.text_content()
    card = shown.locator(f"{tid('view-doubt')}[data-kind=ball_detected]")
    assert "no image here" in card.inner_text()
    page.screenshot(path=str(artifacts / "walk2/no-image-1366x768.png"))
    card.locator(tid("apply-fix")).click()
    confirm = shown.locator(tid("confirm-placement"))
    confirm.wait_for()
    assert "no image here" in shown.locator(tid("confirm-no-image")).inner_text()
    page.screenshot(path=str(artifacts / "walk2/no-image-placed-1366x768.png"))
