"""Issue 15, item 1 over HTTP: a dataset reaches nothing outside itself. A symbolic link in a dataset
under the data root that leads out of it is a 400 naming it before any job is queued; an uploaded
SoccerNet-v3D export whose labels name ``/etc/passwd`` fails its job naming the field and stores nothing;
the image route never serves a file outside the frame's dataset folder."""
from __future__ import annotations

import io
import json
import os
import zipfile
from pathlib import Path

import pytest
from fastapi.testclient import TestClient

from ..conftest import run_queued
from ..factories import Scene


@pytest.fixture
def rooted_app(app, tmp_path: Path):
    root = tmp_path / "root"
    root.mkdir()
    app.state.settings = app.state.settings.model_copy(update={"data_root": root, "jobs_dir": tmp_path / "jobs"})
    return app


def test_a_link_leading_out_of_a_dataset_under_the_data_root_is_400_naming_it(rooted_app, client: TestClient,
                                                                               tmp_path: Path) -> None:
    game = tmp_path / "root" / "v3" / "league" / "season" / "game"
    game.mkdir(parents=True)
    (game / "Labels-v3.json").write_text('{"actions": {}}')
    os.symlink("/etc/passwd", game / "0.png")
    answer = client.post("/api/imports", json={"kind": "soccernet-v3", "path": "v3"})
    assert answer.status_code == 400, answer.text
    assert "game/0.png: path: resolves outside the dataset's folder" in answer.json()["detail"]
    assert "/etc/passwd" not in answer.text  # where the link points is not told
    os.unlink(game / "0.png")
    os.symlink(game / "Labels-v3.json", game / "labels-again.json")  # a link inside the dataset is fine
    assert client.post("/api/imports", json={"kind": "soccernet-v3", "path": "v3"}).status_code == 202


def test_an_uploaded_export_naming_etc_passwd_fails_naming_the_field_and_stores_nothing(
        rooted_app, client: TestClient, scene: Scene) -> None:
    """Was: it imported, and ``GET /api/frames/{id}/image`` answered ``root:x:0:0:...`` to every annotator."""
    exported = client.get("/api/exports/soccernet-v3d", params={"all": "true"})
    with zipfile.ZipFile(io.BytesIO(exported.content)) as zf:
        files = {n: zf.read(n) for n in zf.namelist()}
    labels_name = next(n for n in files if n.endswith("Labels-v3D.json"))
    labels = json.loads(files[labels_name])
    assert "image" not in labels["actions"]["1.png"]["v3d"]  # an export names no server path
    labels["actions"]["1.png"]["v3d"]["image"] = {"path": "/etc/passwd"}
    files[labels_name] = json.dumps(labels).encode()
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w") as zf:
        for name, data in files.items():
            zf.writestr(name, data)
    games_before = client.get("/api/games").json()
    answer = client.post("/api/imports", data={"kind": "soccernet-v3d"},
                         files={"file": ("evil.zip", buf.getvalue(), "application/zip")})
    assert answer.status_code == 202, answer.text
    run_queued(rooted_app)
    job = client.get(answer.json()["url"]).json()
    assert job["state"] == "failed", job
    assert "actions['1.png'].v3d.image.path: resolves outside the dataset's folder" in job["message"]
    assert client.get("/api/games").json() == games_before


def test_the_image_route_refuses_a_reference_leading_out(client: TestClient, scene: Scene, db_session) -> None:
    from app.db.models import Frame

    frame = db_session.get(Frame, scene.frame_ids[1])  # an image file of the scene
    assert client.get(f"/api/frames/{frame.id}/image").status_code == 200
    frame.image_path = "../../../../../../../../etc/passwd"
    db_session.commit()
    answer = client.get(f"/api/frames/{frame.id}/image")
    assert answer.status_code == 404 and "outside its dataset's folder" in answer.json()["detail"]
    assert "root:x" not in answer.text


def test_image_404s_name_no_server_path(client: TestClient, scene: Scene, db_session, act_as) -> None:
    """Was: an image's 404 named the file's full server path to every role (issue 15, item 7)."""
    from app.db.models import Frame

    frame = db_session.get(Frame, scene.frame_ids[1])  # an image file of the scene
    (Path(frame.image_root) / frame.image_path).unlink()
    zipped = db_session.get(Frame, scene.frame_ids[0])  # a zip member
    zipped.image_member = "absent.png"
    db_session.commit()
    for role in ("annotator", "reviewer", "admin"):
        act_as("ana", role)
        for fid, expected in ((frame.id, f"image file {frame.image_path} is missing"),
                              (zipped.id, "'absent.png' is not in")):
            answer = client.get(f"/api/frames/{fid}/image")
            assert answer.status_code == 404 and expected in answer.json()["detail"], answer.text
            assert frame.image_root not in answer.text and "/tmp" not in answer.text, answer.text


def test_images_are_served_with_the_checked_type_nosniff_and_a_sandbox(client: TestClient, scene: Scene,
                                                                       db_session) -> None:
    """Was: a frame file was answered with the type its name suggested (``0.html`` as text/html,
    ``/etc/passwd`` as application/octet-stream); now the header decides, and the answer can run nothing."""
    from app.db.models import Frame

    for frame_id in scene.frame_ids[:2]:  # a zip member and a file
        answer = client.get(f"/api/frames/{frame_id}/image")
        assert answer.status_code == 200 and answer.headers["content-type"] == "image/png"
        assert answer.headers["x-content-type-options"] == "nosniff"
        assert answer.headers["content-security-policy"] == "sandbox"
    frame = db_session.get(Frame, scene.frame_ids[1])
    page = Path(frame.image_root) / "0.html"
    page.write_bytes(b"<html><script>alert(document.cookie)</script></html>")
    frame.image_path, frame.image_type = "0.html", None
    db_session.commit()
    answer = client.get(f"/api/frames/{frame.id}/image")
    assert answer.status_code == 404 and "not a PNG or JPEG image" in answer.json()["detail"]
    assert "<script>" not in answer.text


def _calibration_folder(root: Path) -> Path:
    import numpy as np

    from app.geometry.annotations import to_soccernet_calibration
    from app.geometry.projection import project_pitch_polylines

    from ..factories import BALL, CENTRES, HEIGHT, WIDTH, look_at

    root.mkdir(parents=True)
    cam = look_at(np.array(CENTRES[0]), BALL)
    lines = project_pitch_polylines(cam, WIDTH, HEIGHT, 2.0, 1.0)
    (root / "00000.json").write_text(json.dumps(to_soccernet_calibration(lines, WIDTH, HEIGHT)))
    return root


def test_annotators_and_reviewers_see_dataset_names_admins_the_server_paths(rooted_app, client: TestClient,
                                                                             tmp_path: Path, act_as) -> None:
    """Was: every role read the server's paths in job params, in the audit's import source and in the
    messages of failed jobs (issue 15, item 7)."""
    from ..factories import HEIGHT, WIDTH

    folder = _calibration_folder(tmp_path / "root" / "sets" / "calib")
    queued = client.post("/api/imports", json={"kind": "sn-calibration", "path": "sets/calib", "width": WIDTH,
                                               "height": HEIGHT})
    broken = tmp_path / "root" / "sets" / "broken"
    broken.mkdir()
    (broken / "00000.json").write_text("{not json")
    failed = client.post("/api/imports", json={"kind": "sn-calibration", "path": "sets/broken", "width": WIDTH,
                                               "height": HEIGHT})
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w") as zf:
        zf.writestr("set/00000.json", (folder / "00000.json").read_bytes())
    uploaded = client.post("/api/imports", data={"kind": "sn-calibration", "width": str(WIDTH), "height": str(HEIGHT)},
                           files={"file": ("set.zip", buf.getvalue(), "application/zip")})
    run_queued(rooted_app)
    ids = [a.json()["id"] for a in (queued, failed, uploaded)]
    admin_view = {j["id"]: j for j in client.get("/api/jobs").json()["items"]}
    assert admin_view[ids[0]]["params"]["path"] == str(folder.resolve())  # admins still see full paths
    assert str(tmp_path) in admin_view[ids[1]]["message"]
    admin_audit = client.get("/api/audit").json()["items"]
    assert {e["after"]["source"] for e in admin_audit if e["action"] == "import"} >= {str(folder.resolve())}
    for role in ("annotator", "reviewer"):
        act_as("ana", role)
        listed = client.get("/api/jobs").json()
        text = json.dumps(listed) + json.dumps(client.get("/api/audit").json())
        assert str(tmp_path) not in text and "/tmp" not in text, text
        jobs = {j["id"]: j for j in listed["items"]}
        assert jobs[ids[0]]["params"]["path"] == "sets/calib" and jobs[ids[0]]["result"]["source"] == "sets/calib"
        assert jobs[ids[1]]["state"] == "failed" and jobs[ids[1]]["message"].startswith("sets/broken/00000.json: ")
        upload_name = jobs[ids[2]]["params"]["path"]
        assert upload_name == f"set.zip (upload {ids[2]})"  # the file's name as the browser sent it, never a path
        assert client.get(f"/api/jobs/{ids[2]}").json()["result"]["source"] == upload_name
        sources = [e["after"]["source"] for e in client.get("/api/audit").json()["items"] if e["action"] == "import"]
        assert sorted(sources) == sorted(["sets/calib", upload_name])


@pytest.mark.parametrize("jobs_folder", ["relative", "linked", "moved"])
def test_a_failed_upload_names_its_files_from_the_upload_whatever_the_jobs_folder(
        app, client: TestClient, tmp_path: Path, monkeypatch, act_as, jobs_folder: str) -> None:
    """Issue 27, item 7. Was: once the server ran with another ``V3D_JOBS_DIR`` than the one the upload was
    unpacked under (a restart, another worker), a failed upload's message (``GET /api/jobs``, the job's detail)
    named the upload's server folder (``.../real-jobs/uploads/20261123-...``, here under the server's temporary
    folder) to annotators, as did its params. An upload is now ``<file name> (upload <job id>)`` whatever the jobs
    folder, in every form the message may write it (relative, through a link)."""
    real = tmp_path / "real-jobs"
    real.mkdir()
    if jobs_folder == "relative":
        monkeypatch.chdir(tmp_path)
        jobs = Path("real-jobs")
    elif jobs_folder == "moved":
        jobs = real
    else:
        (tmp_path / "jobs-link").symlink_to(real)
        jobs = tmp_path / "jobs-link"
    app.state.settings = app.state.settings.model_copy(update={"jobs_dir": jobs})
    ids = []
    for kind, member in (("soccernet-v3", "league/season/game/Labels-v3.json"), ("sn-calibration", "set/00000.json")):
        buf = io.BytesIO()
        with zipfile.ZipFile(buf, "w") as zf:
            zf.writestr(member, b"{not json")
        queued = client.post("/api/imports", data={"kind": kind},
                             files={"file": ("broken.zip", buf.getvalue(), "application/zip")})
        assert queued.status_code == 202, queued.text
        ids.append(queued.json()["id"])
    run_queued(app)
    if jobs_folder == "moved":  # the server restarted with its jobs elsewhere
        app.state.settings = app.state.settings.model_copy(update={"jobs_dir": tmp_path / "new-jobs"})
    expected = {ids[0]: f"broken.zip (upload {ids[0]})/league/season/game/Labels-v3.json: invalid or truncated JSON",
                ids[1]: f"broken.zip (upload {ids[1]})/set/00000.json: invalid or truncated JSON"}
    for role in ("annotator", "reviewer"):
        act_as("ana", role)
        listed = {j["id"]: j for j in client.get("/api/jobs").json()["items"]}
        for job_id, start in expected.items():
            detail = client.get(f"/api/jobs/{job_id}").json()
            for job in (listed[job_id], detail):
                assert job["state"] == "failed" and job["message"].startswith(start), job["message"]
                text = json.dumps(job)
                assert str(tmp_path) not in text and "/tmp" not in text and "real-jobs" not in text, text
                assert job["params"]["path"] == f"broken.zip (upload {job_id})"


def test_an_uploads_file_name_reaches_other_users_cleaned(app, client: TestClient, act_as) -> None:
    """Was: an upload's file name reached other users' job listings with right-to-left overrides and terminal
    escapes. Control and format characters are replaced (U+FFFD) and the title kept short before anyone sees it."""
    act_as("adam", "admin")
    name = "\x1b[31mevil\u202egpj.zip" + "x" * 300
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w") as zf:
        zf.writestr("set/00000.json", "{}")
    uploaded = client.post("/api/imports", data={"kind": "sn-calibration", "width": "960", "height": "540"},
                           files={"file": (name, buf.getvalue(), "application/zip")})
    assert uploaded.status_code == 202, uploaded.text
    act_as("ana", "annotator")
    job = client.get(f"/api/jobs/{uploaded.json()['id']}").json()
    shown = job["params"]["path"]
    assert "\x1b" not in json.dumps(job, ensure_ascii=False) and "\u202e" not in json.dumps(job, ensure_ascii=False)
    assert shown.startswith("\ufffd[31mevil\ufffdgpj.zip") and len(shown) <= 120 + len(f" (upload {job['id']})")
