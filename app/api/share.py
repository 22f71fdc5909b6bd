"""Each user's fair share of a server process's computations: calibration previews and evaluations.

A preview or an evaluation computes for a while (a calibration of up to 2,000 line points, a benchmark over every
reference view) on one of the process's request threads and on its one interpreter. One annotator's thirty parallel
previews took thirty of the forty threads, and everyone else's requests waited behind them. :class:`ComputeShare` is
a bounded semaphore per user (``V3D_COMPUTE_SHARE`` permits, 2): a computation takes one without waiting, and one
more than the share is answered **429 with** ``Retry-After`` at once, before it reads or computes anything. Edits are
not counted here: they take their turns in the edit slots (``app.services.curation.writing.EditSlots``) and are never
refused. Each process keeps its own semaphores: with ``v3d serve --workers N`` a user may compute N shares at once,
one per process, each process's threads and core shared the same way.
"""
from __future__ import annotations

import contextlib
import threading
from collections.abc import Iterator
from typing import Any

from fastapi import HTTPException

from app.api.schemas import ErrorOut

#: How long a client refused by its share is told to wait (seconds): about one preview's computation.
RETRY_AFTER_S = 1

#: The OpenAPI answer of the routes that take a share.
SHARE_SPENT: dict[int | str, dict[str, Any]] = {
    429: {"model": ErrorOut, "description": "Your share of the server's computations (V3D_COMPUTE_SHARE previews and "
                                            "evaluations at once) is in use: send it again after Retry-After."}}


class ComputeShare:
    """At most ``share`` computations of one user at once in this process (module docstring).

    Raises:
        ValueError: a share below 1.
    """

    def __init__(self, share: int) -> None:
        if share < 1:
            raise ValueError(f"a compute share is at least 1, not {share}")
        self.share = share
        self._users: dict[str, threading.BoundedSemaphore] = {}
        self._lock = threading.Lock()

    @contextlib.contextmanager
    def turn(self, user: str, what: str) -> Iterator[None]:
        """Hold one of ``user``'s permits for the block; :class:`HTTPException` 429 with ``Retry-After`` when all of
        them are held (``what``, e.g. "calibration preview", names the refused computation)."""
        with self._lock:
            permits = self._users.setdefault(user, threading.BoundedSemaphore(self.share))
        if not permits.acquire(blocking=False):
            raise HTTPException(429, detail=f"{self.share} of your previews and evaluations are being computed "
                                            f"(V3D_COMPUTE_SHARE): send this {what} again when one has answered",
                                headers={"Retry-After": str(RETRY_AFTER_S)})
        try:
            yield
        finally:
            permits.release()
