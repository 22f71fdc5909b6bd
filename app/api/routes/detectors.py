"""Detector data: ``/api/exports/yolo``, ``/api/exports/coco`` (zips) and ``/api/evaluations/monocular``
(the monocular 3D ball benchmark of an uploaded predictions file)."""
from __future__ import annotations

import shutil
import tempfile
import zipfile
from pathlib import Path
from typing import Annotated, Literal, Optional

from fastapi import APIRouter, File, Query, UploadFile
from fastapi.responses import FileResponse
from pydantic import BaseModel
from starlette.background import BackgroundTask

from app.api.deps import SessionDep, SettingsDep
from app.api.schemas import ErrorOut
from app.services import detector_export, monocular
from app.services._readers import is_safe_member
from app.services.errors import InvalidInputError

router = APIRouter(tags=["detectors"])

#: Largest upload accepted (bytes): a zip of YOLO txt files or a COCO results JSON is small.
MAX_UPLOAD_BYTES = 200 * 1024 * 1024
AllQuery = Annotated[bool, Query(alias="all", description="Every system, not only the accepted ones.")]


class CurveOut(BaseModel):
    thresholds_m: list[float]
    precision: list[Optional[float]]


class CountsOut(BaseModel):
    reference_views: int
    detections: int
    views_with_detection: int
    localised: int
    ignored_detections: Optional[int] = None


class MonocularFiguresOut(BaseModel):
    """AP@0.5 (VOC all-point), MAE in metres and percent of the camera-to-ball distance, P@2m
    (fraction), the precision-threshold curve; null where nothing was localised."""

    AP50: Optional[float]
    MAE_m: Optional[float]
    MAE_pct: Optional[float]
    P_2m: Optional[float]
    curve: CurveOut
    counts: CountsOut


class MonocularReportOut(MonocularFiguresOut):
    """The whole set's figures and ``splits`` (train / test as in the exports)."""

    splits: dict[str, MonocularFiguresOut]
    estimator: str


def _zip_export(fmt: Literal["yolo", "coco"], session: SessionDep, include_all: bool,
                ball_diameter_m: float) -> FileResponse:
    tmp = Path(tempfile.mkdtemp(prefix=f"v3d-{fmt}-"))
    try:
        report = detector_export.export_detector(session, fmt, tmp / fmt, include_all, ball_diameter_m)
        archive = shutil.make_archive(str(tmp / f"v3d-{fmt}"), "zip", root_dir=tmp / fmt)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    return FileResponse(
        archive, media_type="application/zip", filename=f"v3d-{fmt}.zip",
        headers={"X-V3D-Images": str(sum(report.images.values())),
                 "X-V3D-Skipped-Without-Image": str(report.skipped_without_image)},
        background=BackgroundTask(shutil.rmtree, tmp, ignore_errors=True),
    )


_ZIP = {200: {"content": {"application/zip": {}}, "description": "The export as a zip."}}


@router.get("/exports/yolo", response_class=FileResponse, responses=_ZIP)
def export_yolo(session: SessionDep, settings: SettingsDep, include_all: AllQuery = False) -> FileResponse:
    """Ultralytics YOLO layout (``app.services.detector_export``): images/<split>, labels/<split>, data.yaml.
    ``X-V3D-Images`` and ``X-V3D-Skipped-Without-Image`` give its size."""
    return _zip_export("yolo", session, include_all, settings.ball_diameter_m)


@router.get("/exports/coco", response_class=FileResponse, responses=_ZIP)
def export_coco(session: SessionDep, settings: SettingsDep, include_all: AllQuery = False) -> FileResponse:
    """COCO layout: per split the images and ``instances.json`` (image ids = frame ids)."""
    return _zip_export("coco", session, include_all, settings.ball_diameter_m)


def _unpack(upload: UploadFile, dest: Path) -> Path:
    """The upload saved under ``dest``: a zip is extracted (safe member names only) and its folder
    returned; anything else is taken as a COCO results JSON."""
    raw = upload.file.read(MAX_UPLOAD_BYTES + 1)
    if len(raw) > MAX_UPLOAD_BYTES:
        raise InvalidInputError(f"the upload is larger than {MAX_UPLOAD_BYTES} bytes", field="predictions")
    if not raw:
        raise InvalidInputError("the upload is empty", field="predictions")
    path = dest / "upload"
    path.write_bytes(raw)
    if not zipfile.is_zipfile(path):
        return path
    folder = dest / "predictions"
    with zipfile.ZipFile(path) as zf:
        for info in zf.infolist():
            if info.is_dir():
                continue
            if not is_safe_member(info.filename):
                raise InvalidInputError(f"unsafe name in the zip: {info.filename!r}", field="predictions")
            if info.filename.endswith((".txt", ".yaml")):
                target = folder / info.filename
                target.parent.mkdir(parents=True, exist_ok=True)
                target.write_bytes(zf.read(info))
    if not folder.is_dir():
        raise InvalidInputError("the zip holds no YOLO .txt file", field="predictions")
    return folder


@router.post(
    "/evaluations/monocular", response_model=MonocularReportOut,
    responses={422: {"model": ErrorOut, "description": "Unreadable predictions (file and line named), or no "
                                                       "view with a 3D ball among the selected systems."}},
)
def evaluate_monocular(
    session: SessionDep, settings: SettingsDep,
    predictions: Annotated[UploadFile, File(description="A zip of YOLO txt files (`class cx cy w h conf`) "
                                                        "or a COCO results JSON.")],
    include_all: AllQuery = False,
    ball_class: Annotated[Optional[int], Query(description="Ball class (YOLO) or category id (COCO).")] = None,
    estimator: Annotated[Optional[Literal["paper", "exact"]], Query(
        description="Monocular ball from a box; default: the one matching the optimised boxes.")] = None,
) -> MonocularReportOut:
    """The monocular 3D ball benchmark (``app.services.monocular``) of the uploaded detections against
    the curated labels: AP50, MAE_m, MAE_pct, P_2m, the precision-threshold curve and counts, for the
    whole set and per split."""
    est = estimator or monocular.default_estimator(settings.optimised_box_method)
    with tempfile.TemporaryDirectory(prefix="v3d-predictions-") as tmp:
        path = _unpack(predictions, Path(tmp))
        report = monocular.evaluate_predictions(session, path, include_all, ball_class, settings.ball_diameter_m, est)
    return MonocularReportOut.model_validate({**report, "estimator": est})
