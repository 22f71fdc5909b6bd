"""Admission is one rule (issue 30): the predicate on a stored calibration (``is_admitted``, from the pure
``jac_admitted``) and its SQL expression (``admitted_jac_sql``) select the same calibrations, at the edges of the
threshold included: equal to it is not admitted (method.md section 4: strictly above), just above it is, and no JaC
never is."""
from __future__ import annotations

import sqlalchemy as sa
from sqlalchemy.orm import Session

from app.core.config import Settings
from app.db.models import JAC_COLUMNS, Calibration, CalibrationSource, CalibrationStatus
from app.geometry.jac import jac_admitted
from app.services.calibration.admission import admission_jac, admitted_jac_sql, is_admitted
from tests.api.factories import CENTRES, make_game, make_system


def test_the_predicate_and_the_sql_expression_admit_the_same_calibrations(db_session: Session, db_settings: Settings):
    settings = db_settings
    centres = (*CENTRES, [-50.0, -45.0, -12.0], [0.0, -60.0, -20.0])  # five views: one per edge value
    scene = make_system(db_session, settings, make_game(db_session), centres=centres)
    assert len(scene.frame_ids) == 5
    edge = settings.admit_jac_min
    values = [None, edge - 1e-9, edge, edge + 1e-9, 1.0]
    column = JAC_COLUMNS[settings.admit_jac_gamma]
    calibrations = []
    for fid, value in zip(scene.frame_ids, values, strict=False):
        cal = db_session.execute(sa.select(Calibration).where(Calibration.frame_id == fid)).scalar_one()
        setattr(cal, column, value)
        cal.status, cal.source, cal.flags = CalibrationStatus.CALIBRATED, CalibrationSource.EDITED, []
        calibrations.append(cal)
    db_session.flush()
    by_predicate = {c.frame_id for c in calibrations if is_admitted(c, settings)}
    by_sql = set(db_session.execute(sa.select(Calibration.frame_id).where(
        Calibration.frame_id.in_(scene.frame_ids), admitted_jac_sql(settings))).scalars())
    assert by_predicate == by_sql == {scene.frame_ids[3], scene.frame_ids[4]}
    assert [jac_admitted(admission_jac(c, settings), edge) for c in calibrations] == [False, False, False, True, True]
