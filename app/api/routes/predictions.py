"""``/api/predictions``: the ball detectors' predictions stored, one summary per source (any logged-in user), and the
removal of a source (admins; audited, the systems it touched recomputed), as ``v3d predictions list`` / ``remove``.
They are imported as jobs (``POST /api/imports`` with ``kind=predictions``)."""
from __future__ import annotations

from typing import Annotated

from fastapi import APIRouter, Path
from fastapi.concurrency import run_in_threadpool

from app.api.auth import AdminDep, PrincipalDep
from app.api.deps import SessionDep, SettingsDep
from app.api.prediction_schemas import PredictionSourcesOut, PredictionsRemovedOut
from app.api.schemas import NOT_FOUND
from app.core.errors import NotFoundError
from app.services.transfer.prediction_sources import source_summaries
from app.services.transfer.predictions import remove_predictions

router = APIRouter(prefix="/predictions", tags=["predictions"])

SourceName = Annotated[str, Path(min_length=1, max_length=200, description="The source's name.")]


@router.get("", response_model=PredictionSourcesOut)
def list_sources(session: SessionDep, principal: PrincipalDep) -> PredictionSourcesOut:
    """Every stored source, by name: its predictions, the views and systems they lie on, the spread of its scores,
    and when and by whom it was imported (null: unknown)."""
    return PredictionSourcesOut.model_validate({"items": source_summaries(session, principal.may("admin"))})


@router.delete("/{source}", response_model=PredictionsRemovedOut, responses=NOT_FOUND)
async def remove_source(session: SessionDep, settings: SettingsDep, principal: AdminDep,
                        source: SourceName) -> PredictionsRemovedOut:
    """Delete every prediction of ``source`` (labels placed from them stay) and recompute the systems they touched;
    one audit entry, by the admin. 404 when no prediction has that source."""
    removed = await run_in_threadpool(remove_predictions, session, settings, source, principal.name)
    if not removed:
        raise NotFoundError("predictions of source", source)
    return PredictionsRemovedOut(source=source, removed=removed)
