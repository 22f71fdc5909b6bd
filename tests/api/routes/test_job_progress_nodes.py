"""A running job's progress as the API shows it: the live file where the job runs on this node, else the row's (the
node running it keeps the file; one left here by an earlier attempt is stale)."""
from __future__ import annotations

from pathlib import Path

from app.api.routes.jobs import job_out
from app.core.config import Settings, jobs_dir
from app.db.models import Job, JobState
from app.db.types import utcnow
from app.services.jobs.progress import write_live


def test_progress_comes_from_the_live_file_on_the_jobs_node_and_from_the_row_elsewhere(tmp_path: Path) -> None:
    here = Settings(_env_file=None, database_url=f"sqlite:///{tmp_path / 'x.sqlite3'}", jobs_dir=tmp_path,
                    node_name="node-a")
    job = Job(id=7, kind="import", params={}, state=JobState.RUNNING, stage="read", done=1, total=3, attempts=1,
              created_at=utcnow())
    write_live(jobs_dir(here), 7, "calibrate", 5, 10)
    job.owner = "node-a:123:t"
    assert (job_out(job, None, here).stage, job_out(job, None, here).done) == ("calibrate", 5)
    job.owner = "node-b:123:t"  # taken over by node B: the file here is A's, older than B's heartbeats in the row
    out = job_out(job, None, here)
    assert (out.stage, out.done, out.total) == ("read", 1, 3)
