"""Keys typed ahead on the system page, in Chromium beside a CPU-bound process: a key pressed while the page is still
loading, saving or taking in an answer is kept and applied in order once the page can act on it, so that ``s Enter``,
``a j``, ``Ctrl+Z Ctrl+Shift+Z``, ``1 s 2 s`` and ``j j j`` typed with no pause each do what they do typed slowly.
Where the order matters, the first key's request is held (``page.route``) until every key has been typed, so that the
later keys certainly arrive while the page is working; every request the keys send and the state they leave are
checked through the API."""
from __future__ import annotations

import json
import re

import pytest

from tests.browser.support import api_json as _api
from tests.browser.support import api_write, cpu_bound, pump_until, settled, tid

pytestmark = pytest.mark.browser

_SYSTEM_PATH = re.compile(r"/systems/(\d+)")


@pytest.fixture(scope="module", autouse=True)
def _a_cpu_bound_process():
    """A process spinning on one core for the module: the page works slower, as on a loaded machine."""
    with cpu_bound():
        yield


def _shown(page) -> int:
    return int(_SYSTEM_PATH.search(page.url).group(1))


class Held:
    """The first ``count`` requests of the page whose URL matches ``pattern`` and whose method is ``method`` are held
    until released; the rest go on. ``sent``: every such request the page made, in order (method, path, JSON body)."""

    def __init__(self, page, pattern: str, method: str, count: int = 1) -> None:
        self.page, self.method, self.count = page, method, count
        self.routes: list = []
        self.sent: list[tuple[str, str, dict | None]] = []
        self.regex = re.compile(pattern)
        page.on("request", self._note)
        page.route(self.regex, self._route)

    def _note(self, request) -> None:
        if request.method == self.method and self.regex.search(request.url):
            body = request.post_data
            self.sent.append((request.method, request.url.split("?")[0], json.loads(body) if body else None))

    def _route(self, route) -> None:
        if route.request.method == self.method and len(self.routes) < self.count:
            self.routes.append(route)
        else:
            route.continue_()

    def wait_held(self, n: int = 1) -> None:
        pump_until(self.page, lambda: len(self.routes) >= n, f"{n} request(s) {self.regex.pattern} to be held")

    def release(self) -> None:
        """Send the held requests on, then stop holding (later ones go straight on)."""
        for route in self.routes:
            route.continue_()
        self.page.unroute(self.regex, self._route)


def _busy(page) -> str:
    return page.evaluate("() => document.body.dataset.busy || ''")


def _open_in_a_pass(page, system_id: int) -> None:
    page.goto(f"/systems/{system_id}?pass=new")
    page.locator(tid("view")).first.wait_for()
    settled(page)


def _four_view_system_with_boxes(page) -> dict:
    items = _api(page, "/api/systems?sort=name&limit=100")["items"]
    return next(s for s in (_api(page, f"/api/systems/{i['id']}") for i in items if i["views_total"] == 4)
                if not s["doubts"] and all(v["ball"].get("box") for v in s["views"]))


def _move_label(page, view: dict, dx: float, dy: float) -> None:
    frame = view["frame_id"]
    etag = page.request.get(f"/api/frames/{frame}").headers["etag"]
    box = view["ball"]["box"]
    moved = api_write(page, "PATCH", f"/api/frames/{frame}/ball", data={"box": [box[0] + dx, box[1] + dy,
                                                                            box[2] + dx, box[3] + dy]},
                      headers={"If-Match": etag})
    assert moved.ok, moved.text()


def _put_back(page, system: dict) -> None:
    for view in system["views"]:
        frame = view["frame_id"]
        etag = page.request.get(f"/api/frames/{frame}").headers["etag"]
        assert api_write(page, "PATCH", f"/api/frames/{frame}/ball", data={"box": view["ball"]["box"]},
                         headers={"If-Match": etag}).ok


def test_j_j_j_then_k_k_k_typed_at_once_walk_the_pass_and_back(page):
    order = [s["id"] for s in _api(page, "/api/systems?limit=100")["items"]]
    assert len(order) >= 4
    page.goto("/")
    page.locator(tid("queue-row")).first.wait_for()
    settled(page)
    page.keyboard.press("Enter")  # the pass begins on the queue's first system
    page.wait_for_url(re.compile(rf"/systems/{order[0]}\?.*pass=\d+"))
    page.locator(tid("view")).first.wait_for()
    settled(page)

    # the first j's visit to the pass is held: the second and third j arrive while the page is still working
    visits = Held(page, r"/api/passes/\d+/visits$", "POST")
    for key in "jjj":
        page.keyboard.press(key)
    visits.wait_held()
    assert "keys" in _busy(page), "the two j typed while the page loads wait for it"
    visits.release()
    settled(page)
    assert _shown(page) == order[3]
    assert [body["system_id"] for _, _, body in visits.sent] == order[1:4]
    assert page.locator(tid("pass-progress")).inner_text().startswith("pass 4 of ")

    # k k k typed with no pause, nothing held: back on the first system of the pass
    for key in "kkk":
        page.keyboard.press(key)
    settled(page)
    assert _shown(page) == order[0]
    assert page.locator(tid("pass-progress")).inner_text().startswith("pass 1 of ")


def test_s_then_enter_typed_at_once_snap_the_label_and_confirm_it(page):
    system = _four_view_system_with_boxes(page)
    k = 1
    _move_label(page, system["views"][k], 90, 40)
    try:
        _open_in_a_pass(page, system["id"])
        assert page.locator(tid("view")).nth(k).locator(tid("view-doubts")).count() == 1
        snaps = Held(page, r"/api/frames/\d+/ball", "PATCH")
        for key in (str(k + 1), "s", "Enter"):
            page.keyboard.press(key)
        snaps.wait_held()
        assert "keys" in _busy(page) and len(snaps.sent) == 1, "Enter waits for the snap's answer"
        snaps.release()
        settled(page)
        (_, snap_url, snap), (_, confirm_url, confirm) = snaps.sent
        frame = system["views"][k]["frame_id"]
        assert snap_url.endswith(f"/api/frames/{frame}/ball") and confirm_url == snap_url
        assert snap.get("provenance") and "provenance" not in confirm  # placed from the doubt, then a person's
        assert confirm["box"] == pytest.approx(snap["box"])
        after = _api(page, f"/api/systems/{system['id']}")
        assert after["views"][k]["ball"]["box"] == pytest.approx(snap["box"])
        assert not after["views"][k]["ball"].get("provenance")
        assert not [d for d in after["doubts"] if d["frame_id"] == frame]
        assert page.locator(tid("view")).nth(k).locator(tid("view-doubts")).count() == 0
    finally:
        _put_back(page, system)


def test_one_s_two_s_typed_at_once_snap_each_view_it_selected(page):
    system = _four_view_system_with_boxes(page)
    _move_label(page, system["views"][0], -80, 35)
    _move_label(page, system["views"][1], 90, 40)
    try:
        moved = _api(page, f"/api/systems/{system['id']}")
        frames = [v["frame_id"] for v in system["views"][:2]]
        suggested = {d["frame_id"]: d["suggestion"]["box"] for d in moved["doubts"]
                     if d["frame_id"] in frames and (d.get("suggestion") or {}).get("box")}
        assert set(suggested) == set(frames), moved["doubts"]
        _open_in_a_pass(page, system["id"])
        snaps = Held(page, r"/api/frames/\d+/ball", "PATCH")
        for key in "1s2s":
            page.keyboard.press(key)
        snaps.wait_held()
        assert len(snaps.sent) == 1 and "keys" in _busy(page)
        snaps.release()
        settled(page)
        assert [url.rsplit("/", 2)[-2] for _, url, _ in snaps.sent] == [str(f) for f in frames]
        after = _api(page, f"/api/systems/{system['id']}")
        for i, frame in enumerate(frames):
            assert after["views"][i]["ball"]["box"] == pytest.approx(suggested[frame], abs=0.06)
    finally:
        _put_back(page, system)


def test_ctrl_z_then_ctrl_shift_z_typed_at_once_undo_and_redo(page):
    system = _four_view_system_with_boxes(page)
    k = 2
    try:
        _open_in_a_pass(page, system["id"])
        page.keyboard.press(str(k + 1))
        page.keyboard.press("ArrowRight")
        settled(page)  # the nudge's pause, its save and its answer drawn
        nudged = _api(page, f"/api/systems/{system['id']}")
        box = system["views"][k]["ball"]["box"]
        assert nudged["views"][k]["ball"]["box"] == pytest.approx([box[0] + 1, box[1], box[2] + 1, box[3]])

        undos = Held(page, r"/api/audit/\d+/undo(\?|$)", "POST")
        page.keyboard.press("Control+z")
        page.keyboard.press("Control+Shift+Z")
        undos.wait_held()
        assert len(undos.sent) == 1 and "keys" in _busy(page), "the redo waits for the undo"
        undos.release()
        settled(page)
        assert len(undos.sent) == 2
        after = _api(page, f"/api/systems/{system['id']}")
        assert after["views"][k]["ball"]["box"] == pytest.approx(nudged["views"][k]["ball"]["box"])
        assert after["ball3d"] == pytest.approx(nudged["ball3d"])
        toast = page.locator(tid("toast")).inner_text()
        assert toast.startswith("Redone: "), toast
    finally:
        _put_back(page, system)


def test_a_then_j_typed_at_once_accept_and_step_on_from_the_next_system(page):
    queue = [s["id"] for s in _api(page, "/api/systems?status=pending&limit=100")["items"]
             if not _api(page, f"/api/systems/{s['id']}")["doubts"]]
    assert len(queue) >= 3
    first = queue[0]
    _open_in_a_pass(page, first)
    pass_id = re.search(r"pass=(\d+)", page.url).group(1)
    systems = _api(page, f"/api/passes/{pass_id}")["systems"]
    at = systems.index(first)
    decisions = Held(page, rf"/api/systems/{first}/review$", "POST")
    page.keyboard.press("a")
    page.keyboard.press("j")
    decisions.wait_held()
    assert "keys" in _busy(page)
    decisions.release()
    settled(page)
    assert _api(page, f"/api/systems/{first}")["review"]["status"] == "accepted"
    # a: the next pending system of the pass; j: the one after it in the pass's order
    next_pending = next(s for s in systems[at + 1:] if _api(page, f"/api/systems/{s}")["review"]["status"] == "pending")
    assert _shown(page) == systems[systems.index(next_pending) + 1]


def test_keys_beyond_the_bound_or_into_a_text_field_are_refused_in_words(page):
    _open_in_a_pass(page, _api(page, "/api/systems?limit=1")["items"][0]["id"])  # the pass's first: j moves
    visits = Held(page, r"/api/passes/\d+/visits$", "POST")
    page.keyboard.press("j")
    visits.wait_held()
    for _ in range(8):  # the bound: eight keys wait
        page.keyboard.press("1")
    page.keyboard.press("2")
    page.locator(tid("toast")).filter(has_text="2 not taken: 8 keys already wait").wait_for()
    visits.release()
    settled(page)
    assert page.evaluate("() => [...document.querySelectorAll('[data-testid=view]')]"
                         ".findIndex((v) => v.classList.contains('selected'))") == 0

    # a key that focused the comment box: the keys typed after it are not applied as the page's keys
    visits = Held(page, r"/api/passes/\d+/visits$", "POST")
    decisions = Held(page, r"/api/systems/\d+/review$", "POST", count=0)  # only counted
    page.keyboard.press("k")
    visits.wait_held()
    for key in "caj":  # c focuses the comment box; a and j, typed after it, are not the page's to apply
        page.keyboard.press(key)
    visits.release()
    page.locator(tid("toast")).filter(has_text="2 keys typed ahead not applied").wait_for()
    settled(page)
    assert page.evaluate("() => document.activeElement?.dataset.testid") == "comment"
    assert decisions.sent == []  # the `a` typed after `c` decided nothing
    assert page.locator(tid("comment")).input_value() == ""
