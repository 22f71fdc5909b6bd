"""An import job row is data, whoever wrote it (the API, an archive restored, a hand-made row): run by a runner, it
reads only under the data root or from its own upload, and its clean-up removes only an upload's own folder under the
server's uploads folder (``app.services.jobs.work.confined_import``, ``remove_upload``). The operator's own
``v3d import`` (``run_job(..., command_line=True)``) still reads any folder it names."""
from __future__ import annotations

from pathlib import Path

import pytest
import sqlalchemy as sa

from app.core.config import Settings
from app.db.models import Game, JobState
from app.db.session import make_engine, make_session_factory
from app.services.jobs import runner as jobs
from app.services.jobs.work import import_params
from tests.conftest import migrate_new_database

from ..datasets import write_v3_game


@pytest.fixture
def deployment(tmp_path: Path):
    """A SQLite database, a folder store, a jobs folder and a data root, all under ``tmp_path``; yields
    ``(settings, session factory)``."""
    url = f"sqlite:///{tmp_path / 'jobs.sqlite3'}"
    migrate_new_database(url)
    (tmp_path / "data").mkdir()
    settings = Settings(_env_file=None, database_url=url, storage_url=(tmp_path / "store").as_uri(),
                        jobs_dir=tmp_path / "jobs", data_root=tmp_path / "data", calibration_workers=1)
    engine = make_engine(url)
    yield settings, make_session_factory(engine)
    engine.dispose()


def _queue_and_run(make, settings: Settings, params: dict) -> jobs.Job:
    """Queue ``params`` as an import row (as an archive or the API leaves one) and run it as a server's runner does."""
    with make() as session:
        job_id = jobs.submit(session, "import", params).id
    owner = jobs.owner_name(settings)
    assert jobs.claim_next(make, owner, settings) == job_id
    return jobs.run_job(make, job_id, settings, owner)


def test_an_upload_row_naming_a_host_folder_neither_reads_nor_removes_it(deployment, tmp_path: Path) -> None:
    settings, make = deployment
    precious = tmp_path / "home" / "precious"
    precious.mkdir(parents=True)
    (precious / "thesis.txt").write_text("years of work")  # no dataset: the import refuses it, then cleans up
    job = _queue_and_run(make, settings, {**import_params("soccernet-v3", precious), "upload": True})
    assert (precious / "thesis.txt").read_text() == "years of work"
    assert job.state is JobState.FAILED and "uploads folder" in str(job.message), job.message
    # through a link inside the uploads folder that leads out of it: neither read nor removed either
    uploads = settings.jobs_dir / "uploads"
    uploads.mkdir(parents=True)
    (uploads / "20260101-000000-deadbeef").symlink_to(precious, target_is_directory=True)
    job = _queue_and_run(make, settings, {**import_params("soccernet-v3", uploads / "20260101-000000-deadbeef"),
                                          "upload": True})
    assert job.state is JobState.FAILED and "uploads folder" in str(job.message), job.message
    assert (precious / "thesis.txt").read_text() == "years of work"


@pytest.mark.parametrize("key", ["uploads/../../home", "exports/x", "uploads/a/b", "uploads/.."])
def test_an_upload_key_that_is_no_upload_is_refused(deployment, key: str) -> None:
    settings, make = deployment
    job = _queue_and_run(make, settings, {**import_params("soccernet-v3", settings.jobs_dir / "uploads" / "x"),
                                          "upload": True, "upload_key": key})
    assert job.state is JobState.FAILED and "not an upload's folder" in str(job.message), job.message


def test_a_queued_import_outside_the_data_root_is_refused_and_the_command_line_still_imports(
        deployment, shared_dir: Path, tmp_path: Path) -> None:
    settings, make = deployment
    tree = write_v3_game(shared_dir, tmp_path / "elsewhere", with_images=False).parent.parent.parent
    job = _queue_and_run(make, settings, import_params("soccernet-v3", tree))
    assert job.state is JobState.FAILED and "data root (V3D_DATA_ROOT)" in str(job.message), job.message
    with make() as session:
        assert session.scalar(sa.select(sa.func.count(Game.id))) == 0
    # the same folder typed on this machine's command line (``v3d import``: run_job_here) is imported
    owner = jobs.owner_name(settings)
    with make() as session:
        job_id = jobs.submit(session, "import", import_params("soccernet-v3", tree), owner=owner).id
    done = jobs.run_job(make, job_id, settings, owner, command_line=True)
    assert done.state is JobState.DONE, done.message
    with make() as session:
        assert session.scalar(sa.select(sa.func.count(Game.id))) == 1
