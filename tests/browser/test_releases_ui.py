"""The releases page (static/releases.html) in Chromium against the real server and the demo dataset: two releases
made through the API (one system accepted, then a second), listed with their hashes; the diff of the two shown as a
table naming the added system, and the histogram of 3D moves (none moved: its empty note)."""
from __future__ import annotations

import re

import pytest

from tests.browser.support import api_json, api_write, hold_first, pump_until, settled

pytestmark = pytest.mark.browser


def _accept(page, system_id: int) -> None:
    answer = page.request.get(f"/api/systems/{system_id}")
    done = api_write(page, "POST", f"/api/systems/{system_id}/review", data={"status": "accepted", "comment": ""},
                     headers={"If-Match": answer.headers["etag"]})
    assert done.ok, done.text()


def test_the_releases_page_lists_releases_and_shows_their_diff(page, artifacts):
    systems = api_json(page, "/api/systems?limit=5&sort=name&status=pending")["items"]
    _accept(page, systems[0]["id"])
    first = api_write(page, "POST", "/api/releases", data={"name": "ui-1", "note": "one"})
    assert first.status == 201, first.text()
    _accept(page, systems[1]["id"])
    assert api_write(page, "POST", "/api/releases", data={"name": "ui-2"}).status == 201
    page.goto("/static/releases.html")
    page.wait_for_selector("[data-testid=releases] tr[data-release=ui-2]")
    row = page.locator("[data-testid=releases] tr[data-release=ui-1]")
    assert first.json()["hash"] in row.text_content()
    page.select_option("[data-testid=diff-from]", "ui-1")
    page.select_option("[data-testid=diff-to]", "ui-2")
    page.click("[data-testid=diff-show]")
    page.wait_for_selector("[data-testid=diff-table]:not([hidden])")
    added = page.locator("[data-testid=diff-table] tr[data-change=added]")
    assert added.count() == 1 and added.get_attribute("data-system") == str(systems[1]["id"])
    unchanged = first.json()["systems"]
    assert page.text_content("[data-testid=diff-counts]") == f"1 added, 0 removed, 0 changed, {unchanged} unchanged"
    assert "no 3D ball moved" in page.text_content("[data-testid=diff-histogram]")
    assert page.get_attribute("[data-testid=diff-csv]", "href").endswith("/diff/ui-2?format=csv")
    page.screenshot(path=str(artifacts / "releases.png"), full_page=True)


def test_an_earlier_diff_coming_back_last_leaves_the_diff_the_selects_say(page):
    """Two diffs asked in quick succession; where the first one's answer (a system added) comes back after the
    second's (a release against itself, held until the second is shown), the table stays the second's."""
    systems = api_json(page, "/api/systems?limit=5&sort=-name&status=pending")["items"]
    _accept(page, systems[0]["id"])
    assert api_write(page, "POST", "/api/releases", data={"name": "race-a"}).status == 201
    _accept(page, systems[1]["id"])
    b = api_write(page, "POST", "/api/releases", data={"name": "race-b"})
    assert b.status == 201, b.text()
    page.goto("/static/releases.html")
    page.wait_for_selector("[data-testid=releases] tr[data-release=race-b]")
    settled(page)
    held = hold_first(page, re.compile(r"/api/releases/.+/diff/"), lambda url: url.endswith("/race-a/diff/race-b"))
    page.select_option("[data-testid=diff-from]", "race-a")
    page.select_option("[data-testid=diff-to]", "race-b")
    page.click("[data-testid=diff-show]")
    pump_until(page, lambda: held, "the first diff's request to be held")
    page.select_option("[data-testid=diff-from]", "race-b")
    page.click("[data-testid=diff-show]")
    same = f"0 added, 0 removed, 0 changed, {b.json()['systems']} unchanged"
    page.wait_for_function("(t) => document.querySelector('[data-testid=diff-counts]').textContent === t", arg=same)
    held[0].continue_()
    settled(page)  # the held answer has come back and been taken in
    assert page.text_content("[data-testid=diff-counts]") == same
    assert page.locator("[data-testid=diff-table] tr[data-change=added]").count() == 0


def test_the_exports_panel_exports_a_release_naming_it(page, tmp_path):
    """The queue page's Exports panel offers each release as a scope; the SoccerNet-v3D zip it downloads names the
    release and its hash in every game's ``Labels-v3D.json``."""
    import io
    import json
    import zipfile

    # a SoccerNet-v3 system with a 3D ball, whatever the module's other test accepted before (the queue's first
    # system by name is a calibration-only frame, which the SoccerNet-v3D export leaves out)
    pending = api_json(page, "/api/systems?limit=100&sort=name&status=pending")["items"]
    _accept(page, next(s["id"] for s in pending if s["kind"] == "soccernet-v3" and s["ball3d"] is not None))
    made = api_write(page, "POST", "/api/releases", data={"name": "panel-1"})
    assert made.status == 201, made.text()
    page.goto("/")
    page.wait_for_selector("[data-testid=exports] [data-testid=export-scope] option[value='release:panel-1']",
                           state="attached")
    page.select_option("[data-testid=export-scope]", "release:panel-1")
    page.click("[data-testid=export-soccernet-v3d-no-images]")
    link = page.locator("[data-testid=export-status-soccernet-v3d-no-images] [data-testid=export-download]")
    link.wait_for(timeout=120_000)
    with page.expect_download() as info:
        link.click()
    with zipfile.ZipFile(io.BytesIO(open(info.value.path(), "rb").read())) as zf:
        labels = [json.loads(zf.read(n)) for n in zf.namelist() if n.endswith("Labels-v3D.json")]
    assert len(labels) == 1  # the one game of the released SoccerNet-v3 systems
    assert labels[0]["GameMetadata"]["v3d_release"] == {"name": "panel-1", "hash": made.json()["hash"]}


def test_a_release_download_beside_a_new_release_delivers_that_release_named_by_it(page):
    """On the Releases page, v1.0's export link goes once v1.1 is made (v1.1 is then the scope shown); the next
    export's link and file name v1.1, and the file holds v1.1."""
    import io
    import json
    import zipfile

    pending = api_json(page, "/api/systems?limit=100&sort=-name&status=pending")["items"]
    v3 = [s["id"] for s in pending if s["kind"] == "soccernet-v3" and s["ball3d"] is not None]
    _accept(page, v3[0])
    assert api_write(page, "POST", "/api/releases", data={"name": "walk-v1.0"}).status == 201
    page.goto("/static/releases.html")
    scope = page.locator("[data-testid=exports] [data-testid=export-scope]")
    page.wait_for_function("() => document.querySelector('[data-testid=export-scope]')?.value"
                           " === 'release:walk-v1.0'")
    page.click("[data-testid=export-soccernet-v3d-no-images]")
    link = page.locator("[data-testid=export-status-soccernet-v3d-no-images] [data-testid=export-download]")
    link.wait_for(timeout=120_000)
    assert link.inner_text().startswith("download soccernet-v3d-no-images-walk-v1.0.zip")

    _accept(page, v3[1])
    page.fill("[data-testid=release-form] [name=name]", "walk-v1.1")
    page.click("[data-testid=release-create]")
    page.locator("[data-testid=release-create-text]").filter(has_text="release walk-v1.1 made").wait_for()
    page.wait_for_function("() => document.querySelector('[data-testid=export-scope]').value === 'release:walk-v1.1'")
    assert link.count() == 0  # v1.0's file is not offered beside v1.1
    assert scope.input_value() == "release:walk-v1.1"
    page.click("[data-testid=export-soccernet-v3d-no-images]")
    link.wait_for(timeout=120_000)
    assert link.inner_text().startswith("download soccernet-v3d-no-images-walk-v1.1.zip")
    with page.expect_download() as info:
        link.click()
    assert info.value.suggested_filename == "soccernet-v3d-no-images-walk-v1.1.zip"
    with zipfile.ZipFile(io.BytesIO(open(info.value.path(), "rb").read())) as zf:
        labels = [json.loads(zf.read(n)) for n in zf.namelist() if n.endswith("Labels-v3D.json")]
    assert {lab["GameMetadata"]["v3d_release"]["name"] for lab in labels} == {"walk-v1.1"}


def test_a_release_made_on_the_page_says_how_many_systems_it_holds_without_a_3d_ball(page, artifacts):
    """A system accepted with no 3D ball is in the release, and the release's words count it: after "made:" and in
    the table's systems cell."""
    pending = api_json(page, "/api/systems?limit=500&sort=name&status=pending")["items"]
    blind = api_json(page, f"/api/systems/{next(s['id'] for s in pending if s['kind'] == 'soccernet-v3')}")
    for view in blind["views"]:  # every ball label removed: its views agree on no ball
        removed = api_write(page, "PATCH", f"/api/frames/{view['frame_id']}/ball", data={"box": None},
                            headers={"If-Match": view["etag"]})
        assert removed.ok, removed.text()
    _accept(page, blind["id"])
    accepted = api_json(page, "/api/systems?limit=500&status=accepted")["items"]
    without = sum(s["ball3d"] is None for s in accepted)
    assert without >= 1
    page.goto("/static/releases.html")
    page.fill("[data-testid=release-form] [name=name]", "no-ball-1")
    page.click("[data-testid=release-create]")
    words = page.locator("[data-testid=release-create-text]").filter(has_text="release no-ball-1 made")
    words.wait_for()
    systems = f"{len(accepted)} accepted system{'' if len(accepted) == 1 else 's'}"
    assert f"made: {systems} ({without} without a 3D ball)," in words.inner_text()
    cell = page.locator("[data-testid=releases] tr[data-release=no-ball-1] [data-testid=release-systems]")
    assert cell.inner_text() == f"{len(accepted)} ({without} without 3D ball)"
    for size in ({"width": 1366, "height": 768}, {"width": 1920, "height": 1080}):
        page.set_viewport_size(size)
        page.screenshot(path=str(artifacts / f"release-without-ball-{size['width']}.png"))
