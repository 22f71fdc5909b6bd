"""The system page shows each view's calibration uncertainty (issue 17): the camera's standard deviations
from the line fit, as the API gives them under ``calibration.uncertainty``. Screenshot in ``test-artifacts/``."""
from __future__ import annotations

import pytest

from tests.browser.support import api_json as _api
from tests.browser.support import tid

pytestmark = pytest.mark.browser


def _fmt(v, digits: int) -> str:
    return "—" if v is None else f"{v:.{digits}f}"


def test_system_page_shows_the_calibration_uncertainty(page, artifacts):
    page.goto("/")
    page.locator(tid("queue-row")).first.wait_for()
    listing = _api(page, "/api/systems?sort=name&limit=50")
    system = None
    for item in listing["items"]:
        candidate = _api(page, f"/api/systems/{item['id']}")
        if any((v["calibration"] or {}).get("uncertainty") for v in candidate["views"]):
            system = candidate
            break
    assert system is not None, "no system with a view calibrated from its lines"
    page.goto(f"/systems/{system['id']}")
    views = page.locator(tid("view"))
    views.first.wait_for()
    shown = 0
    for i, v in enumerate(system["views"]):
        u = (v["calibration"] or {}).get("uncertainty")
        cell = views.nth(i).locator(tid("view-uncertainty"))
        if u is None:
            assert cell.count() == 0
            continue
        p = u["position_m"]
        expected = (f"where x {_fmt(p['x'], 2)}, y {_fmt(p['y'], 2)}, z {_fmt(p['z'], 2)} m · aim pan "
                    f"{_fmt(u['pan_deg'], 2)}°, tilt {_fmt(u['tilt_deg'], 2)}°, roll {_fmt(u['roll_deg'], 2)}° · "
                    f"zoom {_fmt(u['focal_px'], 0)} px")
        assert cell.inner_text() == expected
        shown += 1
    assert shown >= 1
    views.nth(next(i for i, v in enumerate(system["views"]) if (v["calibration"] or {}).get("uncertainty"))) \
        .locator(tid("view-uncertainty")).scroll_into_view_if_needed()
    page.screenshot(path=str(artifacts / "calibration-uncertainty.png"), full_page=True)
