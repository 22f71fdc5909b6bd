"""Per-view decisions, the calibration decision beside the ball's, the synchronised zoom and their keys in the
``?`` overlay (issue 16), in Chromium against the real server and the demo dataset. Screenshots go to
``test-artifacts/`` and ``/tmp/shots/`` (to look at)."""
from __future__ import annotations

import re
from pathlib import Path

import pytest

from tests.browser.support import api_json as _api
from tests.browser.support import api_write, settled, tid

pytestmark = pytest.mark.browser

SHOTS = Path("/tmp/shots")


def _shot(page, artifacts: Path, name: str) -> None:
    SHOTS.mkdir(parents=True, exist_ok=True)
    page.screenshot(path=str(artifacts / name))
    page.screenshot(path=str(SHOTS / name))


def _multi_view_system(page) -> dict:
    """The first system by name with at least three views, a 3D ball and a calibrated view with field lines."""
    for item in _api(page, "/api/systems?sort=name&limit=50")["items"]:
        system = _api(page, f"/api/systems/{item['id']}?sort=name")
        if len(system["views"]) >= 3 and system["ball3d"] is not None and any(
                v["calibration"].get("camera") and v["field_lines"] for v in system["views"]):
            return system
    raise AssertionError("the demo has no system with three views and a 3D ball")


def _open(page, system: dict) -> None:
    page.goto(f"/systems/{system['id']}?sort=name")
    page.locator(tid("view-decisions")).nth(len(system["views"]) - 1).wait_for()


def _bar(page, index: int):
    return page.locator(tid("view")).nth(index).locator(tid("view-decisions"))


def test_per_view_and_calibration_decisions(page, artifacts):
    system = _multi_view_system(page)
    page.goto("/")  # a fresh zoom state for this walk
    page.evaluate("() => sessionStorage.clear()")
    _open(page, system)
    views = system["views"]
    assert page.locator(tid("view-decisions")).count() == len(views)
    assert _bar(page, 0).locator(tid("view-decision-status")).inner_text() == "pending"

    # a click decides V1's ball; keys decide V2's ball and calibration (Shift+letters on the selected view)
    _bar(page, 0).locator("[data-part=view][data-status=accepted]").click()
    page.wait_for_function("() => document.querySelectorAll('[data-testid=view-decision-status]')[0].textContent === "
                           "'accepted'")
    page.keyboard.press("2")
    page.keyboard.press("Shift+F")
    page.keyboard.press("Shift+G")
    cal = (_bar(page, 1).locator(tid("calibration-decision-status")))
    page.wait_for_function(
        "() => { const b = document.querySelectorAll('[data-testid=view-decisions]')[1];"
        " return b && b.querySelector('[data-testid=view-decision-status]').textContent === 'needs fix'"
        " && b.querySelector('[data-testid=calibration-decision-status]').textContent === 'accepted'; }")
    assert cal.inner_text() == "accepted"
    after = _api(page, f"/api/systems/{system['id']}")
    assert after["views"][0]["review"]["status"] == "accepted"
    assert after["views"][1]["review"]["status"] == "needs_fix"
    assert after["views"][1]["review"]["calibration"]["status"] == "accepted"
    assert after["views"][0]["review"]["calibration"]["status"] == "pending"
    # the history lists the calibration decision, in the words of its summary (issue 28)
    page.locator(tid("history")).get_by_text("calibration of V2 accepted").first.wait_for()
    _shot(page, artifacts, "view-decisions.png")

    # the system accepted, then V2's field lines edited (by someone, through the API): both decisions go back
    # to pending with the reason, and the page shows it after its next load
    etag = after["etag"]
    assert api_write(page, "POST", f"/api/systems/{system['id']}/review", data={"status": "accepted", "comment": ""},
                     headers={"If-Match": etag}).ok
    v2 = after["views"][1]
    fewer = {cls: polys for cls, polys in list(v2["field_lines"].items())[:-1]}
    edit = api_write(page, "PUT", f"/api/frames/{v2['frame_id']}/field-lines", data={"lines": fewer},
                     headers={"If-Match": v2["etag"]})
    assert edit.ok, edit.text()
    answer = edit.json()
    reason = answer["review"]["reset_reason"]
    assert answer["review"]["status"] == "pending"
    assert reason.startswith(f"{v2['name']}: field lines replaced by test-admin")
    assert answer["views"][1]["review"]["calibration"] == {**answer["views"][1]["review"]["calibration"],
                                                           "status": "pending", "reset_reason": reason}
    page.reload()
    _bar(page, 1).locator(tid("calibration-reset-reason")).wait_for()
    assert _bar(page, 1).locator(tid("calibration-reset-reason")).inner_text() == reason
    assert page.locator(tid("system-status")).inner_text() == "pending"
    assert page.locator(tid("review-meta")).inner_text() == f"Pending again: {reason}"
    assert _bar(page, 1).locator(tid("view-decision-status")).inner_text() == "needs fix"  # the ball's stays
    _shot(page, artifacts, "view-decisions-reset.png")
    # put the lines back (the demo is shared by the module's tests)
    v2 = _api(page, f"/api/frames/{v2['frame_id']}")
    assert api_write(page, "PUT", f"/api/frames/{v2['frame_id']}/field-lines",
                     data={"lines": after["views"][1]["field_lines"]}, headers={"If-Match": v2["etag"]}).ok


def _windows(page) -> list[list[float]]:
    return page.eval_on_selector_all("[data-testid=view-svg]",
                                     "(ns) => ns.map((n) => n.getAttribute('viewBox').split(' ').map(Number))")


def _centre(view: dict) -> list[float] | None:
    ball = view["ball"]
    if ball["kind"] == "box":
        b = ball["box"]
        return [(b[0] + b[2]) / 2, (b[1] + b[3]) / 2]
    if ball["kind"] == "point":
        return ball["point"]
    return view["reprojected_ball"]


def test_synchronised_zoom_and_pan_kept_across_systems(page, artifacts):
    system = _multi_view_system(page)
    page.goto("/")
    page.evaluate("() => sessionStorage.clear()")
    _open(page, system)
    views = system["views"]
    assert all(w == [0, 0, v["width"], v["height"]] for w, v in zip(_windows(page), views, strict=False))
    radius_whole = float(page.locator(tid("view-svg")).first.locator("circle.annot").first.get_attribute("r"))

    for _ in range(4):  # x1.5 four times: x5.0625
        page.keyboard.press(">")
    settled(page)  # keys typed while the page still works are applied once it can act
    z = 1.5 ** 4
    assert page.locator(tid("zoom-level")).inner_text() == "×5.06"
    for w, v in zip(_windows(page), views, strict=False):
        assert w[2] == pytest.approx(v["width"] / z, abs=0.01) and w[3] == pytest.approx(v["height"] / z, abs=0.01)
        c = _centre(v)
        if c is not None:  # centred on its ball unless that would leave the image
            cx = min(max(c[0], w[2] / 2), v["width"] - w[2] / 2)
            cy = min(max(c[1], w[3] / 2), v["height"] - w[3] / 2)
            assert w[0] + w[2] / 2 == pytest.approx(cx, abs=0.01) and w[1] + w[3] / 2 == pytest.approx(cy, abs=0.01)
    # vector redraw: the marks keep their screen size (radius in image px shrinks by the zoom), the frame's
    # pixels are drawn pixelated once an image pixel covers 3 screen pixels
    radius_zoomed = float(page.locator(tid("view-svg")).first.locator("circle.annot").first.get_attribute("r"))
    assert radius_zoomed == pytest.approx(radius_whole / z, rel=0.02)
    shown = page.locator(tid("view-svg")).first.bounding_box()["width"]
    pixelated = page.locator(tid("view-svg")).first.evaluate("(n) => n.classList.contains('pixelated')")
    assert pixelated == (shown / (views[0]["width"] / z) >= 3)
    _shot(page, artifacts, "zoom-x5.png")

    # a pan moves every view by the same fraction of its image
    before = _windows(page)
    page.keyboard.press("Shift+L")
    moved = _windows(page)
    for b, m, v in zip(before, moved, views, strict=False):
        room = v["width"] - b[2] - b[0]  # how far the window could still go right
        assert m[0] - b[0] == pytest.approx(min(0.25 * v["width"] / z, room), abs=0.01)

    # the wheel over a view zooms them all; the next system keeps zoom and pan
    page.locator(tid("view-svg")).first.hover()
    page.mouse.wheel(0, -100)
    page.wait_for_function("() => document.querySelector('[data-testid=zoom-level]').textContent === '×7.59'")
    next_id = system["next_id"]
    page.keyboard.press("j")
    page.wait_for_url(re.compile(rf"/systems/{next_id}\?sort=name&pass=\d+$"))
    page.wait_for_function(f"() => document.querySelector('[data-testid=view]')?.dataset.frameId === "
                           f"'{_api(page, f'/api/systems/{next_id}?sort=name')['views'][0]['frame_id']}'")
    nxt = _api(page, f"/api/systems/{next_id}?sort=name")
    assert page.locator(tid("zoom-level")).inner_text() == "×7.59"
    for w, v in zip(_windows(page), nxt["views"], strict=False):
        assert w[2] == pytest.approx(v["width"] / 1.5 ** 5, abs=0.01)
    _shot(page, artifacts, "zoom-next-system.png")
    page.keyboard.press("0")
    settled(page)
    assert all(w == [0, 0, v["width"], v["height"]] for w, v in zip(_windows(page), nxt["views"], strict=False))
    assert page.evaluate("() => JSON.parse(sessionStorage.getItem('v3d.zoom'))") == {"z": 1, "pan": [0, 0]}


def test_question_mark_lists_the_new_keys(page, artifacts):
    system = _multi_view_system(page)
    _open(page, system)
    page.keyboard.press("?")
    page.locator(tid("keys-help")).wait_for(state="visible")
    listed = page.eval_on_selector("[data-testid=keys-help] .keys-grid", "(g) => g.textContent")
    for text in ("⇧A / ⇧R / ⇧F", "the selected view's ball: accept / reject / needs fix",
                 "⇧G / ⇧B / ⇧N", "the selected view's calibration: accept / reject / needs fix",
                 "> / <", "zoom every view in / out on its ball", "whole frames (no zoom)",
                 "⇧I / ⇧J / ⇧K / ⇧L", "pan every zoomed view"):
        assert text in listed, text
    _shot(page, artifacts, "keys-help-issue16.png")
    page.keyboard.press("Escape")
