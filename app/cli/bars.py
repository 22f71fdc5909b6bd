"""The progress bars of the command line: one tqdm bar per stage of a job, whether the job runs here or on a server
(``v3d --server``: fed by the job as the client reads it)."""
from __future__ import annotations

from typing import Any

from tqdm import tqdm

#: What each stage of a job is called on its bar.
STAGES = {"games": "importing games", "merge": "merging", "calibrate": "calibrating",
          "rig": "calibrating with game rigs", "triangulate": "triangulating", "recompute": "recomputing systems",
          "export": "exporting games", "predictions": "storing predictions", "tables": "reading tables",
          "files": "copying files", "verify": "verifying (bytes)", "rows": "restoring rows"}


class StageBars:
    """One tqdm bar per stage of a job (import, recompute, export), fed by the services'
    ``progress(stage, done, total)``."""

    def __init__(self) -> None:
        self.bars: dict[str, tqdm] = {}

    def __call__(self, stage: str, done: int, total: int) -> None:
        """Move the bar of ``stage`` to ``done`` of ``total`` (a new stage closes the bars before it)."""
        bar = self.bars.get(stage)
        if bar is None:
            for other in self.bars.values():  # stages run one after the other
                other.close()
            bar = self.bars[stage] = tqdm(total=total, desc=STAGES.get(stage, stage), unit="item", leave=True)
        bar.update(done - bar.n)

    def close(self) -> None:
        """End every bar."""
        for bar in self.bars.values():
            bar.close()

    def job(self, job: Any) -> None:
        """Draw a job as last read (a job row, or a ``v3d_client.Job`` of a server): its ``stage``, ``done`` of
        ``total``."""
        if job.stage:
            self(job.stage, job.done, job.total)
