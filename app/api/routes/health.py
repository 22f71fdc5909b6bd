"""``GET /api/health``: the liveness probe of Docker and the benchmarks, public (no data in it).

It never waits behind the requests it is meant to judge: it is answered on the event loop, and its database query
runs on a connection of its own (``app.api.probe.HealthProbe``: an engine of one connection, on a thread of its own
limiter), never one of the request pool nor a thread of the request thread pool, which a flood of slow requests may
hold.
"""
from __future__ import annotations

from fastapi import APIRouter, Request

from app import __version__
from app.api.schemas import HealthOut

router = APIRouter(tags=["health"])


@router.get("/health", response_model=HealthOut)
async def health(request: Request) -> HealthOut:
    """``{"status": "ok", "version": ...}`` once the database answers on the probe's own connection (a database
    error is a 500); ``version`` is the server's (``app.__version__``), which a client checks at its first call."""
    await request.app.state.health_probe.check()
    return HealthOut(status="ok", version=__version__)
