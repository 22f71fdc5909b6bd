"""Jobs over HTTP: uploads imported as jobs (size limit while streaming, hostile zips refused naming
the member), full recompute and export jobs, the job list and a job's file."""
from __future__ import annotations

import io
import zipfile
from pathlib import Path

import pytest
from fastapi.testclient import TestClient

from ..conftest import run_queued
from ..factories import Scene

pytestmark = pytest.mark.engine


@pytest.fixture
def jobs_app(app, tmp_path: Path):
    """The app with its uploads and export files under this test's folder."""
    app.state.settings = app.state.settings.model_copy(update={"jobs_dir": tmp_path / "jobs"})
    return app


def _dev_game_zip(shared_dir: Path) -> tuple[bytes, str]:
    """One game of the synthetic dev set (labels and Frames-v3.zip) zipped as league/season/game."""
    dev = shared_dir / "data" / "synthetic" / "soccernet-v3-dev"
    labels = sorted(dev.rglob("Labels-v3.json"))[0]
    game = labels.parent
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w", compression=zipfile.ZIP_DEFLATED) as zf:
        for f in sorted(game.iterdir()):
            zf.write(f, f.relative_to(dev).as_posix())
    return buf.getvalue(), game.name


def _upload(client: TestClient, data: bytes, name: str = "dataset.zip", **fields):
    return client.post("/api/imports", data={"kind": "soccernet-v3", **fields},
                       files={"file": (name, data, "application/zip")})


def test_an_uploaded_zip_is_imported_by_a_job_with_its_images(jobs_app, client: TestClient, shared_dir: Path,
                                                               tmp_path: Path) -> None:
    data, match = _dev_game_zip(shared_dir)
    answer = _upload(client, data)
    assert answer.status_code == 202, answer.text
    job = answer.json()
    assert answer.headers["location"] == job["url"] and job["state"] == "queued"
    folder = Path(job["params"]["path"])
    assert folder.parent == (tmp_path / "jobs" / "uploads").resolve() and (folder / "synth_league_a").is_dir()
    run_queued(jobs_app)
    done = client.get(job["url"]).json()
    assert done["state"] == "done", done
    assert (done["result"]["games"], done["result"]["systems"], done["result"]["frames"]) == (1, 20, 55)
    assert [g["match"] for g in client.get("/api/games").json()] == [match]
    frame = client.get("/api/frames", params={"limit": 1}).json()["items"][0]
    image = client.get(frame["image_url"])
    assert image.status_code == 200 and image.content[:4] == b"\x89PNG"
    listed = client.get("/api/jobs", params={"kind": "import"}).json()
    assert listed["total"] == 1 and listed["items"][0]["id"] == job["id"]


def _multipart(fields: dict[str, str], file: bytes, boundary: str = "v3dboundary"):
    """A multipart body sent in 64 kB chunks without Content-Length (chunked transfer)."""
    head = "".join(f'--{boundary}\r\nContent-Disposition: form-data; name="{k}"\r\n\r\n{v}\r\n'
                   for k, v in fields.items())
    head += f'--{boundary}\r\nContent-Disposition: form-data; name="file"; filename="big.zip"\r\n' \
            "Content-Type: application/zip\r\n\r\n"
    body = head.encode() + file + f"\r\n--{boundary}--\r\n".encode()

    def chunks():
        for i in range(0, len(body), 1 << 16):
            yield body[i:i + (1 << 16)]
    return chunks(), {"Content-Type": f"multipart/form-data; boundary={boundary}"}


def test_an_upload_above_the_limit_is_refused_while_it_streams(jobs_app, client: TestClient, tmp_path: Path) -> None:
    jobs_app.state.settings = jobs_app.state.settings.model_copy(update={"max_upload_mb": 0.5})
    big = bytes(600_000)
    declared = _upload(client, big)  # Content-Length above the limit: refused before reading
    assert declared.status_code == 413 and "V3D_MAX_UPLOAD_MB" in declared.json()["detail"]
    chunks, headers = _multipart({"kind": "soccernet-v3"}, big)  # no Content-Length: counted as it arrives
    streamed = client.post("/api/imports", content=chunks, headers=headers)
    assert streamed.status_code == 413 and streamed.json()["field"] == "file"
    assert not (tmp_path / "jobs" / "uploads").exists() or not any((tmp_path / "jobs" / "uploads").iterdir())
    assert client.get("/api/jobs").json()["total"] == 0


def test_hostile_or_broken_uploads_are_refused_naming_the_member(jobs_app, client: TestClient) -> None:
    def zipped(members: dict[str, bytes]) -> bytes:
        buf = io.BytesIO()
        with zipfile.ZipFile(buf, "w") as zf:
            for name, data in members.items():
                zf.writestr(name, data)
        return buf.getvalue()

    slip = _upload(client, zipped({"l/s/g/Labels-v3.json": b"{}", "../../escape.json": b"{}"}))
    assert slip.status_code == 400 and "'../../escape.json'" in slip.json()["detail"], slip.text
    image = _upload(client, zipped({"l/s/g/Labels-v3.json": b"{}", "l/s/g/12.png": b"GIF89a not a png"}))
    assert image.status_code == 400 and "l/s/g/12.png: not a PNG or JPEG image" in image.json()["detail"]
    notzip = _upload(client, b"just text")
    assert notzip.status_code == 400 and "not a readable zip" in notzip.json()["detail"]
    nofile = client.post("/api/imports", data={"kind": "soccernet-v3"}, files={"other": ("x", b"y")})
    assert nofile.status_code == 422 and nofile.json()["field"] == "file"
    kind = _upload(client, zipped({"a.json": b"{}"}), kind="coco")
    assert kind.status_code == 422 and kind.json()["detail"][0]["loc"] == ["body", "kind"]
    unknown = _upload(client, zipped({"a.json": b"{}"}), colour="red")
    assert unknown.status_code == 422 and unknown.json()["detail"][0]["loc"] == ["body", "colour"]
    malformed = client.post("/api/imports", content=b'{"kind": "soccernet-v3", "path": ',
                            headers={"Content-Type": "application/json"})
    assert malformed.status_code == 422 and malformed.json()["detail"][0]["type"] == "json_invalid"
    assert client.get("/api/jobs").json()["total"] == 0 and client.get("/api/games").json() == []


def test_full_recompute_and_export_jobs(jobs_app, client: TestClient, scene: Scene) -> None:
    recompute = client.post("/api/recompute")
    assert recompute.status_code == 202 and recompute.json()["kind"] == "recompute"
    export = client.post("/api/exports/soccernet-v3d", json={"all": True})
    assert export.status_code == 202 and export.json()["params"] == {"format": "soccernet-v3d", "all": True,
                                                                      "images": True}
    early = client.get(f"{export.json()['url']}/result")
    assert early.status_code == 409 and "queued" in early.json()["detail"]
    assert run_queued(jobs_app) == [recompute.json()["id"], export.json()["id"]]
    done = client.get(recompute.json()["url"]).json()
    assert (done["state"], done["result"], done["stage"], done["done"], done["total"]) == (
        "done", {"systems": 1, "triangulated": 1,
                 "summary": {"words": "1 system recomputed, 1 with a 3D ball", "links": []}}, "recompute", 1, 1)
    job = client.get(export.json()["url"]).json()
    assert job["state"] == "done" and job["result"]["systems"] == 1 and job["result"]["rows"] == 3
    assert (job["stage"], job["done"], job["total"]) == ("export", 1, 1)
    file = client.get(job["result_url"])
    assert file.status_code == 200 and file.headers["content-type"] == "application/zip"
    assert int(file.headers["content-length"]) == job["result"]["bytes"]
    streamed = client.get("/api/exports/soccernet-v3d", params={"all": "true"})
    with zipfile.ZipFile(io.BytesIO(file.content)) as a, zipfile.ZipFile(io.BytesIO(streamed.content)) as b:
        assert {n: a.read(n) for n in a.namelist()} == {n: b.read(n) for n in b.namelist()}
    assert client.get(f"{recompute.json()['url']}/result").status_code == 409
    assert client.get("/api/jobs/999999").json()["detail"] == "job 999999 not found"
    assert client.get("/api/jobs", params={"state": "done"}).json()["total"] == 2
    assert client.post("/api/exports/soccernet-v3d", json={"all": "yes"}).status_code == 422


def test_an_upload_whose_dataset_fails_is_removed(jobs_app, client: TestClient, tmp_path: Path) -> None:
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w") as zf:
        zf.writestr("l/s/g/Labels-v3.json", b'{"actions": {"1.png": {"imageMetadata": {"width": 0}}}}')
    answer = _upload(client, buf.getvalue())
    assert answer.status_code == 202
    folder = Path(answer.json()["params"]["path"])
    assert (folder / "l" / "s" / "g" / "Labels-v3.json").is_file() and answer.json()["params"]["upload"] is True
    run_queued(jobs_app)
    job = client.get(answer.json()["url"]).json()
    assert job["state"] == "failed" and "Labels-v3.json" in job["message"] and "width" in job["message"], job
    assert not folder.exists() and client.get("/api/games").json() == []


@pytest.mark.parametrize("path", ["/api/jobs/{}", "/api/jobs/{}/result"])
def test_job_ids_beyond_the_database_integers_are_422_naming_them(client: TestClient, path: str) -> None:
    """Found by benchmarks/fuzz.py on PostgreSQL (issue 15): ``GET /api/jobs/206647351355/result`` reached the query,
    which PostgreSQL refused (integer out of range): a 500."""
    for job_id in (206647351355, -(2**31) - 1, 2**63):
        answer = client.get(path.format(job_id))
        assert answer.status_code == 422 and answer.json()["detail"][0]["loc"] == ["path", "job_id"], answer.text
    assert client.get(path.format(2**31 - 1)).status_code == 404
