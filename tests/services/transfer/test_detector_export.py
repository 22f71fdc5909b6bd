"""YOLO and COCO exports (``app.services.transfer.detector_export``) of three dev systems (true cameras), read
back by third-party readers: supervision (``DetectionDataset.from_yolo`` / ``from_coco``; it needs no
deep-learning framework) and pycocotools."""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from app.db.models import ReviewStatus
from app.services.curation.decisions import decide_review
from app.services.kinds import image_stem
from app.services.transfer.detector_export import CLASSES, ball_boxes, coco_image_id, export_coco, export_yolo

from ..datasets import dev_game_dir

pytestmark = pytest.mark.shared


def _source_counts(shared_dir: Path, names: set[str]) -> tuple[int, int]:
    """(ball boxes, other boxes) of the frames ``names`` in the dev game's Labels-v3.json."""
    data = json.loads((dev_game_dir(shared_dir) / "Labels-v3.json").read_text())
    items = {**data["actions"], **data["replays"]}
    balls = sum(1 for n in names for b in items[n]["bboxes"] if b["class"] == "Ball")
    return balls, sum(1 for n in names for b in items[n]["bboxes"] if b["class"] != "Ball")


def test_yolo_export_reads_back_in_supervision_with_every_box(db_session, imported, shared_dir, tmp_path):
    sv = pytest.importorskip("supervision")
    report = export_yolo(db_session, tmp_path / "yolo", include_all=True)
    frames = [f for s in imported.values() for f in s.frames]
    balls, others = _source_counts(shared_dir, {f.name for f in frames})
    assert sum(report.images.values()) == len(frames) == 8
    assert sum(report.ball_boxes.values()) == balls and sum(report.other_boxes.values()) == others
    assert report.skipped_without_image == 0 and not report.unknown_classes
    items: dict[str, object] = {}
    for split in (s for s, n in report.images.items() if n):  # train, val (drawn from train) and test
        ds = sv.DetectionDataset.from_yolo(str(tmp_path / "yolo" / "images" / split),
                                           str(tmp_path / "yolo" / "labels" / split),
                                           str(tmp_path / "yolo" / "data.yaml"))
        assert list(ds.classes) == list(CLASSES)
        items.update((path, det) for path, _, det in ds)
    assert len(items) == 8
    n_boxes = sum(len(det) for det in items.values())  # type: ignore[arg-type]  # supervision Detections
    assert n_boxes == balls + others
    # Every ball is the box of ball_boxes (to 1e-3 px after normalisation): refined for the views of
    # kept pairs (0.png and 2.png: 6 views), annotated where the system has no 3D ball (3.png).
    assert report.refined_ball_boxes == 6 and report.optimised_ball_boxes == 0
    manifest = json.loads((tmp_path / "yolo" / "manifest.json").read_text())["images"]
    by_image = {row["image"]: row for row in manifest}
    for system in imported.values():
        expected = ball_boxes(system)
        for frame in system.frames:
            row = by_image[frame.name]
            path = str(tmp_path / "yolo" / row["file"])
            assert row["file"] == f"images/{row['split']}/{image_stem(system.game, frame)}.png"
            det = items[path]
            assert np.allclose(det.xyxy[det.class_id == 0], [expected[frame.id][0]], rtol=0, atol=1e-3)  # type: ignore[attr-defined]  # supervision Detections
            assert (row["league"], row["season"], row["game"], row["frame_id"], row["system_id"]) == (
                system.game.league, system.game.season, system.game.match, frame.id, system.id)
            tri = system.triangulation
            assert [row["ball3d_x_m"], row["ball3d_y_m"], row["ball3d_z_m"]] == (
                list(tri.ball3d) if tri is not None and tri.ball3d is not None else [None, None, None])
            rep = frame.reprojection
            assert row["reprojection_error_px"] == (rep.error_px if rep is not None else None)
    # every view of a system in one split; the draw is the same in a second export
    assert all(len({by_image[f.name]["split"] for f in s.frames}) == 1 for s in imported.values())
    again = export_yolo(db_session, tmp_path / "again", include_all=True)
    assert again.images == report.images
    assert (tmp_path / "again" / "manifest.csv").read_bytes() == (tmp_path / "yolo" / "manifest.csv").read_bytes()
    text = (tmp_path / "yolo" / "data.yaml").read_text()
    assert "val: images/val" in text and "classes no box uses here:" in text


def test_coco_export_reads_back_in_pycocotools_and_supervision(db_session, imported, shared_dir, tmp_path):
    sv = pytest.importorskip("supervision")
    coco_api = pytest.importorskip("pycocotools.coco")
    report = export_coco(db_session, tmp_path / "coco", include_all=True)
    frames = [f for s in imported.values() for f in s.frames]
    balls, others = _source_counts(shared_dir, {f.name for f in frames})
    split = next(s for s, n in report.images.items() if n)
    ann_file = tmp_path / "coco" / split / "instances.json"
    coco = coco_api.COCO(str(ann_file))
    assert len(coco.getImgIds()) == 8 and len(coco.getAnnIds()) == balls + others
    ball_cat = coco.getCatIds(catNms=["Ball"])
    assert ball_cat == [1] and len(coco.getAnnIds(catIds=ball_cat)) == balls
    frame = next(f for f in frames if f.optimised_box is not None)
    image_id = coco_image_id(image_stem(frame.system.game, frame))
    (ann,) = coco.loadAnns(coco.getAnnIds(imgIds=[image_id], catIds=ball_cat))
    x1, y1, x2, y2 = ball_boxes(frame.system)[frame.id][0]
    assert np.allclose(ann["bbox"], [x1, y1, x2 - x1, y2 - y1])
    ds = sv.DetectionDataset.from_coco(str(tmp_path / "coco" / split), str(ann_file))
    assert len(ds) == 8 and sum(len(det) for _, _, det in ds) == balls + others
    manifest = json.loads((tmp_path / "coco" / "manifest.json").read_text())["images"]
    assert {row["coco_image_id"] for row in manifest} == set(coco.getImgIds())
    assert all(row["file"] == f"{split}/{coco.loadImgs([row['coco_image_id']])[0]['file_name']}" for row in manifest)


def test_only_accepted_systems_are_exported_by_default(db_session, imported, tmp_path):
    assert sum(export_yolo(db_session, tmp_path / "none").images.values()) == 0
    decide_review(db_session, system_id=imported["0.png"].id, status=ReviewStatus.ACCEPTED)
    db_session.commit()
    report = export_yolo(db_session, tmp_path / "one")
    assert sum(report.images.values()) == len(imported["0.png"].frames)


def test_the_paper_profile_exports_the_optimised_ball_box(db_session, imported, tmp_path):
    """``export_ball_box="optimised"`` (``V3D_PROFILE=paper``): the optimised box wherever a view has one, as the
    paper's detectors were trained on; the refined box is v3d's default."""
    report = export_yolo(db_session, tmp_path / "paper", include_all=True, ball_box="optimised")
    assert report.refined_ball_boxes == 0 and report.optimised_ball_boxes == 6
    for system in imported.values():
        boxes = ball_boxes(system, ball_box="optimised")
        for frame in system.frames:
            if frame.optimised_box is not None:
                assert boxes[frame.id] == (frame.optimised_box.box, "optimised")
