"""A detector's checked box on the system page (Playwright, Chromium): after ``POST /api/imports`` of predictions
(kind ``predictions``) the view nobody labelled shows the ``ball_detected`` doubt, its box drawn in its own colour
with the detector's name and score, and ``s`` places it as a placement to confirm."""
from __future__ import annotations

import re

import pytest

from tests.browser.support import api_json as _api
from tests.browser.support import api_write, tid, wait_for_job, wait_until

pytestmark = pytest.mark.browser


def _consensus_missing(page) -> tuple[dict, dict]:
    """A demo system whose ``ball_missing`` comes from the other views' agreed ball (a box the check can meet)."""
    for item in _api(page, "/api/systems?doubt=ball_missing&limit=500")["items"]:
        system = _api(page, f"/api/systems/{item['id']}")
        for d in system["doubts"]:
            if d["kind"] == "ball_missing" and (d["evidence"] or {}).get("code") == "consensus":
                return system, d
    raise AssertionError("the demo data should have a ball_missing doubt from the other views' consensus")


def test_a_checked_detection_is_drawn_with_its_score_and_placed_with_its_key(page, seeded_settings, artifacts):
    system, doubt = _consensus_missing(page)
    k = next(i for i, v in enumerate(system["views"]) if v["frame_id"] == doubt["frame_id"])
    view = system["views"][k]
    box = doubt["suggestion"]["box"]
    far = [box[0] + 80, box[1], box[2] + 80, box[3]]
    g = system["game"]
    csv = "league,season,match,image,x1,y1,x2,y2,score\n" + "".join(
        f"{g['league']},{g['season']},{g['match']},{view['name']},{b[0]},{b[1]},{b[2]},{b[3]},{score}\n"
        for b, score in ((far, 0.95), (box, 0.66)))
    path = seeded_settings.data_root / "ui-detector.csv"
    path.write_text(csv)
    answer = api_write(page, "POST", "/api/imports", data={"kind": "predictions", "path": str(path),
                                                             "source": "yolo-sn-ball"})
    assert answer.status == 202, answer.text()
    url = answer.json()["url"]
    job = wait_for_job(page, url)
    assert job["state"] == "done", job
    system = _api(page, f"/api/systems/{system['id']}")
    kinds = [d["kind"] for d in system["doubts"] if d["frame_id"] == doubt["frame_id"] and d["accuses_label"]]
    assert kinds == ["ball_detected"]  # one suggestion for the view: the detector's box

    page.goto(f"/systems/{system['id']}")
    shown = page.locator(tid("view")).nth(k)
    shown.locator(tid("detected-box")).wait_for()
    assert "yolo-sn-ball 0.66" in shown.locator("text.det-score").first.text_content()
    card = shown.locator(f"{tid('view-doubt')}[data-kind=ball_detected]")
    assert card.is_visible() and "Place yolo-sn-ball's box (score 0.66)" in card.inner_text()
    doubt_words = card.inner_text()
    page.screenshot(path=str(artifacts / "detector-box.png"), full_page=True)
    shown.locator(tid("view-doubt")).first.click()
    page.keyboard.press("s")

    def placed():
        ball = _api(page, f"/api/frames/{doubt['frame_id']}")["ball"]
        return ball if ball and ball.get("box") else None

    ball = wait_until(placed, timeout_s=60)
    assert ball["provenance"]["detector"] == "yolo-sn-ball" and ball["provenance"]["score"] == 0.66
    assert [round(v) for v in ball["box"]] == [round(v) for v in box]

    # one number for how far the placed box lies from the 3D ball: what the doubt said before the key, what the view
    # shows after it (the placement waiting for Enter), and what it shows once confirmed
    def off_by(text: str) -> float:
        return float(re.match(r"([0-9.]+) px", text).group(1))

    said = re.search(r"confirmed, it lies ([0-9.]+) px", doubt_words).group(1)
    error = shown.locator(tid("view-reproj-error"))
    error.filter(has_text="once confirmed").wait_for()
    waiting = error.inner_text()
    assert abs(off_by(waiting) - float(said)) <= 0.06  # the key sends the box to 0.1 px
    card = shown.locator(f"{tid('view-doubt')}[data-kind=suggested_label]")
    assert f"confirmed, it lies {waiting.split(' px')[0]} px" in card.inner_text()
    for size in ({"width": 1366, "height": 768}, {"width": 1920, "height": 1080}):
        page.set_viewport_size(size)
        page.screenshot(path=str(artifacts / f"detector-box-placed-{size['width']}.png"))
    with page.expect_response(lambda r: r.request.method == "PATCH" and "/ball" in r.url) as answer:
        page.keyboard.press("Enter")
    assert answer.value.status == 200
    error.filter(has_not_text="once confirmed").wait_for()
    assert error.inner_text() == waiting.replace(" once confirmed", "")
    confirmed = _api(page, f"/api/systems/{system['id']}")
    view = next(v for v in confirmed["views"] if v["frame_id"] == doubt["frame_id"])
    assert view["reprojection_error_px"] == pytest.approx(off_by(waiting), abs=0.005)
