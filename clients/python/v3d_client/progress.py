"""Progress callbacks: what the client calls while it uploads, downloads and waits.

A transfer calls ``progress(done, total)`` with bytes sent or received so far and the whole size (None when the
server did not say it); waiting on a job calls ``progress(job)`` with the job as last read (its ``stage``, ``done``
of ``total``). :func:`tqdm_bytes` and :func:`tqdm_job` draw them as terminal bars when tqdm is installed
(``pip install './clients/python[progress]'``).
"""
from __future__ import annotations

from typing import Any, Callable, Optional, Protocol

from v3d_client.models import Job

#: ``progress(done_bytes, total_bytes or None)``.
BytesProgress = Callable[[int, Optional[int]], None]
#: ``progress(job)``, the job as last read.
JobProgress = Callable[[Job], None]


class _Closing(Protocol):
    def close(self) -> None: ...


class tqdm_bytes:
    """A tqdm bar of bytes (``desc`` its label), callable as a :data:`BytesProgress`; ``close()`` it at the end.

    Raises:
        ImportError: tqdm is not installed.
    """

    def __init__(self, desc: str, **options: Any) -> None:
        from tqdm import tqdm

        self._bar: Any = tqdm(desc=desc, unit="B", unit_scale=True, unit_divisor=1024, **options)

    def __call__(self, done: int, total: Optional[int]) -> None:
        if total is not None and self._bar.total != total:
            self._bar.total = total
        self._bar.update(done - self._bar.n)

    def close(self) -> None:
        """End the bar."""
        self._bar.close()


class tqdm_job:
    """tqdm bars of a job's stages (one bar a stage, in turn), callable as a :data:`JobProgress`; ``close()`` it.

    Raises:
        ImportError: tqdm is not installed.
    """

    def __init__(self, **options: Any) -> None:
        from tqdm import tqdm

        self._tqdm, self._options = tqdm, options
        self._bar: Any = None
        self._stage: Optional[str] = None

    def __call__(self, job: Job) -> None:
        if job.stage is None:
            return
        if job.stage != self._stage:
            self.close()
            self._stage = job.stage
            self._bar = self._tqdm(desc=f"job {job.id}: {job.stage}", total=job.total or None, unit="item",
                                   **self._options)
        if job.total and self._bar.total != job.total:
            self._bar.total = job.total
        self._bar.update(job.done - self._bar.n)

    def close(self) -> None:
        """End the current stage's bar."""
        if self._bar is not None:
            self._bar.close()
            self._bar = None
