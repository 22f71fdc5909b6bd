"""Review passes (issue 28, ``app.services.curation.passes``): the frozen order of a queue across its pages,
kept through a decision and a fix that reorder the queue; the next pending system read from current statuses;
an accept over open label doubts records them in its audit entry."""
from __future__ import annotations

import pytest
from sqlalchemy.orm import Session

from app.core.config import Settings
from app.core.errors import ForbiddenError
from app.db.models import ReviewStatus, User, UserRole
from app.geometry.doubts import label_severity
from app.services.audit import log as audit
from app.services.curation import decisions, editing, passes, queue, writing
from app.services.curation.queue import SystemFilters
from tests.api.factories import Scene, ball_box, make_game, make_system

pytestmark = pytest.mark.engine


@pytest.fixture
def six(db_session: Session, db_settings: Settings) -> list[Scene]:
    """Six three-view systems of one game; three of them with one ball box off by 40-60 px (a label doubt
    each), so the doubts sort puts them first."""
    game = make_game(db_session)
    shifts = [(0.0, 0.0, 0.0), (0.0, 60.0, 0.0), (0.0, 0.0, 0.0), (40.0, 0.0, 0.0), (0.0, 0.0, 0.0),
              (0.0, 0.0, 50.0)]
    return [make_system(db_session, db_settings, game, f"{i + 1}.png", shift_px=s) for i, s in enumerate(shifts)]


def _pages(session: Session, sort: str, limit: int) -> tuple[list[int], int]:
    """The queue's ids as the queue page reads them: page after page by cursor; and how many pages."""
    ids, cursor, pages = [], None, 0
    while True:
        page = queue.list_systems(session, SystemFilters(), sort, limit=limit, after=cursor)
        ids += [s.id for s in page.items]
        pages += 1
        if page.next_cursor is None:
            return ids, pages
        cursor = page.next_cursor


def test_a_pass_keeps_the_queue_order_of_its_start_through_a_decision_and_a_fix(
        db_session: Session, db_settings: Settings, six: list[Scene]) -> None:
    order, pages = _pages(db_session, "-doubts", limit=4)
    assert pages == 2 and sorted(order) == sorted(s.system_id for s in six)
    doubtful = [s.system_id for s in six if writing.get_system(db_session, s.system_id).label_doubts > 0]
    assert len(doubtful) >= 2 and order[:len(doubtful)] == sorted(  # the doubts sort: the doubtful first
        doubtful, key=lambda i: order.index(i))

    rp = passes.start_pass(db_session, "ana", SystemFilters(), "-doubts", system_id=order[0])
    assert rp.system_ids == order and rp.position == 0

    # a decision on the first, and a fix of the second (its label put back where the other views agree)
    decisions.decide_review(db_session, system_id=order[0], status="rejected", actor="ana")
    fixed = order[1]
    scene = next(s for s in six if s.system_id == fixed)
    for frame_id, camera in zip(scene.frame_ids, scene.cameras, strict=True):
        editing.update_ball_label(db_session, frame_id, box=ball_box(camera), settings=db_settings, actor="ana")
    assert writing.get_system(db_session, fixed).label_doubts == 0
    for scene in six:  # the stored severity is the one its stored doubts give (the queue's default order reads it)
        system = writing.get_system(db_session, scene.system_id)
        assert system.label_severity == label_severity(d.kind for d in system.doubts)
    assert writing.get_system(db_session, fixed).label_severity == 0
    assert any(writing.get_system(db_session, i).label_severity > 0 for i in doubtful if i != fixed)
    now, _ = _pages(db_session, "-doubts", limit=4)
    assert now != order and now.index(fixed) > 1  # the fix moved it in the queue's current order ...
    assert passes.get_pass(db_session, rp.id).system_ids == order  # ... not in the pass

    # the next pending after the fixed system is the pass's next, not the fixed system's queue neighbour
    at_fixed = passes.place(db_session, rp, fixed)
    assert at_fixed.index == 1 and at_fixed.next_id == order[2] and at_fixed.next_pending_id == order[2]
    assert at_fixed.prev_id == order[0]

    # decided systems are skipped: accept the third and fourth, then from the second the next pending is the fifth
    for sid in order[2:4]:
        decisions.decide_review(db_session, system_id=sid, status="accepted", actor="bob")
    at_fixed = passes.place(db_session, rp, fixed)
    assert at_fixed.next_pending_id == order[4] and not at_fixed.finished
    assert at_fixed.first_pending_id == order[1]  # the fixed one itself is still pending
    # ana's pass counts ana's decision, not bob's two
    assert at_fixed.counts == {"accepted": 0, "rejected": 1, "needs_fix": 0, "sent_back": 0, "by_others": 2,
                               "skipped": 3}

    # the last one: the next pending wraps round to the pass's start (a pass resumed late reaches the systems left
    # pending before its resume point); once every other system is decided the pass is finished there
    last = passes.place(db_session, rp, order[-1])
    assert not last.finished and last.next_pending_id == order[1] and last.next_pending_index == 1
    assert last.next_id is None
    for sid in order[1:-1]:
        if sid != order[4]:
            decisions.decide_review(db_session, system_id=sid, status="accepted", actor="bob")
    assert passes.place(db_session, rp, order[-1]).next_pending_id == order[4]
    decisions.decide_review(db_session, system_id=order[4], status="accepted", actor="bob")
    last = passes.place(db_session, rp, order[-1])
    assert last.finished and last.next_pending_id is None and last.next_pending_index is None

    # opening a system of the same queue continues the pass; a fresh one freezes the queue's order now
    assert passes.start_pass(db_session, "ana", SystemFilters(), "-doubts", system_id=order[4]).id == rp.id
    fresh = passes.start_pass(db_session, "ana", SystemFilters(), "-doubts", system_id=order[4], fresh=True)
    assert fresh.id != rp.id and fresh.system_ids == now and fresh.position == now.index(order[4])
    assert passes.start_pass(db_session, "bob", SystemFilters(), "-doubts").id not in (rp.id, fresh.id)


def test_a_pass_of_a_filtered_queue_and_its_position(db_session: Session, six: list[Scene]) -> None:
    pending = SystemFilters(status=ReviewStatus.PENDING, doubt="any")
    expected = [s.id for s in queue.list_systems(db_session, pending, "name", limit=100).items]
    rp = passes.start_pass(db_session, "ana", pending, "name")
    assert rp.system_ids == expected and rp.filters == {"status": "pending", "doubt": "any"} and rp.sort == "name"
    assert len(expected) >= 2

    place = passes.visit(db_session, rp, expected[1], "ana")
    assert passes.get_pass(db_session, rp.id).position == 1 and place.index == 1
    with pytest.raises(ForbiddenError):
        passes.visit(db_session, rp, expected[0], "bob")
    outside = next(s.system_id for s in six if s.system_id not in expected)
    there = passes.visit(db_session, rp, outside, "ana")  # not in the pass: the stored position is the anchor
    assert there.index is None and there.prev_id == expected[0] and passes.get_pass(db_session, rp.id).position == 1
    assert [p.id for p in passes.list_passes(db_session, "ana")] == [rp.id]


def test_an_accept_over_open_label_doubts_records_them(db_session: Session, six: list[Scene]) -> None:
    doubtful = next(s.system_id for s in six if writing.get_system(db_session, s.system_id).label_doubts > 0)
    system = writing.get_system(db_session, doubtful)
    open_doubts = [(d.kind, d.frame_id, d.message) for d in system.doubts if d.accuses_label]
    assert open_doubts

    decisions.decide_review(db_session, system_id=doubtful, status="accepted", actor="script")
    entry = audit.latest_entry(db_session, system_id=doubtful)
    assert entry.action == "system.review" and entry.after["review"]["status"] == "accepted"
    assert [(d["kind"], d["frame_id"], d["message"]) for d in entry.after["overrode_doubts"]] == open_doubts
    assert "overrode_doubts" not in entry.before

    # a reject records none; an accept of a clean system records none
    decisions.decide_review(db_session, system_id=doubtful, status="rejected", actor="script")
    assert "overrode_doubts" not in audit.latest_entry(db_session, system_id=doubtful).after
    clean = next(s.system_id for s in six if writing.get_system(db_session, s.system_id).label_doubts == 0)
    decisions.decide_review(db_session, system_id=clean, status="accepted", actor="script")
    assert "overrode_doubts" not in audit.latest_entry(db_session, system_id=clean).after


def test_a_pass_counts_its_owners_decisions_and_names_what_was_sent_back_or_decided_by_others(
        db_session: Session, six: list[Scene]) -> None:
    """The counts of a pass are its owner's decisions in it (an earlier decision, another reviewer's, a decision
    undone by a later one are not), then the systems sent back as fixed, then those decided by others."""
    ids = [s.system_id for s in six]
    db_session.add(User(name="ben", role=UserRole.ANNOTATOR, password_hash="not a hash: ben never logs in"))
    db_session.flush()
    decisions.decide_review(db_session, system_id=ids[0], status="accepted", actor="ana")  # before the pass
    rp = passes.start_pass(db_session, "ana", SystemFilters(), "name", system_id=ids[1], fresh=True)
    decisions.decide_review(db_session, system_id=ids[1], status="accepted", actor="ana")
    decisions.decide_review(db_session, system_id=ids[2], status="needs_fix", actor="ana", return_to="ben")
    decisions.decide_review(db_session, system_id=ids[3], status="rejected", actor="ana")
    decisions.decide_review(db_session, system_id=ids[3], status="accepted", actor="bob")  # decided again by bob
    decisions.decide_review(db_session, system_id=ids[4], status="needs_fix", actor="bob", return_to="ben")
    decisions.decide_review(db_session, system_id=ids[4], status="fixed", actor="ben")  # back to decide again
    counts = passes.pass_counts(db_session, passes.get_pass(db_session, rp.id))
    assert counts == {"accepted": 1, "rejected": 0, "needs_fix": 1, "sent_back": 1, "by_others": 2, "skipped": 1}
    place = passes.place(db_session, rp, ids[1])
    assert place.counts == counts and place.next_pending_id == ids[4]  # a system sent back is visited again
