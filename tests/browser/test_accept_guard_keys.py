"""The accept guard and keys that cannot act (issue 28), in Chromium, against the real server and the demo.

``a`` on a system with open label doubts shows ``[data-testid=accept-guard]`` listing them in words (the
view, the doubt's name, the server's sentence); ``Esc`` leaves the system pending, ``a`` then ``Enter``
accepts it, and the audit entry of the decision lists the doubts it overrode. Keys that cannot act say why
in the toast: ``s`` with no suggestion, ``4`` on a 3-view system, ``x`` with no view selected, and the rest
of the key table's "cannot" paths."""
from __future__ import annotations

import re

import pytest

from tests.browser.support import api_json as _api
from tests.browser.support import tid

pytestmark = pytest.mark.browser


def _open(page, system_id: int, query: str = "sort=name") -> None:
    page.goto(f"/systems/{system_id}?{query}")
    page.wait_for_function(
        """(id) => location.pathname === `/systems/${id}` && !document.body.classList.contains('loading')
          && document.querySelectorAll('[data-testid=view]').length > 0
          && /pass \\d+ of \\d+/.test(document.querySelector('[data-testid=pass-progress]')?.textContent || '')""",
        arg=system_id)


def _says(page, key: str, text: str) -> None:
    """Press ``key``: the toast says ``text`` (a part of it)."""
    page.evaluate("() => { const t = document.querySelector('[data-testid=toast]'); t.textContent = ''; }")
    page.keyboard.press(key)
    page.locator(tid("toast")).filter(has_text=text).wait_for()


def _systems(page) -> list[dict]:
    return [_api(page, f"/api/systems/{s['id']}?sort=name")
            for s in _api(page, "/api/systems?sort=name&limit=100")["items"]]


def test_a_on_a_doubtful_system_asks_first_esc_keeps_it_pending_enter_accepts(page, artifacts):
    systems = _systems(page)
    doubtful = next(s for s in systems if any(d["accuses_label"] for d in s["doubts"]))
    open_doubts = [d for d in doubtful["doubts"] if d["accuses_label"]]
    _open(page, doubtful["id"])
    url = page.url

    page.keyboard.press("a")
    guard = page.locator(tid("accept-guard"))
    guard.wait_for(state="visible")
    items = guard.locator(tid("accept-guard-doubt"))
    assert items.count() == len(open_doubts)
    for i, d in enumerate(open_doubts):
        v = next(j for j, view in enumerate(doubtful["views"]) if view["frame_id"] == d["frame_id"])
        text = items.nth(i).inner_text()
        assert text.startswith(f"V{v + 1} ({doubtful['views'][v]['name']}) · ") and text.endswith(d["message"]), text
        assert "_" not in text.split(":")[0].split("·")[1], text  # the doubt's name in words, not its code
    for size in ((1366, 768), (1920, 1080)):
        page.set_viewport_size({"width": size[0], "height": size[1]})
        box = guard.bounding_box()
        assert box["y"] >= 0 and box["y"] + box["height"] <= size[1]  # the whole guard in the window
        page.screenshot(path=str(artifacts / f"accept-guard-{size[0]}x{size[1]}.png"))

    # Esc: nothing decided, the page stays
    page.keyboard.press("Escape")
    guard.wait_for(state="hidden")
    page.locator(tid("toast")).filter(has_text="not accepted").wait_for()
    assert page.url == url
    assert _api(page, f"/api/systems/{doubtful['id']}")["review"]["status"] == "pending"
    assert not [e for e in _api(page, f"/api/audit?system_id={doubtful['id']}")["items"]
                if e["action"] == "system.review"]

    # a, then Enter: accepted, the next pending system opens, the audit entry names the doubts overridden
    page.keyboard.press("a")
    guard.wait_for(state="visible")
    page.keyboard.press("Enter")
    page.wait_for_url(lambda u: f"/systems/{doubtful['id']}?" not in u)
    assert _api(page, f"/api/systems/{doubtful['id']}")["review"]["status"] == "accepted"
    entry = next(e for e in _api(page, f"/api/audit?system_id={doubtful['id']}")["items"]
                 if e["action"] == "system.review")
    assert [(d["kind"], d["frame_id"]) for d in entry["after"]["overrode_doubts"]] == \
        [(d["kind"], d["frame_id"]) for d in open_doubts]

    # the Accept button asks too; a system without open doubts is accepted at once
    clean = next(s for s in systems if not any(d["accuses_label"] for d in s["doubts"]) and len(s["views"]) > 1
                 and s["review"]["status"] == "pending" and s["ball3d"] is not None)
    _open(page, clean["id"])
    page.click(tid("accept"))
    page.wait_for_url(lambda u: f"/systems/{clean['id']}?" not in u)
    assert not guard.is_visible()
    assert _api(page, f"/api/systems/{clean['id']}")["review"]["status"] == "accepted"


def test_a_system_without_a_3d_ball_is_not_accepted_by_one_key(page, artifacts):
    """Its ball labels removed, a pending system of several views has no 3D ball and no doubt: `a` alone leaves it
    pending and the guard says it has no 3D ball; `Enter` then accepts it."""
    from tests.browser.support import api_write

    system = next(s for s in _systems(page) if not any(d["accuses_label"] for d in s["doubts"])
                  and len(s["views"]) > 1 and s["review"]["status"] == "pending" and s["ball3d"] is not None)
    for view in system["views"]:
        if view["ball"].get("box") or view["ball"].get("point"):
            etag = page.request.get(f"/api/frames/{view['frame_id']}").headers["etag"]
            removed = api_write(page, "PATCH", f"/api/frames/{view['frame_id']}/ball", data={"box": None},
                                headers={"If-Match": etag})
            assert removed.ok, removed.text()
    now = _api(page, f"/api/systems/{system['id']}")
    assert now["ball3d"] is None and not any(d["accuses_label"] for d in now["doubts"])
    _open(page, system["id"])
    page.keyboard.press("a")
    guard = page.locator(tid("accept-guard"))
    guard.wait_for(state="visible")
    assert "without a 3D ball" in guard.locator("h2").text_content()
    assert "no 3D ball" in guard.locator(tid("accept-guard-no-ball")).inner_text()
    assert _api(page, f"/api/systems/{system['id']}")["review"]["status"] == "pending"
    for size in ((1366, 768), (1920, 1080)):
        page.set_viewport_size({"width": size[0], "height": size[1]})
        box = guard.bounding_box()
        assert box["y"] >= 0 and box["y"] + box["height"] <= size[1]
        page.screenshot(path=str(artifacts / f"accept-guard-no-ball-{size[0]}x{size[1]}.png"))
    with page.expect_response(lambda r: r.request.method == "POST" and r.url.endswith(f"/{system['id']}/review")):
        page.keyboard.press("Enter")
    assert _api(page, f"/api/systems/{system['id']}")["review"]["status"] == "accepted"


def test_keys_that_cannot_act_say_why(page, artifacts):
    systems = _systems(page)
    three = next(s for s in systems if len(s["views"]) == 3
                 and not any(d.get("suggestion") for d in s["doubts"])
                 and not any(v["calibration"].get("probably_mirrored") for v in s["views"]))
    _open(page, three["id"])

    _says(page, "s", "no doubt of this system has a suggested fix")
    _says(page, "4", "this system has 3 views: 4 selects none")
    _says(page, "x", "select a view first (1…9) to exclude it")
    _says(page, "ArrowLeft", "select a view first")
    _says(page, "Delete", "select a view first")
    _says(page, "Shift+A", "select a view first")
    _says(page, "m", "no view of this system is flagged as mirrored")
    _says(page, ",", "only the frames of an ISSIA sequence")
    _says(page, "0", "the views already show the whole frames")
    _says(page, "Shift+I", "zoom in first (>) to pan")
    _says(page, "<", "the views already show the whole frames")
    _says(page, "[", "press e to edit")
    _says(page, "Enter", "nothing to confirm")
    _says(page, "Control+z", "nothing to undo")

    page.keyboard.press("1")
    _says(page, "s", "V1 has no doubt with a suggested fix")
    _says(page, "m", "V1 is not flagged as mirrored")
    _says(page, "z", "V1's ball label is as imported: nothing to restore")
    page.screenshot(path=str(artifacts / "key-cannot.png"))

    # the ends of the pass: k on its first system, j on its last
    pass_id = re.search(r"pass=(\d+)", page.url).group(1)
    place = _api(page, f"/api/passes/{pass_id}")
    _open(page, place["systems"][0], f"sort=name&pass={place['id']}")
    _says(page, "k", "this is the first system of the pass")
    _open(page, place["systems"][-1], f"sort=name&pass={place['id']}")
    _says(page, "j", "this is the last system of the pass")

    # a view without a ball label: the arrows and Del say so (the calibration-only frame has none)
    single = next(s for s in systems if len(s["views"]) == 1 and not s["views"][0]["ball"]["kind"])
    _open(page, single["id"])
    _says(page, "x", "a single view has no 3D ball")
    page.keyboard.press("1")
    _says(page, "ArrowUp", "V1 has no ball label to move")
    _says(page, "Delete", "V1 has no ball label to remove")


def test_the_queue_offers_to_resume_the_open_pass_where_it_was_left(page):
    pending = [s["id"] for s in _api(page, "/api/systems?sort=name&status=pending&limit=100")["items"]]
    assert len(pending) >= 2
    _open(page, pending[1])
    pass_id = int(re.search(r"pass=(\d+)", page.url).group(1))
    mine = _api(page, "/api/passes")
    assert mine[0]["id"] == pass_id

    # another browser of the same user (a fresh context: no sessionStorage, no history) resumes it
    context = page.context.browser.new_context(base_url=page.url.split("/systems/")[0],
                                               storage_state=page.context.storage_state())
    try:
        other = context.new_page()
        other.goto("/")
        link = other.locator(tid("resume-pass"))
        link.wait_for()
        assert f"pass={pass_id}" in link.get_attribute("href")
        link.click()
        other.wait_for_url(re.compile(rf"/systems/{pending[1]}\?.*pass={pass_id}"))
        other.locator(tid("pass-progress")).filter(has_text="pass ").wait_for()
    finally:
        context.close()
