"""Progress callbacks: what the client calls while it uploads, downloads and waits.

A transfer calls ``progress(done, total)`` with bytes sent or received so far and the whole size (None when the
server did not say it); waiting on a job calls ``progress(job)`` with the job as last read (its ``stage``, ``done``
of ``total``). :class:`tqdm_bytes` draws a transfer as a terminal bar when tqdm is installed
(``pip install './clients/python[progress]'``).
"""
from __future__ import annotations

from typing import Any, Callable, Optional

from v3d_client.models import Job

#: ``progress(done_bytes, total_bytes or None)``.
BytesProgress = Callable[[int, Optional[int]], None]
#: ``progress(job)``, the job as last read.
JobProgress = Callable[[Job], None]


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
