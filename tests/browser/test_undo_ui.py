"""Issue 28, items 3 and 4 in Chromium: on an accepted system, a keyboard nudge of a ball sets the decision back
to pending (with the reason); Ctrl+Z undoes it (the stored box, the camera and the 3D ball as before, to the
same numbers), Ctrl+Shift+Z redoes it; an exclusion (`x`) is undone the same way; a decision too; the history
panel says each entry in words."""
from __future__ import annotations

from urllib.parse import urlsplit

import pytest
from playwright.sync_api import TimeoutError as PlaywrightTimeoutError

from tests.browser.support import api_json as _api
from tests.browser.support import api_write, tid

pytestmark = pytest.mark.browser


def _undo_answer(page, key: str):
    """Press ``key`` (an undo or redo key) and answer the page's ``/undo`` response; when none comes, fail with what
    the page said instead (its toast and its error bar), so that a run that meets it shows why."""
    try:
        with page.expect_response(lambda r: r.url.split("?")[0].endswith("/undo")) as answer:
            page.keyboard.press(key)
        return answer.value
    except PlaywrightTimeoutError:
        said = page.evaluate("() => [...document.querySelectorAll('[data-testid=toast], [data-testid=error]')]"
                             ".map((e) => e.textContent.trim()).filter(Boolean)")
        raise AssertionError(f"{key} sent no undo within 30 s; the page says {said}") from None


def _numbers(system: dict) -> dict:
    return {"ball3d": system["ball3d"],
            "views": [{"ball": v["ball"], "camera": (v.get("calibration") or {}).get("camera"),
                       "excluded": (v.get("review") or {}).get("excluded", False)} for v in system["views"]]}


def _triangulated_with_box(page) -> tuple[dict, int]:
    listing = _api(page, "/api/systems?sort=name&limit=500")["items"]
    for s in listing[len(listing) // 2:]:
        system = _api(page, f"/api/systems/{s['id']}")
        if not isinstance(system["ball3d"], list) or len(system["views"]) < 3:
            continue
        kept = {v for p in system["triangulation"]["pairs"] if p["kept"] for v in (p["view_a"], p["view_b"])}
        for k, v in enumerate(system["views"]):
            if v["ball"]["kind"] == "box" and (v["frame_id"] in kept or v["name"] in kept):
                return system, k
    raise AssertionError("the demo data should have a triangulated system of three views with a box in a kept pair")


def test_nudge_undo_redo_exclusion_and_the_history_summaries(page, artifacts):
    system, k = _triangulated_with_box(page)
    sid = system["id"]
    accepted = api_write(page, "POST", f"/api/systems/{sid}/review",
                         data={"status": "accepted", "comment": "looked fine"},
                         headers={"If-Match": system["etag"]})
    assert accepted.ok, accepted.text()
    before = _api(page, f"/api/systems/{sid}")
    page.goto(f"/systems/{sid}")
    page.locator(tid("view")).nth(k).locator(tid("ball-hit")).wait_for()
    shown_x = page.locator(tid("ball3d-x")).inner_text()

    # a nudge of 3 px right: saved after the pause, the system pending again with the reason
    page.keyboard.press(str(k + 1))
    with page.expect_response(lambda r: r.request.method == "PATCH") as answer:
        for _ in range(3):
            page.keyboard.press("ArrowRight")
    assert answer.value.status == 200
    nudged = _api(page, f"/api/systems/{sid}")
    box = before["views"][k]["ball"]["box"]
    assert nudged["views"][k]["ball"]["box"] == pytest.approx([box[0] + 3, box[1], box[2] + 3, box[3]], abs=0.05)
    assert nudged["ball3d"] != before["ball3d"]
    assert nudged["review"]["status"] == "pending"
    assert f"ball of V{k + 1} moved 3.0 px" in nudged["review"]["reset_reason"]
    page.wait_for_function("() => document.querySelector('[data-testid=system-status]')"
                           ".textContent.toLowerCase().includes('pending')")

    # Ctrl+Z: the undo of that entry; label, camera and 3D ball to the same numbers
    undo = _undo_answer(page, "Control+z")
    assert undo.status == 200, undo.text()
    undone = _api(page, f"/api/systems/{sid}")
    assert _numbers(undone) == _numbers(before)
    page.wait_for_function(f"() => document.querySelector('[data-testid=ball3d-x]').textContent === {shown_x!r}")
    page.screenshot(path=str(artifacts / "undo-nudge-undone.png"))

    # Ctrl+Shift+Z: the nudge again
    undo = _undo_answer(page, "Control+Shift+Z")
    assert undo.status == 200
    assert _numbers(_api(page, f"/api/systems/{sid}")) == _numbers(nudged)

    # `x` excludes the selected view; Ctrl+Z restores it and the 3D ball of the redone nudge
    with page.expect_response(lambda r: r.request.method == "POST" and "/exclusion" in r.url) as answer:
        page.keyboard.press("x")
    assert answer.value.status == 200
    assert _api(page, f"/api/systems/{sid}")["views"][k]["review"]["excluded"] is True
    undo = _undo_answer(page, "Control+z")
    assert undo.status == 200
    assert _numbers(_api(page, f"/api/systems/{sid}")) == _numbers(nudged)

    # the history panel: every entry in words
    # the panel refreshes after the last undo's answer: wait for that entry, not for a count the earlier six reach
    page.wait_for_function("() => [...document.querySelectorAll('[data-testid=history-entry]')]"
                           ".some(e => e.textContent.includes('restored to the 3D ball'))")
    texts = page.locator(tid("history-entry")).all_inner_texts()
    joined = "\n".join(texts)
    for words in (f"ball of V{k + 1} moved 3.0 px", f"V{k + 1} excluded from the 3D ball",
                  f"V{k + 1} restored to the 3D ball", "system set back to pending", "system accepted",
                  "undo of entry"):
        assert words in joined, (words, texts)
    page.locator(tid("history")).scroll_into_view_if_needed()
    page.screenshot(path=str(artifacts / "undo-history-summaries.png"))

    # the exclusion again (redo), then nothing left to redo: the key says so
    undo = _undo_answer(page, "Control+Shift+Z")
    assert undo.status == 200
    assert _api(page, f"/api/systems/{sid}")["views"][k]["review"]["excluded"] is True
    page.keyboard.press("Control+Shift+Z")
    page.wait_for_function("() => document.querySelector('[data-testid=toast]')"
                           ".textContent.includes('Nothing to redo')")


def test_a_decision_is_undone_by_ctrl_z_on_its_system(page, artifacts):
    system, _ = _triangulated_with_box(page)
    sid = system["id"]
    page.goto(f"/systems/{sid}?pass=new")  # a pass of its own, whatever earlier tests left open
    page.locator(tid("view")).first.wait_for()
    status = _api(page, f"/api/systems/{sid}")["review"]["status"]
    page.keyboard.press("f")  # needs fix: nobody edited it, so to the annotator the page offers
    page.locator(tid("return-to")).wait_for()
    with page.expect_response(lambda r: r.request.method == "POST" and "/review" in r.url) as answer:
        page.click(tid("return-to-send"))  # then the next system is shown
    assert answer.value.status == 200
    assert _api(page, f"/api/systems/{sid}")["review"]["status"] == "needs_fix"
    # the next system's page is loaded (a key pressed while the browser changes pages reaches neither page)
    page.wait_for_url(lambda url: urlsplit(url).path != f"/systems/{sid}")
    page.locator(tid("view")).first.wait_for()
    with page.expect_response(lambda r: r.url.split("?")[0].endswith("/undo")) as answer:
        page.keyboard.press("Control+z")  # back on the decided system, its decision undone
    assert answer.value.status == 200
    assert _api(page, f"/api/systems/{sid}")["review"]["status"] == status  # the decision undone, on the server
    # the jump back is said: the toast names the system undone, and the page says, until it moves on, that the
    # next key acts on that system (its name outlined)
    name = system["name"]
    notice = page.locator(tid("undo-back"))
    notice.wait_for()
    assert urlsplit(page.url).path == f"/systems/{sid}"
    assert f"Back on {name}" in notice.inner_text() and "next key acts on this system" in notice.inner_text()
    assert page.locator(tid("system-name")).inner_text() == name
    assert "undo-landed" in (page.locator(tid("system-name")).get_attribute("class") or "")
    toast = page.locator(tid("toast")).inner_text()
    assert toast.startswith("Undone: ") and f"({name})" in toast and f"back on {name}" in toast
    for size in ({"width": 1366, "height": 768}, {"width": 1920, "height": 1080}):
        page.set_viewport_size(size)
        page.screenshot(path=str(artifacts / f"undo-decision-{size['width']}.png"))
    page.keyboard.press("j")  # the page moves on: the notice is gone with it
    page.wait_for_url(lambda url: urlsplit(url).path != f"/systems/{sid}")
    notice.wait_for(state="hidden")


def test_a_mirror_fix_is_undone_to_the_same_numbers(page, artifacts):
    listing = _api(page, "/api/systems?sort=name&limit=500")["items"]
    found = None
    for s in listing:
        system = _api(page, f"/api/systems/{s['id']}")
        k = next((i for i, v in enumerate(system["views"]) if (v.get("calibration") or {}).get("probably_mirrored")),
                 None)
        if k is not None:
            found = (system, k)
            break
    assert found is not None, "the demo data should have a view flagged as mirrored"
    system, k = found
    sid = system["id"]
    before = _api(page, f"/api/systems/{sid}")
    page.goto(f"/systems/{sid}")
    page.locator(tid("view")).nth(k).wait_for()
    page.keyboard.press(str(k + 1))
    with page.expect_response(lambda r: r.request.method == "POST" and "/field-lines/mirror" in r.url) as answer:
        page.keyboard.press("m")
    assert answer.value.status == 200, answer.value.text()
    fixed = _api(page, f"/api/systems/{sid}")
    assert fixed["views"][k]["calibration"]["camera"] != before["views"][k]["calibration"]["camera"]
    undo = _undo_answer(page, "Control+z")
    assert undo.status == 200, undo.text()
    undone = _api(page, f"/api/systems/{sid}")
    assert _numbers(undone) == _numbers(before)
    assert undone["views"][k]["field_lines"] == before["views"][k]["field_lines"]
    page.wait_for_function("() => document.querySelector('[data-testid=toast]').textContent.startsWith('Undone: field "
                           "lines of V')")
    page.screenshot(path=str(artifacts / "undo-mirror.png"))
