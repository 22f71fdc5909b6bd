"""The detector benchmark page (static/monocular.html) and the dataset statistics page (static/stats.html) in
Chromium against the real server and the demo dataset: reached from the queue's top bar, the benchmark page uploads
a zip of YOLO predictions made from the server's own YOLO export and shows the report (AP@0.5 = 1 for the exported
boxes themselves) and the curve, and the paper's Table 1 once precise boxes are stored (the system page then draws
them); the statistics page draws ``/api/stats`` (issue 19)."""
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


def _store_precise_boxes(settings, tmp_path) -> dict[int, list[float]]:
    """Precise boxes for every view of the demo with a ball box: its box shrunk by 1 px on each side (stored as
    ``v3d import precise-boxes`` does). Returns frame id -> precise box."""
    import csv

    import sqlalchemy as sa

    from app.db.models import BallLabel, Frame
    from app.db.session import make_engine, make_session_factory
    from app.services.evaluation.boxes import PRECISE_COLUMNS, store_precise_boxes

    engine = make_engine(settings.database_url)
    try:
        with make_session_factory(engine)() as session:
            frames = session.scalars(sa.select(Frame).join(BallLabel).where(BallLabel.box.is_not(None))).all()
            boxes = {f.id: [f.ball_label.box[0] + 1, f.ball_label.box[1] + 1, f.ball_label.box[2] - 1,
                            f.ball_label.box[3] - 1] for f in frames}
            path = tmp_path / "precise.csv"
            with path.open("w", newline="") as fh:
                w = csv.writer(fh)
                w.writerow(PRECISE_COLUMNS)
                for f in frames:
                    g = f.system.game
                    w.writerow([g.league, g.season, g.match, f.name, *boxes[f.id]])
            assert store_precise_boxes(session, path) >= len(frames)
            return {fid: b for fid, b in boxes.items()}
    finally:
        engine.dispose()


def test_table_1_on_the_benchmark_page_and_the_precise_box_on_the_system_page(page, seeded_settings, tmp_path,
                                                                             artifacts):
    from tests.browser.support import api_json, tid

    page.goto("/static/monocular.html")
    page.wait_for_selector("[data-testid=boxes-note]:not(:empty)")
    assert "v3d import precise-boxes" in page.text_content(tid("boxes-note"))  # none stored yet
    precise = _store_precise_boxes(seeded_settings, tmp_path)
    report = api_json(page, "/api/evaluations/boxes?all=true")
    assert report["views"] >= len(precise) and report["original"]["n"] == len(precise) > 0
    page.check(tid("boxes-all"))
    page.click(tid("boxes-score"))
    page.wait_for_function("(t) => document.querySelector('[data-testid=boxes-iou-original]')?.textContent === t",
                           arg=f"{report['original']['iou']:.3f}")
    for kind in ("original", "optimised", "refined"):
        r = report[kind]
        assert page.text_content(tid(f"boxes-iou-{kind}")) == ("–" if r["iou"] is None else f"{r['iou']:.3f}")
        assert page.text_content(tid(f"boxes-size-{kind}")) == (
            "–" if r["size_error_pct"] is None else f"{r['size_error_pct']:.1f}")
    page.locator(tid("boxes")).screenshot(path=str(artifacts / "table1-boxes.png"))

    # the system page draws the precise box of each view that has one, where its pixels say
    frame_id = next(iter(precise))
    frame = api_json(page, f"/api/frames/{frame_id}")
    assert frame["precise_box"] == precise[frame_id]
    page.goto(f"/systems/{frame['system_id']}")
    rect = page.locator(f"[data-testid=view][data-frame-id='{frame_id}'] [data-testid=precise-box]")
    rect.wait_for(state="attached")
    x1, y1, x2, y2 = precise[frame_id]
    assert [float(rect.get_attribute(a)) for a in ("x", "y", "width", "height")] == pytest.approx(
        [x1, y1, x2 - x1, y2 - y1])
    view = page.locator(f"[data-testid=view][data-frame-id='{frame_id}']")
    view.screenshot(path=str(artifacts / "precise-box-view.png"))


def test_the_statistics_page_draws_the_stats_of_the_api(page, artifacts):
    from tests.browser.support import api_json, tid

    page.goto("/")
    page.click(tid("link-stats"))
    page.wait_for_url("**/static/stats.html")
    page.wait_for_selector("[data-testid=stats]:not([hidden])")
    stats = api_json(page, "/api/stats")
    for kind, k in stats["kinds"].items():
        row = page.locator(tid(f"count-{kind}-all"))
        assert row.locator(tid("systems")).text_content() == f"{k['systems']:,}"
        assert row.locator(tid("images")).text_content() == f"{k['images']:,}"
        for split, c in k["splits"].items():
            images = page.locator(tid(f"count-{kind}-{split}")).locator(tid("images"))
            assert images.text_content() == f"{c['images']:,}"
    # the systems per tier of what backs their 3D ball, every tier in the API's order
    assert page.eval_on_selector_all("[data-testid=evidence] tbody tr", "(rs) => rs.map((r) => r.dataset.testid)") == [
        f"evidence-{tier}" for tier in stats["ball_evidence"]]
    for tier, n in stats["ball_evidence"].items():
        assert page.locator(tid(f"evidence-{tier}")).locator(tid("systems")).text_content() == f"{n:,}"
    # the counts plot: one segment per non-empty class of images of each kind and split
    segments = sum(1 for k in stats["kinds"].values() for c in k["splits"].values()
                   for n in (c["admitted_images"], c["calibrated_images"] - c["admitted_images"],
                             c["images"] - c["calibrated_images"]) if n > 0)
    assert page.locator("[data-testid=plot-counts] rect.seg").count() == segments
    # Fig. 3: a point per threshold for each kind with a kept system, and the threshold in force
    drawn = [kind for kind, sweep in stats["jac_sweep_by_kind"].items() if sweep[0]["systems_kept"] > 0]
    assert drawn and page.locator(tid("sweep-point")).count() == 21 * len(drawn)
    assert page.locator(tid("threshold")).count() == 1
    # every histogram: one bar per bin, the bars' counts and the tail add up to n
    for name, hist in stats["distributions"].items():
        bars = page.locator(f"[data-testid=plot-{name}] [data-testid=bar]")
        assert bars.count() == len(hist["counts"]), name
        assert sum(int(bars.nth(i).get_attribute("data-count"))
                   for i in range(bars.count())) + hist["above"] == hist["n"]
        assert f"n = {hist['n']:,}" in page.locator(f"[data-testid=plot-{name}]").text_content()
    page.screenshot(path=str(artifacts / "stats-page.png"), full_page=True)
