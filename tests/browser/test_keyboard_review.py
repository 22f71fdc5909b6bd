"""A review of the 40 systems of ``soccernet-v3-dev`` by keyboard only, in Chromium, against the real server
(issue 16): the queue, Enter, then on every system each view's calibration decided by keys and the system
accepted with ``a``, until the last one (``benchmarks/keyboard_review.py``'s walk). Every decision is checked
through the API; the time per system is printed (the benchmark reports it on its own server)."""
from __future__ import annotations

import pytest

from benchmarks.keyboard_review import LAST_SYSTEM_TEXT, review_by_keyboard, summary
from tests.browser.support import api_json as _api
from tests.browser.support import seed_dev_set, tid

pytestmark = pytest.mark.browser


@pytest.fixture(scope="module")
def seeded_settings(seeded_databases, shared_dir, tmp_path_factory: pytest.TempPathFactory):
    """This module's database: ``soccernet-v3-dev`` (2 games, 40 systems) imported through the importer
    (the browser fixtures of conftest.py serve it and log the admin in)."""
    return seed_dev_set(seeded_databases, shared_dir, tmp_path_factory.mktemp("kb"))


def test_the_40_dev_systems_reviewed_by_keyboard_only(page, artifacts, capsys):
    queue = _api(page, "/api/systems?limit=100")
    assert queue["total"] == 40 and queue["counts"]["pending"] == 40

    reviews = review_by_keyboard(page, "/")

    page.screenshot(path=str(artifacts / "keyboard-review-last.png"))
    assert [r.system_id for r in reviews] == [s["id"] for s in queue["items"]]  # the queue's order, every system
    after = _api(page, "/api/systems?limit=100")
    assert after["counts"] == {"pending": 0, "accepted": 40, "rejected": 0, "needs_fix": 0, "fixed": 0}
    for r in reviews:
        system = _api(page, f"/api/systems/{r.system_id}")
        assert system["review"]["status"] == "accepted"
        assert len(system["views"]) == r.views and r.keys[-1] in ("a", "Enter")
        for i, v in enumerate(system["views"]):
            admitted = v["calibration"].get("admitted") is True and v["calibration"].get("camera") is not None
            assert v["review"]["calibration"]["status"] == ("accepted" if admitted else "needs_fix"), (r.system_id, i)
            assert v["review"]["status"] == "pending"  # the ball's decision was not touched
    assert page.locator(tid("toast")).text_content().endswith(LAST_SYSTEM_TEXT)  # the pass's end (issue 28)
    s = summary(reviews)
    with capsys.disabled():
        print(f"\nkeyboard review: {s['systems']} systems, {s['views']} views, {s['keys']} keys; per system median "
              f"{s['median_s']:.2f} s, p95 {s['p95_s']:.2f} s; whole queue {s['total_s']:.1f} s")
