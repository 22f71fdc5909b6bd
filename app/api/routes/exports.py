"""``/api/exports``: download reviewed labels."""
from __future__ import annotations

import shutil
import tempfile
from pathlib import Path
from typing import Annotated

from fastapi import APIRouter, Query
from fastapi.responses import FileResponse
from starlette.background import BackgroundTask

from app.api.deps import SessionDep
from app.services import exporting

router = APIRouter(prefix="/exports", tags=["exports"])


@router.get(
    "/soccernet-v3d",
    response_class=FileResponse,
    responses={200: {"content": {"application/zip": {}}, "description": "Labels-v3D.json per game and SNv3D.csv."}},
)
def export_soccernet_v3d(
    session: SessionDep,
    include_all: Annotated[bool, Query(alias="all", description="Every system, not only the accepted ones.")] = False,
) -> FileResponse:
    """A zip of the SoccerNet-v3D export (``app.services.exporting``), built in a temporary folder that
    is removed once the download has been sent. ``X-V3D-Systems`` and ``X-V3D-Rows`` give its size."""
    tmp = Path(tempfile.mkdtemp(prefix="v3d-export-"))
    try:
        tree = tmp / "SoccerNet-v3D"
        report = exporting.export_soccernet_v3d(session, tree, include_all=include_all)
        archive = shutil.make_archive(str(tmp / "soccernet-v3d"), "zip", root_dir=tree)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    return FileResponse(
        archive, media_type="application/zip", filename="soccernet-v3d.zip",
        headers={"X-V3D-Systems": str(report.systems), "X-V3D-Rows": str(report.rows)},
        background=BackgroundTask(shutil.rmtree, tmp, ignore_errors=True),
    )
