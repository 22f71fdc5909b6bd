"""The paper's Table 1 from the service (issue 19): precise boxes built from the synthetic truth's ``precise_box``,
stored, and the original / optimised / refined boxes scored against them; the original boxes' figures equal an
independent computation from the truth file (its ``annotated_box``, the box the labels were drawn with)."""
from __future__ import annotations

import csv
import json
import math
from pathlib import Path

import pytest
import sqlalchemy as sa

from app.core.errors import DatasetError
from app.db.models import Frame
from app.services.curation.decisions import decide_review
from app.services.evaluation.boxes import PRECISE_COLUMNS, evaluate_boxes, store_precise_boxes

from ..datasets import DEV_GAME


def _truth_views(shared_dir: Path) -> list[dict]:
    raw = json.loads((shared_dir / "data" / "synthetic" / "soccernet-v3-dev.truth.json").read_text())
    game = next(g for g in raw["games"] if (g["league"], g["season"], g["match"]) == DEV_GAME)
    return [v for s in game["systems"] for v in s["views"]]


def write_precise_csv(views: list[dict], path: Path, game=DEV_GAME) -> Path:
    """The precise-box CSV of ``views`` (truth entries with ``precise_box``)."""
    with path.open("w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(PRECISE_COLUMNS)
        for v in views:
            w.writerow([*game, v["image"], *v["precise_box"]])
    return path


def _iou(a, b) -> float:
    iw = max(0.0, min(a[2], b[2]) - max(a[0], b[0]))
    ih = max(0.0, min(a[3], b[3]) - max(a[1], b[1]))
    inter = iw * ih
    union = (a[2] - a[0]) * (a[3] - a[1]) + (b[2] - b[0]) * (b[3] - b[1]) - inter
    return inter / union


def _size_pct(a, b) -> float:
    da, db = math.hypot(a[2] - a[0], a[3] - a[1]), math.hypot(b[2] - b[0], b[3] - b[1])
    return 100.0 * abs(da - db) / db


def test_table1_original_boxes_match_an_independent_computation_from_the_truth(
        db_session, imported, shared_dir, tmp_path):
    names = {f.name for s in imported.values() for f in s.frames}
    views = [v for v in _truth_views(shared_dir) if v["image"] in names and v.get("precise_box")]
    assert len(views) == len(names)
    stored = store_precise_boxes(db_session, write_precise_csv(views, tmp_path / "precise.csv"))
    assert stored == len(views)

    assert evaluate_boxes(db_session)["views"] == 0  # nothing accepted yet
    report = evaluate_boxes(db_session, include_all=True)
    boxed = [v for v in views if v.get("annotated_box")]  # the views whose label is a box (wherever drawn)
    assert report["views"] == len(views) and report["original"]["n"] == len(boxed) > 0
    assert report["original"]["iou"] == pytest.approx(
        sum(_iou(v["annotated_box"], v["precise_box"]) for v in boxed) / len(boxed), abs=1e-12)
    assert report["original"]["size_error_pct"] == pytest.approx(
        sum(_size_pct(v["annotated_box"], v["precise_box"]) for v in boxed) / len(boxed), abs=1e-9)
    for kind in ("optimised", "refined"):
        assert report[kind]["n"] > 0 and report[kind]["iou"] > report["original"]["iou"], (kind, report)
    # accepted systems only by default
    decide_review(db_session, system_id=imported["2.png"].id, status="accepted")
    accepted = evaluate_boxes(db_session)
    assert accepted["views"] == len(imported["2.png"].frames)


def test_a_precise_box_row_naming_an_unknown_image_stores_nothing(db_session, imported, shared_dir, tmp_path):
    views = [v for v in _truth_views(shared_dir) if v["image"] in ("0.png", "99.png")]
    path = write_precise_csv([*views, {"image": "nowhere.png", "precise_box": [1, 2, 3, 4]}], tmp_path / "p.csv")
    with pytest.raises(DatasetError, match=r"row \d+ image"):
        store_precise_boxes(db_session, path)
    assert db_session.scalars(sa.select(Frame).where(Frame.precise_box.is_not(None))).all() == []
    path.write_text("league,season,match,image,x1,y1,x2,y2\n" + ",".join(DEV_GAME) + ",0.png,5,5,5,9\n")
    with pytest.raises(DatasetError, match="row 2 x1..y2"):
        store_precise_boxes(db_session, path)


def test_issia_views_are_named_one_by_one_and_get_their_own_precise_box(db_session, db_settings, shared_dir, tmp_path):
    """An ISSIA camera's views share its name (``cam3``): a precise-box row names one view as its kind does,
    ``cam<k>_<frame index, 6 digits>``, and stores on that view alone; ISSIA labels are points, so only the
    optimised and refined boxes are scored."""
    from app.services.issia.sequences import LEAGUE, SEASON, import_issia
    from tests.services.issia_data import dev_truth, write_issia_stretch

    root = write_issia_stretch(shared_dir, tmp_path / "issia-dev", 0, 19, videos=False)
    import_issia(db_session, root, db_settings)
    truth = {(f"cam{cam}", f["frame"]): v["precise_box"] for f in dev_truth(shared_dir)["frames"] if f["frame"] < 20
             for cam, v in f["cams"].items() if v.get("precise_box")}
    path = tmp_path / "issia-precise.csv"
    with path.open("w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(PRECISE_COLUMNS)
        for (cam, index), box in truth.items():
            w.writerow([LEAGUE, SEASON, "issia-dev", f"{cam}_{index:06d}", *box])
    assert store_precise_boxes(db_session, path) == len(truth) >= 40  # 40 in frames 0-19
    stored = {(f.name, f.system.frame_index): f.precise_box for f in
              db_session.scalars(sa.select(Frame).where(Frame.precise_box.is_not(None)))}
    assert stored == truth
    report = evaluate_boxes(db_session, include_all=True)
    assert report["views"] == len(truth) and report["original"]["n"] == 0
    assert report["optimised"]["n"] > 0 and report["optimised"]["iou"] > 0.5
