"""``POST /api/imports`` (server-side datasets, run as jobs) and ``GET /api/exports/soccernet-v3d`` (a zip)."""
from __future__ import annotations

import csv
import io
import json
import zipfile
from pathlib import Path

import numpy as np
from fastapi.testclient import TestClient

from app.geometry.annotations import to_soccernet_calibration
from app.geometry.projection import project_pitch_polylines

from ..conftest import run_queued
from ..factories import BALL, CENTRES, HEIGHT, WIDTH, Scene, look_at


def _calibration_folder(root: Path, frames: int = 2) -> Path:
    """A SoccerNet-calibration folder (normalised field lines, no images) seen by the scene's cameras."""
    root.mkdir()
    for i in range(frames):
        cam = look_at(np.array(CENTRES[i]), BALL)
        lines = project_pitch_polylines(cam, WIDTH, HEIGHT, 2.0, 1.0)
        (root / f"{i:05d}.json").write_text(json.dumps(to_soccernet_calibration(lines, WIDTH, HEIGHT)))
    return root


def _import(app, client: TestClient, body: dict) -> dict:
    """POST the import, check the 202 and its Location, run the job, and answer the finished job."""
    answer = client.post("/api/imports", json=body)
    assert answer.status_code == 202, answer.text
    job = answer.json()
    assert answer.headers["location"] == f"/api/jobs/{job['id']}" == job["url"]
    assert (job["kind"], job["state"], job["params"]["kind"]) == ("import", "queued", body["kind"])
    assert run_queued(app) == [job["id"]]
    return client.get(job["url"]).json()


def test_import_sn_calibration_then_list_it(app, client: TestClient, tmp_path: Path) -> None:
    folder = _calibration_folder(tmp_path / "valid")
    body = {"kind": "sn-calibration", "path": str(folder), "width": WIDTH, "height": HEIGHT}
    job = _import(app, client, body)
    assert job["state"] == "done" and job["attempts"] == 1 and job["finished_at"] is not None, job
    report = job["result"]
    assert (report["games"], report["systems"], report["frames"], report["systems_new"]) == (1, 2, 2, 2)
    assert report["calibrated"] + report["refused"] == 2
    games = client.get("/api/games").json()
    assert [(g["league"], g["match"], g["systems"]) for g in games] == [("sn-calibration", "valid", 2)]
    frames = client.get("/api/frames").json()["items"]
    assert [f["image_url"] for f in frames] == [None, None]
    refused = client.post("/api/imports", json=body)  # its game is stored now: say how to merge it
    # the game is named by its folders: tmp_path's own name, whose number depends on what this worker ran before
    assert refused.status_code == 409 and f"sn-calibration/{tmp_path.name}/valid" in refused.text
    again = _import(app, client, {**body, "merge": "keep-newer"})["result"]  # idempotent
    assert (again["systems_new"], again["systems_changed"], again["systems_merged"]) == (0, 0, 0)


def test_bad_imports_are_rejected_and_store_nothing(app, client: TestClient, tmp_path: Path) -> None:
    missing = client.post("/api/imports", json={"kind": "soccernet-v3", "path": str(tmp_path / "nope")})
    assert missing.status_code == 400 and "nope" in missing.json()["detail"]
    folder = _calibration_folder(tmp_path / "broken", frames=1)
    (folder / "00001.json").write_text('{"Middle line": [{"x": 0.5, "y": "high"}]}')
    broken = _import(app, client, {"kind": "sn-calibration", "path": str(folder), "width": WIDTH, "height": HEIGHT})
    assert broken["state"] == "failed" and "00001.json" in broken["message"], broken
    assert broken["result"] == {"error": "DatasetError", "invalid_input": True}
    assert client.get("/api/games").json() == []
    kind = client.post("/api/imports", json={"kind": "coco", "path": "/x"})
    assert kind.status_code == 422 and "kind" in kind.text
    size = client.post("/api/imports", json={"kind": "soccernet-v3", "path": "/x", "width": 960})
    assert size.status_code == 422 and "width" in size.text


def _export(client: TestClient, **params) -> tuple[dict[str, bytes], list[dict[str, str]]]:
    answer = client.get("/api/exports/soccernet-v3d", params=params)
    assert answer.status_code == 200, answer.text
    assert answer.headers["content-type"] == "application/zip"
    assert "soccernet-v3d.zip" in answer.headers["content-disposition"]
    with zipfile.ZipFile(io.BytesIO(answer.content)) as zf:
        files = {n: zf.read(n) for n in zf.namelist()}
    rows = list(csv.DictReader(io.StringIO(files["SNv3D.csv"].decode("utf-8"))))
    return files, rows


def test_export_zip_holds_accepted_systems_unless_all(client: TestClient, scene: Scene) -> None:
    _, rows = _export(client)
    assert rows == []
    files, rows = _export(client, all="true")
    assert len(rows) == 3 and {r["main_action"] for r in rows} == {"1.png"}
    assert any(n.endswith("Labels-v3D.json") for n in files)
    client.post(f"/api/systems/{scene.system_id}/review", json={"status": "accepted"})
    _, rows = _export(client)
    assert len(rows) == 3


def test_streamed_zip_holds_the_same_tree_as_the_folder_export(client: TestClient, scene: Scene,
                                                                db_session, tmp_path) -> None:
    """The API streams the archive while it reads the database (game by game, the CSV last); its
    members are byte for byte the files ``export_soccernet_v3d`` writes into a folder."""
    from app.services.transfer.exporting import export_soccernet_v3d

    answer = client.get("/api/exports/soccernet-v3d", params={"all": "true"})
    assert answer.status_code == 200
    assert (answer.headers["x-v3d-systems"], answer.headers["x-v3d-rows"]) == ("1", "3")
    with zipfile.ZipFile(io.BytesIO(answer.content)) as zf:
        assert zf.testzip() is None
        streamed = {n: zf.read(n) for n in zf.namelist()}
    report = export_soccernet_v3d(db_session, tmp_path / "tree", include_all=True)
    written = {p.relative_to(tmp_path / "tree").as_posix(): p.read_bytes()
               for p in (tmp_path / "tree").rglob("*") if p.is_file()}
    assert streamed == written and report.rows == 3


def test_imports_read_only_under_the_data_root(app, client: TestClient, tmp_path: Path) -> None:
    """``POST /api/imports`` opened any server path (the answer told whether /etc/passwd exists and is a
    zip). Paths are now confined to ``V3D_DATA_ROOT``: outside it, or with no root set, 403 with the same
    message whether the path exists or not; ``..`` and symbolic links are resolved first."""
    root = tmp_path / "root"
    root.mkdir()
    folder = _calibration_folder(root / "calib")
    app.state.settings = app.state.settings.model_copy(update={"data_root": root})
    body = {"kind": "sn-calibration", "width": WIDTH, "height": HEIGHT}
    assert client.post("/api/imports", json={**body, "path": "calib"}).status_code == 202  # relative to the root
    assert client.post("/api/imports", json={**body, "path": str(folder)}).status_code == 202
    (root / "escape").symlink_to("/etc", target_is_directory=True)
    answers = [client.post("/api/imports", json={**body, "path": p})
               for p in ("/etc/passwd", "/etc/no-such-file", "../../etc/passwd", "calib/../../x", "escape/passwd")]
    assert {a.status_code for a in answers} == {403}
    assert len({a.json()["detail"] for a in answers}) == 1 and "V3D_DATA_ROOT" in answers[0].json()["detail"]
    app.state.settings = app.state.settings.model_copy(update={"data_root": None})
    refused = client.post("/api/imports", json={**body, "path": str(folder)})
    assert refused.status_code == 403 and "disabled" in refused.json()["detail"]


def test_an_import_body_that_is_not_utf8_is_422_naming_the_body(client) -> None:
    """Found by the fuzzer: a JSON import body in another encoding was a 500 (UnicodeDecodeError)."""
    answer = client.post("/api/imports", content=b'{"kind": "\xe9t\xe9"}', headers={"Content-Type": "application/json"})
    assert answer.status_code == 422 and answer.json()["field"] == "body"
