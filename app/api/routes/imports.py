"""``/api/imports``: import a dataset that is on the server's disk under the data root (for scripts)."""
from __future__ import annotations

from fastapi import APIRouter, status

from app.api.deps import SessionDep, SettingsDep
from app.api.schemas import ErrorOut, ImportIn, ImportOut
from app.services import importing
from app.services.data_root import confined_path

router = APIRouter(prefix="/imports", tags=["imports"])


@router.post(
    "", response_model=ImportOut, status_code=status.HTTP_201_CREATED,
    responses={400: {"model": ErrorOut, "description": "The dataset cannot be imported (file and field named)."},
               403: {"model": ErrorOut, "description": "The path is outside the data root (V3D_DATA_ROOT)."}},
)
def create_import(session: SessionDep, settings: SettingsDep, body: ImportIn) -> ImportOut:
    """Import, calibrate and triangulate a SoccerNet-v3, SoccerNet-v3D or SoccerNet-calibration tree,
    or an ISSIA folder (kind "issia": one system per frame index, its trajectory fitted)
    in one transaction (idempotent: importing the same tree again changes nothing).

    ``path`` is absolute or relative to the data root (``V3D_DATA_ROOT``); 403 when it lies outside it
    (or no root is set), without saying whether it exists. 400 naming the file and field when the
    dataset cannot be imported; nothing is stored then.
    """
    path = confined_path(body.path, settings.data_root)
    if body.kind == "soccernet-v3":
        report = importing.import_soccernet_v3(session, path, settings)
    elif body.kind == "issia":
        from app.services.issia import import_issia

        report = import_issia(session, path, settings, from_lines=body.from_lines, flipped_cameras=body.flip)
    elif body.kind == "soccernet-v3d":
        report = importing.import_soccernet_v3d(session, path, settings)
    else:
        report = importing.import_sn_calibration(session, path, settings, width=body.width, height=body.height)
    return ImportOut.model_validate(report, from_attributes=True)
