"""``POST /api/imports`` kind ``predictions``: a detector's CSV from the data root or uploaded in a zip, run as a job
(its result the counts), a malformed one failing the job naming the line with nothing stored, an upload above
``V3D_MAX_PREDICTION_IMPORT_MB`` refused (413) before it is unpacked; and ``v3d import predictions`` /
``v3d predictions list|remove`` on a database file."""
from __future__ import annotations

import io
import zipfile
from pathlib import Path

import pytest
import sqlalchemy as sa
from fastapi.testclient import TestClient
from typer.testing import CliRunner

from tests.accounts import as_token

from ..conftest import run_queued
from ..factories import Scene

pytestmark = pytest.mark.engine

HEADER = "league,season,match,image,x1,y1,x2,y2,score\n"
GAME = "england_epl,2014-2015,2015-02-21 - 18-00 Chelsea 1 - 1 Burnley"


def _csv(rows: list[str]) -> str:
    return HEADER + "".join(f"{GAME},{r}\n" for r in rows)


def _count(app, source: str) -> int:
    from app.db.models import Prediction

    with app.state.session_factory() as s:
        return int(s.scalar(sa.select(sa.func.count(Prediction.id)).where(Prediction.source == source)))


def test_a_predictions_file_under_the_data_root_is_imported_as_a_job(app, client: TestClient, scene: Scene,
                                                                     tmp_path: Path) -> None:
    path = tmp_path / "dets.csv"
    path.write_text(_csv(["1_1.png,400,200,412,212,0.91", "1_2.png,-4,5,8,17,0.4", "9.png,1,1,5,5,0.2"]))
    answer = client.post("/api/imports", json={"kind": "predictions", "path": str(path), "source": "yolo-sn-ball"})
    assert answer.status_code == 202, answer.text
    assert run_queued(app) == [answer.json()["id"]]
    job = client.get(answer.json()["url"]).json()
    assert job["state"] == "done", job
    r = job["result"]
    assert (r["source"], r["stored"], r["clipped"], r["unknown"], r["systems"]) == ("yolo-sn-ball", 2, 1, 1, 1)
    assert r["unknown_images"] == [f"{GAME.replace(',', '/')}/9.png"]
    assert _count(app, "yolo-sn-ball") == 2
    # an option of another kind is refused for it, and its option for the others
    assert client.post("/api/imports", json={"kind": "predictions", "path": str(path), "width": 9}).status_code == 422
    assert client.post("/api/imports", json={"kind": "soccernet-v3", "path": str(path),
                                             "source": "x"}).status_code == 422


def test_a_malformed_upload_fails_its_job_naming_the_line_and_stores_nothing(app, client: TestClient,
                                                                              scene: Scene) -> None:
    data = io.BytesIO()
    with zipfile.ZipFile(data, "w") as zf:
        zf.writestr("dets.csv", _csv(["1_1.png,400,200,412,212,0.91", "1_2.png,400,200,nan,212,0.9"]))
    answer = client.post("/api/imports", data={"kind": "predictions", "source": "det"},
                         files={"file": ("dets.zip", data.getvalue())})
    assert answer.status_code == 202, answer.text
    run_queued(app)
    job = client.get(answer.json()["url"]).json()
    assert job["state"] == "failed" and "dets.csv: line 3 x1..score: NaN or infinite value" in job["message"], job
    assert _count(app, "det") == 0


def test_an_upload_above_its_own_limit_is_413_naming_the_setting(app, db_settings, accounts, scene: Scene) -> None:
    """A 100 MB predictions file against the default 256 MB would pass; held to 1 MB here, a 2 MB upload is
    refused naming V3D_MAX_PREDICTION_IMPORT_MB, nothing stored."""
    from app.main import create_app

    small = create_app(db_settings.model_copy(update={"max_prediction_import_mb": 1.0}))
    small.state.session_factory = app.state.session_factory
    with TestClient(small) as c:
        client = as_token(c, accounts["admin"])
        big = client.post("/api/imports", data={"kind": "predictions"},
                          files={"file": ("dets.zip", b"0" * (2 << 20))})
        assert big.status_code == 413 and "V3D_MAX_PREDICTION_IMPORT_MB" in big.json()["detail"], big.text
    assert _count(app, "dets") == 0


def test_the_cli_imports_lists_and_removes_a_source(tmp_path: Path, db_settings) -> None:
    import app.cli.predictions  # noqa: F401  # registers the commands
    from app.cli._root import cli
    from app.db.session import make_engine, make_session_factory, upgrade_database

    from ..factories import make_game, make_system

    url = f"sqlite:///{tmp_path / 'cli.sqlite3'}"
    upgrade_database(url)
    engine = make_engine(url)
    with make_session_factory(engine)() as session:
        make_system(session, db_settings.model_copy(update={"database_url": url}), make_game(session), "1.png",
                    labelled=(True, True, False))
    engine.dispose()
    runner = CliRunner()
    path = tmp_path / "dets.csv"
    path.write_text(_csv(["1_2.png,400,200,412,212,0.91", "7.png,1,1,5,5,0.2"]))
    ok = runner.invoke(cli, ["import", "predictions", str(path), "--source", "yolo-sn-ball", "--database-url", url])
    assert ok.exit_code == 0, ok.output
    assert "imported 1 prediction(s) of source 'yolo-sn-ball' from 2 row(s)" in ok.output
    assert "unknown: england_epl/2014-2015/2015-02-21 - 18-00 Chelsea 1 - 1 Burnley/7.png" in ok.output
    listed = runner.invoke(cli, ["predictions", "list", "--database-url", url])
    assert "yolo-sn-ball: 1 prediction(s) on 1 frame(s)" in listed.output, listed.output
    path.write_text(HEADER + f"{GAME},1_2.png,400,200,412\n")
    bad = runner.invoke(cli, ["import", "predictions", str(path), "--source", "yolo-sn-ball", "--database-url", url])
    assert bad.exit_code == 2 and "line 2: 7 cells, expected 9" in bad.output, bad.output
    assert "yolo-sn-ball: 1 prediction(s)" in runner.invoke(cli, ["predictions", "list", "--database-url", url]).output
    gone = runner.invoke(cli, ["predictions", "remove", "yolo-sn-ball", "--database-url", url])
    assert gone.exit_code == 0 and "removed 1 prediction(s)" in gone.output
    assert runner.invoke(cli, ["predictions", "remove", "yolo-sn-ball", "--database-url", url]).exit_code == 2


def test_the_monocular_benchmark_scores_an_imported_source_without_a_second_upload(
        app, client: TestClient, scene: Scene, tmp_path: Path) -> None:
    from app.geometry.ball import sphere_image_box

    from ..factories import BALL

    rows = [f"{name},{','.join(f'{v:.2f}' for v in sphere_image_box(cam, BALL, 0.11))},0.9"
            for name, cam in zip(("1.png", "1_1.png", "1_2.png"), scene.cameras, strict=True)]
    path = tmp_path / "exact.csv"
    path.write_text(_csv(rows))
    answer = client.post("/api/imports", json={"kind": "predictions", "path": str(path), "source": "exact"})
    assert answer.status_code == 202 and run_queued(app) == [answer.json()["id"]]
    report = client.get("/api/evaluations/monocular", params={"source": "exact", "all": "true"})
    assert report.status_code == 200, report.text
    r = report.json()
    assert r["counts"]["reference_views"] == 3 and r["counts"]["localised"] == 3 and r["AP50"] == 1.0, r["counts"]
    assert r["MAE_m"] < 0.5
    missing = client.get("/api/evaluations/monocular", params={"source": "nope", "all": "true"})
    assert missing.status_code == 422 and "no predictions of source 'nope'" in missing.text


def test_yolo_files_and_coco_results_are_imported_by_the_exports_stems_and_ids(app, client: TestClient,
                                                                               scene: Scene, tmp_path: Path) -> None:
    """The layout of v3d's own detector exports: YOLO txt files named by the exported stem (anywhere in the folder),
    COCO results by ``coco_image_id(stem)``; a YOLO file of an image v3d does not hold is counted and named."""
    import json

    from app.db.models import Frame, Game
    from app.services.kinds.base import image_stem
    from app.services.transfer.detector_export import coco_image_id

    with app.state.session_factory() as s:
        game = s.get(Game, scene.game_id)
        stems = [image_stem(game, s.get(Frame, fid)) for fid in scene.frame_ids]
    yolo = tmp_path / "yolo" / "labels" / "test"
    yolo.mkdir(parents=True)
    (yolo / f"{stems[1]}.txt").write_text("0 0.5 0.5 0.02 0.04 0.91\n0 0.1 0.9 0.02 0.04 0.2\n")
    (yolo / "someone_else_3.txt").write_text("0 0.5 0.5 0.02 0.04 0.5\n")
    answer = client.post("/api/imports", json={"kind": "predictions", "path": str(tmp_path / "yolo"),
                                               "source": "yolo-sn-ball"})
    assert answer.status_code == 202 and run_queued(app) == [answer.json()["id"]]
    r = client.get(answer.json()["url"]).json()["result"]
    assert (r["stored"], r["unknown"], r["unknown_images"]) == (2, 1, ["someone_else_3"]), r
    coco = tmp_path / "results.json"
    coco.write_text(json.dumps([{"image_id": coco_image_id(stems[2]), "category_id": 1,
                                 "bbox": [470.0, 260.0, 12.0, 12.0], "score": 0.8},
                                {"image_id": 12345, "category_id": 1, "bbox": [1, 1, 5, 5], "score": 0.5}]))
    answer = client.post("/api/imports", json={"kind": "predictions", "path": str(coco), "source": "coco-det"})
    assert answer.status_code == 202 and run_queued(app) == [answer.json()["id"]]
    r = client.get(answer.json()["url"]).json()["result"]
    assert (r["stored"], r["unknown"]) == (1, 1), r
    from app.db.models import Prediction

    with app.state.session_factory() as s:
        p = s.scalars(sa.select(Prediction).where(Prediction.source == "coco-det")).one()
        assert (p.frame_id, p.x1, p.y1, p.x2, p.y2, p.score) == (scene.frame_ids[2], 470.0, 260.0, 482.0, 272.0, 0.8)
        y = s.scalars(sa.select(Prediction).where(Prediction.source == "yolo-sn-ball").order_by(Prediction.score)).all()
        assert [q.frame_id for q in y] == [scene.frame_ids[1]] * 2 and abs(y[1].x1 - (0.49 * 960)) < 1e-6


def test_a_checked_detection_is_one_key_fix_kept_as_a_placement_until_confirmed(app, client: TestClient,
                                                                                db_session, db_settings,
                                                                                tmp_path: Path) -> None:
    """The ball's detection in a view nobody labelled (a false one beside it scores higher): ``ball_detected`` with
    its fix; applied, the label keeps the detector's provenance, makes no 3D ball and no export holds it; confirmed
    (the same box without provenance), it is a label like any other."""
    from app.geometry.ball import sphere_image_box

    from ..factories import BALL, make_game, make_system
    from .test_imports_exports import _export

    scene = make_system(db_session, db_settings, make_game(db_session), "2.png", labelled=(True, True, False))
    true = sphere_image_box(scene.cameras[2], BALL, 0.11)
    fake = true + [0.0, -60.0, 0.0, -60.0]
    path = tmp_path / "det.csv"
    path.write_text(_csv([f"2_2.png,{','.join(f'{v:.2f}' for v in fake)},0.97",
                          f"2_2.png,{','.join(f'{v:.2f}' for v in true)},0.64"]))
    answer = client.post("/api/imports", json={"kind": "predictions", "path": str(path), "source": "det"})
    assert answer.status_code == 202 and run_queued(app) == [answer.json()["id"]]
    system = client.get(f"/api/systems/{scene.system_id}").json()
    (d,) = [d for d in system["doubts"] if d["frame_id"] == scene.frame_ids[2] and d["accuses_label"]]
    assert d["kind"] == "ball_detected" and "det, score 0.64" in d["message"]
    queue = client.get("/api/systems", params={"doubt": "ball_detected"}).json()["items"]
    assert [q["id"] for q in queue] == [scene.system_id]  # the queue's filter for detector suggestions
    req = d["suggestion"]["request"]
    assert req["body"]["box"] == [round(v) for v in true] and req["body"]["provenance"]["detector"] == "det"
    etag = client.get(f"/api/frames/{scene.frame_ids[2]}").headers["etag"]
    placed = client.request(req["method"], req["path"], json=req["body"], headers={"If-Match": etag})
    assert placed.status_code == 200, placed.text
    frame = client.get(f"/api/frames/{scene.frame_ids[2]}")
    ball = frame.json()["ball"]
    assert ball["provenance"]["detector"] == "det" and ball["provenance"]["score"] == 0.64
    rows = {r["replay"] or r["main_action"]: r for r in _export(client, all="true")[1] if r["main_action"] == "2.png"}
    assert rows["2_2.png"]["is_ball"] == "False" and rows["2_2.png"]["ball_bbox"] == ""  # not before a person confirms
    confirmed = client.patch(f"/api/frames/{scene.frame_ids[2]}/ball", json={"box": ball["box"]},
                             headers={"If-Match": frame.headers["etag"]})
    assert confirmed.status_code == 200, confirmed.text
    assert client.get(f"/api/frames/{scene.frame_ids[2]}").json()["ball"].get("provenance") is None
    rows = {r["replay"] or r["main_action"]: r for r in _export(client, all="true")[1] if r["main_action"] == "2.png"}
    assert rows["2_2.png"]["is_ball"] == "True"


def test_the_sources_are_listed_with_who_imported_them_and_an_admin_removes_one(app, client: TestClient, scene: Scene,
                                                                                 tmp_path: Path, act_as) -> None:
    act_as("adam", "admin")
    path = tmp_path / "dets.csv"
    path.write_text(_csv(["1.png,400,200,412,212,0.9", "1_1.png,100,100,112,112,0.5", "1_2.png,10,10,22,22,0.7"]))
    answer = client.post("/api/imports", json={"kind": "predictions", "path": str(path), "source": "yolo-a"})
    assert answer.status_code == 202, answer.text
    run_queued(app)
    words = client.get(answer.json()["url"]).json()["result"]["summary"]["words"]
    assert words == "3 predictions on 3 views of 1 system"
    with app.state.session_factory() as s:  # a source stored before its import was recorded: who is unknown
        from app.db.models import Prediction

        s.add(Prediction(source="old", frame_id=scene.frame_ids[0], score=0.3, x1=1, y1=1, x2=9, y2=9))
        s.commit()
    act_as("ana", "annotator")
    listed = {x["source"]: x for x in client.get("/api/predictions").json()["items"]}
    a = listed["yolo-a"]
    assert (a["predictions"], a["frames"], a["systems"], a["imported_by"]) == (3, 3, 1, "adam")
    assert a["scores"] == {"min": 0.5, "q1": 0.6, "median": 0.7, "q3": 0.8, "max": 0.9}
    assert a["imported_at"] is not None
    assert listed["old"]["imported_by"] is None and listed["old"]["predictions"] == 1
    assert client.delete("/api/predictions/yolo-a").status_code == 403
    act_as("adam", "admin")
    removed = client.delete("/api/predictions/yolo-a")
    assert removed.status_code == 200 and removed.json() == {"source": "yolo-a", "removed": 3}
    assert _count(app, "yolo-a") == 0
    assert client.delete("/api/predictions/yolo-a").status_code == 404
    assert [x["source"] for x in client.get("/api/predictions").json()["items"]] == ["old"]
    entries = client.get("/api/audit", params={"user": "adam", "limit": 50}).json()["items"]
    assert any(e["action"] == "import" and (e.get("after") or {}).get("removed") == 3 for e in entries)


def test_one_labelled_ray_and_one_detection_place_a_ball_that_enters_the_3d_ball_only_once_confirmed(
        app, client: TestClient, db_session, db_settings, tmp_path: Path) -> None:
    """One labelled view and one detected view (the third view's detector saw nothing): ``ball_detected`` code
    ``one_ray``; its placement keeps that provenance and makes no 3D ball until a person confirms it."""
    from app.geometry.ball import sphere_image_box

    from ..factories import BALL, make_game, make_system

    scene = make_system(db_session, db_settings, make_game(db_session), "3.png", labelled=(True, False, False))
    # the labelled view's box as a careful annotator draws it (the factory's is twice the ball's size: its depth
    # would be read wrong by half)
    label = [round(float(v), 1) for v in sphere_image_box(scene.cameras[0], BALL, 0.11)]
    etag = client.get(f"/api/frames/{scene.frame_ids[0]}").headers["etag"]
    assert client.patch(f"/api/frames/{scene.frame_ids[0]}/ball", json={"box": label},
                        headers={"If-Match": etag}).status_code == 200
    assert client.get(f"/api/systems/{scene.system_id}").json()["ball3d"] is None  # one labelled view
    true = sphere_image_box(scene.cameras[2], BALL, 0.11)
    far = true + [-400.0, 150.0, -400.0, 150.0]  # off the labelled view's ray
    path = tmp_path / "det.csv"
    path.write_text(_csv([f"3_2.png,{','.join(f'{v:.2f}' for v in far)},0.95",
                          f"3_2.png,{','.join(f'{v:.2f}' for v in true + 1.0)},0.7"]))
    answer = client.post("/api/imports", json={"kind": "predictions", "path": str(path), "source": "det"})
    assert answer.status_code == 202 and run_queued(app) == [answer.json()["id"]]
    system = client.get(f"/api/systems/{scene.system_id}").json()
    (d,) = [d for d in system["doubts"] if d["frame_id"] == scene.frame_ids[2] and d["accuses_label"]]
    assert d["kind"] == "ball_detected" and d["evidence"]["code"] == "one_ray"
    assert "one labelled view and this detection" in d["message"]
    req = d["suggestion"]["request"]
    assert req["body"]["provenance"]["code"] == "one_ray" and req["body"]["provenance"]["from_views"] == [
        scene.frame_ids[0]]
    etag = client.get(f"/api/frames/{scene.frame_ids[2]}").headers["etag"]
    assert client.request(req["method"], req["path"], json=req["body"], headers={"If-Match": etag}).status_code == 200
    assert client.get(f"/api/systems/{scene.system_id}").json()["ball3d"] is None  # an unconfirmed prediction
    frame = client.get(f"/api/frames/{scene.frame_ids[2]}")
    ball = frame.json()["ball"]
    confirmed = client.patch(f"/api/frames/{scene.frame_ids[2]}/ball", json={"box": ball["box"]},
                             headers={"If-Match": frame.headers["etag"]})
    assert confirmed.status_code == 200, confirmed.text
    import numpy as np
    ball3d = client.get(f"/api/systems/{scene.system_id}").json()["ball3d"]
    assert ball3d is not None and np.linalg.norm(np.asarray(ball3d) - BALL) < 0.3
