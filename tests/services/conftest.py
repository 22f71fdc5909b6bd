"""Fixtures of the service tests (datasets from :mod:`tests.services.datasets`, extra databases)."""
from __future__ import annotations

from collections.abc import Callable, Iterator
from pathlib import Path

import pytest
from sqlalchemy.orm import Session

from app.core.config import Settings
from app.db.session import make_engine, make_session_factory
from tests.conftest import migrate_new_database

from .datasets import write_v3_game


@pytest.fixture
def v3_tree(shared_dir: Path, tmp_path: Path) -> Path:
    """Root of a SoccerNet-v3 tree with the :data:`DEFAULT_ACTIONS` systems of the dev game."""
    root = tmp_path / "v3"
    write_v3_game(shared_dir, root)
    return root


@pytest.fixture
def fresh_session_factory(tmp_path: Path) -> Iterator[Callable[[str], Session]]:
    """``make(name)``: a session on a new migrated SQLite file (for tests that need two databases)."""
    engines = []

    def make(name: str) -> Session:
        url = f"sqlite:///{tmp_path / (name + '.sqlite3')}"
        migrate_new_database(url)
        engine = make_engine(url)
        engines.append(engine)
        return make_session_factory(engine)()

    yield make
    for e in engines:
        e.dispose()


@pytest.fixture
def settings(db_settings: Settings) -> Settings:
    return db_settings


@pytest.fixture
def imported(db_session: Session, settings: Settings, v3_tree: Path, shared_dir: Path) -> dict:
    """:func:`v3_tree` imported, then every frame's camera replaced by its true camera (source
    "edited", JaC computed against the frame's lines) and every system recomputed, so that what the
    tests read does not depend on the calibration solver of the day. Returns system name -> System.

    With the true cameras: 0.png has one kept pair; 2.png four admitted views (2_3.png at
    JaC@0.5 % = 0.867, the others 1.0) and six kept pairs; 3.png a near-duplicate replay whose
    only pair is dropped for its baseline (0.47 m).
    """
    import sqlalchemy as sa

    from app.datasets.records import CalibrationFields
    from app.db.models import CalibrationSource, CalibrationStatus, System
    from app.geometry.annotations import lines_from_json_lists
    from app.geometry.camera import Camera
    from app.geometry.jac import JAC_GAMMAS, jac_at_gammas
    from app.services.calibration.calibrating import apply_calibration
    from app.services.derivation.recompute import recompute_systems
    from app.services.transfer.importing import import_soccernet_v3

    from .datasets import true_cameras

    import_soccernet_v3(db_session, v3_tree, settings)
    cameras = true_cameras(shared_dir)
    systems = db_session.scalars(sa.select(System).order_by(System.id)).all()
    for system in systems:
        for frame in system.frames:
            cam = cameras[(system.name, frame.name)]
            jac = jac_at_gammas(Camera.from_soccernet(cam), lines_from_json_lists(frame.field_lines.lines),
                                frame.width, frame.height, JAC_GAMMAS)
            apply_calibration(frame, CalibrationFields(CalibrationStatus.CALIBRATED, cam,
                                                       tuple(jac[g] for g in JAC_GAMMAS)), CalibrationSource.EDITED)
    recompute_systems(db_session, systems, settings)
    db_session.commit()
    return {s.name: s for s in systems}
