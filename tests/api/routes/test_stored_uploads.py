"""Uploads, images and export files through the store (``V3D_STORAGE_URL``): by default the jobs folder (the layout
v3d always had), or a folder store of its own, in which case the jobs folder is only scratch: emptied, every image is
still served and every export file still downloads."""
from __future__ import annotations

import io
import shutil
import zipfile
from pathlib import Path

import pytest
import sqlalchemy as sa
from fastapi.testclient import TestClient

from app.db.models import Frame, Game
from tests.nodes.uploads import small_v3_upload

from ..conftest import run_queued

# Served: the store's behaviour, the same on either engine, so not an ``engine`` module.
pytestmark = pytest.mark.served


def _upload_and_export(app, client: TestClient, tmp_path: Path) -> tuple[list[int], str]:
    data = small_v3_upload(tmp_path / "src", systems=2, league="stored")
    answer = client.post("/api/imports", data={"kind": "soccernet-v3"},
                         files={"file": ("stored.zip", data, "application/zip")})
    assert answer.status_code == 202, answer.text
    export = client.post("/api/exports/soccernet-v3d", json={"all": True})
    assert export.status_code == 202, export.text
    run_queued(app)
    job = client.get(export.json()["url"]).json()
    assert job["state"] == "done", job
    with app.state.session_factory() as session:
        game_ids = session.scalars(sa.select(Game.id).where(Game.league == "stored-0")).all()
        assert len(game_ids) == 1
        frames = session.execute(sa.select(Frame.id, Frame.image_root).where(Frame.image_root.is_not(None))).all()
    roots = {root for _, root in frames}
    assert roots and all(r.startswith("storage:uploads/") for r in roots), roots  # no server path
    return [fid for fid, _ in frames], job["result_url"]


def _served(client: TestClient, frame_ids: list[int], result_url: str) -> None:
    for fid in frame_ids:
        image = client.get(f"/api/frames/{fid}/image")
        assert image.status_code == 200 and image.content[:8] == b"\x89PNG\r\n\x1a\n"
    download = client.get(result_url)
    assert download.status_code == 200
    assert any(n.endswith("Labels-v3D.json") for n in zipfile.ZipFile(io.BytesIO(download.content)).namelist())


def test_by_default_the_jobs_folder_is_the_store(app, client: TestClient, tmp_path: Path) -> None:
    app.state.settings = app.state.settings.model_copy(update={"jobs_dir": tmp_path / "jobs"})
    frame_ids, result_url = _upload_and_export(app, client, tmp_path)
    assert list((tmp_path / "jobs" / "uploads").glob("*/stored-0/*/*/Frames-v3.zip"))  # where uploads always lay
    assert list((tmp_path / "jobs" / "exports").glob("job-*-soccernet-v3d.zip"))
    _served(client, frame_ids, result_url)


def test_with_a_store_of_its_own_the_jobs_folder_is_only_scratch(app, client: TestClient, tmp_path: Path) -> None:
    store = tmp_path / "store"
    app.state.settings = app.state.settings.model_copy(
        update={"jobs_dir": tmp_path / "jobs", "storage_url": store.as_uri()})
    frame_ids, result_url = _upload_and_export(app, client, tmp_path)
    assert list((store / "uploads").glob("*/stored-0/*/*/Frames-v3.zip"))
    assert list((store / "exports").glob("job-*-soccernet-v3d.zip"))
    shutil.rmtree(tmp_path / "jobs")
    _served(client, frame_ids, result_url)
