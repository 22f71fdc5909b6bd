"""Admission, recomputation and the calibration pool."""
from __future__ import annotations

import pytest
import sqlalchemy as sa

from app.db.models import CalibrationStatus, System, TriangulationStatus
from app.services.importing import import_soccernet_v3, read_soccernet_v3
from app.services.recompute import admission_jac, calibrate_many, expected_side, is_admitted, recompute_system


def test_admission_follows_the_jac_threshold(db_session, settings, v3_tree):
    import_soccernet_v3(db_session, v3_tree, settings)
    system = db_session.scalars(sa.select(System).where(System.name == "2.png")).one()
    jacs = {f.name: f.calibration.jac_0005 for f in system.frames}
    assert jacs["2_1.png"] is None and 0.75 < jacs["2_3.png"] < 1.0  # refused; a middling frame

    strict = settings.model_copy(update={"admit_jac_min": jacs["2_3.png"]})  # strictly above is required
    tri = recompute_system(db_session, system, strict)
    admitted = {f.name for f in system.frames if f.calibration.admitted}
    assert admitted == {n for n, j in jacs.items() if j is not None and j > jacs["2_3.png"]}
    assert "2_3.png" not in admitted and len(tri.pairs) == len(admitted) * (len(admitted) - 1) // 2

    lenient = settings.model_copy(update={"admit_jac_min": 0.0})
    tri = recompute_system(db_session, system, lenient)
    assert {f.name for f in system.frames if f.calibration.admitted} == {"2.png", "2_2.png", "2_3.png"}
    assert tri.status is TriangulationStatus.TRIANGULATED and len(tri.pairs) == 3

    frame = system.frames[0]
    assert admission_jac(frame.calibration, settings.model_copy(update={"admit_jac_gamma": 0.02})) == frame.calibration.jac_002
    with pytest.raises(ValueError, match="not a stored JaC gamma"):
        is_admitted(frame.calibration, settings.model_copy(update={"admit_jac_gamma": 0.004}))
    refused = next(f for f in system.frames if f.calibration.status is CalibrationStatus.REFUSED)
    assert not is_admitted(refused.calibration, lenient)


def test_the_process_pool_gives_the_in_process_results(v3_tree):
    (game,) = read_soccernet_v3(v3_tree)
    jobs = [(f.lines, f.width, f.height, expected_side(f.role)) for s in game.systems for f in s.frames]
    assert len(jobs) >= 8  # enough for calibrate_many to use the pool
    seen = []
    pooled = calibrate_many(jobs, workers=2, progress=lambda stage, done, total: seen.append((stage, done, total)))
    inline = calibrate_many(jobs, workers=1)
    strip = [(r.status, r.camera, r.jac, r.residuals_px, r.flags, r.reason) for r in pooled]
    assert strip == [(r.status, r.camera, r.jac, r.residuals_px, r.flags, r.reason) for r in inline]
    assert seen[-1] == ("calibrate", len(jobs), len(jobs)) and len(seen) == len(jobs)
