"""``GET /metrics``: the service's metrics in Prometheus' text format (``app.core.metrics``), for admins (Prometheus
sends an admin's API token: ``authorization: {type: Bearer, credentials: ...}`` in its scrape config)."""
from __future__ import annotations

from fastapi import APIRouter, Response

from app.api.auth import AdminDep
from app.api.deps import SessionDep
from app.core.metrics import CONTENT_TYPE, exposition, job_families
from app.db.models import JobState
from app.services.jobs import runner as jobs

router = APIRouter(tags=["metrics"])


@router.get("/metrics", include_in_schema=False)
def metrics(session: SessionDep, _admin: AdminDep) -> Response:
    """Request latencies, edits, recomputations (counted by the serving processes) and the jobs by kind and state
    (from the database, at this scrape)."""
    counts = jobs.count_jobs(session)
    body = exposition(job_families(counts, jobs.JOB_KINDS, [s.value for s in JobState]))
    return Response(body, media_type=CONTENT_TYPE)
