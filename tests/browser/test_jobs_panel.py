"""The queue page's jobs panel in Chromium against the real server and its real job runner: a full
recompute and an export queued while the page is open appear with their progress or outcome, the
export with its download link, a failing import with its message."""
from __future__ import annotations

import pytest

from tests.browser.support import api_write, tid

pytestmark = pytest.mark.browser


def test_jobs_panel_follows_jobs_queued_while_the_page_is_open(page, tmp_path_factory):
    page.goto("/")
    page.wait_for_selector(f"{tid('queue')} tbody tr")
    assert page.locator(tid("jobs")).is_hidden()
    recompute = api_write(page, "POST", "/api/recompute")
    assert recompute.status == 202
    export = api_write(page, "POST", "/api/exports/soccernet-v3d", {"all": True})
    assert export.status == 202
    missing = tmp_path_factory.mktemp("empty-import")
    failing = api_write(page, "POST", "/api/imports", {"kind": "soccernet-v3", "path": str(missing)})
    assert failing.status == 202
    ids = [r.json()["id"] for r in (recompute, export, failing)]
    for job_id, state in zip(ids, ("done", "done", "failed"), strict=False):
        page.wait_for_selector(f'{tid("job")}[data-id="{job_id}"][data-state="{state}"]', timeout=120_000)
    panel = page.locator(tid("jobs"))
    assert panel.is_visible()
    row = panel.locator(f'{tid("job")}[data-id="{ids[1]}"]')
    assert row.locator(tid("job-download")).get_attribute("href") == f"/api/jobs/{ids[1]}/result"
    message = panel.locator(f'{tid("job")}[data-id="{ids[2]}"] {tid("job-message")}').inner_text()
    assert "no Labels-v3.json found" in message
    assert "full recompute" in panel.locator(f'{tid("job")}[data-id="{ids[0]}"]').inner_text()
