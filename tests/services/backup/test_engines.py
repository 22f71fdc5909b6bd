"""The move from one machine to N and back: a deployment on SQLite and a folder, worked on over HTTP (decisions, a
needs-fix hand-off, a comment, a release and its export job), backed up with ``v3d backup``, restored with ``v3d
restore`` into a fresh PostgreSQL database and an S3 store (SeaweedFS on loopback, as the two-node test runs it),
then backed up there and restored into SQLite and a folder again: every answer the API gives (system pages with
their ETags, the queue, the audit, the comments, the hand-off, the releases, the export's bytes, the release
exported again, the annotators' figures, the jobs, the images) is the source's, field for field and byte for byte,
times included; the password and the token log in. And a key longer than S3 holds in the target's bucket is refused
before anything is written."""
from __future__ import annotations

import json
import zipfile
from pathlib import Path
from typing import Any

import pytest
import sqlalchemy as sa
from fastapi.testclient import TestClient
from sqlalchemy.orm import Session

from app.core.config import Settings
from app.db.models import Frame
from app.db.session import make_engine
from app.main import create_app
from app.services.accounts.users import create_user
from app.services.backup.archive import MANIFEST
from app.services.storage import _s3
from app.services.transfer.importing import import_soccernet_v3
from tests.conftest import migrate_new_database
from tests.seaweed import Seaweed, seaweed_for_tests
from tests.services.backup.test_backup import PASSWORD, deployment, invoke
from tests.services.datasets import write_v3_game

pytestmark = pytest.mark.processes


@pytest.fixture(scope="module")
def seaweed(tmp_path_factory: pytest.TempPathFactory):
    with seaweed_for_tests(tmp_path_factory.mktemp("seaweed")) as server:
        yield server


def settings_of(env: dict[str, str]) -> Settings:
    return Settings(_env_file=None, database_url=env["V3D_DATABASE_URL"], storage_url=env["V3D_STORAGE_URL"],
                    jobs_dir=Path(env["V3D_JOBS_DIR"]), calibration_workers=1, job_heartbeat_seconds=3600.0)


def s3_deployment(folder: Path, url: str, seaweed: Seaweed, prefix: str) -> dict[str, str]:
    folder.mkdir(parents=True, exist_ok=True)
    return {"V3D_DATABASE_URL": url, "V3D_STORAGE_URL": f"s3://{seaweed.bucket}/{prefix}",
            "V3D_JOBS_DIR": str(folder / "jobs"), "V3D_CALIBRATION_WORKERS": "1", **seaweed.env()}


def run_jobs(app: Any) -> None:
    from app.services.jobs import runner as jobs

    owner = jobs.owner_name(app.state.settings)
    while (job_id := jobs.claim_next(app.state.session_factory, owner, app.state.settings)) is not None:
        jobs.run_job(app.state.session_factory, job_id, app.state.settings, owner)


def work(env: dict[str, str], shared_dir: Path, tree: Path) -> dict[str, Any]:
    """The source deployment: the dev game's three systems imported from this machine's folder, an admin and an
    annotator, decisions (one needs fix: a hand-off), a comment, a release and its SoccerNet-v3D export job."""
    write_v3_game(shared_dir, tree)
    settings = settings_of(env)
    migrate_new_database(settings.database_url)
    engine = make_engine(settings.database_url)
    with Session(engine) as session:
        import_soccernet_v3(session, tree, settings, actor="ana")
        _admin, token = create_user(session, "ana", "admin", PASSWORD)
        create_user(session, "bo", "annotator", PASSWORD)
        ids = list(session.scalars(sa.select(Frame.system_id).distinct().order_by(Frame.system_id)))
    engine.dispose()
    with TestClient(create_app(settings)) as client:
        client.headers["Authorization"] = f"Bearer {token}"
        for system_id, status in zip(ids, ("accepted", "needs_fix", "accepted"), strict=True):
            etag = client.get(f"/api/systems/{system_id}").headers["etag"]
            body = {"status": status, "comment": "seen", **({"assignee": "bo"} if status == "needs_fix" else {})}
            answer = client.post(f"/api/systems/{system_id}/review", json=body, headers={"If-Match": etag})
            assert answer.status_code == 200, answer.text
        frame_id = client.get(f"/api/systems/{ids[1]}").json()["views"][0]["frame_id"]
        made = client.post(f"/api/systems/{ids[1]}/comments", json={"frame_id": frame_id, "point": [10.5, 20.0],
                                                                     "text": "the ball is behind the post"})
        assert made.status_code == 201, made.text
        assert client.post("/api/releases", json={"name": "v1", "note": "first"}).status_code == 201
        job = client.post("/api/exports/soccernet-v3d", json={"release": "v1"})
        assert job.status_code == 202, job.text
        run_jobs(client.app)
    return {"token": token, "ids": ids}


def answers(env: dict[str, str], token: str, ids: list[int]) -> dict[str, Any]:
    """What the API of the deployment ``env`` answers: every page the issue names, as JSON or bytes."""
    out: dict[str, Any] = {}
    with TestClient(create_app(settings_of(env))) as client:
        client.headers["Authorization"] = f"Bearer {token}"

        def get(path: str, **params: Any) -> Any:
            answer = client.get(path, params=params)
            assert answer.status_code == 200, (path, answer.text)
            return answer

        out["queue"] = get("/api/systems", limit=50).json()
        for system_id in ids:
            page = get(f"/api/systems/{system_id}")
            out[f"system {system_id}"] = (page.headers["etag"], page.json())
            out[f"comments {system_id}"] = get(f"/api/systems/{system_id}/comments").json()
            out[f"handoff {system_id}"] = get(f"/api/systems/{system_id}/handoff").json()
            for view in page.json()["views"]:
                image = get(f"/api/frames/{view['frame_id']}/image")
                out[f"image {view['frame_id']}"] = (image.headers["etag"], image.content)
        out["audit"] = get("/api/audit", limit=500).json()
        out["releases"] = get("/api/releases").json()
        out["release v1"] = get("/api/releases/v1").json()
        out["release v1 exported again"] = get("/api/exports/soccernet-v3d", release="v1").content
        out["annotators"] = get("/api/stats/annotators").json()
        out["users"] = get("/api/users").json()
        jobs = get("/api/jobs").json()
        out["jobs"] = jobs
        export = next(j for j in jobs["items"] if j["kind"] == "export")
        out["export file"] = get(export["result_url"]).content
        out["me"] = get("/api/auth/me").json()
        login = TestClient(client.app).post("/api/auth/login", json={"name": "bo", "password": PASSWORD})
        assert login.status_code == 200, login.text
    return out


@pytest.mark.postgres
def test_sqlite_and_a_folder_to_postgresql_and_s3_and_back(shared_dir, tmp_path, monkeypatch, seaweed, pg_url):
    source = deployment(tmp_path / "source")
    made = work(source, shared_dir, tmp_path / "v3")
    expected = answers(source, made["token"], made["ids"])
    assert len(expected["audit"]["items"]) > 5 and expected["comments " + str(made["ids"][1])]["items"]
    assert len(expected["release v1 exported again"]) > 1000 and len(expected["export file"]) > 1000

    first = tmp_path / "one-machine.zip"
    assert invoke(source, monkeypatch, "backup", str(first)).exit_code == 0
    team = s3_deployment(tmp_path / "team", pg_url, seaweed, "team")
    result = invoke(team, monkeypatch, "restore", str(first))
    assert result.exit_code == 0, result.output
    assert answers(team, made["token"], made["ids"]) == expected
    engine = make_engine(pg_url)
    with engine.begin() as conn:  # the sequences moved past the restored ids: a new row takes the next one
        next_id = conn.execute(sa.text("INSERT INTO review_comments (system_id, frame_id, author, text, created_at, "
                                       "resolved) SELECT system_id, frame_id, author, 'x', created_at, resolved "
                                       "FROM review_comments RETURNING id")).scalar_one()
        conn.execute(sa.text("DELETE FROM review_comments WHERE id = :i"), {"i": next_id})
    engine.dispose()
    assert next_id == expected[f"comments {made['ids'][1]}"]["items"][0]["id"] + 1

    # and back, by way of the bucket: backed up to s3:// and restored from there
    back = s3_deployment(tmp_path / "back-src", pg_url, seaweed, "team")
    assert invoke(back, monkeypatch, "backup", f"s3://{seaweed.bucket}/backups/team.zip").exit_code == 0
    again = {**deployment(tmp_path / "again"), **seaweed.env()}
    result = invoke(again, monkeypatch, "restore", f"s3://{seaweed.bucket}/backups/team.zip")
    assert result.exit_code == 0, result.output
    assert answers(again, made["token"], made["ids"]) == expected


def test_a_key_longer_than_s3_holds_is_refused_before_anything_is_written(tmp_path, monkeypatch, seaweed):
    source = deployment(tmp_path / "source")
    migrate_new_database(source["V3D_DATABASE_URL"])
    engine = make_engine(source["V3D_DATABASE_URL"])
    long_key = "exports/" + "/".join(["k" * 250] * 4) + ".zip"  # 1,015 bytes: a folder holds it
    with engine.begin() as conn:
        conn.execute(sa.text("INSERT INTO jobs (id, kind, params, state, done, total, attempts, created_at, result) "
                             "VALUES (1, 'export', '{}', 'done', 0, 0, 1, '2026-11-28 10:00:00', :r)"),
                     {"r": json.dumps({"file": "job-1-coco.zip"})})
    engine.dispose()
    store = Path(source["V3D_STORAGE_URL"].removeprefix("file://"))
    (store / "exports").mkdir(parents=True)
    (store / "exports" / "job-1-coco.zip").write_bytes(b"PK\x05\x06" + bytes(18))
    archive = tmp_path / "a.zip"
    assert invoke(source, monkeypatch, "backup", str(archive)).exit_code == 0
    hacked = tmp_path / "long.zip"
    with zipfile.ZipFile(archive) as zin, zipfile.ZipFile(hacked, "w") as zout:
        manifest = json.loads(zin.read(MANIFEST))
        for member in manifest["members"].values():  # re-zipped below: its stored bytes differ, its content not
            member.pop("stored_sha256")
        manifest["objects"] = {long_key: "store/exports/job-1-coco.zip"}
        for name in zin.namelist():
            if name != MANIFEST:
                zout.writestr(name, zin.read(name))
        zout.writestr(MANIFEST, json.dumps(manifest))
    target = s3_deployment(tmp_path / "target", f"sqlite:///{tmp_path / 'target.sqlite3'}", seaweed,
                           "a-prefix-of-the-team")  # prefix + "/" + key: 1,036 bytes
    result = invoke(target, monkeypatch, "restore", str(hacked))
    assert result.exit_code == 2 and "1036 bytes" in result.output and "1024" in result.output, result.output
    assert not (tmp_path / "target.sqlite3").exists()
    assert list(_s3(seaweed.bucket, "a-prefix-of-the-team").list("exports")) == []
