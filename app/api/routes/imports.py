"""``/api/imports``: import a dataset that is on the server's disk (for scripts)."""
from __future__ import annotations

from fastapi import APIRouter, status

from app.api.deps import SessionDep, SettingsDep
from app.api.schemas import ErrorOut, ImportIn, ImportOut
from app.services import importing

router = APIRouter(prefix="/imports", tags=["imports"])


@router.post(
    "", response_model=ImportOut, status_code=status.HTTP_201_CREATED,
    responses={400: {"model": ErrorOut, "description": "The dataset cannot be imported (file and field named)."}},
)
def create_import(session: SessionDep, settings: SettingsDep, body: ImportIn) -> ImportOut:
    """Import, calibrate and triangulate a SoccerNet-v3, SoccerNet-v3D or SoccerNet-calibration tree,
    or an ISSIA folder (kind "issia": one system per frame index, its trajectory fitted)
    in one transaction (idempotent: importing the same tree again changes nothing).

    400 naming the file and field when the dataset cannot be imported; nothing is stored then.
    """
    if body.kind == "soccernet-v3":
        report = importing.import_soccernet_v3(session, body.path, settings)
    elif body.kind == "issia":
        from app.services.issia import import_issia

        report = import_issia(session, body.path, settings, from_lines=body.from_lines, flipped_cameras=body.flip)
    elif body.kind == "soccernet-v3d":
        report = importing.import_soccernet_v3d(session, body.path, settings)
    else:
        report = importing.import_sn_calibration(session, body.path, settings, width=body.width, height=body.height)
    return ImportOut.model_validate(report, from_attributes=True)
