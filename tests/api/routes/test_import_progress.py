"""An uploaded import is titled by its file's name (not the server's upload folder) and shows its stage and count
from its first second: the runner keeps them in the live progress file the API reads while the job's own transaction
holds its row back (SQLite), reading -> calibrating -> triangulating, each with done / total."""
from __future__ import annotations

from pathlib import Path

import pytest
from fastapi.testclient import TestClient

from app.core.config import jobs_dir
from app.core.names import TITLE_MAX, clean_title
from app.services.jobs import runner as jobs
from app.services.jobs.progress import live_file, read_live

from .test_jobs import _dev_game_zip, _upload

pytestmark = pytest.mark.engine


@pytest.fixture
def jobs_app(app, tmp_path: Path):
    """The app with its uploads and live progress under this test's folder."""
    app.state.settings = app.state.settings.model_copy(update={"jobs_dir": tmp_path / "jobs"})
    return app


def test_an_upload_is_titled_by_its_file_and_its_progress_is_live(jobs_app, client: TestClient,
                                                                  shared_dir: Path) -> None:
    data, _ = _dev_game_zip(shared_dir)
    answer = _upload(client, data, name="C:\\Users\\ana\\Season 2015.zip")
    assert answer.status_code == 202, answer.text
    job = answer.json()
    assert job["params"]["name"] == "Season 2015.zip"  # its last path component, as the browser named it
    settings = jobs_app.state.settings
    seen: list[tuple[str, int, int]] = []

    def progress(stage: str, done: int, total: int) -> None:
        # what GET /api/jobs/{id} answers for the running job at this moment: this stage, its count as last written
        # (at most every 0.25 s: never ahead, the last of a stage always)
        live = read_live(jobs_dir(settings), job["id"])
        assert live is not None and live[0] == stage and live[2] == total and live[1] <= done
        assert done < total or live[1] == done
        seen.append((stage, done, total))

    owner = jobs.owner_name(settings)
    assert jobs.claim_next(jobs_app.state.session_factory, owner, settings) == job["id"]
    ran = jobs.run_job(jobs_app.state.session_factory, job["id"], settings, owner, progress=progress)
    assert ran.state.value == "done", ran.message
    assert seen[0] == ("read", 0, 1)  # the first thing the job says: reading its one game
    stages = [s for s, _, _ in seen]
    assert stages.index("read") < stages.index("calibrate") < stages.index("triangulate")
    assert all(total > 0 and 0 <= done <= total for _, done, total in seen)
    assert not live_file(jobs_dir(settings), job["id"]).exists()  # gone with the job; the row keeps the last
    done = client.get(job["url"]).json()
    assert done["state"] == "done" and done["params"]["name"] == "Season 2015.zip"
    assert done["result"]["games"] == 1


def test_a_crafted_upload_name_is_only_a_title(jobs_app, client: TestClient, shared_dir: Path, tmp_path: Path) -> None:
    """A file name sent with an upload is shown, never used as a path: a name leading out of the jobs folder, with
    markup in it, becomes its last component as a title (``clean_title``: at most ``TITLE_MAX`` characters), and
    nothing is written outside the jobs folder under any part of it (the pages set it as text)."""
    data, _ = _dev_game_zip(shared_dir)
    crafted = "../../../outside/" + "x" * 300 + "<img src=x onerror=alert(1)>.zip"
    answer = _upload(client, data, name=crafted)
    assert answer.status_code == 202, answer.text
    name = answer.json()["params"]["name"]
    assert name == clean_title("x" * 300 + "<img src=x onerror=alert(1)>.zip") and "/" not in name
    assert len(name) <= TITLE_MAX
    assert not (tmp_path / "outside").exists() and not (tmp_path.parent / "outside").exists()
    written = [p for p in tmp_path.rglob("*") if p.is_file()]
    assert written and all(p.is_relative_to(tmp_path / "jobs") or p.suffix == ".sqlite3" for p in written), written
