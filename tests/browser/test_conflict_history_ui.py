"""Conflict-safe edits and the history panel in Chromium: a view changed by someone else after the page
read it -> the page's nudge is answered 412 -> the conflict notice names the change and the page shows
their box -> "re-apply my change" stores mine against the new version -> the history panel lists both
writes and one click reverts mine (their box is back)."""
from __future__ import annotations

import pytest

from tests.browser.support import api_json as _api
from tests.browser.support import api_write, tid, wait_for_steady_layout

pytestmark = pytest.mark.browser


def _view_with_box(system: dict) -> int | None:
    for i, v in enumerate(system["views"]):
        if v["ball"]["kind"] == "box" and v["optimised_box"] is not None:
            return i
    return None


def test_conflict_notice_reapply_and_history_revert(page, artifacts):
    listing = _api(page, "/api/systems?sort=name&limit=500")["items"]
    # the middle of the queue: the other browser tests work at its start and its end
    candidates = [s["id"] for s in listing[len(listing) // 3:]]
    system = next(sys for sys in (_api(page, f"/api/systems/{i}") for i in candidates)
                  if _view_with_box(sys) is not None)
    sid, k = system["id"], _view_with_box(system)
    view = system["views"][k]
    fid, box = view["frame_id"], view["ball"]["box"]
    page.goto(f"/systems/{sid}")
    page.locator(tid("view")).nth(k).locator(tid("ball-hit")).wait_for()

    # someone else moves the box 6 px down while the page shows the old version
    theirs = [box[0], box[1] + 6, box[2], box[3] + 6]
    other = api_write(page, "PATCH", f"/api/frames/{fid}/ball", data={"box": theirs},
                      headers={"If-Match": view["etag"]})
    assert other.ok, other.text()

    # the page's nudge (1 px right) is made against the old version: 412, nothing stored
    sent: list[dict] = []
    page.on("request", lambda r: sent.append(r.headers) if r.method == "PATCH" else None)
    page.keyboard.press(str(k + 1))
    with page.expect_response(lambda r: r.request.method == "PATCH") as answer:
        page.keyboard.press("ArrowRight")  # saved after the nudge's pause
    assert answer.value.status == 412
    assert sent[0]["if-match"] == view["etag"]
    notice = page.locator(tid("conflict"))
    notice.wait_for()
    assert f"ball label of V{k + 1}" in page.locator(tid("conflict-who")).inner_text()
    mine = [box[0] + 1, box[1], box[2] + 1, box[3]]
    assert "box [" in page.locator(tid("conflict-mine")).inner_text()
    assert _api(page, f"/api/frames/{fid}")["ball"]["box"] == pytest.approx(theirs)
    page.screenshot(path=str(artifacts / "conflict-notice.png"))

    # re-apply mine against the current version
    with page.expect_response(lambda r: r.request.method == "PATCH") as answer:
        page.locator(tid("conflict-reapply")).click()
    assert answer.value.status == 200
    assert sent[-1]["if-match"] == other.headers["etag"]
    assert notice.is_hidden()
    assert _api(page, f"/api/frames/{fid}")["ball"]["box"] == pytest.approx(mine, abs=0.05)

    # the history lists both writes, newest first; revert mine: their box is back, and the revert is listed
    entries = page.locator(tid("history-entry"))
    page.wait_for_function("() => document.querySelectorAll('[data-testid=history-entry]').length >= 2")
    assert entries.first.get_attribute("data-action") == "ball.edit"
    with page.expect_response(lambda r: "/revert" in r.url) as answer:
        entries.first.locator(tid("history-revert")).click()
    assert answer.value.status == 200
    assert _api(page, f"/api/frames/{fid}")["ball"]["box"] == pytest.approx(theirs)
    page.wait_for_function("() => document.querySelector('[data-testid=history-entry]')?.dataset.action === 'revert'")
    page.screenshot(path=str(artifacts / "history-revert.png"))


def test_a_stale_decision_lists_what_changed_under_the_page(page, artifacts):
    """The page's decision sent after someone moved a ball of the system: 412, and the notice lists the change
    in words ("Since your page: ...") before the reviewer re-applies anything."""
    listing = _api(page, "/api/systems?sort=name&limit=500")["items"]
    candidates = [s["id"] for s in listing[len(listing) // 2:]]
    system = next(sys for sys in (_api(page, f"/api/systems/{i}") for i in candidates)
                  if _view_with_box(sys) is not None and sys["review"]["status"] == "pending")
    sid, k = system["id"], _view_with_box(system)
    view = system["views"][k]
    page.goto(f"/systems/{sid}")
    page.locator(tid("view")).nth(k).locator(tid("ball-hit")).wait_for()
    box = view["ball"]["box"]
    moved = api_write(page, "PATCH", f"/api/frames/{view['frame_id']}/ball",
                      data={"box": [box[0] + 40, box[1], box[2] + 40, box[3]]}, headers={"If-Match": view["etag"]})
    assert moved.ok, moved.text()
    with page.expect_response(lambda r: r.url.endswith(f"/api/systems/{sid}/review")) as answer:
        page.keyboard.press("r")  # reject: sent with the page's system ETag
    assert answer.value.status == 412
    since = page.locator(tid("conflict-since"))
    since.wait_for()
    assert f"ball of V{k + 1} moved 40.0 px" in since.inner_text()
    assert _api(page, f"/api/systems/{sid}")["review"]["status"] == "pending"
    for width, height in ((1366, 768), (1920, 1080)):
        page.set_viewport_size({"width": width, "height": height})
        page.screenshot(path=str(artifacts / f"conflict-since-{width}.png"))
    page.locator(tid("conflict-keep")).click()


def test_the_conflict_notice_of_a_lower_view_is_drawn_in_the_window(page, artifacts):
    """The lowest view of a system on the page selected (scrolled into sight) and its box moved by someone else: the
    page's nudge is answered 412 and the notice is in the window, at both sizes."""
    listing = _api(page, "/api/systems?sort=-name&limit=500")["items"]
    labelled = [sys for sys in (_api(page, f"/api/systems/{s['id']}") for s in listing if s["views_labelled"] >= 3)]
    system = max(labelled, key=lambda sys: len(sys["views"]))  # the most views: one far below the page's top
    sid = system["id"]
    boxed = [i for i, v in enumerate(system["views"]) if v["ball"]["kind"] == "box" and v["ball"].get("box")]
    for width, height in ((1366, 768), (1920, 1080)):
        page.set_viewport_size({"width": width, "height": height})
        page.goto(f"/systems/{sid}")
        page.locator(tid("view")).nth(boxed[0]).locator(tid("ball-hit")).wait_for()
        wait_for_steady_layout(page, tid("view"))
        tops = page.locator(tid("view")).evaluate_all("(vs) => vs.map((v) => v.getBoundingClientRect().top)")
        k = max(boxed, key=lambda i: tops[i])  # the lowest labelled view on the page
        fid = system["views"][k]["frame_id"]
        page.keyboard.press(str(k + 1))  # selected: scrolled into sight
        page.wait_for_function("() => scrollY > 0")  # below the page's top
        box = _api(page, f"/api/frames/{fid}")["ball"]["box"]
        other = api_write(page, "PATCH", f"/api/frames/{fid}/ball",
                          data={"box": [box[0], box[1] + 3, box[2], box[3] + 3]},
                          headers={"If-Match": page.request.get(f"/api/frames/{fid}").headers["etag"]})
        assert other.ok, other.text()
        with page.expect_response(lambda r, fid=fid: r.request.method == "PATCH" and f"/{fid}/ball" in r.url) as answer:
            page.keyboard.press("ArrowRight")
        assert answer.value.status == 412
        notice = page.locator(tid("conflict"))
        notice.wait_for()
        wait_for_steady_layout(page, tid("conflict"))
        drawn = notice.bounding_box()
        assert drawn["y"] >= 0 and drawn["y"] + drawn["height"] <= height, (width, drawn)
        page.screenshot(path=str(artifacts / f"conflict-lower-view-{width}x{height}.png"))
        page.locator(tid("conflict-keep")).click()
        notice.wait_for(state="hidden")
