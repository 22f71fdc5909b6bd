"""A keyboard pass of the demo after a fix (issue 28), in Chromium, against the real server: the queue, Enter on
its first row, the one-key mirror fix ``m`` on that system, then ``a`` again and again (``Enter`` when the accept
guard lists open doubts): every system of the queue is decided exactly once, in the order the queue had when
the pass began, and the page then says the pass is finished with its counts. Before the pass, ``a`` after the
mirror fix went to the fixed system's neighbour in the queue's new order and skipped pending systems.
Screenshots at 1366x768 and 1920x1080 go to ``test-artifacts/``; the time per system is printed."""
from __future__ import annotations

import re
import time

import pytest

from tests.browser.support import api_json as _api
from tests.browser.support import tid

pytestmark = pytest.mark.browser

_SYSTEM_URL = re.compile(r"/systems/(\d+)\?(.*&)?pass=(\d+)")


def _wait_ready(page, system_id: int) -> None:
    """The page shows ``system_id`` with its views and the pass's place."""
    page.wait_for_function(
        """(id) => location.pathname === `/systems/${id}` && !document.body.classList.contains('loading')
          && document.querySelectorAll('[data-testid=view]').length > 0
          && /pass \\d+ of \\d+/.test(document.querySelector('[data-testid=pass-progress]')?.textContent || '')""",
        arg=system_id)


def test_a_keyboard_pass_after_a_mirror_fix_decides_every_system_once(page, artifacts, capsys):
    queue = _api(page, "/api/systems?limit=100")
    order = [s["id"] for s in queue["items"]]
    assert queue["counts"]["pending"] == len(order) >= 9

    page.set_viewport_size({"width": 1366, "height": 768})
    page.goto("/")
    page.locator(tid("queue-row")).first.wait_for()
    page.keyboard.press("Enter")
    page.wait_for_url(_SYSTEM_URL)
    _wait_ready(page, order[0])
    pass_id = int(_SYSTEM_URL.search(page.url).group(3))
    frozen = _api(page, f"/api/passes/{pass_id}")
    assert frozen["systems"] == order and frozen["position"] == 0

    # the one-key mirror fix on the first system: it moves in the queue's order, not in the pass
    first = _api(page, f"/api/systems/{order[0]}")
    assert any(v["calibration"].get("probably_mirrored") for v in first["views"]), "the demo's first system is mirrored"
    page.keyboard.press("m")
    page.locator(tid("toast")).filter(has_text="mirrored labels applied").wait_for()
    now = [s["id"] for s in _api(page, "/api/systems?limit=100")["items"]]
    assert now != order, "the fix must move the system in the queue's current order (what the pass guards against)"
    assert _api(page, f"/api/passes/{pass_id}")["systems"] == order

    decided, guarded, seconds = [], 0, []
    for _ in range(len(order) + 2):
        shown = int(re.search(r"/systems/(\d+)", page.url).group(1))
        start = time.perf_counter()
        decided.append(shown)
        page.keyboard.press("a")
        guard = page.locator(tid("accept-guard"))
        finished = page.locator(tid("pass-finished"))
        # the guard opens (open doubts), the next system loads, or the pass is finished
        page.wait_for_function(
            """(id) => document.querySelector('[data-testid=accept-guard]')?.open
              || !document.querySelector('[data-testid=pass-finished]').hidden
              || (location.pathname !== `/systems/${id}` && !document.body.classList.contains('loading'))""",
            arg=shown)
        if guard.evaluate("(d) => d.open"):
            guarded += 1
            assert guard.locator(tid("accept-guard-doubt")).count() >= 1
            if guarded == 1:
                page.screenshot(path=str(artifacts / "pass-guard-1366x768.png"))
            page.keyboard.press("Enter")
            page.wait_for_function(
                """(id) => !document.querySelector('[data-testid=pass-finished]').hidden
                  || (location.pathname !== `/systems/${id}` && !document.body.classList.contains('loading'))""",
                arg=shown)
        if finished.is_visible():
            seconds.append(time.perf_counter() - start)
            break
        next_id = int(re.search(r"/systems/(\d+)", page.url).group(1))
        _wait_ready(page, next_id)
        seconds.append(time.perf_counter() - start)
    else:
        pytest.fail(f"the pass never finished; decided {decided}")

    # every system of the queue decided exactly once, in the pass's (the queue's first) order
    assert decided == order, (decided, order)
    for sid in order:
        entries = _api(page, f"/api/audit?system_id={sid}&limit=50")["items"]
        reviews = [e for e in entries if e["action"] == "system.review"]
        assert len(reviews) == 1 and reviews[0]["after"]["review"]["status"] == "accepted", (sid, reviews)
    assert _api(page, "/api/systems?limit=100")["counts"]["pending"] == 0
    assert guarded >= 1  # the demo has systems with open label doubts: each asked once

    finished = page.locator(tid("pass-finished"))
    counts = finished.locator(tid("pass-counts")).inner_text()
    assert counts == f"{len(order)} accepted · 0 rejected · 0 needs fix · 0 skipped"
    assert page.locator(tid("toast")).inner_text().endswith("Nothing pending is left in this pass.")
    assert finished.locator(tid("pass-queue-link")).get_attribute("href").startswith(f"/#system-{order[-1]}")
    assert finished.is_visible() and finished.bounding_box()["y"] < 768  # said above the fold
    page.screenshot(path=str(artifacts / "pass-finished-1366x768.png"))
    page.set_viewport_size({"width": 1920, "height": 1080})
    page.screenshot(path=str(artifacts / "pass-finished-1920x1080.png"))

    # j at the end of the pass says why it cannot move
    page.keyboard.press("j")
    page.locator(tid("toast")).filter(has_text="last system of the pass").wait_for()

    # the pass is kept: a reload shows the same pass, and the queue offers nothing to resume (all decided)
    page.reload()
    _wait_ready(page, order[-1])
    assert int(_SYSTEM_URL.search(page.url).group(3)) == pass_id
    mine = _api(page, "/api/passes")
    assert mine[0]["id"] == pass_id and mine[0]["counts"]["accepted"] == len(order)

    with capsys.disabled():
        ordered = sorted(seconds)
        print(f"\nkeyboard pass (a, Enter on the guard) of {len(order)} systems: median "
              f"{ordered[len(ordered) // 2]:.2f} s per system, total {sum(seconds):.1f} s, {guarded} accept guard(s)")
