"""All API routers, one per resource, gathered under one router (mounted at ``/api``).

Every router but the public part of ``/api/auth`` (login, demo) and ``/api/health`` is included under the dependencies
of ``app.api.authentication.PROTECTED`` (a principal, the OpenAPI security schemes), so a new router or
route needs a logged-in user by default; the least role of a write is stated on its router or route
with ``app.api.auth.require_role``.
"""
from __future__ import annotations

from fastapi import APIRouter

from app.api.authentication import PROTECTED
from app.api.bodies import BODY_REFUSED
from app.api.routes import (
    annotators,
    assignments,
    audit,
    auth,
    backups,
    batches,
    comments,
    detectors,
    exports,
    frames,
    games,
    handoffs,
    health,
    imports,
    issia,
    jobs,
    passes,
    pitch,
    predictions,
    releases,
    systems,
    users,
)
from app.api.schemas import ErrorOut

api_router = APIRouter(responses=BODY_REFUSED)
api_router.include_router(auth.public_router)
api_router.include_router(health.router)
_protected = APIRouter(dependencies=PROTECTED, responses={
    401: {"model": ErrorOut, "description": "No session or token (log in, or send Authorization: Bearer <token>)."},
    403: {"model": ErrorOut, "description": "The role is below the route's, or a session write lacks X-CSRF-Token."},
    503: {"model": ErrorOut, "description": "A write waited for the database's lock longer than "
                                            "V3D_WRITE_LOCK_TIMEOUT_S: nothing was changed; send it again after the "
                                            "Retry-After header's seconds."},
})
for _module in (auth, users, games, annotators, systems, assignments, comments, handoffs, frames, imports, exports,
                jobs, backups, detectors, issia, audit, pitch, passes, batches, releases,
                predictions):
    _protected.include_router(_module.router)
api_router.include_router(_protected)
