"""The liveness probe's own way to the database (``GET /api/health``, ``app.api.routes.health``): made once by the app
factory (``app.main.create_app``) with an engine of one connection, apart from the request pool."""
from __future__ import annotations

import anyio
import sqlalchemy as sa
from sqlalchemy.engine import Engine


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
