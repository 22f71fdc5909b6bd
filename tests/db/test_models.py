"""Model behaviour that the services rely on: enums by value, UTC timestamps, constraints, cascades,
and the per-test rollback of the fixtures."""
from __future__ import annotations

from datetime import datetime, timedelta, timezone

import pytest
import sqlalchemy as sa
from sqlalchemy.orm import Session

from app.db.models import (
    BallKind,
    BallLabel,
    Calibration,
    CalibrationSource,
    CalibrationStatus,
    FieldLineAnnotation,
    Frame,
    FrameRole,
    Game,
    ReviewDecision,
    ReviewStatus,
    System,
    SystemKind,
)
from app.db.types import json_safe

pytestmark = pytest.mark.engine


def _game(session: Session, match: str = "m") -> Game:
    game = Game(league="l", season="s", match=match, source_path="/x")
    system = System(name="1.png", kind=SystemKind.SINGLE_VIEW)
    frame = Frame(name="1.png", role=FrameRole.CAMERA, width=960, height=540)
    frame.field_lines = FieldLineAnnotation(lines={"Middle line": [[[1.0, 2.0], [3.0, 4.0]]]},
                                            original_lines={"Middle line": [[[1.0, 2.0], [3.0, 4.0]]]})
    frame.ball_label = BallLabel(kind=BallKind.BOX, box=[1.0, 2.0, 11.0, 12.0], original_kind=BallKind.BOX,
                                 original_box=[1.0, 2.0, 11.0, 12.0])
    system.frames.append(frame)
    system.review = ReviewDecision(status=ReviewStatus.PENDING)
    game.systems.append(system)
    session.add(game)
    session.flush()
    return game


def test_enums_are_stored_by_value(db_session):
    game = _game(db_session)
    frame = game.systems[0].frames[0]
    frame.calibration = Calibration(source=CalibrationSource.COMPUTED, status=CalibrationStatus.REFUSED,
                                    reason="too few lines")
    db_session.flush()
    row = db_session.execute(sa.text("SELECT s.kind, f.role, c.source, c.status, r.status FROM systems s "
                                     "JOIN frames f ON f.system_id = s.id JOIN calibrations c ON c.frame_id = f.id "
                                     "JOIN review_decisions r ON r.system_id = s.id")).one()
    assert tuple(row) == ("single-view", "camera", "computed", "refused", "pending")


def test_unknown_enum_string_is_rejected_by_the_database(db_session):
    game = _game(db_session)
    with pytest.raises(sa.exc.IntegrityError):
        with db_session.begin_nested():
            db_session.execute(sa.text("UPDATE systems SET kind = 'bogus' WHERE id = :i"), {"i": game.systems[0].id})


def test_timestamps_are_aware_utc_after_a_round_trip(db_session):
    game = _game(db_session)
    decided = datetime(2026, 1, 2, 3, 4, 5, tzinfo=timezone(timedelta(hours=2)))
    review = game.systems[0].review
    review.decided_at = decided
    db_session.flush()
    db_session.expire_all()
    got = db_session.get(ReviewDecision, review.id).decided_at
    assert got == decided and got.tzinfo is not None and got.utcoffset() == timedelta(0)
    assert got.hour == 1  # 03:04 at +02:00 is 01:04 UTC
    assert db_session.get(Game, game.id).created_at.tzinfo is not None


def test_naive_timestamps_are_refused(db_session):
    game = _game(db_session)
    game.systems[0].review.decided_at = datetime(2026, 1, 1)
    with pytest.raises(sa.exc.StatementError, match="naive datetime"):
        db_session.flush()
    db_session.rollback()


def test_foreign_keys_are_enforced(db_session):
    with pytest.raises(sa.exc.IntegrityError):
        with db_session.begin_nested():
            db_session.execute(sa.text("INSERT INTO frames (system_id, name, role, position, width, height) "
                                       "VALUES (987654, 'x.png', 'action', 0, 10, 10)"))


def test_review_needs_exactly_one_subject(db_session):
    with pytest.raises(sa.exc.IntegrityError):
        with db_session.begin_nested():
            db_session.add(ReviewDecision(status=ReviewStatus.ACCEPTED))
            db_session.flush()


def test_deleting_a_game_cascades_to_everything_below(db_session):
    game = _game(db_session)
    frame_id = game.systems[0].frames[0].id
    db_session.delete(game)
    db_session.flush()
    for table in ("systems", "frames", "field_lines", "ball_labels", "review_decisions"):
        assert db_session.execute(sa.text(f"SELECT count(*) FROM {table}")).scalar() == 0, table
    assert db_session.get(Frame, frame_id) is None


def test_natural_keys_are_unique(db_session):
    _game(db_session, match="same")
    with pytest.raises(sa.exc.IntegrityError):
        with db_session.begin_nested():
            db_session.add(Game(league="l", season="s", match="same", source_path="/y"))
            db_session.flush()


def test_commits_inside_a_test_are_rolled_back_afterwards(db_engine):
    with db_engine.connect() as conn:
        outer = conn.begin()
        session = Session(bind=conn, join_transaction_mode="create_savepoint")
        _game(session, match="rolled-back")
        session.commit()  # a savepoint release, not a real commit
        assert session.scalar(sa.select(sa.func.count()).select_from(Game).where(Game.match == "rolled-back")) == 1
        session.close()
        outer.rollback()
    with db_engine.connect() as conn:
        assert conn.execute(sa.text("SELECT count(*) FROM games WHERE match = 'rolled-back'")).scalar() == 0


def test_json_safe_turns_numpy_and_non_finite_values_into_json():
    import numpy as np

    assert json_safe({"a": np.float64(1.5), "b": np.array([1, 2]), "c": float("nan"), "d": (np.bool_(True),)}) == \
        {"a": 1.5, "b": [1, 2], "c": None, "d": [True]}
    with pytest.raises(TypeError):
        json_safe(object())
