"""An ISSIA sequence in the browser (Playwright, Chromium): imported through the API from its videos
and, as a second sequence, without them; a frame's page shows its views (decoded video frames, or
blank canvases), the trajectory over time with the flagged frame and the current frame marked, and
the pitch map's track; the scrubber and the ``.`` key move from frame to frame."""
from __future__ import annotations

import re

import pytest

from tests.browser.support import api_json as _api
from tests.browser.support import api_write, tid, wait_for_job
from tests.services.issia_data import write_issia_stretch

pytestmark = pytest.mark.browser


@pytest.fixture(scope="module")
def sequences(shared_dir, tmp_path_factory):
    """Frames 0..29 of the dev sequence with its videos (folder "issia-dev") and without (folder
    "issia-dev-novideo")."""
    root = tmp_path_factory.mktemp("issia-ui")
    return (write_issia_stretch(shared_dir, root / "issia-dev", 0, 29),
            write_issia_stretch(shared_dir, root / "issia-dev-novideo", 0, 29, videos=False))


def _import(page, path) -> dict:
    """Import through the API: a job the server's runner runs; wait for it to finish."""
    r = api_write(page, "POST", "/api/imports", {"kind": "issia", "path": str(path)})
    assert r.status == 202, r.text()
    url = r.json()["url"]
    job = wait_for_job(page, url)
    assert job["state"] == "done", job
    game = next(g for g in _api(page, "/api/games") if g["match"] == path.name)
    return _api(page, f"/api/games/{game['id']}/trajectory")


def _at(system_id: int) -> re.Pattern:
    """The address of a system's page (with the review pass the page follows, issue 28)."""
    return re.compile(rf"/systems/{system_id}(\?pass=\d+)?$")


def test_sequence_from_videos_and_without(page, sequences, artifacts):
    with_videos, without = sequences
    traj = _import(page, with_videos)
    assert [f["frame_index"] for f in traj["frames"]] == list(range(30))
    f13 = traj["frames"][13]
    assert f13["flagged"] == ["cam4"]

    page.goto(f"/systems/{f13['system_id']}")
    page.locator(tid("trajectory-fit")).first.wait_for()
    assert page.locator(tid("trajectory-card")).is_visible()
    assert page.locator(tid("trajectory-x")).count() == 1 and page.locator(tid("trajectory-h")).count() == 1
    assert page.locator(tid("trajectory-flag")).count() >= 3  # frame 13 marked in each of the 3 panels
    assert page.locator(tid("trajectory-frame")).inner_text() == "frame 13"
    assert page.locator(tid("pitch-track")).count() == 1
    assert page.locator(f"{tid('doubt')}[data-kind='ball_off_consensus']").count() == 1
    # the views show the decoded video frames at the labels' resolution
    page.wait_for_function("() => document.querySelectorAll('.view[data-image=loaded]').length === 6")
    page.screenshot(path=str(artifacts / "issia-frame13.png"), full_page=True)
    page.locator(tid("trajectory-card")).screenshot(path=str(artifacts / "issia-trajectory13.png"))
    page.locator(tid("pitch-map")).scroll_into_view_if_needed()
    page.locator(tid("pitch-map")).screenshot(path=str(artifacts / "issia-pitchmap13.png"))

    # the scrubber moves the page to another frame's system
    page.locator(tid("trajectory-scrubber")).fill("20")
    page.wait_for_url(_at(traj['frames'][20]['system_id']))
    page.locator(tid("system-name")).get_by_text("20", exact=True).wait_for()
    page.locator(tid("trajectory-frame")).get_by_text("frame 20").wait_for()
    # "." and "," step frame by frame
    page.keyboard.press(".")
    page.wait_for_url(_at(traj['frames'][21]['system_id']))
    page.locator(tid("system-name")).get_by_text("21", exact=True).wait_for()
    page.locator(tid("trajectory-frame")).get_by_text("frame 21").wait_for()
    page.keyboard.press(",")
    page.wait_for_url(_at(traj['frames'][20]['system_id']))
    page.locator(tid("trajectory-frame")).get_by_text("frame 20").wait_for()
    page.screenshot(path=str(artifacts / "issia-frame20.png"), full_page=True)

    # a review pass over the queue (issue 28): it lists every frame of the sequence as a system; a decision
    # goes to the pass's next pending system
    pass_id = int(re.search(r"pass=(\d+)", page.url).group(1))
    frozen = _api(page, f"/api/passes/{pass_id}")
    assert {f["system_id"] for f in traj["frames"]} <= set(frozen["systems"])
    f20 = traj["frames"][20]["system_id"]
    place = _api(page, f"/api/passes/{pass_id}/place?system_id={f20}")
    assert place["index"] == frozen["systems"].index(f20) and place["next_pending_id"] is not None
    page.keyboard.press("r")
    page.wait_for_url(_at(place["next_pending_id"]))
    assert _api(page, f"/api/systems/{f20}")["review"]["status"] == "rejected"

    # without videos: the same page, no images (blank canvases), the trajectory all the same
    bare = _import(page, without)
    system = _api(page, f"/api/systems/{bare['frames'][5]['system_id']}")
    assert all(v["image_url"] is None for v in system["views"])
    page.goto(f"/systems/{bare['frames'][5]['system_id']}")
    page.locator(tid("trajectory-fit")).first.wait_for()
    assert page.locator(tid("trajectory-frame")).inner_text() == "frame 5"
    assert page.locator(".view[data-image=missing]").count() == 6
    page.screenshot(path=str(artifacts / "issia-novideo-frame5.png"), full_page=True)
