"""The detector benchmark page (static/monocular.html) in Chromium against the real server and the demo
dataset: reached from the queue's top bar, it uploads a zip of YOLO predictions made from the server's
own YOLO export and shows the report (AP@0.5 = 1 for the exported boxes themselves) and the curve."""
from __future__ import annotations

import io
import zipfile

import pytest

pytestmark = pytest.mark.browser


def _predictions_zip(page, factor: float = 1.0) -> bytes:
    """YOLO predictions (conf 0.8) of the ball boxes of ``GET /api/exports/yolo?all=true``."""
    response = page.request.get("/api/exports/yolo?all=true")
    assert response.ok, response.status
    out = io.BytesIO()
    with zipfile.ZipFile(io.BytesIO(response.body())) as zin, zipfile.ZipFile(out, "w") as zout:
        for name in zin.namelist():
            if name.startswith("labels/") and name.endswith(".txt"):
                rows = [line.split() for line in zin.read(name).decode().splitlines()]
                zout.writestr(name, "".join(f"0 {cx} {cy} {float(w) * factor} {float(h) * factor} 0.8\n"
                                            for c, cx, cy, w, h in rows if c == "0"))
    return out.getvalue()


def test_the_benchmark_page_shows_the_report_of_an_upload(page, artifacts):
    page.goto("/")
    page.click("[data-testid=link-monocular]")
    page.wait_for_url("**/static/monocular.html")
    assert page.locator("[data-testid=report]").is_hidden()
    page.set_input_files("[data-testid=predictions-file]",
                         {"name": "pred.zip", "mimeType": "application/zip", "buffer": _predictions_zip(page)})
    page.check("[data-testid=include-all]")
    page.click("[data-testid=evaluate]")
    page.wait_for_selector("[data-testid=report]:not([hidden])")
    assert page.text_content("[data-testid=ap50-all]") == "1.0000"
    localised = page.locator("[data-testid=row-all] td").nth(5).text_content()
    assert int(localised) > 0
    assert page.locator("[data-testid=curve-all]").count() == 1
    page.screenshot(path=str(artifacts / "monocular-report.png"), full_page=True)


def test_an_unreadable_upload_shows_the_error(page):
    page.goto("/static/monocular.html")
    page.set_input_files("[data-testid=predictions-file]",
                         {"name": "r.json", "mimeType": "application/json", "buffer": b"{broken"})
    page.check("[data-testid=include-all]")
    page.click("[data-testid=evaluate]")
    page.wait_for_selector("[data-testid=error].visible")
    assert "predictions" in page.text_content("[data-testid=error] .msg")
    assert page.locator("[data-testid=report]").is_hidden()
