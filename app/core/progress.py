"""The progress callback of long work (imports, recomputes, exports), below every service that reports it: the
calibration, the recomputation and the transfers report through it, and the jobs (``app.services.jobs``) and the
CLI listen."""
from __future__ import annotations

from typing import Callable

#: ``progress(stage, done, total)``: called as work advances (the CLI draws a tqdm bar from it, a job stores it).
Progress = Callable[[str, int, int], None]
