"""The per-annotator figures (``app.services.evaluation.annotators``) on a system whose truth is known: exact cameras,
one label shifted by a known number of pixels by ana, a hand-off to her, decisions at known times; and
``v3d stats annotators`` printing and writing them."""
from __future__ import annotations

import csv
from datetime import datetime, timedelta, timezone

import pytest
import sqlalchemy as sa
from sqlalchemy.orm import Session
from typer.testing import CliRunner

from app.core.config import Settings
from app.db.models import AuditEntry, Frame, ReviewHandoff, ReviewStatus, System, User, UserRole
from app.geometry.pair_error import REFERENCE_WIDTH_PX
from app.services.curation.editing import update_ball_label
from app.services.derivation.recompute import recompute_system
from app.services.evaluation.annotators import FIELDS, annotator_figures
from tests.api.factories import WIDTH, make_game, make_system

pytestmark = pytest.mark.engine

T0 = datetime(2026, 11, 1, 12, 0, tzinfo=timezone.utc)


@pytest.fixture
def worked(db_session: Session, db_settings: Settings) -> dict:
    """:func:`work` in the test's database."""
    return work(db_session, db_settings)


def work(db_session: Session, db_settings: Settings) -> dict:
    """Two three-view systems. ana moves V2's ball of system 1 by 8 px (off the others' ball) and V3's ball of system 2
    by 0 px (a confirm: on it); rev marks system 1 needs fix and returns it to her; system 2, back fixed, is accepted
    by rev 90 s after her edit."""
    game = make_game(db_session)
    one = make_system(db_session, db_settings, game, "1.png")
    two = make_system(db_session, db_settings, game, "2.png")
    db_session.add_all([User(name="ana", role=UserRole.ANNOTATOR, password_hash="-"),
                        User(name="rev", role=UserRole.REVIEWER, password_hash="-")])
    db_session.commit()
    for scene, k, dx in ((one, 1, 8.0), (two, 2, 0.0)):
        frame = db_session.get(Frame, scene.frame_ids[k])
        box = list(frame.ball_label.box)
        update_ball_label(db_session, frame.id, box=[box[0] + dx, box[1], box[2] + dx, box[3]],
                          settings=db_settings, actor="ana")
    ana = db_session.scalar(sa.select(User).where(User.name == "ana"))
    # the times of the entries as the test wants them (the table is append-only: insert, never update)
    edits = db_session.scalars(sa.select(AuditEntry).where(AuditEntry.actor == "ana").order_by(AuditEntry.id)).all()
    for entry, at in zip(edits, (T0, T0 + timedelta(seconds=30)), strict=True):
        db_session.execute(sa.insert(AuditEntry).values(actor="ana", action="field_lines.replace", at=at,
                                                        frame_id=entry.frame_id, system_id=entry.system_id,
                                                        game_id=entry.game_id, summary="an edit at a known time"))
    db_session.execute(sa.insert(AuditEntry).values(actor="rev", action="system.review", system_id=two.system_id,
                                                    at=T0 + timedelta(seconds=120), summary="system accepted",
                                                    before={"review": {"status": "fixed", "comment": ""}},
                                                    after={"review": {"status": "accepted", "comment": ""}}))
    db_session.execute(sa.insert(AuditEntry).values(actor="rev", action="system.review", system_id=one.system_id,
                                                    at=T0 - timedelta(seconds=10), summary="system needs fix",
                                                    before={"review": {"status": "pending", "comment": ""}},
                                                    after={"review": {"status": "needs_fix", "comment": "off"}}))
    db_session.add(ReviewHandoff(system_id=one.system_id, returned_to_id=ana.id, returned_by="rev", note="off",
                                 returned_at=T0 + timedelta(seconds=60)))
    db_session.get(System, two.system_id).review_status = ReviewStatus.ACCEPTED
    db_session.commit()
    return {"one": one, "two": two, "settings": db_settings}


def test_the_figures_of_a_known_day(db_session: Session, worked: dict) -> None:
    figures = {f.name: f for f in annotator_figures(db_session)}
    assert list(figures) == ["ana", "rev"]  # rev only decided: a reviewer's figures, no label edit
    rev = figures["rev"]
    assert (rev.decisions, rev.accepted, rev.rejected, rev.needs_fix, rev.re_reviews) == (2, 1, 0, 1, 1)
    assert (rev.edits, rev.systems_touched, rev.median_label_distance_px) == (0, 0, None)
    ana = figures["ana"]
    assert (ana.decisions, ana.accepted) == (0, 0)
    # two ball edits (now) and two line edits (at T0 and T0 + 30 s)
    assert (ana.edits, ana.systems_touched, ana.systems_decided, ana.accepted_first_review) == (4, 2, 1, 1)
    assert ana.needs_fix_received == 1
    # her last edits are the ball edits made now, after the decision at T0 + 120 s: no decision follows them
    assert ana.median_edit_to_review_s is None
    # the 8 px shift of a 960-px frame is 16 px at 1920 width from the others' ball; the confirmed label is on it
    scale = REFERENCE_WIDTH_PX / WIDTH
    assert ana.median_label_distance_px == pytest.approx((8.0 * scale + 0.0) / 2, abs=0.5)
    assert 0.0 <= ana.accused_share <= 1.0

    # a window that ends before the ball edits: the two line edits, and the decision 90 s after the last one
    early = {f.name: f for f in annotator_figures(db_session, T0 - timedelta(hours=1), T0 + timedelta(hours=1))}["ana"]
    assert (early.edits, early.systems_touched) == (2, 2)
    assert early.median_edit_to_review_s == pytest.approx(90.0)  # system 2: edit at T0 + 30 s, decision at T0 + 120 s
    assert early.median_label_distance_px is None and early.accused_share is None  # no ball edit in the window
    assert annotator_figures(db_session, T0 + timedelta(days=400)) == []
    # a window holding the accept alone: one decision, a re-review of a system that came back fixed
    late = {f.name: f for f in annotator_figures(db_session, T0 + timedelta(seconds=100), T0 + timedelta(seconds=130))}
    assert (late["rev"].decisions, late["rev"].accepted, late["rev"].re_reviews) == (1, 1, 1)


def test_the_distance_is_stored_by_the_recomputation(db_session: Session, worked: dict) -> None:
    frame = db_session.get(Frame, worked["one"].frame_ids[1])
    stored = frame.reprojection.others_distance_px
    assert stored == pytest.approx(8.0 * REFERENCE_WIDTH_PX / WIDTH, abs=0.5)
    recompute_system(db_session, frame.system, worked["settings"])
    assert frame.reprojection.others_distance_px == pytest.approx(stored)


def test_the_command_prints_and_writes_the_figures(fresh_session_factory, db_settings: Settings, tmp_path) -> None:
    from app.cli import (
        cli,
        detectors,  # noqa: F401  # registers `v3d stats`
    )

    session = fresh_session_factory("cli")
    url = session.get_bind().url.render_as_string(hide_password=False)
    work(session, db_settings.model_copy(update={"database_url": url}))
    session.close()
    out = tmp_path / "annotators.csv"
    res = CliRunner().invoke(cli, ["stats", "annotators", "--csv", str(out), "--database-url", url])
    assert res.exit_code == 0, res.output
    assert "ana: 4 edit(s) on 2 system(s), 1 decided, 1 accepted at first review, 1 returned to them" in res.output
    rows = list(csv.reader(out.open()))
    assert rows[0] == list(FIELDS) and rows[1][:7] == ["ana", "4", "2", "1", "1", "1", ""]
    assert "rev: 0 edit(s)" in res.output
    assert "reviewed: 2 decision(s), 1 accepted, 0 rejected, 1 needs fix" in res.output
    rev = dict(zip(rows[0], rows[2], strict=True))
    assert (rev["name"], rev["decisions"], rev["needs_fix"], rev["re_reviews"]) == ("rev", "2", "1", "1")


def test_a_persons_figures_as_a_reviewer_count_only_a_reviewers_decisions(db_session: Session,
                                                                           db_settings: Settings) -> None:
    """rev accepts a system and marks another needs fix, returned to ana; ana sends it back fixed, and her ball edit
    of the accepted system sets its decision back to pending: both are ``system.review`` entries of hers, neither a
    decision she made as a reviewer."""
    from app.services.curation.decisions import decide_review

    game = make_game(db_session)
    one = make_system(db_session, db_settings, game, "1.png")
    two = make_system(db_session, db_settings, game, "2.png")
    db_session.add_all([User(name="ana", role=UserRole.ANNOTATOR, password_hash="-"),
                        User(name="rev", role=UserRole.REVIEWER, password_hash="-")])
    db_session.commit()
    ana = db_session.scalar(sa.select(User).where(User.name == "ana"))
    frame = db_session.get(Frame, one.frame_ids[1])
    box = list(frame.ball_label.box)
    update_ball_label(db_session, frame.id, box=[box[0] + 1, box[1], box[2] + 1, box[3]], settings=db_settings,
                      actor="ana")  # ana's edit: the needs fix returns the system to her
    decide_review(db_session, system_id=one.system_id, status="needs_fix", comment="off", actor="rev")
    decide_review(db_session, system_id=one.system_id, status="fixed", actor="ana", fixed_by=ana.id)
    decide_review(db_session, system_id=two.system_id, status="accepted", actor="rev")
    frame = db_session.get(Frame, two.frame_ids[2])
    box = list(frame.ball_label.box)
    update_ball_label(db_session, frame.id, box=[box[0] + 3, box[1], box[2] + 3, box[3]], settings=db_settings,
                      actor="ana")
    assert db_session.get(System, two.system_id).review_status == ReviewStatus.PENDING  # her edit's reset
    assert db_session.scalar(sa.select(sa.func.count()).select_from(AuditEntry).where(
        AuditEntry.actor == "ana", AuditEntry.action == "system.review")) == 2
    figures = {f.name: f for f in annotator_figures(db_session)}
    assert (figures["ana"].decisions, figures["ana"].accepted, figures["ana"].needs_fix) == (0, 0, 0)
    rev = figures["rev"]
    assert (rev.decisions, rev.accepted, rev.needs_fix, rev.re_reviews) == (2, 1, 1, 0)
