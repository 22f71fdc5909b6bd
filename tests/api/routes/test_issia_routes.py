"""ISSIA routes: ``POST /api/imports`` kind "issia", ``GET /api/games/{id}/trajectory``, a video frame
served at the annotation resolution, a point edit that re-fits, and ``GET /api/exports/issia-3d``."""
from __future__ import annotations

import io
import zipfile

import cv2
import numpy as np
import pytest

from tests.services.issia_data import write_issia_stretch

from ..conftest import run_queued


def _import_job(app, client, body: dict) -> dict:
    """POST the import (202), run its job, and answer the finished job."""
    r = client.post("/api/imports", json=body)
    assert r.status_code == 202, r.text
    run_queued(app)
    return client.get(r.json()["url"]).json()


@pytest.fixture
def issia(app, client, shared_dir, tmp_path):
    """Frames 0..24 of the dev sequence imported through the API; returns (import report, trajectory JSON)."""
    root = write_issia_stretch(shared_dir, tmp_path / "issia-dev", 0, 24)
    job = _import_job(app, client, {"kind": "issia", "path": str(root), "flip": []})
    assert job["state"] == "done", job
    game = next(g for g in client.get("/api/games").json() if g["league"] == "issia")
    t = client.get(f"/api/games/{game['id']}/trajectory")
    assert t.status_code == 200, t.text
    return job["result"], t.json()


def test_import_and_trajectory(issia):
    report, traj = issia
    assert (report["systems"], report["frames"], report["calibrated"]) == (25, 150, 6)
    assert traj["cameras"] == [f"cam{k}" for k in range(1, 7)]
    assert traj["camera_set"]["cam1"] == "test" and traj["camera_set"]["cam3"] == "train"
    assert [f["frame_index"] for f in traj["frames"]] == list(range(25))
    f13 = traj["frames"][13]
    assert f13["flagged"] == ["cam4"] and "cam4" not in f13["cam_list"] and f13["label_doubts"] >= 1
    assert all(f["ball3d_smoothed"] is not None for f in traj["frames"])
    assert traj["pieces"] and traj["pieces"][0]["kind"] in ("flight", "roll")


def test_import_errors_name_the_field(app, client, tmp_path):
    job = _import_job(app, client, {"kind": "issia", "path": str(tmp_path)})
    assert job["state"] == "failed" and "issia_calibration.json" in job["message"]
    r = client.post("/api/imports", json={"kind": "soccernet-v3", "path": str(tmp_path), "from_lines": True})
    assert r.status_code == 422


def test_unknown_or_non_issia_game_trajectory_is_404(client):
    assert client.get("/api/games/999999/trajectory").status_code == 404


def test_game_id_beyond_the_id_column_is_422_naming_it(client):
    """Found by benchmarks/fuzz.py: such an id overflowed SQLite's driver (OverflowError, a 500)."""
    r = client.get("/api/games/18446744073709551616/trajectory")
    assert r.status_code == 422 and r.json()["detail"][0]["loc"] == ["path", "game_id"]


def test_video_frame_image_at_annotation_size(client, issia):
    _, traj = issia
    system = client.get(f"/api/systems/{traj['frames'][10]['system_id']}").json()
    view = next(v for v in system["views"] if v["name"] == "cam4")
    assert view["image_url"]
    r = client.get(view["image_url"])
    assert r.status_code == 200 and r.headers["content-type"] == "image/png"
    # a frame v3d decoded and encoded itself, served inert like every image (issue 15, item 2)
    assert r.headers["x-content-type-options"] == "nosniff" and r.headers["content-security-policy"] == "sandbox"
    assert r.content[:8] == b"\x89PNG\r\n\x1a\n"
    img = cv2.imdecode(np.frombuffer(r.content, np.uint8), cv2.IMREAD_COLOR)
    assert img.shape == (1080, 1920, 3)  # the 960x540 video, resized to the labels' resolution
    assert img.std() > 5  # a real picture, not a blank
    again = client.get(view["image_url"], headers={"If-None-Match": r.headers["etag"]})
    assert again.status_code == 304


def test_point_edit_refits_and_export_zip(client, issia):
    _, traj = issia
    sid = traj["frames"][20]["system_id"]
    view = next(v for v in client.get(f"/api/systems/{sid}").json()["views"] if v["name"] == "cam3")
    x, y = view["ball"]["point"]
    r = client.patch(f"/api/frames/{view['frame_id']}/ball", json={"point": [x + 80, y]})
    assert r.status_code == 200, r.text
    doubts = [d for d in r.json()["doubts"] if d["kind"] == "ball_off_consensus"]
    assert [d["frame"] for d in doubts] == ["cam3"] and doubts[0]["suggestion"]["action"] == "snap_point"
    # the suggestion carries the exact request its fix key sends; sent as it is, it fixes the label
    req = doubts[0]["suggestion"]["request"]
    point = [round(v) for v in doubts[0]["suggestion"]["point"]]
    # snapped to where the trajectory projects, the label agrees by construction: it keeps its provenance (issue 18)
    assert req == {"method": "PATCH", "path": f"/api/frames/{view['frame_id']}/ball",
                   "body": {"point": point, "provenance": {"doubt": "ball_off_consensus", "code": "trajectory",
                                                          "from_views": []}}}
    fixed = client.request(req["method"], req["path"], json=req["body"])
    assert fixed.status_code == 200, fixed.text
    assert [d for d in fixed.json()["doubts"] if d["kind"] == "ball_off_consensus" and d["frame"] == "cam3"] == []
    r = client.patch(f"/api/frames/{view['frame_id']}/ball", json={"point": [x + 80, y]})
    assert r.status_code == 200, r.text
    t = client.get(f"/api/games/{traj['game_id']}/trajectory").json()
    assert t["frames"][20]["flagged"] == ["cam3"]
    r = client.get("/api/exports/issia-3d", params={"all": "true"})
    assert r.status_code == 200 and r.headers["x-v3d-rows"] == "25"
    with zipfile.ZipFile(io.BytesIO(r.content)) as zf:
        assert sorted(n for n in zf.namelist() if not n.endswith("/")) == [
            "issia-dev/ISSIA-3D.csv", *(f"issia-dev/calibration/cam{k}.json" for k in range(1, 7)),
            "issia-dev/issia_calibration.json", "issia-dev/split.json"]  # the importer's file: it imports again
        lines = zf.read("issia-dev/ISSIA-3D.csv").decode().splitlines()
    assert len(lines) == 26 and lines[0].startswith("frame,x_cam1,")
    assert client.get("/api/exports/issia-3d").headers["x-v3d-rows"] == "0"  # nothing accepted yet
