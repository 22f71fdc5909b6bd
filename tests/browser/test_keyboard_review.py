"""A review of the systems of ``soccernet-v3-dev`` by keyboard only, in Chromium, against the real server
(issue 16): the queue, Enter, then on every system each view's calibration decided by keys and the system
accepted with ``a``, until the last one (``benchmarks/keyboard_review.py``'s walk). Every decision is checked
through the API; the time per system is printed (the benchmark reports it on its own server).

The quick tier walks the queue's first :data:`FIRST` systems, the others decided (rejected) through the API
beforehand and the walk begun on the queue of pending systems: its review pass holds those alone, so the walk still
ends by itself on the last of them, as the whole queue's does. The whole queue's 40 systems are the ``slow`` walk."""
from __future__ import annotations

import pytest

from benchmarks.keyboard_review import LAST_SYSTEM_TEXT, review_by_keyboard, summary
from tests.browser.support import api_json as _api
from tests.browser.support import api_write, seed_dev_set, tid
from tests.conftest import sizes

pytestmark = pytest.mark.browser

#: The dev set's systems (2 games of 20).
SYSTEMS = 40
#: How many of the queue's first systems the quick walk reviews.
FIRST = 5


@pytest.fixture(scope="module")
def seeded_settings(seeded_databases, shared_dir, tmp_path_factory: pytest.TempPathFactory):
    """This module's database: ``soccernet-v3-dev`` (2 games, 40 systems) imported through the importer
    (the browser fixtures of conftest.py serve it and log the admin in)."""
    return seed_dev_set(seeded_databases, shared_dir, tmp_path_factory.mktemp("kb"))


def _set_status(page, system_id: int, status: str) -> None:
    etag = page.request.get(f"/api/systems/{system_id}").headers["etag"]
    answer = api_write(page, "POST", f"/api/systems/{system_id}/review", data={"status": status},
                       headers={"If-Match": etag})
    assert answer.ok, answer.text()


@pytest.mark.parametrize("walked", sizes(FIRST, SYSTEMS))
def test_the_dev_systems_reviewed_by_keyboard_only(page, artifacts, capsys, walked):
    queue = _api(page, "/api/systems?limit=100")
    assert queue["total"] == SYSTEMS and queue["counts"]["pending"] == SYSTEMS
    order = [s["id"] for s in queue["items"]]
    walk, others = order[:walked], order[walked:]
    try:
        for system_id in others:  # decided before the walk: the pass of pending systems leaves them out
            _set_status(page, system_id, "rejected")
        assert [s["id"] for s in _api(page, "/api/systems?status=pending&limit=100")["items"]] == walk

        reviews = review_by_keyboard(page, "/?status=pending" if others else "/")

        page.screenshot(path=str(artifacts / "keyboard-review-last.png"))
        assert [r.system_id for r in reviews] == walk  # the queue's order, every system to walk
        after = _api(page, "/api/systems?limit=100")
        assert after["counts"] == {"pending": 0, "accepted": len(walk), "rejected": len(others), "needs_fix": 0,
                                   "fixed": 0}
        for r in reviews:
            system = _api(page, f"/api/systems/{r.system_id}")
            assert system["review"]["status"] == "accepted"
            assert len(system["views"]) == r.views and r.keys[-1] in ("a", "Enter")
            for i, v in enumerate(system["views"]):
                admitted = v["calibration"].get("admitted") is True and v["calibration"].get("camera") is not None
                assert v["review"]["calibration"]["status"] == ("accepted" if admitted else "needs_fix"), \
                    (r.system_id, i)
                assert v["review"]["status"] == "pending"  # the ball's decision was not touched
        assert page.locator(tid("toast")).text_content().endswith(LAST_SYSTEM_TEXT)  # the pass's end (issue 28)
    finally:
        for system_id in order:  # the queue as it was, for the module's other walk
            _set_status(page, system_id, "pending")
    s = summary(reviews)
    with capsys.disabled():
        print(f"\nkeyboard review: {s['systems']} systems, {s['views']} views, {s['keys']} keys; per system median "
              f"{s['median_s']:.2f} s, p95 {s['p95_s']:.2f} s; whole queue {s['total_s']:.1f} s")
