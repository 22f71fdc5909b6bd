"""``GET /api/health``: the liveness probe of Docker and the benchmarks, public (no data in it).

It never waits behind the requests it is meant to judge: it is answered on the event loop, and its database query
runs on a connection of its own (:class:`HealthProbe`: an engine of one connection, on a thread of its own limiter),
never one of the request pool nor a thread of the request thread pool, which a flood of slow requests may hold.
"""
from __future__ import annotations

import anyio
import sqlalchemy as sa
from fastapi import APIRouter, Request
from pydantic import BaseModel
from sqlalchemy.engine import Engine

router = APIRouter(tags=["health"])


class HealthOut(BaseModel):
    status: str


class HealthProbe:
    """``SELECT 1`` on ``engine`` (the app factory makes one of a single pooled connection), one probe at a time on a
    thread of its own (``anyio``'s capacity limiter of one, apart from the request threads' limiter)."""

    def __init__(self, engine: Engine) -> None:
        self.engine = engine
        self.limiter = anyio.CapacityLimiter(1)

    def _select_one(self) -> None:
        with self.engine.connect() as conn:
            conn.execute(sa.text("SELECT 1"))

    async def check(self) -> None:
        """Ask the database; raises what the database raised (a 500)."""
        await anyio.to_thread.run_sync(self._select_one, limiter=self.limiter)


@router.get("/health", response_model=HealthOut)
async def health(request: Request) -> HealthOut:
    """``{"status": "ok"}`` once the database answers on the probe's own connection (a database error is a 500)."""
    await request.app.state.health_probe.check()
    return HealthOut(status="ok")
