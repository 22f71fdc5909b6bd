"""Box and 3D-ball metrics (app.geometry.metrics)."""
from __future__ import annotations

import json

import numpy as np
import pytest

from app.geometry.metrics import (
    Detections,
    average_precision,
    box_iou,
    box_size_error_pct,
    coco_results,
    load_yolo_detections,
    monocular_metrics,
    precision_curve,
    voc_ap,
)


def test_iou_values_and_broadcasting():
    a = np.array([[0.0, 0.0, 10.0, 10.0], [0.0, 0.0, 2.0, 2.0]])
    b = np.array([[5.0, 0.0, 15.0, 10.0], [0.0, 0.0, 2.0, 2.0], [20.0, 20.0, 30.0, 30.0]])
    np.testing.assert_allclose(box_iou(a[0], b[0]), 50.0 / 150.0)
    m = box_iou(a[:, None], b[None])
    assert m.shape == (2, 3)
    np.testing.assert_allclose(m, [[1 / 3, 4 / 100, 0.0], [0.0, 1.0, 0.0]])
    assert box_iou(np.array([1.0, 1.0, 1.0, 1.0]), np.array([1.0, 1.0, 1.0, 1.0])) == 0.0  # empty union
    with pytest.raises(ValueError, match="boxes_b must have a last dimension of 4"):
        box_iou(a, np.zeros((2, 3)))


def test_size_error_is_relative_to_the_reference_diagonal():
    ref = np.array([10.0, 10.0, 16.0, 18.0])  # diagonal 10
    np.testing.assert_allclose(box_size_error_pct(np.array([[0.0, 0.0, 3.0, 4.0], [5.0, 5.0, 14.0, 17.0]]), ref),
                               [50.0, 50.0])
    with pytest.raises(ValueError, match="references must have a positive diagonal"):
        box_size_error_pct(ref, np.array([1.0, 1.0, 1.0, 1.0]))


def test_average_precision_on_a_hand_computed_example():
    gt = {"img1": np.array([[0, 0, 10, 10], [20, 20, 30, 30]], float), "img2": np.array([[0, 0, 10, 10]], float)}
    det = Detections(
        ("img2", "img1", "img1", "img2", "img1", "img3", "img1"),
        np.array([[50, 50, 60, 60],    # 0.90 FP (nothing there)
                  [0, 0, 10, 10],      # 0.95 TP (G1, IoU 1)
                  [1, 1, 10, 10],      # 0.85 FP (G1 already matched)
                  [0, 0, 10, 8],       # 0.80 TP (G3, IoU 0.8)
                  [20, 20, 30, 36],    # 0.60 TP (G2, IoU 0.625)
                  [0, 0, 5, 5],        # 0.50 FP (image without ground truth)
                  [22, 20, 32, 30]], float),  # 0.40 FP (G2 already matched)
        np.array([0.90, 0.95, 0.85, 0.80, 0.60, 0.50, 0.40]))
    # ranks: TP FP FP TP TP FP FP; precision 1, 1/2, 1/3, 1/2, 3/5, 1/2, 3/7; recall 1/3 .. 1
    # monotone precision: 1 up to recall 1/3, then 3/5 -> AP = 1/3 + 2/3 * 3/5 = 11/15
    assert average_precision(det, gt) == pytest.approx(11 / 15)
    # at IoU 0.7 the 0.625 match becomes a false positive: AP = 1/3 + 1/3 * 1/2 = 1/2
    assert average_precision(det, gt, iou_threshold=0.7) == pytest.approx(0.5)


def test_average_precision_threshold_is_inclusive_and_empty_truth_raises():
    gt = {"a": np.array([[0.0, 0.0, 10.0, 10.0]])}
    exactly_half = Detections(("a",), np.array([[0.0, 0.0, 10.0, 5.0]]), np.array([0.9]))
    assert average_precision(exactly_half, gt) == 1.0
    assert average_precision(Detections((), np.zeros((0, 4)), np.zeros(0)), gt) == 0.0
    with pytest.raises(ValueError, match="no box"):
        average_precision(exactly_half, {"a": np.zeros((0, 4))})
    with pytest.raises(ValueError, match="differ in length"):
        Detections(("a", "b"), np.zeros((1, 4)), np.zeros(1))


def test_voc_ap_all_point_interpolation():
    # one detection of two ground truths, correct: recall 1/2 at precision 1 -> 0.5
    assert voc_ap(np.array([0.5]), np.array([1.0])) == pytest.approx(0.5)
    # precision rising later lifts the earlier plateau (VOC 2010 monotone envelope)
    assert voc_ap(np.array([0.25, 0.25, 0.5, 1.0]), np.array([1.0, 0.5, 2 / 3, 0.8])) == pytest.approx(0.85)


def test_yolo_loader_converts_normalised_centres_to_pixels(tmp_path):
    f = tmp_path / "frame_7.txt"
    f.write_text("0 0.5 0.5 0.1 0.2 0.9\n1 0.1 0.1 0.05 0.05 0.3\n\n")
    det = load_yolo_detections(f, 1920, 1080)
    assert det.image_ids == ("frame_7", "frame_7")
    np.testing.assert_allclose(det.boxes[0], [864.0, 432.0, 1056.0, 648.0])
    np.testing.assert_allclose(det.scores, [0.9, 0.3])
    only0 = load_yolo_detections(f, 1920, 1080, class_id=0, image_id=7)
    assert only0.image_ids == (7,) and len(only0.boxes) == 1
    f.write_text("0 0.5 0.5 0.1 0.2\n")
    with pytest.raises(ValueError, match="frame_7.txt:1"):
        load_yolo_detections(f, 1920, 1080)


def test_coco_results_are_read_entry_by_entry_and_checked(tmp_path):
    f = tmp_path / "results.json"
    f.write_text(json.dumps([{"image_id": 1, "category_id": 1, "bbox": [10, 20, 5, 6], "score": 0.7},
                             {"image_id": 2, "category_id": 3, "bbox": [0, 0, 1, 1], "score": 0.1}]))
    entries = list(coco_results(f))
    assert [(image_id, category) for image_id, category, _, _ in entries] == [(1, 1), (2, 3)]
    np.testing.assert_allclose(entries[0][2], [10.0, 20.0, 15.0, 26.0])
    assert entries[0][3] == pytest.approx(0.7)
    f.write_text(json.dumps([{"image_id": 1, "bbox": [0, 0, 1, 1]}]))
    with pytest.raises(ValueError, match="entry 0 lacks 'score'"):
        list(coco_results(f))


def test_monocular_metrics_count_only_detections_that_overlap():
    ref = np.array([[0.0, 0.0, 0.0], [5.0, 5.0, 0.0], [10.0, 0.0, 0.0]])
    cams = np.array([[0.0, 10.0, 0.0], [5.0, 25.0, 0.0], [10.0, 30.0, 0.0]])   # 10, 20, 30 m away
    pred = ref + np.array([[1.0, 0.0, 0.0], [100.0, 0.0, 0.0], [0.0, 0.0, 3.0]])  # errors 1, 100, 3
    m = monocular_metrics(pred, ref, cams, ious=np.array([0.5, 0.0, 0.2]), tau_m=2.0)
    assert m.n == 2
    assert m.mae_m == pytest.approx(2.0)
    assert m.mae_pct == pytest.approx(10.0)  # mean(1/10, 3/30)
    assert m.precision_at_tau == pytest.approx(0.5)
    empty = monocular_metrics(pred, ref, cams, ious=np.zeros(3))
    assert empty.n == 0 and np.isnan(empty.mae_m)
    with pytest.raises(ValueError, match="same length"):
        monocular_metrics(pred, ref, cams, ious=np.ones(2))


def test_precision_curve_is_a_strict_fraction_below_each_threshold():
    np.testing.assert_allclose(precision_curve(np.array([2.0, 0.5, 1.0, 4.0]), np.array([0.5, 1.0, 2.0, 10.0])),
                               [0.0, 0.25, 0.5, 1.0])
    assert np.isnan(precision_curve(np.zeros(0), np.array([1.0]))).all()


def test_monocular_metrics_refuse_wrong_shapes_and_nan():
    """Regression: inputs were read with ``reshape(-1, 3)``, so (3, 2) pixel arrays passed for world
    points became two 3D points and, with two IoUs, returned figures without a word; a NaN IoU
    silently dropped its detection and a NaN prediction made MAE NaN."""
    ref = np.array([[0.0, 0.0, 0.0], [5.0, 5.0, 0.0]])
    cams = np.array([[0.0, 10.0, 0.0], [5.0, 25.0, 0.0]])
    with pytest.raises(ValueError, match="predicted"):
        monocular_metrics(np.zeros((3, 2)), ref, cams, ious=np.ones(2))
    with pytest.raises(ValueError, match="finite"):
        monocular_metrics(ref, ref, cams, ious=np.array([0.5, np.nan]))
    with pytest.raises(ValueError, match="ious"):
        monocular_metrics(ref, ref, cams, ious=np.ones((2, 1)))
    assert monocular_metrics(np.zeros(0), np.zeros(0), np.zeros(0), ious=np.zeros(0)).n == 0
