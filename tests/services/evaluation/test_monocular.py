"""The monocular benchmark (``app.services.evaluation.monocular``) on hand-built views with known answers.

Two views of one camera 1000 px focal: ball A 15 m in front of the camera on its optical axis, ball
B 50 m away off the axis. Reference boxes are the paper's boxes of those balls (Eq. min_diametre on
the true projection), so the paper estimator recovers the balls exactly; boxes scaled by 1.1 about
their centres put the ball at 1/1.1 of its depth on the same ray: error = D (1 - 1/1.1).
"""
from __future__ import annotations

import json

import numpy as np
import pytest

from app.core.errors import InvalidInputError
from app.geometry.ball import optimise_box, sphere_image_box
from app.geometry.camera import Camera
from app.geometry.metrics import Detections
from app.geometry.sensitivity import scale_boxes
from app.services.evaluation.monocular import ReferenceView, evaluate
from app.services.transfer.detector_export import coco_image_id
from app.services.transfer.detector_files import load_predictions

CAM = Camera.from_parameters(focal_px=1000.0, principal_point=(960.0, 540.0), pan_deg=0.0, tilt_deg=90.0,
                             roll_deg=0.0, position_m=[0.0, 50.0, -10.0])
SHRINK = 1 - 1 / 1.1  # 0.0909...


def _view(stem: str, ball: list[float], split: str, method: str = "paper") -> ReferenceView:
    ball_a = np.array(ball)
    uv, _ = CAM.project(ball_a[None, :])
    box = optimise_box(CAM, uv[0], ball_a, 0.22, method=method).box
    return ReferenceView(hash(stem) % 1000, stem, split, 1920, 1080, box, ball_a, CAM)


@pytest.fixture
def views() -> list[ReferenceView]:
    # The camera looks along +y (tilt 90 deg) from y = 50: depth = 50 - y.
    return [_view("a", [0.0, 35.0, -10.0], "train"), _view("b", [6.0, 0.0, -12.0], "test")]


def _dets(views, factor=1.0, extra=()):
    ids = [v.stem for v in views] + [e[0] for e in extra]
    boxes = [scale_boxes(v.box[None], factor)[0] for v in views] + [e[1] for e in extra]
    scores = [0.9] * len(views) + [e[2] for e in extra]
    return Detections(tuple(ids), np.array(boxes), np.array(scores))


def test_reference_boxes_as_detections_give_ap_1_and_no_error(views):
    rep = evaluate(views, _dets(views), estimator="paper")
    assert rep["AP50"] == 1.0
    assert rep["MAE_m"] == pytest.approx(0.0, abs=1e-9) and rep["MAE_pct"] == pytest.approx(0.0, abs=1e-9)
    assert rep["P_2m"] == 1.0
    assert rep["counts"]["localised"] == 2 and rep["counts"]["reference_views"] == 2


def test_boxes_scaled_by_1_1_give_mae_pct_9_09_and_ap_1(views):
    rep = evaluate(views, _dets(views, 1.1), estimator="paper")
    d_a = 15.0
    d_b = float(np.linalg.norm(np.array([6.0, 0.0, -12.0]) - CAM.C))
    assert rep["AP50"] == 1.0  # IoU of a box scaled by 1.1 with itself: 1 / 1.21 = 0.83 >= 0.5
    assert rep["MAE_pct"] == pytest.approx(100 * SHRINK, abs=1e-6)  # 9.0909
    assert rep["MAE_m"] == pytest.approx((d_a + d_b) * SHRINK / 2, abs=1e-6)  # (15 + 50.36) * 0.0909 / 2
    # A: 15 * 0.0909 = 1.36 m < 2 m; B: 4.58 m > 2 m.
    assert rep["P_2m"] == 0.5
    curve = dict(zip(rep["curve"]["thresholds_m"], rep["curve"]["precision"], strict=False))
    assert (curve[1.25], curve[1.5], curve[4.5], curve[4.75]) == (0.0, 0.5, 0.5, 1.0)
    # Per split: A in train, B in test.
    assert rep["splits"]["train"]["MAE_m"] == pytest.approx(d_a * SHRINK, abs=1e-6)
    assert rep["splits"]["test"]["MAE_pct"] == pytest.approx(100 * SHRINK, abs=1e-6)
    assert set(rep) == {"AP50", "MAE_m", "MAE_pct", "P_2m", "curve", "counts", "splits"}
    json.dumps(rep)


def test_the_exact_estimator_on_exact_boxes_scaled_by_1_1():
    """Exact silhouette boxes (v3d's default optimised boxes): the exact inverse recovers the ball;
    scaled by 1.1 the ball comes 1/1.1 nearer up to the sphere's angular size (asin(r/D) ~ r/D)."""
    vs = [_view("a", [0.0, 35.0, -10.0], "train", "exact_ray"), _view("b", [6.0, 0.0, -12.0], "test", "exact_ray")]
    assert evaluate(vs, _dets(vs), estimator="exact")["MAE_m"] == pytest.approx(0.0, abs=1e-6)
    assert evaluate(vs, _dets(vs, 1.1), estimator="exact")["MAE_pct"] == pytest.approx(100 * SHRINK, abs=0.01)


def test_false_positives_lower_ap_and_do_not_count_for_the_3d_error(views):
    far = np.array([100.0, 100.0, 110.0, 110.0])
    # ranks: FP (0.95) in a, TP a, TP b -> precision 1/2 and 2/3 at recall 1/2 and 1 -> AP = 2/3.
    rep = evaluate(views, _dets(views, 1.0, extra=[("a", far, 0.95), ("elsewhere", far, 0.99)]), ignored=1,
                   estimator="paper")
    assert rep["AP50"] == pytest.approx(2 / 3)
    assert rep["MAE_m"] == pytest.approx(0.0, abs=1e-9)  # the overlapping detection is used, not the FP
    assert rep["counts"]["detections"] == 3 and rep["counts"]["ignored_detections"] == 1


def test_a_view_whose_detections_do_not_overlap_is_not_localised(views):
    far = np.array([0.0, 0.0, 10.0, 10.0])
    dets = Detections(("a", "b"), np.array([views[0].box, far]), np.array([0.9, 0.8]))
    rep = evaluate(views, dets, estimator="paper")
    assert rep["counts"]["localised"] == 1
    assert rep["AP50"] == pytest.approx(0.5)  # TP then FP: recall 1/2 at precision 1
    assert rep["splits"]["test"]["MAE_m"] is None and rep["splits"]["test"]["AP50"] == 0.0


def test_yolo_and_coco_predictions_are_matched_by_stem_and_image_id(views, tmp_path):
    folder = tmp_path / "pred" / "labels"
    folder.mkdir(parents=True)
    b = views[0].box
    cx, cy, w, h = (b[0] + b[2]) / 2 / 1920, (b[1] + b[3]) / 2 / 1080, (b[2] - b[0]) / 1920, (b[3] - b[1]) / 1080
    (folder / "a.txt").write_text(f"0 {cx} {cy} {w} {h} 0.8\n3 0.5 0.5 0.1 0.1 0.9\n")
    (folder / "zzz.txt").write_text("0 0.5 0.5 0.1 0.1 0.7\n")
    (tmp_path / "pred" / "data.yaml").write_text('names:\n  0: "Player"\n  3: "Ball"\n')
    dets, ignored = load_predictions(tmp_path / "pred", views)  # ball class 3 from data.yaml
    assert dets.image_ids == ("a",) and dets.scores.tolist() == [0.9] and ignored == 0
    dets, ignored = load_predictions(tmp_path / "pred", views, ball_class=0)  # zzz is no reference view
    assert dets.image_ids == ("a",) and np.allclose(dets.boxes[0], b) and ignored == 1

    coco = tmp_path / "results.json"
    coco.write_text(json.dumps([
        {"image_id": coco_image_id("b"), "category_id": 1, "bbox": [1.0, 2.0, 3.0, 4.0], "score": 0.5},
        {"image_id": -5, "category_id": 1, "bbox": [1.0, 2.0, 3.0, 4.0], "score": 0.5},
        {"image_id": coco_image_id("b"), "category_id": 2, "bbox": [1.0, 2.0, 3.0, 4.0], "score": 0.5}]))
    dets, ignored = load_predictions(coco, views)
    assert dets.image_ids == ("b",) and dets.boxes.tolist() == [[1.0, 2.0, 4.0, 6.0]] and ignored == 1


def test_bad_predictions_are_refused_with_the_field(views, tmp_path):
    (tmp_path / "a.txt").write_text("0 0.5 0.5 0.1\n")
    with pytest.raises(InvalidInputError, match="predictions.*expected 'class cx cy w h conf'"):
        load_predictions(tmp_path, views)
    with pytest.raises(InvalidInputError, match="no such file"):
        load_predictions(tmp_path / "missing.json", views)
    with pytest.raises(InvalidInputError, match="no view with a 3D ball"):
        evaluate([], _dets([]))


def test_sphere_box_sanity():
    """The reference ball B is off the optical axis: its exact box is not square (why 'exact' exists)."""
    box = sphere_image_box(CAM, [6.0, 0.0, -12.0], 0.11)
    assert box[2] - box[0] != pytest.approx(box[3] - box[1], rel=1e-6)
