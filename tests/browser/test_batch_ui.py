"""Accept the vouched after a sample, in Chromium against the real server: from the queue, "Accept the vouched after a
sample" (75 % sure that at most 50 % are wrong: a sample of 2 of the 4 vouched) opens a review pass over the sample,
counted "sample 1 of 2"; two ``a`` typed ahead decide both; the end of the sample offers "accept the other 2" with the
plan in words, and its button accepts them, each audited with the batch's id. A second batch, its sample's pass
resumed from the queue, whose sampled system is rejected (``r``) ends there, saying so and naming it; nothing else of
it is accepted."""
from __future__ import annotations

import re
import sqlite3

import pytest
import sqlalchemy as sa

from tests.browser.support import api_json, settled, tid

pytestmark = pytest.mark.browser

_SAMPLE_URL = re.compile(r"/systems/(\d+)\?.*batch=(\d+)")


def _vouch(seeded_settings, ids: list[int]) -> None:
    """Make ``ids`` the pending systems vouched for in the served database, the other pending ones the rule vouched
    for unconfirmed (the tier's computation is not this test's subject: the batch's systems are known)."""
    path = sa.make_url(seeded_settings.database_url).database
    with sqlite3.connect(str(path)) as conn:
        conn.execute("UPDATE systems SET ball_evidence = 'unconfirmed' WHERE ball_evidence = 'vouched' "
                     "AND review_status = 'pending'")
        conn.executemany("UPDATE systems SET ball_evidence = 'vouched' WHERE id = ?", [(i,) for i in ids])


def _start(page, confidence: str, wrong: str) -> int:
    """Start a batch from the queue of the pending systems without a label doubt; the sample's first system shown.
    Answers the batch id."""
    page.goto("/?status=pending&doubt=none")
    page.locator(tid("queue-row")).first.wait_for()
    page.locator(tid("batch-start")).wait_for()
    page.fill(tid("batch-confidence"), confidence)
    page.fill(tid("batch-wrong"), wrong)
    page.click(tid("batch-start"))
    page.wait_for_url(_SAMPLE_URL)
    page.locator(tid("pass-progress")).filter(has_text=re.compile(r"sample 1 of \d+")).wait_for()
    settled(page)
    return int(_SAMPLE_URL.search(page.url).group(2))


def test_the_vouched_are_accepted_after_a_sample_and_a_rejected_sample_ends_its_batch(page, seeded_settings):
    clean = [s["id"] for s in api_json(page, "/api/systems?status=pending&doubt=none&sort=name&limit=100")["items"]]
    assert len(clean) >= 6, "the demo has enough systems without a label doubt"
    first, second = sorted(clean[:4]), sorted(clean[4:6])
    _vouch(seeded_settings, first)

    batch_id = _start(page, "75", "50")
    batch = api_json(page, f"/api/batches/{batch_id}")
    assert batch["systems"] == first and len(batch["sample"]) == 2
    assert int(_SAMPLE_URL.search(page.url).group(1)) == batch["sample"][0]
    assert page.locator(tid("pass-progress")).inner_text().startswith("sample 1 of 2")

    page.keyboard.press("a")  # both typed ahead: the second waits for the next sampled system, then decides it
    page.keyboard.press("a")
    plan = page.locator(tid("batch-plan"))
    plan.wait_for()
    settled(page)
    assert "if none of these 2 is wrong, you can be 75 % sure that at most 50 % of the 4 are" in plan.inner_text()
    accept = page.locator(tid("batch-accept"))
    assert accept.inner_text() == "accept the other 2"
    assert all(api_json(page, f"/api/systems/{sid}")["review"]["status"] == "accepted" for sid in batch["sample"])
    accept.click()
    page.locator(tid("batch-accepted")).filter(has_text="2 accepted after the sample").wait_for()
    for sid in (i for i in first if i not in batch["sample"]):
        assert api_json(page, f"/api/systems/{sid}")["review"]["status"] == "accepted"
        entry = api_json(page, f"/api/audit?system_id={sid}&limit=1")["items"][0]
        assert entry["after"]["review"]["batch_id"] == batch_id
    assert api_json(page, f"/api/batches/{batch_id}")["state"] == "accepted"
    # an accepted one's page says the batch accepted it after a sample, with the plan; a sampled one's does not
    other = next(i for i in first if i not in batch["sample"])
    page.goto(f"/systems/{other}")
    said = page.locator(tid("review-batch"))
    said.filter(has_text=f"Accepted in batch {batch_id} after a sample of 2 of 4").wait_for()
    assert "you can be 75 % sure that at most 50 % of the 4 are" in said.inner_text()
    page.goto(f"/systems/{batch['sample'][0]}")
    page.locator(tid("system-status")).filter(has_text="accepted").wait_for()
    assert page.locator(tid("review-batch")).is_hidden()

    _vouch(seeded_settings, second)
    batch_id = _start(page, "50", "50")  # one sampled of the two
    batch = api_json(page, f"/api/batches/{batch_id}")
    assert batch["systems"] == second and len(batch["sample"]) == 1
    rejected = batch["sample"][0]
    page.goto("/")  # left for the queue, the sample's pass is resumed from there
    resume = page.locator(tid("resume-pass"))
    resume.wait_for()
    assert resume.inner_text() == "resume sample 1/1" and "sort=" not in (resume.get_attribute("href") or "")
    resume.click()
    page.wait_for_url(_SAMPLE_URL)
    page.locator(tid("pass-progress")).filter(has_text="sample 1 of 1").wait_for()
    settled(page)
    page.keyboard.press("r")
    ended = page.locator(tid("batch-ended"))
    ended.wait_for()
    settled(page)
    said = ended.inner_text()
    assert f"system {rejected} was rejected" in said and "other 1 system stays pending" in said
    assert page.locator(tid("batch-accept")).count() == 0
    assert [api_json(page, f"/api/systems/{sid}")["review"]["status"] for sid in second] == [
        "rejected" if sid == rejected else "pending" for sid in second]
