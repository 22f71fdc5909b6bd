"""The team's loop in Chromium, a reviewer (rev) and two annotators (ana, ben) on the demo dataset: ana moves a ball
label; rev pins a comment on that view from the system page (a click on the frame) and marks it needs fix (`f`); ana's
queue shows **To fix 1**, her system page the comment at its point and in its thread; `Shift+C` selects its view; she
resolves it and sends the system back as fixed; rev's queue shows **To re-review 1** and the statistics page her row.
Screenshots of the queue, the system page with its pinned comment and the annotator table at 1366x768 and 1920x1080
go to ``test-artifacts/team-loop/``."""
from __future__ import annotations

from typing import Optional

import pytest

from tests.accounts import PASSWORD, Account
from tests.browser.support import log_in, tid, wait_for_steady_layout

pytestmark = pytest.mark.browser

SIZES = {"1366x768": {"width": 1366, "height": 768}, "1920x1080": {"width": 1920, "height": 1080}}


@pytest.fixture(scope="module")
def team(seeded_settings) -> dict:
    """rev (reviewer), ana and ben (annotators); ana's 3 px move of the second view's ball in the first system with
    two labelled views (through the service, as her edit from the page would be)."""
    import sqlalchemy as sa

    from app.db.models import System
    from app.db.session import make_engine, make_session_factory
    from app.services.accounts.users import create_user
    from app.services.curation.editing import update_ball_label

    engine = make_engine(seeded_settings.database_url)
    out: dict = {}
    try:
        with make_session_factory(engine)() as session:
            for name, role in (("rev", "reviewer"), ("ana", "annotator"), ("ben", "annotator")):
                _, token = create_user(session, name, role, PASSWORD)
                out[name] = Account(name, role, PASSWORD, token)
            system = next(s for s in session.scalars(sa.select(System).order_by(System.id))
                          if sum(1 for f in s.frames if f.ball_label is not None and f.ball_label.box) >= 2)
            frame = [f for f in system.frames if f.ball_label is not None and f.ball_label.box][1]
            box = list(frame.ball_label.box)
            out["system_id"], out["frame_id"] = system.id, frame.id
            update_ball_label(session, frame.id, box=[box[0] + 3, box[1], box[2] + 3, box[3]],
                              settings=seeded_settings, actor="ana")
    finally:
        engine.dispose()
    return out


def _page_of(browser, server_url, account: Account, size: str = "1366x768"):
    context = browser.new_context(viewport=SIZES[size], base_url=server_url)
    p = context.new_page()
    p.errors = []
    p.on("pageerror", lambda exc: p.errors.append(str(exc)))
    p.goto("/")
    log_in(p, account)
    p.wait_for_url(f"{server_url}/")
    return context, p


def _shoot(p, shots, what: str) -> None:
    for size, viewport in SIZES.items():
        p.set_viewport_size(viewport)
        # the window at its new size, and the page laid out again for it (what its screenshot shows)
        p.wait_for_function("([w, h]) => innerWidth === w && innerHeight === h",
                            arg=[viewport["width"], viewport["height"]])
        wait_for_steady_layout(p)
        p.screenshot(path=str(shots / f"{what}-{size}.png"))
    p.set_viewport_size(SIZES["1366x768"])


def test_needs_fix_reaches_ana_with_the_comment_and_comes_back_fixed(browser, server_url, team, artifacts):
    shots = artifacts / "team-loop"
    shots.mkdir(exist_ok=True)
    sid = team["system_id"]
    # ----- rev pins a comment on ana's view (a click on its frame) and marks the system needs fix
    rev_context, rev = _page_of(browser, server_url, team["rev"])
    try:
        rev.goto(f"/systems/{sid}")
        view = rev.locator(f'{tid("view")}[data-frame-id="{team["frame_id"]}"]')
        view.wait_for()
        # the page's cards drawn: the view no longer moves under the click
        rev.wait_for_function("() => !document.body.classList.contains('loading')")
        wait_for_steady_layout(rev, tid("view"))
        rev.click(tid("comment-pin-start"))
        rev.wait_for_selector("body.pinning")
        frame = view.locator(tid("view-svg"))
        box = frame.bounding_box()
        # a position within the element, resolved when the click happens (a layout shift meanwhile cannot miss it)
        frame.click(position={"x": box["width"] * 0.4, "y": box["height"] * 0.5})
        rev.locator(tid("comment-form")).wait_for()
        rev.fill(tid("comment-text"), "the box sits on the shadow")
        rev.press(tid("comment-text"), "Enter")
        rev.locator(tid("review-comment")).first.wait_for()
        assert rev.locator(tid("review-comment-pin")).count() == 1
        rev.fill(tid("comment"), "the box sits on the shadow")
        rev.locator("body").click(position={"x": 5, "y": 5})
        rev.keyboard.press("f")
        rev.wait_for_function(f"() => !location.pathname.endsWith('/systems/{sid}')"
                              " || document.querySelector('[data-testid=system-status]').textContent !== 'pending'")
        assert rev.errors == []
    finally:
        rev_context.close()

    # ----- ana: To fix 1 on her queue; the comment on the system page, at its point and in its thread
    ana_context, ana = _page_of(browser, server_url, team["ana"])
    try:
        count = ana.locator(tid("to-fix-count"))
        count.wait_for()
        assert count.inner_text().split() == ["To", "fix", "1"]
        assert ana.locator(tid("to-re-review-count")).count() == 0  # annotators re-review nothing
        ana.locator(tid("queue-row")).first.wait_for()
        _shoot(ana, shots, "queue-to-fix")
        ana.goto(f"/systems/{sid}")
        comment = ana.locator(tid("review-comment"))
        comment.wait_for()
        assert "the box sits on the shadow" in comment.inner_text()
        assert ana.locator(tid("review-comment-pin")).count() == 1
        assert ana.locator(tid("handoff")).inner_text() == "returned to ana by rev: the box sits on the shadow"
        ana.locator("body").click(position={"x": 5, "y": 5})
        ana.keyboard.press("Shift+C")
        selected = ana.locator(f'{tid("view")}.selected')
        selected.wait_for()
        assert selected.get_attribute("data-frame-id") == str(team["frame_id"])
        _shoot(ana, shots, "system-comment")
        assert ana.locator(tid("accept")).is_hidden() and ana.locator(tid("needs-fix")).is_hidden()  # a reviewer's
        assert ana.locator(tid("send-fixed")).is_visible()  # ... hers: it was returned to her
        ana.click(tid("comment-resolve"))
        ana.locator(f'{tid("review-comment")}[data-resolved="true"]').wait_for()
        decided: list[Optional[str]] = []  # each decision's If-Match: a fixed never overrides what it did not see
        ana.on("request", lambda r: decided.append(r.headers.get("if-match"))
               if r.method == "POST" and r.url.endswith("/review") else None)
        ana.click(tid("send-fixed"))
        ana.wait_for_function("() => !document.querySelector('[data-testid=send-fixed]') ||"
                              " document.querySelector('[data-testid=send-fixed]').hidden ||"
                              " document.querySelector('[data-testid=system-status]').textContent.startsWith('fixed')")
        assert len(decided) == 1 and (decided[0] or "").startswith('"system-'), decided
        assert ana.errors == []
    finally:
        ana_context.close()

    # ----- ben's queue: nothing to fix (shown, 0)
    ben_context, ben = _page_of(browser, server_url, team["ben"])
    try:
        ben.locator(tid("to-fix-count")).wait_for()
        assert ben.locator(tid("to-fix-count")).inner_text().split() == ["To", "fix", "0"]
        ben.goto(f"/systems/{sid}")
        ben.locator(tid("review-comment")).first.wait_for()
        # not returned to him: neither the hand-back nor a pin is offered (hidden, whatever a button's display)
        assert ben.locator(tid("send-fixed")).is_hidden() and ben.locator(tid("comment-pin-start")).is_hidden()
    finally:
        ben_context.close()

    # ----- rev: To re-review 1; the statistics page's annotator table has ana's row
    rev_context, rev = _page_of(browser, server_url, team["rev"])
    try:
        rev.locator(tid("to-re-review-count")).wait_for()
        assert rev.locator(tid("to-re-review-count")).inner_text().split() == ["To", "re-review", "1"]
        rev.goto(f"/systems/{sid}")
        rev.locator(tid("review-comment")).first.wait_for()
        assert rev.locator(tid("accept")).is_visible() and rev.locator(tid("send-fixed")).is_hidden()
        # the re-review's decision box is empty: the earlier note is the hand-off's, not the next decision's comment
        rev.locator(tid("handoff")).filter(has_text="fixed by ana").wait_for()
        assert rev.locator(tid("comment")).input_value() == ""
        rev.goto("/static/stats.html")
        row = rev.locator(f'{tid("annotator-row")}[data-name="ana"]')
        row.wait_for()
        cells = row.locator("td").all_inner_texts()
        assert cells[:2] == ["ana", "1"] and cells[4] == "1"  # one edit, one needs fix received
        _shoot(rev, shots, "stats-annotators")
        assert rev.errors == []
    finally:
        rev_context.close()


def test_an_admin_imports_a_zip_from_the_queue_page_and_its_job_is_titled_by_the_file(page, artifacts):
    """The Import panel uploads the chosen zip (here one laid out as a SoccerNet-v3 game, so that the upload is taken,
    whose labels file is no JSON: the job fails naming why) and the Jobs panel follows its job under the file's name,
    not the server's upload folder."""
    import io
    import zipfile

    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w") as zf:
        zf.writestr("league/2024-2025/a match/Labels-v3.json", "{ not JSON")
    page.goto("/")
    panel = page.locator(tid("import"))
    panel.wait_for()
    sent: list[str] = []
    page.on("request", lambda r: sent.append(r.method) if r.url.endswith("/api/imports") else None)
    page.set_input_files(tid("import-file"), files=[{"name": "my games.zip", "mimeType": "application/zip",
                                                     "buffer": buf.getvalue()}])
    page.click(tid("import-start"))
    page.locator(tid("import-upload-text")).filter(has_text="my games.zip uploaded: import job #").wait_for()
    assert sent == ["POST"]
    job = page.locator(tid("job")).filter(has_text="my games.zip")
    job.wait_for(timeout=60_000)
    assert job.locator(tid("job-title")).inner_text() == "import soccernet-v3 my games.zip"
    shots = artifacts / "team-loop"
    shots.mkdir(exist_ok=True)
    _shoot(page, shots, "queue-admin-import")


def _untouched_systems(seeded_settings, count: int) -> list[int]:
    """The ids of the last ``count`` systems of two or more views that nobody edited, decided or was assigned (the
    module's other tests work on the first ones)."""
    import sqlalchemy as sa

    from app.db.models import AuditEntry, System
    from app.db.session import make_engine, make_session_factory

    engine = make_engine(seeded_settings.database_url)
    try:
        with make_session_factory(engine)() as session:
            touched = set(session.scalars(sa.select(AuditEntry.system_id).where(AuditEntry.system_id.is_not(None))))
            ids = [s.id for s in session.scalars(sa.select(System).order_by(System.id.desc()))
                   if len(s.frames) >= 2 and s.id not in touched and s.assignee_id is None]
    finally:
        engine.dispose()
    assert len(ids) >= count, ids
    return ids[:count]


def _return_to(seeded_settings, system_ids: list[int], who: str, note: str) -> None:
    """rev's needs fix of each system, returned to ``who`` (through the service, as the page's decision would be)."""
    from app.db.session import make_engine, make_session_factory
    from app.services.curation.decisions import decide_review

    engine = make_engine(seeded_settings.database_url)
    try:
        with make_session_factory(engine)() as session:
            for system_id in system_ids:
                decide_review(session, system_id=system_id, status="needs_fix", comment=note, actor="rev",
                              return_to=who)
    finally:
        engine.dispose()


def test_a_needs_fix_nobody_would_get_asks_whom_it_goes_to(browser, server_url, seeded_settings, team, artifacts):
    """Nobody edited the system and nobody is assigned: `f` offers the team's annotators instead of returning it to
    nobody; the one chosen gets it."""
    from tests.browser.support import api_json

    (sid,) = _untouched_systems(seeded_settings, 1)
    rev_context, rev = _page_of(browser, server_url, team["rev"])
    try:
        rev.goto(f"/systems/{sid}")
        rev.locator(tid("view")).first.wait_for()
        rev.wait_for_function("() => !document.body.classList.contains('loading')")
        rev.locator("body").click(position={"x": 5, "y": 5})
        rev.keyboard.press("f")
        chooser = rev.locator(tid("return-to"))
        chooser.wait_for()
        shots = artifacts / "team-loop"
        shots.mkdir(exist_ok=True)
        _shoot(rev, shots, "return-to-chooser")  # the chooser at both sizes, for people to look at
        assert "nobody edited this system's labels" in rev.locator(tid("return-to-why")).inner_text()
        offered = rev.locator(f'{tid("return-to-user")} option').evaluate_all("(os) => os.map((o) => o.value)")
        assert {"ana", "ben"} <= set(offered) and "rev" not in offered  # the team's annotators
        assert api_json(rev, f"/api/systems/{sid}/handoff") is None  # nothing sent yet
        rev.select_option(tid("return-to-user"), "ben")
        with rev.expect_response(lambda r: r.request.method == "POST" and r.url.endswith(f"/systems/{sid}/review")
                                 ) as decided:
            rev.click(tid("return-to-send"))
        assert decided.value.ok and decided.value.json()["returned_to"] == "ben"
        rev.locator(tid("toast")).filter(has_text="returned to ben by rev").wait_for()
        assert api_json(rev, f"/api/systems/{sid}/handoff")["returned_to"] == "ben"
        assert rev.errors == []
    finally:
        rev_context.close()


def test_send_back_as_fixed_opens_the_next_system_to_fix(browser, server_url, seeded_settings, team):
    """ana's To fix list is walked in order: after "Send back as fixed" the next system returned to her comes, and
    after the last one the page says nothing is left (no unrelated system of the queue)."""
    first, second = _untouched_systems(seeded_settings, 2)[::-1]  # the older hand-off first
    _return_to(seeded_settings, [first, second], "ana", "look at the ball again")
    ana_context, ana = _page_of(browser, server_url, team["ana"])
    try:
        ana.goto(f"/systems/{first}")
        ana.locator(tid("send-fixed")).wait_for()
        ana.click(tid("send-fixed"))
        ana.wait_for_url(f"{server_url}/systems/{second}**")
        ana.locator(tid("system-name")).wait_for()
        ana.locator(tid("send-fixed")).wait_for()
        ana.click(tid("send-fixed"))
        ana.locator(tid("toast")).filter(has_text="Nothing else is returned to you to fix").wait_for()
        assert ana.url.split("?")[0].endswith(f"/systems/{second}")
        assert ana.errors == []
    finally:
        ana_context.close()
