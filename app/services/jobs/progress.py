"""A running job's live progress, kept in a small file beside the jobs' files so that any process serving the API
reads it at once (the callback the job listens to, ``app.core.progress.Progress``, is below the services).

A job's row holds its progress as its heartbeat last stored it. On SQLite the heartbeat may write only between the
job's transactions (``app.services.jobs.runner``), and an import calibrates and triangulates a batch of games inside
one: its row said ``running``, no stage, 0/0 until the batch committed. The runner therefore also writes each change
of stage, and the count at most every :data:`LIVE_EVERY_S`, to ``<jobs dir>/live/<job id>.json`` (written whole and
renamed into place: a reader never sees half of it), which the API reads for a running job (:func:`read_live`). The
file goes when the job ends.
"""
from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Optional

#: Least seconds between two writes of the same stage's count.
LIVE_EVERY_S = 0.25


def live_file(jobs_folder: Path, job_id: int) -> Path:
    """Where job ``job_id``'s live progress is kept."""
    return jobs_folder / "live" / f"{int(job_id)}.json"


def write_live(jobs_folder: Path, job_id: int, stage: str, done: int, total: int) -> None:
    """Store the job's progress now (an error is ignored: the heartbeat's copy in the row remains)."""
    path = live_file(jobs_folder, job_id)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        part = path.with_suffix(f".{os.getpid()}.part")
        part.write_text(json.dumps({"stage": stage, "done": int(done), "total": int(total)}))
        os.replace(part, path)
    except OSError:
        pass


def read_live(jobs_folder: Path, job_id: int) -> Optional[tuple[str, int, int]]:
    """``(stage, done, total)`` of a running job as its runner last wrote it, or None (no file, or unreadable)."""
    try:
        data = json.loads(live_file(jobs_folder, job_id).read_text())
        return str(data["stage"]), int(data["done"]), int(data["total"])
    except (OSError, ValueError, KeyError, TypeError):
        return None


def remove_live(jobs_folder: Path, job_id: int) -> None:
    """The job ended: its live progress goes (the row holds the last one)."""
    try:
        live_file(jobs_folder, job_id).unlink()
    except OSError:
        pass
