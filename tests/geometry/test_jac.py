"""JaC as SoccerNet's official evaluator computes it (app/geometry/jac.py).

Synthetic scene: a camera 60 m straight above the centre spot (f = 500 px, principal point
(480, 270), 960x540), so a ground point (X, Y) lands at (480 + X * 500 / 60, 270 + Y * 500 / 60).
Moving that camera 0.72 m along world x moves every ground line by exactly 6 px in the image, which
fixes by hand which classes pass at 5 px and which at 10 px.

Real data: the official evaluator's values for PnLCalib's cameras on the SoccerNet-calibration 2022
test split and the WC14 test split (``/work/shared/data/real``).
"""
from __future__ import annotations

import json
import zipfile
from pathlib import Path

import numpy as np
import pytest

from app.geometry.annotations import AnnotationError, FieldLines, from_soccernet_calibration, mirror_lines
from app.geometry.camera import Camera
from app.geometry.jac import (
    evaluate_jac,
    gamma_thresholds,
    jac_at_gammas,
    point_to_polyline_distances,
)
from app.geometry.pitch import CIRCLES, KEY_POINTS, LINE_EXTREMITY_KEYS, MIRROR_CLASSES, sample_pitch_polylines

W, H = 960, 540
SCALE = 500.0 / 60.0

# Classes of the overhead scene, by the direction of their image: lines along world y are vertical
# in the image (a shift along x moves them by 6 px), lines along world x slide along themselves.
ALONG_Y = {"Side line left", "Side line right", "Middle line", "Big rect. left main", "Big rect. right main",
           "Small rect. left main", "Small rect. right main"}
ALONG_X = {"Big rect. left top", "Big rect. left bottom", "Big rect. right top", "Big rect. right bottom",
           "Small rect. left top", "Small rect. left bottom", "Small rect. right top", "Small rect. right bottom"}
CIRCLE_CLASSES = {"Circle central", "Circle left", "Circle right"}
CROSSBARS = {"Goal left crossbar", "Goal right crossbar"}
POSTS = {"Goal left post left ", "Goal left post right", "Goal right post left", "Goal right post right"}
VISIBLE = ALONG_Y | ALONG_X | CIRCLE_CLASSES | CROSSBARS | POSTS


def overhead(x: float = 0.0) -> Camera:
    return Camera.from_parameters(focal_px=500.0, principal_point=(480.0, 270.0), pan_deg=0.0, tilt_deg=0.0,
                                  roll_deg=0.0, position_m=[x, 0.0, -60.0])


def annotate(camera: Camera) -> FieldLines:
    """Annotated points: each element's world samples at 20 %, 35 %, 50 %, 65 % and 80 % of its
    length (the centre circle also at angle 0), projected with ``camera``; kept 10 px inside."""
    out: FieldLines = {}
    for cls, pts in sample_pitch_polylines(0.1, 0.2).items():
        fractions = [0.0, 0.25, 0.5, 0.75] if cls == "Circle central" else [0.2, 0.35, 0.5, 0.65, 0.8]
        idx = np.round(np.array(fractions) * (len(pts) - 1)).astype(int)
        uv, ok = camera.project(pts[idx])
        keep = ok & np.all((uv > 10) & (uv < np.array([W, H]) - 10), axis=1)
        if keep.any():
            out[cls] = [uv[keep]]
    return out


@pytest.fixture(scope="module")
def truth_lines() -> FieldLines:
    return annotate(overhead())


def test_the_synthetic_annotation_covers_the_expected_classes(truth_lines):
    assert set(truth_lines) == VISIBLE


def test_a_perfect_camera_scores_one(truth_lines):
    result = evaluate_jac(overhead(), truth_lines, W, H, (5, 10, 20))
    assert result.jac == {5.0: 1.0, 10.0: 1.0, 20.0: 1.0}
    at5 = result.at(5.0)
    assert (at5.tp, at5.fp, at5.fn, at5.mirrored) == (len(VISIBLE), 0, 0, False)
    assert set(at5.classes.values()) == {"TP"}
    assert max(float(d.max()) for d in result.distances_px.values()) < 0.01


def test_a_shifted_camera_drops_exactly_the_classes_that_moved_across_the_threshold(truth_lines):
    result = evaluate_jac(overhead(x=0.72), truth_lines, W, H, (5, 10, 20))
    # Lines along y move 6 px away; the circles' points at angle 0 or 180 degrees too; the crossbars
    # (2.44 m nearer the camera) 6.25 px. Lines along x and the nearly radial posts stay within 5 px.
    np.testing.assert_allclose(result.distances_px["Middle line"], 6.0, atol=1e-9)
    np.testing.assert_allclose(result.distances_px["Big rect. left top"], 0.0, atol=1e-9)
    # (float32 pixel coordinates, as the evaluator: agreement to 1e-4 px, not 1e-9)
    assert result.distances_px["Goal left crossbar"] == pytest.approx(500 * 0.72 / 57.56, abs=1e-4)
    failing = ALONG_Y | CIRCLE_CLASSES | CROSSBARS
    at5 = result.at(5.0)
    assert {c for c, o in at5.classes.items() if o == "FP"} == failing
    assert at5.jac == pytest.approx((len(VISIBLE) - len(failing)) / len(VISIBLE), abs=1e-7)
    assert result.at(10.0).jac == 1.0 and result.at(20.0).jac == 1.0


def test_a_mirrored_labelling_scores_the_same_through_the_mirror(truth_lines):
    mirrored_labels = mirror_lines(truth_lines)
    result = evaluate_jac(overhead(), mirrored_labels, W, H, (5, 10, 20))
    assert result.jac == {5.0: 1.0, 10.0: 1.0, 20.0: 1.0}
    assert all(t.mirrored for t in result.per_threshold)
    assert set(result.at(5.0).classes) == VISIBLE  # scored under the model's own names
    # Taken as they are, the mirrored labels miss: "Big rect. right main" sits where the left one is.
    assert result.distances_px["Big rect. right main"].min() > 100


def test_a_tie_keeps_the_direct_labelling(truth_lines):
    # Middle line and centre circle are their own mirrors: both labellings score the same.
    lines = {c: truth_lines[c] for c in ("Middle line", "Circle central")}
    result = evaluate_jac(overhead(), lines, W, H, (5,))
    at5 = result.at(5.0)
    assert not at5.mirrored
    # The other visible classes are projected but not annotated: false positives.
    assert (at5.tp, at5.fp, at5.fn) == (2, len(VISIBLE) - 2, 0)
    assert at5.jac == pytest.approx(2 / len(VISIBLE), abs=1e-7)


def test_annotated_classes_without_projection_are_false_negatives(truth_lines):
    lines = dict(truth_lines)
    lines["Side line top"] = [np.array([[100.0, 5.0], [800.0, 5.0]])]  # out of view for this camera
    lines["Goal unknown"] = [np.array([[30.0, 280.0]])]  # no model element at all
    at5 = evaluate_jac(overhead(), lines, W, H, (5,)).at(5.0)
    assert (at5.tp, at5.fp, at5.fn) == (len(VISIBLE), 0, 2)
    assert at5.classes["Side line top"] == "FN" and at5.classes["Goal unknown"] == "FN"
    assert at5.jac == float(np.float32(len(VISIBLE)) / np.float32(len(VISIBLE) + 2))


def test_a_camera_that_sees_no_pitch_scores_zero(truth_lines):
    sky = Camera.from_parameters(focal_px=500.0, principal_point=(480.0, 270.0), pan_deg=0.0, tilt_deg=170.0,
                                 roll_deg=0.0, position_m=[0.0, 0.0, -60.0])
    result = evaluate_jac(sky, truth_lines, W, H, (20,))
    assert result.projected_classes == frozenset()
    at20 = result.at(20.0)
    assert (at20.jac, at20.tp, at20.fp, at20.fn) == (0.0, 0, 0, len(VISIBLE))
    assert evaluate_jac(sky, {}, W, H, (20,)).at(20.0).jac == 0.0  # nothing at all: 0, as the evaluator


def test_a_class_split_into_several_polylines_pools_its_points(truth_lines):
    split = {c: [p[:2], p[2:]] if len(p) > 2 else [p] for c, (p,) in truth_lines.items()}
    a = evaluate_jac(overhead(x=0.72), truth_lines, W, H, (5, 10))
    b = evaluate_jac(overhead(x=0.72), split, W, H, (5, 10))
    assert a.jac == b.jac
    for cls in a.distances_px:
        np.testing.assert_array_equal(a.distances_px[cls], b.distances_px[cls])


def test_jac_at_gammas_uses_the_image_diagonal(truth_lines):
    assert gamma_thresholds(960, 540) == pytest.approx((5.50727, 11.01454, 22.02907), abs=1e-5)
    assert gamma_thresholds(1920, 1080)[1] == pytest.approx(22.02907, abs=1e-5)
    scores = jac_at_gammas(overhead(x=0.72), truth_lines, W, H)
    n = len(VISIBLE)
    failing = len(ALONG_Y | CIRCLE_CLASSES | CROSSBARS)  # 6 and 6.25 px > 5.51 px
    assert scores == pytest.approx({0.005: (n - failing) / n, 0.01: 1.0, 0.02: 1.0}, abs=1e-7)


def test_bad_input_raises_clear_errors(truth_lines):
    with pytest.raises(AnnotationError, match="Side line middle"):
        evaluate_jac(overhead(), {"Side line middle": [np.zeros((1, 2))]}, W, H)
    with pytest.raises(AnnotationError, match="finite"):
        evaluate_jac(overhead(), {"Middle line": [np.array([[np.nan, 1.0]])]}, W, H)
    with pytest.raises(ValueError, match="thresholds_px"):
        evaluate_jac(overhead(), truth_lines, W, H, (5, -1))
    with pytest.raises(ValueError, match="gamma"):
        jac_at_gammas(overhead(), truth_lines, W, H, (0.0,))
    with pytest.raises(KeyError):
        evaluate_jac(overhead(), truth_lines, W, H, (5,)).at(7.0)


def test_point_to_polyline_distances_on_known_geometry():
    poly = np.array([[0.0, 0.0], [10.0, 0.0], [10.0, 10.0]])
    pts = np.array([[5.0, 2.0], [12.0, 5.0], [-3.0, -4.0], [10.0, 13.0], [10.0, 0.0], [7.0, 3.0]])
    np.testing.assert_allclose(point_to_polyline_distances(pts, poly), [2.0, 2.0, 5.0, 3.0, 0.0, 3.0], atol=1e-12)
    # A one-point polyline and a zero-length segment fall back to point distances.
    np.testing.assert_allclose(point_to_polyline_distances(pts[:1], poly[:1]), [np.hypot(5, 2)])
    np.testing.assert_allclose(point_to_polyline_distances(pts[:1], np.array([[1.0, 1.0], [1.0, 1.0]])),
                               [np.hypot(4, 1)])
    with pytest.raises(ValueError, match="polyline"):
        point_to_polyline_distances(pts, np.zeros((0, 2)))


def test_point_to_polyline_distances_agree_with_dense_sampling():
    rng = np.random.default_rng(7)
    poly = rng.uniform(0, 100, size=(8, 2))
    pts = rng.uniform(-20, 120, size=(60, 2))
    t = np.linspace(0, 1, 1001)[:, None, None]
    dense = (poly[:-1] + t * (poly[1:] - poly[:-1])).reshape(-1, 2)
    ref = np.min(np.linalg.norm(pts[:, None, :] - dense[None], axis=2), axis=1)
    got = point_to_polyline_distances(pts, poly)
    assert np.all(got <= ref + 1e-9)
    assert np.max(ref - got) < 0.08  # dense spacing <= 0.15 px, so the sampled distance is <= 0.075 px too long


def test_mirror_map_is_the_180_degree_rotation_of_the_model():
    """Regression: the foundation's map sent "Goal left post left " to "Goal right post right"; the
    180-degree rotation (x, y) -> (-x, -y) sends the post at y = +3.66 to the one at y = -3.66,
    "Goal right post left" (official ``symetric_classes``). JaC of mirrored frames was wrong."""
    def rotated(name: str) -> np.ndarray:
        return KEY_POINTS[name] * np.array([-1.0, -1.0, 1.0])

    for cls, (a, b) in LINE_EXTREMITY_KEYS.items():
        ma, mb = LINE_EXTREMITY_KEYS[MIRROR_CLASSES[cls]]
        ends = {tuple(np.round(KEY_POINTS[k], 9)) for k in (ma, mb)}
        assert {tuple(np.round(rotated(k), 9)) for k in (a, b)} == ends, cls
    for cls, (centre, _) in CIRCLES.items():
        np.testing.assert_allclose(centre * [-1, -1, 1], CIRCLES[MIRROR_CLASSES[cls]][0], atol=1e-12)


# ----- the official values ------------------------------------------------------------------------

def _official_comparison(folder: Path) -> tuple[int, list[str], list[str]]:
    """(pairs compared, unexplained mismatches, explained mismatches) over every frame of a folder."""
    official = json.loads((folder / "official-jac-pnlcalib.json").read_text())
    w, h, thresholds = official["width"], official["height"], official["thresholds_px"]
    with zipfile.ZipFile(folder / "annotations.zip") as za, zipfile.ZipFile(folder / "pnlcalib-cameras.zip") as zc:
        cameras = {Path(n).name: n for n in zc.namelist()}
        frames = {Path(n).stem: n for n in za.namelist() if n.endswith(".json")}
        assert set(frames) == set(official["frames"])
        pairs, unexplained, explained = 0, [], []
        for frame, name in sorted(frames.items()):
            expected = official["frames"][frame]
            cam_name = cameras.get(f"camera_{frame}.json")
            assert (cam_name is None) == (expected is None), frame
            if cam_name is None:
                continue
            lines = from_soccernet_calibration(json.loads(za.read(name)), w, h)
            result = evaluate_jac(Camera.from_soccernet(json.loads(zc.read(cam_name))), lines, w, h, thresholds)
            for t, got, want in zip(thresholds, (r.jac for r in result.per_threshold), expected, strict=False):
                pairs += 1
                if abs(got - want) <= 1e-6:
                    continue
                d = np.concatenate([np.zeros(0), *result.distances_px.values(),
                                    *result.mirrored_distances_px.values()])
                gap = float(np.min(np.abs(d - t))) if len(d) else np.inf
                (explained if gap <= 0.01 else unexplained).append(
                    f"{folder.name}/{frame}@{t}px: v3d {got:.7f} official {want:.7f}, "
                    f"nearest point {gap:.4f} px from t")
    return pairs, unexplained, explained


@pytest.mark.parametrize("dataset", ["sn-calib-2022-test-main", "wc14-test"])
def test_reproduces_the_official_evaluator_on_every_frame(shared_dir, dataset):
    pairs, unexplained, explained = _official_comparison(shared_dir / "data" / "real" / dataset)
    mismatches = unexplained + explained
    print(f"{dataset}: {pairs - len(mismatches)}/{pairs} pairs within 1e-6; {len(explained)} explained "
          f"by a point within 0.01 px of the threshold: {mismatches}")
    assert pairs > 500
    assert not unexplained, unexplained
    assert (pairs - len(mismatches)) / pairs >= 0.998, mismatches


def test_polylines_that_are_not_pixel_pairs_raise():
    """Regression: annotated polylines were read with ``reshape(-1, 2)``, so an (N, 3) array (world
    points passed by mistake for pixels) was regrouped into pixel pairs and scored without a word."""
    with pytest.raises(AnnotationError, match="'Middle line', polyline 0: expected"):
        evaluate_jac(overhead(), {"Middle line": [np.zeros((2, 3))]}, W, H)
    assert evaluate_jac(overhead(), {"Middle line": [np.array([480.0, 100.0])]}, W, H).per_threshold
