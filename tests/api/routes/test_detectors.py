"""``/api/exports/yolo|coco`` and ``/api/evaluations/monocular`` on the factory scene (one system,
three exactly calibrated views with ball boxes; images for the first two)."""
from __future__ import annotations

import io
import json
import zipfile

import pytest
from sqlalchemy.orm import Session

from app.db.models import Frame
from app.services.kinds import image_stem
from app.services.transfer.detector_export import coco_image_id

from ..factories import zip_listing


def test_yolo_export_zip_skips_the_view_without_an_image(client, scene):
    r = client.get("/api/exports/yolo", params={"all": "true"})
    assert r.status_code == 200 and r.headers["content-type"] == "application/zip"
    assert r.headers["x-v3d-images"] == "2" and r.headers["x-v3d-skipped-without-image"] == "1"
    names = zip_listing(r.content)
    assert "data.yaml" in names
    assert sum(n.startswith("images/") and n.endswith(".png") for n in names) == 2
    assert sum(n.startswith("labels/") and n.endswith(".txt") for n in names) == 2
    # Only accepted systems by default: none here.
    assert client.get("/api/exports/yolo").headers["x-v3d-images"] == "0"


def test_coco_export_zip(client, scene, db_session):
    r = client.get("/api/exports/coco", params={"all": "true"})
    assert r.status_code == 200
    with zipfile.ZipFile(io.BytesIO(r.content)) as zf:
        docs = [json.loads(zf.read(n)) for n in zf.namelist() if n.endswith("instances.json")]
    assert sum(len(d["images"]) for d in docs) == 2
    game = db_session.get(Frame, scene.frame_ids[0]).system.game
    ids = {coco_image_id(image_stem(game, db_session.get(Frame, i))) for i in scene.frame_ids[:2]}
    assert {a["image_id"] for d in docs for a in d["annotations"] if a["category_id"] == 1} == ids
    assert {i["id"] for d in docs for i in d["images"]} == ids  # derived from the name, not the database id


def _reference(db_session: Session, scene) -> list[Frame]:
    return [db_session.get(Frame, i) for i in scene.frame_ids]


def test_evaluation_of_a_yolo_zip_of_the_reference_boxes(client, scene, db_session):
    frames = _reference(db_session, scene)
    assert all(f.optimised_box is not None for f in frames)
    game = frames[0].system.game
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w") as zf:
        for f in frames:
            x1, y1, x2, y2 = f.optimised_box.box
            w, h = f.width, f.height
            zf.writestr(f"runs/labels/{image_stem(game, f)}.txt",
                        f"0 {(x1 + x2) / 2 / w} {(y1 + y2) / 2 / h} {(x2 - x1) / w} {(y2 - y1) / h} 0.7\n")
    r = client.post("/api/evaluations/monocular", params={"all": "true"},
                    files={"predictions": ("pred.zip", buf.getvalue(), "application/zip")})
    assert r.status_code == 200, r.text
    rep = r.json()
    assert rep["AP50"] == 1.0 and rep["counts"]["localised"] == 3 == rep["counts"]["reference_views"]
    assert rep["MAE_m"] == pytest.approx(0.0, abs=1e-3) and rep["P_2m"] == 1.0
    assert rep["estimator"] == "exact" and set(rep["splits"]) <= {"train", "test"}


def test_evaluation_of_a_coco_results_json_scaled_by_1_1(client, scene, db_session):
    frames = _reference(db_session, scene)
    game = frames[0].system.game
    results = []
    for f in frames:
        x1, y1, x2, y2 = f.optimised_box.box
        cx, cy, w, h = (x1 + x2) / 2, (y1 + y2) / 2, (x2 - x1) * 1.1, (y2 - y1) * 1.1
        results.append({"image_id": coco_image_id(image_stem(game, f)), "category_id": 1,
                        "bbox": [cx - w / 2, cy - h / 2, w, h], "score": 0.5})
    r = client.post("/api/evaluations/monocular", params={"all": "true", "estimator": "exact"},
                    files={"predictions": ("results.json", json.dumps(results).encode(), "application/json")})
    assert r.status_code == 200, r.text
    assert r.json()["AP50"] == 1.0
    assert r.json()["MAE_pct"] == pytest.approx(100 * (1 - 1 / 1.1), abs=0.02)


def test_unreadable_predictions_answer_422_naming_the_field(client, scene):
    r = client.post("/api/evaluations/monocular", params={"all": "true"},
                    files={"predictions": ("results.json", b"{not json", "application/json")})
    assert r.status_code == 422 and "predictions" in r.text
    r = client.post("/api/evaluations/monocular", files={"predictions": ("r.json", b"[]", "application/json")})
    assert r.status_code == 422 and "no view with a 3D ball" in r.text  # nothing accepted


def test_malformed_evaluation_requests_answer_the_declared_422(client, app, scene):
    """Found by benchmarks/fuzz.py: FastAPI's 422 (a list of errors) did not match the declared ``ErrorOut``,
    and a broken multipart body answered an undeclared 400."""
    declared = app.openapi()["paths"]["/api/evaluations/monocular"]["post"]["responses"]["422"]
    assert declared["content"]["application/json"]["schema"] == {"$ref": "#/components/schemas/InvalidOut"}
    r = client.post("/api/evaluations/monocular", params={"ball_class": "x"},
                    files={"predictions": ("r.json", b"[]", "application/json")})
    assert r.status_code == 422 and r.json()["detail"][0]["loc"] == ["query", "ball_class"]
    r = client.post("/api/evaluations/monocular", content=b"--b\r\ngarbage--b--\r\n",
                    headers={"Content-Type": "multipart/form-data; boundary=b"})
    assert r.status_code == 422, r.text
    assert r.json()["detail"][0]["loc"][0] == "body"


def test_stats_and_box_evaluation_routes(client, scene, db_session):
    """Issue 19: ``/api/stats`` (counts per kind and split, JaC sweep, distributions) and ``/api/evaluations/boxes``
    (Table 1 against the stored precise boxes) answer what the services compute."""
    from app.services.evaluation.boxes import evaluate_boxes
    from app.services.evaluation.stats import dataset_stats

    stats = client.get("/api/stats")
    assert stats.status_code == 200, stats.text
    body = stats.json()
    assert body["kinds"]["soccernet-v3"]["images"] == 3 and body["kinds"]["soccernet-v3"]["systems"] == 1
    assert len(body["jac_sweep"]) == 21 and set(body["distributions"]) == {
        "jac", "pair_reprojection_error_px", "ball_distance_m", "box_size_px"}
    # the systems per tier of what backs their 3D ball, every tier present: the one system's, counted once
    from app.db.models import System
    tier = db_session.query(System).one().ball_evidence.value
    assert body["ball_evidence"] == {t: int(t == tier) for t in ("vouched", "unconfirmed", "doubted", "none")}
    frames = db_session.query(Frame).all()
    for f in frames:
        x1, y1, x2, y2 = f.ball_label.box
        f.precise_box = [x1 + 1.0, y1 + 1.0, x2 - 1.0, y2 - 1.0]
    db_session.commit()
    boxes = client.get("/api/evaluations/boxes", params={"all": "true"})
    assert boxes.status_code == 200, boxes.text
    expected = evaluate_boxes(db_session, include_all=True)
    assert boxes.json()["views"] == 3 and boxes.json()["original"] == pytest.approx(expected["original"])
    assert 0 < boxes.json()["original"]["iou"] < 1
    assert client.get("/api/evaluations/boxes").json()["views"] == 0  # nothing accepted
    stats = dataset_stats(db_session, client.app.state.settings)
    assert client.get("/api/stats").json() == json.loads(json.dumps(stats))
