"""Admission, recomputation and the calibration pool."""
from __future__ import annotations

import numpy as np
import pytest

from app.db.models import Calibration, CalibrationSource, CalibrationStatus, TriangulationStatus
from app.services.calibration.admission import admission_jac, is_admitted
from app.services.calibration.calibrating import expected_side
from app.services.calibration.pool import calibrate_many
from app.services.derivation.recompute import recompute_system
from app.services.transfer.importing import read_soccernet_v3

from ..datasets import true_balls


def test_admission_follows_the_jac_threshold(db_session, settings, imported):
    system = imported["2.png"]
    jacs = {f.name: f.calibration.jac_0005 for f in system.frames}
    assert jacs == {"2.png": 1.0, "2_1.png": 1.0, "2_2.png": 1.0, "2_3.png": pytest.approx(13 / 15)}

    strict = settings.model_copy(update={"admit_jac_min": jacs["2_3.png"], "ball_rule": "weights"})  # strictly above
    tri = recompute_system(db_session, system, strict)
    assert {f.name for f in system.frames if f.calibration.admitted} == {"2.png", "2_1.png", "2_2.png"}
    assert len(tri.pairs) == 3 and _frame(system, "2_3.png").optimised_box is None
    assert _frame(system, "2_3.png").reprojection is not None  # calibrated: the ball is still drawn there

    # Judged by evidence, a view below admission whose camera still fits most of its own lines (13 of 15 points)
    # takes part, weighed by its uncertainty; one that fits under half of them does not.
    tri = recompute_system(db_session, system, strict.model_copy(update={"ball_rule": "evidence"}))
    assert not _frame(system, "2_3.png").calibration.admitted and len(tri.pairs) == 6
    assert tri.status is TriangulationStatus.TRIANGULATED
    assert _frame(system, "2_3.png").optimised_box is None  # drawn for admitted views only, as before
    _frame(system, "2_3.png").calibration.jac_0005 = 0.4
    tri = recompute_system(db_session, system, strict.model_copy(update={"ball_rule": "evidence"}))
    assert len(tri.pairs) == 3
    _frame(system, "2_3.png").calibration.jac_0005 = jacs["2_3.png"]

    tri = recompute_system(db_session, system, settings)
    assert all(f.calibration.admitted for f in system.frames)
    assert tri.status is TriangulationStatus.TRIANGULATED and len(tri.pairs) == 6

    frame = system.frames[0]
    assert admission_jac(frame.calibration,
                         settings.model_copy(update={"admit_jac_gamma": 0.02})) == frame.calibration.jac_002
    with pytest.raises(ValueError, match="not a stored JaC gamma"):
        is_admitted(frame.calibration, settings.model_copy(update={"admit_jac_gamma": 0.004}))
    refused = Calibration(source=CalibrationSource.COMPUTED, status=CalibrationStatus.REFUSED, jac_0005=1.0)
    assert not is_admitted(refused, settings) and not is_admitted(None, settings)


def _frame(system, name):
    return next(f for f in system.frames if f.name == name)


def test_triangulation_with_true_cameras_finds_the_true_ball(imported, shared_dir, settings):
    balls = true_balls(shared_dir)
    for name in ("0.png", "2.png"):
        tri = imported[name].triangulation
        assert tri.status is TriangulationStatus.TRIANGULATED and all(p.kept for p in tri.pairs)
        assert np.linalg.norm(np.subtract(tri.ball3d, balls[name])) < 0.1  # metres
        for frame in imported[name].frames:
            assert frame.reprojection.error_px < 5.0  # px, label noise only
            box = frame.optimised_box.box
            # d_opt is the mean of the optimised box's width and height (square for the paper's box).
            assert (box[2] - box[0] + box[3] - box[1]) / 2 == pytest.approx(frame.optimised_box.d_opt_px)
            # on the annotated centre, to the sub-pixel outward shift of an off-axis sphere's image
            assert [(box[0] + box[2]) / 2, (box[1] + box[3]) / 2] == pytest.approx(frame.ball_label.centre, abs=0.1)
    # 3.png: the replay is a near-duplicate viewpoint; its pair is dropped for the baseline
    (pair,) = imported["3.png"].triangulation.pairs
    assert (pair.kept, pair.reason) == (False, "baseline_below_min") and pair.baseline_m < settings.min_baseline_m
    assert imported["3.png"].triangulation.status is TriangulationStatus.NO_PAIR_KEPT
    assert imported["3.png"].triangulation.ball3d is None


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


def test_a_changed_profile_marks_the_stored_results_stale_until_recompute(db_session, settings, imported):
    """Issue 19 (item 5): each system stores the fingerprint of the settings it was computed with; under
    ``V3D_PROFILE=paper`` every system computed with v3d's defaults counts as stale (``/api/stats``, ``v3d serve``)
    until ``v3d recompute``; an explicit setting equal to the default changes nothing."""
    from app.core.config import Settings
    from app.services.derivation.recompute import recompute_all_systems, systems_computed_otherwise
    from app.services.evaluation.stats import dataset_stats

    n = len(imported)
    assert systems_computed_otherwise(db_session, settings) == 0
    paper = Settings(_env_file=None, database_url=settings.database_url, calibration_workers=1, profile="paper")
    assert systems_computed_otherwise(db_session, paper) == n
    assert dataset_stats(db_session, paper)["stale_systems"] == n
    same = settings.model_copy(update={"min_parallax_deg": settings.min_parallax_deg})
    assert systems_computed_otherwise(db_session, same) == 0
    assert recompute_all_systems(db_session, paper)[0] == n
    assert systems_computed_otherwise(db_session, paper) == 0
    assert systems_computed_otherwise(db_session, settings) == n


def test_a_pair_whose_views_disagree_on_their_players_makes_no_ball_by_evidence(db_session, settings, imported):
    """0.png's two views (true cameras) make one kept pair and a ball. The players' boxes moved 120 px (of 960) in the
    replay, as a replay of another instant shows them (27 standard deviations against the main view's players; 40 px
    gives 8.6, within ``LINES_CONTRADICTED_SIGMA``), the ball's label left as it is, so its rays still meet: judged by
    evidence the pair is left out (``players_disagree``) and no ball stands; the rule by class, which reads no
    players, keeps it."""
    system = imported["0.png"]
    by_evidence = settings.model_copy(update={"ball_rule": "evidence"})
    tri = recompute_system(db_session, system, by_evidence)
    assert tri.status is TriangulationStatus.TRIANGULATED and [p.kept for p in tri.pairs] == [True]
    replay = _frame(system, "0_1.png")
    assert sum(p.ident is not None for p in replay.players) >= 3
    for p in replay.players:
        p.x1, p.x2 = p.x1 + 120.0, p.x2 + 120.0
    tri = recompute_system(db_session, system, by_evidence)
    assert tri.ball3d is None and [p.reason for p in tri.pairs] == ["players_disagree"]
    tri = recompute_system(db_session, system, by_evidence.model_copy(update={"ball_rule": "weights"}))
    assert tri.ball3d is not None
