"""``POST /api/backups`` and its archive's download: an admin's job, its archive verified whole and holding the
deployment's rows and images; every other role refused (403), a browser session's write without its CSRF token
refused (403), no one anonymous (401); the archive downloaded by admins only (it holds password and token hashes)."""
from __future__ import annotations

import zipfile
from pathlib import Path

import pytest
from fastapi import FastAPI
from fastapi.testclient import TestClient

from app.api.authentication import CSRF_HEADER
from app.services.backup.archive import verify_archive
from tests.accounts import Account, as_session, as_token

from ..conftest import run_queued
from ..factories import Scene

#: The job reads the database through its own engine, as a served process does (tests/api/conftest.py).
pytestmark = [pytest.mark.served, pytest.mark.engine]


def test_an_admin_backs_up_the_deployment_and_downloads_its_archive(app: FastAPI, scene: Scene,
                                                                    accounts: dict[str, Account], tmp_path: Path):
    with as_session(TestClient(app), accounts["admin"]) as admin:
        made = admin.post("/api/backups", json={})
        assert made.status_code == 202, made.text
        job = made.json()
        assert job["kind"] == "backup" and made.headers["location"] == job["url"]
        assert run_queued(app) == [job["id"]]
        done = admin.get(job["url"]).json()
        assert done["state"] == "done", done
        assert done["result"]["rows"] > 0 and done["result"]["missing"] == 0 and "destination" not in done["result"]
        archive = admin.get(done["result_url"])
        assert archive.status_code == 200 and archive.headers["content-type"] == "application/zip"
    path = tmp_path / "backup.zip"
    path.write_bytes(archive.content)
    manifest = verify_archive(path)
    counts = {t.name: t.rows for t in manifest.tables}
    assert counts["users"] == len(accounts) and counts["systems"] == 1 and counts["frames"] == 3
    with zipfile.ZipFile(path) as zf:  # the two views' images, read from their folder on this machine
        assert sum(1 for n in zf.namelist() if n.startswith("local/")) == 2


def test_only_an_admin_may_back_up_and_a_browser_needs_its_csrf_token(app: FastAPI, accounts: dict[str, Account]):
    with TestClient(app) as anonymous:
        assert anonymous.post("/api/backups", json={}).status_code == 401
    for role in ("annotator", "reviewer"):
        with as_session(TestClient(app), accounts[role]) as browser:
            assert browser.post("/api/backups", json={}).status_code == 403
        with as_token(TestClient(app), accounts[role]) as script:
            assert script.post("/api/backups", json={}).status_code == 403
    with as_session(TestClient(app), accounts["admin"]) as browser:
        browser.headers.pop(CSRF_HEADER)
        refused = browser.post("/api/backups", json={})
        assert refused.status_code == 403 and "csrf" in refused.text.lower()
    assert run_queued(app) == []  # nothing was queued
    with as_token(TestClient(app), accounts["admin"]) as script:  # a token sends no CSRF token
        assert script.post("/api/backups", json={"local_files": False}).status_code == 202
        assert script.post("/api/backups", json={"local_files": "no"}).status_code == 422


def test_the_archive_is_downloaded_by_admins_only(app: FastAPI, accounts: dict[str, Account]):
    with as_token(TestClient(app), accounts["admin"]) as admin:
        job = admin.post("/api/backups").json()  # no body: the defaults
        run_queued(app)
        url = admin.get(job["url"]).json()["result_url"]
        assert url == f"/api/jobs/{job['id']}/result"
        for role in ("annotator", "reviewer"):
            with as_token(TestClient(app), accounts[role]) as other:
                assert other.get(job["url"]).status_code == 200  # the job is seen
                assert other.get(url).status_code == 403  # its archive is not
            with as_session(TestClient(app), accounts[role]) as other:
                assert other.get(url).status_code == 403
        with TestClient(app) as anonymous:
            assert anonymous.get(url).status_code == 401
        assert admin.get(url).content[:2] == b"PK"


def test_the_store_keeps_the_newest_archives_and_refuses_one_it_has_no_room_for(app: FastAPI,
                                                                                 accounts: dict[str, Account]):
    """V3D_BACKUPS_KEPT=2: three backups leave the two newest archives (the oldest's download 404); an archive that
    took more than the disk has free refuses the next backup in words (409), nothing queued."""
    import shutil

    from app.services.jobs.work import backup_key
    from app.services.storage import storage_for

    app.state.settings = app.state.settings.model_copy(update={"backups_kept": 2})
    settings = app.state.settings
    storage = storage_for(settings)
    with as_token(TestClient(app), accounts["admin"]) as script:
        ids = []
        for _ in range(3):
            made = script.post("/api/backups", json={"local_files": False})
            assert made.status_code == 202, made.text
            ids.append(made.json()["id"])
            assert run_queued(app) == [ids[-1]]
        kept = sorted(o.key for o in storage.list("backups") if o.key.endswith("-backup.zip"))
        assert kept == sorted(backup_key(f"job-{i}-backup.zip") for i in ids[1:])
        assert script.get(f"/api/jobs/{ids[0]}/result").status_code == 404
        assert script.get(f"/api/jobs/{ids[2]}/result").status_code == 200
        # the newest archive as large as the disk's free space and more (a sparse file: it takes no room itself)
        newest = storage.local_path(backup_key(f"job-{ids[2]}-backup.zip"))
        assert newest is not None
        with open(newest, "r+b") as f:
            f.truncate(shutil.disk_usage(newest.parent).free + (1 << 30))
        refused = script.post("/api/backups", json={"local_files": False})
        assert refused.status_code == 409 and "no backup was queued" in refused.json()["detail"] \
            and "V3D_BACKUPS_KEPT" in refused.json()["detail"], refused.text
        assert run_queued(app) == []
