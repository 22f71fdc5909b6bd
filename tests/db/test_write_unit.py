"""The write unit (``app.db.unit``) on synthetic rows: it commits or rolls back, keeps the queue's copy of a system's
decision, and refuses a commit that changed a system's rows without bumping the version that covers them (the check
the suite runs with, ``tests/conftest.py``), whatever the writer and however its changes were flushed."""
from __future__ import annotations

import pytest
import sqlalchemy as sa
from sqlalchemy.orm import Session

from app.db import unit
from app.db.models import (
    BallKind,
    BallLabel,
    Calibration,
    CalibrationSource,
    CalibrationStatus,
    Frame,
    FrameRole,
    Game,
    ReviewDecision,
    ReviewStatus,
    System,
    SystemKind,
)
from app.db.scope import system_tables
from app.db.unit import VersionNotBumped, write_unit

pytestmark = pytest.mark.engine


@pytest.fixture
def system(db_session: Session) -> System:
    """One stored system with two views, a ball label on the first, no decision yet."""
    game = Game(league="l", season="s", match="m", source_path="/synthetic")
    system = System(game=game, name="1.png", kind=SystemKind.SOCCERNET_V3)
    for i, role in enumerate((FrameRole.ACTION, FrameRole.REPLAY)):
        system.frames.append(Frame(name=f"1_{i}.png", role=role, position=i, width=960, height=540))
    system.frames[0].ball_label = BallLabel(kind=BallKind.BOX, box=[10.0, 10.0, 20.0, 20.0])
    with write_unit(db_session):
        db_session.add(game)
    return system


def _stored(session: Session, column: sa.orm.InstrumentedAttribute, key: int) -> object:
    """The stored value of ``column`` (of ``BallLabel`` or ``System``) of the row ``key`` (its frame's id or its id)."""
    table = column.class_
    where = BallLabel.frame_id == key if table is BallLabel else System.id == key
    return session.execute(sa.select(column).where(where)).scalar_one()


def test_the_suite_runs_with_the_check_on() -> None:
    assert unit.CHECK_VERSIONS
    assert {"ball_labels", "frames", "systems", "review_decisions", "doubts", "predictions"} <= system_tables()


def test_a_change_without_its_version_bump_is_refused_and_rolled_back(db_session: Session, system: System) -> None:
    frame = system.frames[0]
    version = system.version
    with pytest.raises(VersionNotBumped, match=rf"system {system.id}: ball_labels \(box\)"):
        with write_unit(db_session):
            frame.ball_label.box = [11.0, 10.0, 21.0, 20.0]
    assert _stored(db_session, BallLabel.box, frame.id) == [10.0, 10.0, 20.0, 20.0]
    with write_unit(db_session):
        frame.ball_label.box = [11.0, 10.0, 21.0, 20.0]
        system.version += 1
    assert _stored(db_session, BallLabel.box, frame.id) == [11.0, 10.0, 21.0, 20.0]
    assert _stored(db_session, System.version, system.id) == version + 1


def test_a_change_flushed_early_is_still_checked(db_session: Session, system: System) -> None:
    frame = system.frames[1]
    with pytest.raises(VersionNotBumped, match="ball_labels"):
        with write_unit(db_session):
            frame.ball_label = BallLabel(kind=BallKind.POINT, point=[5.0, 6.0])
            db_session.execute(sa.select(sa.func.count(BallLabel.frame_id)))  # autoflush: the insert is sent now
    assert db_session.get(Frame, frame.id).ball_label is None  # rolled back
    with pytest.raises(VersionNotBumped, match="frames"):
        with write_unit(db_session):
            db_session.delete(system.frames[1])


def test_a_view_decision_is_covered_by_its_frame_version(db_session: Session, system: System) -> None:
    frame = system.frames[0]
    with pytest.raises(VersionNotBumped, match="review_decisions"):
        with write_unit(db_session):
            frame.review = ReviewDecision(status=ReviewStatus.ACCEPTED)
    with write_unit(db_session):
        frame.review = ReviewDecision(status=ReviewStatus.ACCEPTED)
        frame.edit_version += 1
    assert _stored(db_session, System.review_status, system.id) is ReviewStatus.PENDING  # a view's is not the system's


def test_columns_no_version_covers_need_no_bump(db_session: Session, system: System) -> None:
    version = system.version
    with write_unit(db_session):
        system.frames[0].split = "test"
        system.assigned_by = "ana"
    assert _stored(db_session, System.version, system.id) == version


def test_with_the_check_off_nothing_is_checked(db_session: Session, system: System, monkeypatch) -> None:
    monkeypatch.setattr(unit, "CHECK_VERSIONS", False)
    with write_unit(db_session):
        system.frames[0].ball_label.box = [12.0, 10.0, 22.0, 20.0]
    assert _stored(db_session, BallLabel.box, system.frames[0].id) == [12.0, 10.0, 22.0, 20.0]


def test_the_queue_copy_of_a_system_decision_is_written_by_the_unit(db_session: Session, system: System) -> None:
    with write_unit(db_session):
        system.review = ReviewDecision(status=ReviewStatus.ACCEPTED)
        system.version += 1
    assert _stored(db_session, System.review_status, system.id) is ReviewStatus.ACCEPTED
    decision = db_session.scalars(sa.select(ReviewDecision).where(ReviewDecision.system_id == system.id)).one()
    with write_unit(db_session):  # the decision changed alone, through a row read on its own
        decision.status = ReviewStatus.NEEDS_FIX
        decision.system.version += 1
    assert _stored(db_session, System.review_status, system.id) is ReviewStatus.NEEDS_FIX


def test_an_exception_rolls_back_and_propagates(db_session: Session, system: System) -> None:
    with pytest.raises(KeyError):
        with write_unit(db_session):
            system.frames[0].ball_label.box = [13.0, 10.0, 23.0, 20.0]
            system.version += 1
            raise KeyError("refused")
    assert _stored(db_session, BallLabel.box, system.frames[0].id) == [10.0, 10.0, 20.0, 20.0]


def test_a_change_of_what_the_game_version_covers_without_its_bump_is_refused(db_session: Session,
                                                                              system: System) -> None:
    """``Game.version`` covers the game's camera rig (its frames' calibrations) and its camera prior, which an edit of
    any of its systems reads: a write of either that leaves the game's version as it was is refused and rolled back,
    as one of a system's rows without its system's version is."""
    from app.services.kinds import POLICIES  # registers the kinds whose calibrations feed a rig

    assert POLICIES[system.kind].uses_rig
    game, frame = system.game, system.frames[0]
    version = game.version
    with pytest.raises(VersionNotBumped, match=rf"game {game.id}: calibrations"):
        with write_unit(db_session):
            frame.calibration = Calibration(source=CalibrationSource.EDITED, status=CalibrationStatus.CALIBRATED,
                                            camera={"x": 1})
            system.version += 1  # the system's own bump is not the game's
    assert db_session.get(Frame, frame.id).calibration is None
    with pytest.raises(VersionNotBumped, match=rf"game {game.id}: games \(camera_prior\)"):
        with write_unit(db_session):
            game.camera_prior = {"learned": True}
    assert db_session.execute(sa.select(Game.camera_prior).where(Game.id == game.id)).scalar_one() is None
    with write_unit(db_session):
        frame.calibration = Calibration(source=CalibrationSource.EDITED, status=CalibrationStatus.CALIBRATED,
                                            camera={"x": 1})
        system.version += 1
        game.version += 1
    with write_unit(db_session):
        game.camera_prior = {"learned": True}
        game.version += 1
    assert db_session.execute(sa.select(Game.version).where(Game.id == game.id)).scalar_one() == version + 2
