"""A detector's checked box on the system page (Playwright, Chromium): after ``POST /api/imports`` of predictions
(kind ``predictions``) the view nobody labelled shows the ``ball_detected`` doubt, its box drawn in its own colour
with the detector's name and score, and ``s`` places it as a placement to confirm."""
from __future__ import annotations

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
    page.screenshot(path=str(artifacts / "detector-box.png"), full_page=True)
    shown.locator(tid("view-doubt")).first.click()
    page.keyboard.press("s")

    def placed():
        ball = _api(page, f"/api/frames/{doubt['frame_id']}")["ball"]
        return ball if ball and ball.get("box") else None

    ball = wait_until(placed, timeout_s=60)
    assert ball["provenance"]["detector"] == "yolo-sn-ball" and ball["provenance"]["score"] == 0.66
    assert [round(v) for v in ball["box"]] == [round(v) for v in box]
