"""Admission is one rule (issue 30): the predicate on a stored calibration (``is_admitted``, from the pure
``jac_admitted``) and its SQL expression (``admitted_jac_sql``) select the same calibrations, at the edges of the
threshold included: equal to it is not admitted (method.md section 4: strictly above), just above it is, and no JaC
never is."""
from __future__ import annotations

import sqlalchemy as sa
from sqlalchemy.orm import Session

from app.core.config import Settings
from app.datasets.records import CalibrationFields
from app.db.models import JAC_COLUMNS, Calibration, CalibrationSource, CalibrationStatus
from app.geometry.jac import JAC_GAMMAS, jac_admitted
from app.services.calibration.admission import admission_jac, admitted_jac_sql, fields_admitted, is_admitted
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


def test_a_calibration_not_stored_yet_is_admitted_as_its_stored_row_would_be(db_settings: Settings):
    """``fields_admitted`` (what an import's pool task reads of its fresh results) is ``is_admitted`` of the row
    ``apply_calibration`` would write, at the threshold's edges and for a refusal."""
    settings = db_settings
    edge = settings.admit_jac_min
    index = JAC_GAMMAS.index(settings.admit_jac_gamma)
    camera = {"position_meters": [0.0, 60.0, -14.0]}
    for value in (None, edge - 1e-9, edge, edge + 1e-9, 1.0):
        jac = tuple(value if k == index else 0.5 for k in range(3))
        for status in (CalibrationStatus.CALIBRATED, CalibrationStatus.REFUSED):
            fields = CalibrationFields(status=status, camera=camera if status is CalibrationStatus.CALIBRATED else None,
                                       jac=jac)  # type: ignore[arg-type]  # three gammas
            row = Calibration(status=status, camera=fields.camera, flags=[], source=CalibrationSource.COMPUTED)
            row.jac_0005, row.jac_001, row.jac_002 = fields.jac
            assert fields_admitted(fields, settings) == is_admitted(row, settings), (value, status)
    assert fields_admitted(CalibrationFields(status=CalibrationStatus.CALIBRATED, camera=camera,
                                             jac=tuple(1.0 for _ in range(3))), settings)  # type: ignore[arg-type]  # three gammas
