"""All API routers, one per resource, gathered under one router (mounted at ``/api``)."""
from __future__ import annotations

from fastapi import APIRouter

from app.api.routes import detectors, exports, frames, games, imports, issia, systems

api_router = APIRouter()
for _module in (games, systems, frames, imports, exports, detectors, issia):
    api_router.include_router(_module.router)
