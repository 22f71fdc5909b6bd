"""Field-line editing on the system page in Chromium (issue 16, items 1, 2 and 7), on the synthetic SoccerNet-v3
dev set (``../shared``; skips without it): drag a point and see JaC change, add and delete a point, relabel a
line (the class's projected model line highlighted), undo and redo (Ctrl+Z / Ctrl+Shift+Z: the lines and JaC
come back exactly, the audit marks the undo), and fix a refused view by drawing the line its image shows
until it is admitted. Screenshots in ``test-artifacts/`` (``line-edit-*.png``)."""
from __future__ import annotations

import json
from pathlib import Path

import pytest

from tests.browser.support import api_json as _api
from tests.browser.support import seed_dev_set, tid, wait_for_steady_layout

pytestmark = pytest.mark.browser


@pytest.fixture(scope="module")
def seeded_settings(seeded_databases, shared_dir: Path, tmp_path_factory: pytest.TempPathFactory):
    """A copy of the synthetic dev set (both games), imported as a user would."""
    return seed_dev_set(seeded_databases, shared_dir, tmp_path_factory.mktemp("lines-ui"))


def _system(page, name: str, views: int) -> dict:
    """The dev set's system ``name`` with ``views`` views (names repeat across the two games)."""
    for item in _api(page, "/api/systems?sort=name&limit=200")["items"]:
        if item["name"] == name and item["views_total"] == views:
            return _api(page, f"/api/systems/{item['id']}")
    raise AssertionError(f"no system {name} of {views} views in the dev set")


def _view(page, system: dict, frame_name: str) -> tuple[int, dict]:
    k = next(i for i, v in enumerate(system["views"]) if v["name"] == frame_name)
    return k, system["views"][k]


def _jac_text(page, k: int) -> str:
    return page.locator(tid("view")).nth(k).locator(tid("view-jac")).inner_text()


def _screen(page, k: int, x: float, y: float) -> tuple[float, float]:
    """Screen position of image pixel (x, y) of view ``k`` (through the SVG's own mapping)."""
    svg = page.locator(tid("view")).nth(k).locator(tid("view-svg"))
    return tuple(svg.evaluate("(s, [x, y]) => { const p = new DOMPoint(x, y).matrixTransform(s.getScreenCTM());"
                              " return [p.x, p.y]; }", [x, y]))


def _point(page, frame_id: int, cls: str, poly: int, index: int):
    return page.locator(f'[data-testid=line-point][data-frame-id="{frame_id}"][data-class="{cls}"]'
                        f'[data-polyline="{poly}"][data-index="{index}"]')


def _put(page):
    return page.expect_response(lambda r: r.request.method == "PUT" and "/field-lines" in r.url)


def _open(page, system: dict, k: int) -> None:
    page.goto(f"/systems/{system['id']}")
    page.locator(tid("view")).nth(k).locator(tid("line-point")).first.wait_for()
    page.keyboard.press(str(k + 1))  # select the view
    page.keyboard.press("e")  # edit its lines
    page.locator(tid("view")).nth(k).locator(tid("lines-bar")).wait_for()
    page.locator(tid("view")).nth(k).scroll_into_view_if_needed()


def _saved(page, fid: int) -> None:
    """Wait until the view's save is drawn (its 'saving…' tag hidden again)."""
    page.locator(f'[data-testid=view][data-frame-id="{fid}"] [data-testid=view-saving]').wait_for(state="hidden")


def test_drag_add_delete_relabel_undo_redo(page, artifacts):
    system = _system(page, "2.png", 4)
    k, view = _view(page, system, "2_3.png")
    fid = view["frame_id"]
    assert view["calibration"]["admitted"] is True
    lines0 = view["field_lines"]
    _open(page, system, k)
    # the contract: one line-point per annotated point, named by class, polyline and index
    assert page.locator(f'[data-testid=line-point][data-frame-id="{fid}"]').count() == sum(
        len(p) for polys in lines0.values() for p in polys)
    # the worst-fitting classes are named with their residual
    worst = page.locator(tid("view")).nth(k).locator(tid("worst-line"))
    top = max(view["calibration"]["residuals_px"].items(), key=lambda kv: kv[1])
    assert worst.first.get_attribute("data-class") == top[0]
    assert f"{top[1]:.1f} px" in worst.first.inner_text()

    # drag: a point inside the image of the best-fitting line 40 px to the right; JaC changes
    def inside(p):
        return 100 < p[0] < view["width"] - 100 and 50 < p[1] < view["height"] - 50
    residuals = view["calibration"]["residuals_px"]
    cls = min((c for c in lines0 if c in residuals and any(map(inside, lines0[c][0]))), key=residuals.get)
    i = next(i for i, p in enumerate(lines0[cls][0]) if inside(p))
    x, y = lines0[cls][0][i]
    jac_before = _jac_text(page, k)
    # where the point is on the screen is read once the view's image is drawn (its arrival redraws the view, which a
    # drag under way would meet) and the page has stopped moving, so that the drag starts and ends where it was aimed
    if view.get("image_url"):
        page.locator(f'[data-testid=view][data-frame-id="{fid}"] [data-testid=view-svg] image').first.wait_for(
            state="attached")
    wait_for_steady_layout(page)
    sx, sy = _screen(page, k, x, y)
    page.screenshot(path=str(artifacts / "line-edit-open.png"))
    tx, ty = _screen(page, k, x + 40, y)
    with _put(page) as answer:
        page.mouse.move(sx, sy)
        page.mouse.down()
        page.mouse.move((sx + tx) / 2, sy, steps=4)
        # the page moves under the drag by half a pixel (as a preview's badge or a toast can): the point follows the
        # pointer's motion, not the page's (read per move through the moved view, it landed 2 px off in y)
        page.evaluate("() => { document.body.style.paddingTop = '0.5px'; }")
        page.mouse.move(tx, ty, steps=4)
        page.mouse.up()
    page.evaluate("() => { document.body.style.paddingTop = ''; }")
    assert answer.value.status == 200, answer.value.text()
    _saved(page, fid)
    moved = _api(page, f"/api/frames/{fid}")
    assert moved["field_lines"][cls][0][i] == pytest.approx([x + 40, y], abs=0.6)
    assert moved["calibration"]["jac"] != view["calibration"]["jac"]
    assert _jac_text(page, k) != jac_before
    page.screenshot(path=str(artifacts / "line-edit-drag.png"))

    # add a point: double-click the middle of the side line's first segment
    side = "Side line top"
    pts = moved["field_lines"][side][0]
    mid = [(pts[0][0] + pts[1][0]) / 2, (pts[0][1] + pts[1][1]) / 2]
    with _put(page) as answer:
        page.mouse.dblclick(*_screen(page, k, *mid))
    assert answer.value.status == 200, answer.value.text()
    _saved(page, fid)
    added = _api(page, f"/api/frames/{fid}")["field_lines"][side][0]
    assert len(added) == len(pts) + 1 and added[1] == pytest.approx(mid, abs=1.0)

    # delete that point again: click it (select), Del; the ball label stays
    _point(page, fid, side, 0, 1).click()
    with _put(page) as answer:
        page.keyboard.press("Delete")
    assert answer.value.status == 200, answer.value.text()
    _saved(page, fid)
    after_delete = _api(page, f"/api/frames/{fid}")
    assert after_delete["field_lines"][side][0] == pts
    assert after_delete["ball"]["kind"] == view["ball"]["kind"]

    # relabel the middle line as the right side line: the chosen class's projection is highlighted
    cls = "Middle line"
    page.locator(f'[data-testid=view][data-frame-id="{fid}"] [data-testid=line-hit][data-class="{cls}"]').click()
    bar = page.locator(tid("view")).nth(k).locator(tid("lines-bar"))
    assert "Middle line" in bar.locator(tid("line-selection")).inner_text()
    bar.locator(tid("line-class")).select_option("Side line right")
    highlight = page.locator(tid("view")).nth(k).locator(tid("model-line-highlight"))
    assert highlight.count() >= 1 and highlight.first.get_attribute("data-class") == "Side line right"
    page.screenshot(path=str(artifacts / "line-edit-relabel-choice.png"))
    before_relabel = _api(page, f"/api/frames/{fid}")
    with _put(page) as answer:
        bar.locator(tid("relabel-line")).click()
    assert answer.value.status == 200, answer.value.text()
    _saved(page, fid)
    relabelled = _api(page, f"/api/frames/{fid}")
    assert cls not in relabelled["field_lines"]
    assert relabelled["field_lines"]["Side line right"][-1] == before_relabel["field_lines"][cls][0]
    assert relabelled["calibration"]["jac"] != before_relabel["calibration"]["jac"]
    relabel_entry = int(answer.value.headers["x-v3d-audit-entry"])
    page.screenshot(path=str(artifacts / "line-edit-relabelled.png"))

    # Ctrl+Z: the lines before the relabel come back exactly, with the same camera and JaC
    with _put(page) as answer:
        page.keyboard.press("Control+z")
    assert answer.value.status == 200, answer.value.text()
    assert json.loads(answer.value.request.post_data)["undo_of"] == relabel_entry
    _saved(page, fid)
    undone = _api(page, f"/api/frames/{fid}")
    assert undone["field_lines"] == before_relabel["field_lines"]
    assert undone["calibration"]["camera"] == before_relabel["calibration"]["camera"]
    assert undone["calibration"]["jac"] == before_relabel["calibration"]["jac"]
    undo_entry = int(answer.value.headers["x-v3d-audit-entry"])
    audit = {e["id"]: e for e in _api(page, f"/api/audit?frame_id={fid}")["items"]}
    assert (audit[undo_entry]["action"], audit[undo_entry]["reverts_id"]) == ("field_lines.replace", relabel_entry)
    page.screenshot(path=str(artifacts / "line-edit-undone.png"))

    # Ctrl+Shift+Z: the relabel again (marked as the undo of the undo), then undo it again
    with _put(page) as answer:
        page.keyboard.press("Control+Shift+Z")
    assert answer.value.status == 200, answer.value.text()
    assert json.loads(answer.value.request.post_data)["undo_of"] == undo_entry
    _saved(page, fid)
    redone = _api(page, f"/api/frames/{fid}")
    assert redone["field_lines"] == relabelled["field_lines"]
    assert redone["calibration"]["jac"] == relabelled["calibration"]["jac"]
    # the whole stack undone: the imported lines, and the calibration they give
    for _ in range(4):  # redo of relabel, delete, add, drag
        with _put(page) as answer:
            page.keyboard.press("Control+z")
        assert answer.value.status == 200, answer.value.text()
        _saved(page, fid)
    first = _api(page, f"/api/frames/{fid}")
    assert first["field_lines"] == lines0
    assert first["calibration"]["jac"] == pytest.approx(view["calibration"]["jac"], abs=1e-6) \
        or view["calibration"]["source"] != "computed"


def test_fix_a_refused_view_by_drawing_the_line_it_shows(page, artifacts, shared_dir):
    """13_2.png of the 4-view system 13.png is refused by its lines: its middle line and centre circle alone leave
    the camera undetermined (its players place one, which no line admits). The image also shows the top side line:
    the annotator draws it (where the true
    camera projects it: what the image shows), looks at the calibration and the worst lines, and drags the
    line's ends out to the image's edges while the view is not admitted. It ends admitted and joins the
    triangulation."""
    from app.geometry.camera import Camera
    from app.geometry.projection import project_pitch_polylines

    system = _system(page, "13.png", 4)
    k, view = _view(page, system, "13_2.png")
    fid, w = view["frame_id"], view["width"]
    cal = view["calibration"]
    assert not cal["admitted"] and "Side line top" not in view["field_lines"]
    assert cal["status"] == "refused" or "player_assisted" in cal["flags"], cal
    truth = json.loads(shared_dir.joinpath("data", "synthetic", "soccernet-v3-dev.truth.json").read_text())
    game = next(g for g in truth["games"] if g["match"] == system["game"]["match"])
    camera = next(v["camera"] for s in game["systems"] if s["action"] == "13.png"
                  for v in s["views"] if v["image"] == "13_2.png")
    run = project_pitch_polylines(Camera.from_soccernet(camera), w, view["height"])["Side line top"][0]

    def on_line(x: float) -> tuple[float, float]:  # the visible side line at image column x
        i = int(abs(run[:, 0] - x).argmin())
        return float(run[i, 0]), float(run[i, 1])

    _open(page, system, k)
    bar = page.locator(tid("view")).nth(k).locator(tid("lines-bar"))
    bar.locator(tid("line-class")).select_option("Side line top")
    bar.locator(tid("draw-line")).click()
    clicks = [on_line(f * w) for f in (0.2, 0.38, 0.55, 0.71, 0.86)]  # the middle of the line, as a first go
    for x, y in clicks:
        page.mouse.click(*_screen(page, k, x, y))
    page.screenshot(path=str(artifacts / "line-edit-drawing.png"))
    with _put(page) as answer:
        page.keyboard.press("Enter")
    assert answer.value.status == 200, answer.value.text()
    _saved(page, fid)
    state = _api(page, f"/api/frames/{fid}")
    assert state["field_lines"]["Side line top"] == [[pytest.approx(list(p), abs=0.06) for p in clicks]]
    page.screenshot(path=str(artifacts / "line-edit-first-go.png"))

    # not admitted yet: stretch the line to the image's edges, one end at a time, until it is
    for index, to_x in ((0, 0.05 * w), (len(clicks) - 1, 0.95 * w)):
        if state["calibration"]["admitted"]:
            break
        x, y = state["field_lines"]["Side line top"][0][index]
        tx, ty = on_line(to_x)
        handle = _point(page, fid, "Side line top", 0, index)
        handle.wait_for()
        with _put(page) as answer:
            page.mouse.move(*_screen(page, k, x, y))
            page.mouse.down()
            page.mouse.move(*_screen(page, k, (x + tx) / 2, (y + ty) / 2), steps=3)
            page.mouse.move(*_screen(page, k, tx, ty), steps=3)
            page.mouse.up()
        assert answer.value.status == 200, answer.value.text()
        _saved(page, fid)
        state = _api(page, f"/api/frames/{fid}")
    assert state["calibration"]["status"] == "calibrated", state["calibration"]
    assert state["calibration"]["admitted"] is True, state["calibration"]
    card = page.locator(tid("view")).nth(k)
    assert "· admitted" in card.locator(tid("view-calibration")).inner_text()
    sys_after = _api(page, f"/api/systems/{system['id']}")
    assert any(fid in (p["view_a"], p["view_b"]) for p in sys_after["triangulation"]["pairs"])
    page.screenshot(path=str(artifacts / "line-edit-fixed.png"))


def test_an_undo_after_someone_elses_edit_stops_with_the_conflict_notice(page, accounts, artifacts):
    """The page's edit, then someone else's edit of the same view: Ctrl+Z is refused (412, nothing stored),
    the conflict notice names their change, and the stack is emptied: a second Ctrl+Z does not send the refused undo
    again, it asks the server's history for the person's last edit (the one of this page), whose undo the server
    refuses in turn (409: changed since by someone else), said in the error bar; their lines stay. The page's keys are
    in the `?` overlay."""
    system = _system(page, "2.png", 4)
    k, view = _view(page, system, "2_2.png")
    fid = view["frame_id"]
    _open(page, system, k)
    cls = next(c for c, polys in view["field_lines"].items() if len(polys[0]) > 2)
    x, y = view["field_lines"][cls][0][1]
    with _put(page) as answer:
        page.mouse.move(*_screen(page, k, x, y))
        page.mouse.down()
        page.mouse.move(*_screen(page, k, x + 6, y + 4), steps=4)
        page.mouse.up()
    assert answer.value.status == 200, answer.value.text()
    _saved(page, fid)

    current = page.request.get(f"/api/frames/{fid}")
    theirs = current.json()["field_lines"]
    theirs[cls][0][1] = [x - 5, y]
    # the annotator's edit (their token, not this page's session: another person's change)
    other = page.request.put(f"/api/frames/{fid}/field-lines", data={"lines": theirs},
                             headers={"If-Match": current.headers["etag"], **accounts["annotator"].bearer})
    assert other.ok, other.text()

    puts: list[str] = []
    page.on("request", lambda r: puts.append(r.url) if r.method == "PUT" else None)
    with _put(page) as answer:
        page.keyboard.press("Control+z")
    assert answer.value.status == 412
    page.locator(tid("conflict")).wait_for()
    assert "field lines" in page.locator(tid("conflict-who")).inner_text()
    assert _api(page, f"/api/frames/{fid}")["field_lines"] == theirs  # nothing stored
    page.screenshot(path=str(artifacts / "line-edit-undo-conflict.png"))
    page.locator(tid("conflict-keep")).click()
    with page.expect_response(lambda r: r.request.method == "POST" and "/undo" in r.url) as older:
        page.keyboard.press("Control+z")  # the stack was emptied: the server's history is asked instead
    assert older.value.status == 409, older.value.text()
    page.locator(tid("error")).filter(has_text="refused").wait_for()  # the second Ctrl+Z's last step
    assert len(puts) == 1  # the refused undo was not sent again
    assert _api(page, f"/api/frames/{fid}")["field_lines"] == theirs

    page.keyboard.press("?")
    page.locator(tid("keys-help")).wait_for(state="visible")
    rows = page.locator("[data-testid=keys-help] .keys-grid").inner_text()
    for row in ("Ctrl+Z", "Ctrl+Shift+Z", "edit the selected view's field lines", "Shift+Del",
                "draw a new line of the chosen class"):
        assert row in rows, row
    page.screenshot(path=str(artifacts / "line-edit-keys.png"))


def test_a_label_far_off_where_its_players_placed_camera_sees_the_ball_snaps_with_one_key(page, artifacts):
    """8.png of the dev set's first game: its camera the players placed (three line classes), its ball label on the
    wrong spot, 700 px@1920 from where that camera sees the ball the other views agree on. The view offers the snap
    to that ball's box, and s places it, as for any label off the agreed ball."""
    system = next(s for s in (_api(page, f"/api/systems/{item['id']}") for item in
                              _api(page, "/api/systems?sort=name&limit=200")["items"] if item["name"] == "8.png")
                  if "Dunmore" in s["game"]["match"])
    k, view = _view(page, system, "8.png")
    assert "player_assisted" in view["calibration"]["flags"]
    (doubt,) = [d for d in system["doubts"] if d["frame_id"] == view["frame_id"] and d["kind"] == "ball_off_consensus"]
    box = doubt["suggestion"]["box"]
    page.goto(f"/systems/{system['id']}")
    shown = page.locator(tid("view")).nth(k)
    shown.locator(f"{tid('view-doubt')}[data-kind=ball_off_consensus]").wait_for()
    for size in ({"width": 1366, "height": 768}, {"width": 1920, "height": 1080}):
        page.set_viewport_size(size)
        page.screenshot(path=str(artifacts / f"players-placed-off-{size['width']}.png"))
    page.keyboard.press(str(k + 1))
    with page.expect_response(lambda r: r.request.method == "PATCH" and "/ball" in r.url) as answer:
        page.keyboard.press("s")
    assert answer.value.status == 200
    placed = _api(page, f"/api/frames/{view['frame_id']}")["ball"]["box"]
    assert placed == pytest.approx([round(v, 1) for v in box], abs=1e-6)
    page.locator(tid("toast")).filter(has_text="ball snapped to the suggested box").wait_for()


@pytest.mark.parametrize("size", [(1366, 768), (1440, 900), (1920, 1080)], ids=["1366x768", "1440x900", "1920x1080"])
def test_the_pass_count_arriving_never_moves_a_view_under_the_pointer(page, size):
    """The review pass's count ("pass 5 of 40 · 40 pending") comes after the views are drawn (its own request): it
    must land in room the top bar already has. At laptop widths it wrapped to four lines and grew the bar by 15 px
    while the annotator could already be clicking: a line drawn then had a point 0.5 screen px (1.75 image px) off
    where it was clicked (a full run met it), or 15 px off with the page at its top. The pass's requests are held
    here until the views are drawn and still, so the count surely comes last."""
    system = _system(page, "13.png", 4)
    page.set_viewport_size({"width": size[0], "height": size[1]})
    held: list = []
    released: list[bool] = []

    def hold(route) -> None:
        if released:
            route.continue_()
        else:
            held.append(route)

    page.route("**/api/passes**", hold)
    page.goto(f"/systems/{system['id']}")
    page.locator(tid("view")).nth(3).locator(tid("line-point")).first.wait_for()
    wait_for_steady_layout(page)

    def where() -> dict:
        return page.evaluate("""() => ({
          bar: document.querySelector('.topbar').getBoundingClientRect().height,
          views: [...document.querySelectorAll('[data-testid=view-svg]')].map((s) => {
            const r = s.getBoundingClientRect(); return [r.left, r.top, r.width, r.height]; }),
          side: document.querySelector('.side').getBoundingClientRect().top,
          count: document.querySelector('[data-testid=pass-progress]').textContent })""")

    before = where()
    assert held and before["count"] == "", before["count"]  # the count is still on its way
    released.append(True)
    for route in held:
        route.continue_()
    page.wait_for_function("""() => /pass \\d+ of \\d+ · \\d+ pending/.test(
        document.querySelector('[data-testid=pass-progress]').textContent)""")
    wait_for_steady_layout(page)
    after = where()
    assert after["bar"] == pytest.approx(before["bar"], abs=0.01)
    assert after["side"] == pytest.approx(before["side"], abs=0.01)
    for b, a in zip(before["views"], after["views"], strict=True):
        assert a == pytest.approx(b, abs=0.01)
    count = page.locator(tid("pass-progress"))
    box, bar = count.bounding_box(), page.locator(".topbar").bounding_box()
    assert box["y"] >= bar["y"] and box["y"] + box["height"] <= bar["y"] + bar["height"]  # wholly in the bar
    assert count.evaluate("(e) => e.scrollHeight <= e.clientHeight + 1"), "the count is cut"
