"""``GET /api/health``: the liveness probe of Docker and the benchmarks, public (no data in it)."""
from __future__ import annotations

import sqlalchemy as sa
from fastapi import APIRouter
from pydantic import BaseModel

from app.api.deps import SessionDep

router = APIRouter(tags=["health"])


class HealthOut(BaseModel):
    status: str


@router.get("/health", response_model=HealthOut)
def health(session: SessionDep) -> HealthOut:
    """``{"status": "ok"}`` once the database answers (a database error is a 500)."""
    session.execute(sa.text("SELECT 1"))
    return HealthOut(status="ok")
