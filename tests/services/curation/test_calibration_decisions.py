"""A view's calibration decision beside its ball decision, and the reset of decisions when an edit of the
field lines changes a calibration (issue 16): pending again with the reason, in the edit's transaction,
audited and revertible."""
from __future__ import annotations

import pytest
from sqlalchemy import select

from app.core.errors import InvalidInputError, StaleVersionError
from app.db.models import AuditEntry, Frame, ReviewStatus, System
from app.services.accounts.users import create_user
from app.services.curation.decisions import decide_calibration, decide_review
from app.services.curation.editing import replace_field_lines, update_ball_label
from app.services.curation.reverting import revert_entry


def _frame(systems, system, name) -> Frame:
    return next(f for f in systems[system].frames if f.name == name)


def _entries(session, **where) -> list[AuditEntry]:
    q = select(AuditEntry).order_by(AuditEntry.id)
    for k, v in where.items():
        q = q.where(getattr(AuditEntry, k) == v)
    return list(session.scalars(q))


def test_a_calibration_decision_is_kept_apart_from_the_ball_decision(db_session, imported):
    frame = _frame(imported, "2.png", "2_3.png")
    decide_review(db_session, frame_id=frame.id, status="accepted", comment="ball fine")
    version = frame.edit_version
    d = decide_calibration(db_session, frame.id, status="needs_fix", comment="left post mislabelled",
                           expected={version})
    assert d is frame.review and d.status is ReviewStatus.ACCEPTED and d.comment == "ball fine"
    assert (d.calibration_status, d.calibration_comment) == (ReviewStatus.NEEDS_FIX, "left post mislabelled")
    assert d.calibration_decided_at.tzinfo is not None and frame.edit_version == version + 1
    last = _entries(db_session, frame_id=frame.id)[-1]
    assert last.action == "view.calibration_review"
    assert last.before == {"calibration_review": {"status": "pending", "comment": ""}}
    assert last.after == {"calibration_review": {"status": "needs_fix", "comment": "left post mislabelled"}}
    with pytest.raises(StaleVersionError):  # the same ETag again: someone else came first
        decide_calibration(db_session, frame.id, status="accepted", expected={version})
    with pytest.raises(InvalidInputError, match="unknown review status") as exc:
        decide_calibration(db_session, frame.id, status="fine")
    assert exc.value.field == "status"
    db_session.expire_all()
    assert db_session.get(Frame, frame.id).review.calibration_status is ReviewStatus.NEEDS_FIX
    revert_entry(db_session, last.id, settings=None)  # a decision needs no settings to revert
    assert db_session.get(Frame, frame.id).review.calibration_status is ReviewStatus.PENDING


def test_an_edit_that_changes_a_calibration_sets_the_decisions_back_to_pending(db_session, settings, imported):
    system = imported["2.png"]
    frame = _frame(imported, "2.png", "2_3.png")
    other = _frame(imported, "2.png", "2_2.png")
    decide_calibration(db_session, frame.id, status="accepted")
    decide_calibration(db_session, other.id, status="accepted")
    decide_review(db_session, system_id=system.id, status="accepted", comment="all good")
    version = system.version
    first_entry = _entries(db_session)[-1].id
    original = frame.field_lines.lines
    one_line = {cls: polys for cls, polys in list(original.items())[:1]}  # too few lines: refused

    replace_field_lines(db_session, frame.id, one_line, settings=settings, actor="ana")

    db_session.expire_all()
    system = db_session.get(System, system.id)
    frame, other = db_session.get(Frame, frame.id), db_session.get(Frame, other.id)
    assert frame.calibration.camera is None
    assert frame.review.calibration_status is ReviewStatus.PENDING
    reason = frame.review.calibration_reset_reason
    assert reason.startswith("2_3.png: field lines replaced by ana, the view was recalibrated (JaC@0.5 % ")
    assert ", admitted -> not calibrated); decide it again" in reason
    assert other.review.calibration_status is ReviewStatus.ACCEPTED  # only the edited view's calibration
    assert (system.review.status, system.review_status, system.review.reset_reason) == (
        ReviewStatus.PENDING, ReviewStatus.PENDING, reason)
    assert system.review.comment == "all good" and system.version > version
    new = [e for e in _entries(db_session) if e.id > first_entry]
    # one transaction: the two resets, then the edit itself (the frame's newest entry)
    assert [(e.action, e.actor) for e in new] == [
        ("view.calibration_review", "ana"), ("system.review", "ana"), ("field_lines.replace", "ana")]
    assert new[1].before == {"review": {"status": "accepted", "comment": "all good"}}
    assert new[1].after == {"review": {"status": "pending", "comment": "all good"}}

    # deciding again clears the reasons
    create_user(db_session, "ana", "annotator", "a password of ana's")  # whom the needs-fix goes back to
    decide_review(db_session, system_id=system.id, status="needs_fix", return_to="ana")
    decide_calibration(db_session, frame.id, status="rejected")
    assert system.review.reset_reason is None and frame.review.calibration_reset_reason is None

    # a pending decision has nothing to reset; a ball edit changes no calibration (but it changes the labels:
    # the system's decision goes back to pending, issue 28 item 3)
    count = len(_entries(db_session))
    decide_review(db_session, system_id=system.id, status="pending")
    decide_calibration(db_session, frame.id, status="pending")
    replace_field_lines(db_session, frame.id, original, settings=settings)
    assert [e.action for e in _entries(db_session)[count:]] == ["system.review", "view.calibration_review",
                                                                "field_lines.replace"]
    decide_review(db_session, system_id=system.id, status="accepted")
    box = other.ball_label.box
    update_ball_label(db_session, other.id, box=[box[0] + 1, box[1], box[2] + 1, box[3]], settings=settings)
    assert system.review.status is ReviewStatus.PENDING and "ball of V" in system.review.reset_reason
    assert other.review.calibration_status is ReviewStatus.ACCEPTED


def test_the_resets_commit_with_the_edit_or_not_at_all(db_session, settings, imported, monkeypatch):
    from app.services.audit import log as audit

    system = imported["2.png"]
    frame = _frame(imported, "2.png", "2_3.png")
    decide_calibration(db_session, frame.id, status="accepted")
    decide_review(db_session, system_id=system.id, status="accepted")
    count = len(_entries(db_session))
    record = audit.record

    def failing(session, **kw):  # the edit's own entry fails, after the resets were made
        if kw["action"] == "field_lines.replace":
            raise RuntimeError("disk full")
        return record(session, **kw)

    monkeypatch.setattr(audit, "record", failing)
    lines = frame.field_lines.lines
    with pytest.raises(RuntimeError, match="disk full"):
        replace_field_lines(db_session, frame.id, {k: v for k, v in list(lines.items())[:1]}, settings=settings)
    db_session.expire_all()
    assert db_session.get(Frame, frame.id).review.calibration_status is ReviewStatus.ACCEPTED
    assert db_session.get(System, system.id).review.status is ReviewStatus.ACCEPTED
    assert db_session.get(Frame, frame.id).field_lines.lines == lines and len(_entries(db_session)) == count


def test_the_same_lines_again_reset_nothing(db_session, settings, imported):
    system = imported["3.png"]
    frame = system.frames[0]
    decide_calibration(db_session, frame.id, status="accepted")
    decide_review(db_session, system_id=system.id, status="accepted")
    replace_field_lines(db_session, frame.id, frame.field_lines.lines, settings=settings)
    assert frame.review.calibration_status is ReviewStatus.ACCEPTED and system.review.status is ReviewStatus.ACCEPTED
