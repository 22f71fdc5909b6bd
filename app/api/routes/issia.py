"""ISSIA-3D sequences: ``GET /api/games/{id}/trajectory`` and ``GET /api/exports/issia-3d``."""
from __future__ import annotations

import shutil
import tempfile
from pathlib import Path
from typing import Annotated

from fastapi import APIRouter, Depends, Query
from fastapi import Path as PathParam
from fastapi.responses import FileResponse
from starlette.background import BackgroundTask

from app.api.auth import require_role
from app.api.deps import SessionDep
from app.api.issia_schemas import TrajectoryOut
from app.api.schemas import DbInt, ErrorOut
from app.services.issia import export as issia_export

router = APIRouter(tags=["issia"])


@router.get("/games/{game_id}/trajectory", response_model=TrajectoryOut,
            responses={404: {"model": ErrorOut, "description": "No such game, or it is not an ISSIA sequence."}})
def game_trajectory(
    session: SessionDep, game_id: Annotated[DbInt, PathParam(description="Game id.")],
) -> TrajectoryOut:
    """The ISSIA sequence's ball over time: per frame the observed ``ball3d``, the fitted
    ``ball3d_smoothed`` and its source, the kept and the flagged cameras; the motion pieces."""
    return TrajectoryOut.of(issia_export.sequence_data(session, game_id))


@router.get(
    "/exports/issia-3d",
    response_class=FileResponse,
    dependencies=[Depends(require_role("admin"))],
    responses={200: {"content": {"application/zip": {}},
                     "description": "<sequence>/ISSIA-3D.csv and <sequence>/split.json per ISSIA sequence."}},
)
def export_issia3d(
    session: SessionDep,
    include_all: Annotated[bool, Query(alias="all", description="Every frame, not only the accepted ones.")] = False,
) -> FileResponse:
    """A zip of the ISSIA-3D export (``app.services.issia.export``). ``X-V3D-Sequences`` and
    ``X-V3D-Rows`` give its size."""
    tmp = Path(tempfile.mkdtemp(prefix="v3d-issia-"))
    try:
        tree = tmp / "ISSIA-3D"
        tree.mkdir()
        report = issia_export.export_issia3d(session, tree, include_all=include_all)
        archive = shutil.make_archive(str(tmp / "issia-3d"), "zip", root_dir=tree)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    return FileResponse(
        archive, media_type="application/zip", filename="issia-3d.zip",
        headers={"X-V3D-Sequences": str(report.sequences), "X-V3D-Rows": str(report.rows)},
        background=BackgroundTask(shutil.rmtree, tmp, ignore_errors=True),
    )
