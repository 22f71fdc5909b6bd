"""Acceptance test of the whole pipeline on the synthetic SoccerNet-v3 dev set (``../shared``).

The dev set is imported once per module with the service (``benchmarks/synthetic_pipeline.py``:
calibration, game rig, admission, triangulation, optimised boxes into a fresh migrated SQLite file),
and what was stored is compared with the truth. Bounds sit well away from the measured figures
(quoted in each test) so that they catch regressions, not noise; nothing here is tuned to the dev
games.
"""
from __future__ import annotations

import json
from pathlib import Path

import pytest

pytestmark = pytest.mark.shared


def _benchmark():
    from benchmarks import synthetic_pipeline

    return synthetic_pipeline


@pytest.fixture(scope="module")
def result(shared_dir: Path, tmp_path_factory: pytest.TempPathFactory):
    """The benchmark's figures (import of the 2 dev games, 40 systems, 105 views: about 15 s)."""
    return _benchmark().run(shared_dir, tmp_path_factory.mktemp("synthetic-pipeline"))


def test_the_import_stores_every_view_and_its_labels_unchanged(result):
    rep = result.import_report
    assert (rep["games"], rep["systems"], rep["frames"]) == (2, 40, 105)
    assert rep["calibrated"] + rep["refused"] == 105
    assert result.checks["annotated_box_mismatches"] == []
    assert result.checks["admission_mismatches"] == []
    # The service's first pass is the pure calibrate_frame: recomputing it gives what was stored
    # for every view the rig did not touch (and a refusal where it did).
    assert result.checks["no_rig_recomputation_mismatches"] == []
    json.dumps(result.to_json())  # --json output is plain JSON


def test_calibrated_cameras_are_close_to_the_true_cameras(result):
    """Measured (admitted views, labels not mirrored): centre 0.17 / 1.16 m, rotation 0.06 / 0.18 deg
    (median / p90); 84 of 105 views admitted."""
    row = result.calibration["rows"]["with_rig"]
    assert row["admitted"] >= 70
    assert row["mean_jac_admitted"] > 0.9
    pos, ang = row["position_error_m_admitted"], row["angle_error_deg_admitted"]
    assert pos["n"] >= 70 and pos["median"] < 0.5 and pos["p90"] < 2.5
    assert ang["median"] < 0.2 and ang["p90"] < 0.5


def test_the_game_rig_admits_more_views_without_lowering_their_jac(result):
    """Measured: 74 views admitted without the rig, 84 with it (ratio 1.135; mean JaC 0.944 -> 0.948),
    every reachable view: the issue asked for 1.5 times as many, but on this dev set at most 84 views
    can be admitted at all (true camera above the admission rule and enough lines for a known
    centre), so the test asks for nearly all of what is reachable instead. Every rig-assisted view is
    near its true camera (measured at most 0.67 m, 0.41 deg): a rig fit that does not fit the labels
    is refused, not stored (before: one view placed 89 m off with JaC 0, one 22 deg off)."""
    cal = result.calibration
    without, with_rig = cal["rows"]["no_rig"], cal["rows"]["with_rig"]
    assert with_rig["admitted"] > without["admitted"]
    assert with_rig["mean_jac_admitted"] >= without["mean_jac_admitted"] - 0.01
    assert cal["lost_by_rig"] == []
    assert with_rig["admitted"] >= 0.95 * cal["reachable"]
    assert cal["rig_assisted_views"]
    for view in cal["rig_assisted_views"]:
        position_m, angle_deg = view["pose"]
        assert position_m < 2.0 and angle_deg < 1.0, view


def test_no_view_with_correct_labels_is_flagged_mirrored(result):
    assert result.mirror["flagged_not_mirrored"] == 0, result.mirror["views"]


def test_every_view_with_mirrored_labels_is_flagged(result):
    """The dev set's two mirrored views are a replay (no camera-side prior: only the other views of
    its system or the game rig can tell) and an action its lines alone cannot calibrate."""
    assert result.mirror["mirrored"] >= 2
    assert result.mirror["missed"] == 0, result.mirror["views"]


def test_3d_ball_of_uncorrupted_systems_is_within_decimetres(result):
    """Measured: 22 of 32 uncorrupted systems triangulated, error median 0.068 m, p90 0.101 m, max
    0.140 m; fused ball reprojects within 1.8 px (median) of the labelled centres."""
    clean = result.ball["uncorrupted"]
    assert clean["systems"] == 32 and clean["triangulated"] >= 18
    err = clean["error_m"]
    assert err["median"] < 0.2 and err["p90"] < 0.3 and err["max"] < 0.5
    rep = clean["reprojection_error_px_kept_views"]
    assert rep["median"] < 4.0 and rep["p90"] < 12.0


def test_corrupted_views_never_enter_a_kept_pair(result):
    kinds = result.ball["corruptions"]
    assert set(kinds) == {"desync", "wrong_ball", "mirrored", "no_ball"}
    for kind, k in kinds.items():
        assert k["systems"] >= 1
        # Mirrored line labels corrupt a camera fitted to them; a camera the players placed is theirs, not its lines',
        # and its ray may join the ball (judged by evidence, a view below admission that fits most of its own lines
        # takes part: measured, the dev set's mirrored action, placed by its players, JaC 0.6, ball 0.03 m off).
        by_players = sum(kind == "mirrored" and d["camera_by_players"] and d["view"] in d["contributing"]
                         for d in k["details"])
        assert k["corrupted_view_dropped"] + by_players == k["systems"], (kind, k["details"])
        if k["triangulated"]:  # the other views still give the right ball (measured 5 to 11 cm)
            assert k["error_m"]["max"] < 0.5, (kind, k["details"])
    for nd in result.ball["near_duplicates"]:  # a near-duplicate viewpoint never makes the only pair
        assert nd["status"] != "triangulated" or nd["view"] not in nd["contributing"], nd


def test_optimised_boxes_beat_the_annotated_boxes(result):
    """Paper, real data: IoU 0.57 -> 0.66, size error 19.0 % -> 7.3 %. Measured here (v3d's own
    cameras and 3D balls, 57 views): annotated 0.573 / 19.9 %; optimised, paper 0.634 / 1.46 %,
    exact_ray (the default) 0.638 / 0.26 %, exact_fused 0.649 / 0.26 %. The synthetic precise box is
    the exact silhouette, so only the 3D error limits the size; the annotated centre, which paper
    and exact_ray keep, limits the IoU."""
    boxes = result.boxes
    assert boxes["views"] >= 40
    assert result.checks["optimised_box_mismatches"] == []  # stored = optimise_box on stored inputs
    ann = boxes["annotated"]
    assert 0.45 < ann["iou_mean"] < 0.7 and 12.0 < ann["size_error_pct_mean"] < 28.0  # the generator's loose boxes
    for name in ("optimised", "recomputed paper", "recomputed exact_ray", "recomputed exact_fused"):
        opt = boxes[name]
        assert opt["n"] == boxes["views"], name
        assert opt["iou_mean"] > ann["iou_mean"] + 0.03, name
        assert opt["size_error_pct_mean"] < 5.0 < ann["size_error_pct_mean"], name


def test_calibration_stays_fast(result):
    """Measured: median 16 ms per frame in one process (27 ms in the pool); wall times on a shared
    machine, so the bound only catches a change of order of magnitude."""
    assert result.timing["pure_calibration_ms"]["median"] < 500.0
    assert result.timing["import_wall_s"] < 300.0
