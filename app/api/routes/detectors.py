"""Detector data: ``/api/exports/yolo``, ``/api/exports/coco`` (zips) and ``/api/evaluations/monocular``
(the monocular 3D ball benchmark of an uploaded predictions file)."""
from __future__ import annotations

import shutil
import tempfile
import zipfile
from pathlib import Path
from typing import Annotated, Any, Literal, Optional

from fastapi import APIRouter, Depends, File, Query, UploadFile
from fastapi.responses import FileResponse
from starlette.background import BackgroundTask

from app.api.auth import AnnotatorDep, require_role
from app.api.bodies import UPLOAD_LIMIT
from app.api.deps import SessionDep, SettingsDep, ShareDep
from app.api.detector_schemas import BoxesReportOut, MonocularReportOut, StatsOut
from app.api.schemas import InvalidOut, QueryText
from app.api.share import SHARE_SPENT
from app.core.config import Settings
from app.core.errors import DatasetError, InvalidInputError
from app.geometry.metrics import MAX_YOLO_FILE_BYTES
from app.services.evaluation import monocular
from app.services.evaluation.boxes import evaluate_boxes as boxes_report
from app.services.evaluation.stats import dataset_stats
from app.services.storage.datasets import DatasetFiles
from app.services.transfer import detector_export
from app.services.transfer.archives import MB, ArchiveLimits, file_chunks, receive, unpack_zip, upload_limit

router = APIRouter(tags=["detectors"])
#: Every export needs the admin role; evaluating detections against the labels (it stores nothing) any role.
ADMIN = Depends(require_role("admin"))

AllQuery = Annotated[bool, Query(alias="all", description="Every system, not only the accepted ones.")]
#: What bounds a predictions upload (a COCO results JSON or a zip of YOLO files), counted while its body streams:
#: the largest results file the benchmark reads, so that nothing larger is ever spooled or copied to disk.
PREDICTIONS_LIMIT = "V3D_MAX_PREDICTIONS_MB"


def _zip_export(fmt: Literal["yolo", "coco"], session: SessionDep, include_all: bool,
                settings: Settings) -> FileResponse:
    tmp = Path(tempfile.mkdtemp(prefix=f"v3d-{fmt}-"))
    try:
        report = detector_export.export_detector(session, fmt, tmp / fmt, include_all, settings.ball_diameter_m,
                                                 settings.export_ball_box,
                                                 files=DatasetFiles.from_settings(settings))
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


_ZIP: dict[int | str, dict[str, Any]] = {
    200: {"content": {"application/zip": {}}, "description": "The export as a zip."}}


@router.get("/exports/yolo", response_class=FileResponse, responses=_ZIP, dependencies=[ADMIN])
def export_yolo(session: SessionDep, settings: SettingsDep, include_all: AllQuery = False) -> FileResponse:
    """Ultralytics YOLO layout (``app.services.transfer.detector_export``): images/<split>, labels/<split>, data.yaml.
    ``X-V3D-Images`` and ``X-V3D-Skipped-Without-Image`` give its size."""
    return _zip_export("yolo", session, include_all, settings)


@router.get("/exports/coco", response_class=FileResponse, responses=_ZIP, dependencies=[ADMIN])
def export_coco(session: SessionDep, settings: SettingsDep, include_all: AllQuery = False) -> FileResponse:
    """COCO layout: per split the images and ``instances.json`` (image ids = frame ids)."""
    return _zip_export("coco", session, include_all, settings)


def _unpack(upload: UploadFile, dest: Path, settings: Settings) -> Path:
    """The upload saved under ``dest`` (counted against :data:`PREDICTIONS_LIMIT` while it is written: 413
    beyond, which the body's count answered already while it streamed): a zip is unpacked by the one safe
    unpacker (``app.services.transfer.archives.unpack_zip``: unsafe, linked or repeated member names and zip bombs
    refused naming the member, 422 here; only its YOLO ``.txt`` and ``.yaml`` files kept, each at most
    ``app.geometry.metrics.MAX_YOLO_FILE_BYTES``, counted while they unpack) and its folder returned; anything else
    is taken as a COCO results JSON."""
    path = dest / "upload"
    limit, setting = upload_limit(settings, PREDICTIONS_LIMIT)
    if not receive(file_chunks(upload.file), path, limit, field="predictions", setting=setting):
        raise InvalidInputError("the upload is empty", field="predictions")
    if not zipfile.is_zipfile(path):
        return path
    folder = dest / "predictions"
    limits = ArchiveLimits.from_settings(settings, max_member_bytes=MAX_YOLO_FILE_BYTES)
    try:
        unpack_zip(path, folder, limits, where=_upload_name(upload, "predictions.zip"),
                   keep=lambda name: name.endswith((".txt", ".yaml")))
    except DatasetError as exc:  # predictions are no dataset: an unusable upload is the benchmark's 422
        raise InvalidInputError(str(exc), field="predictions") from None
    if not any(folder.rglob("*.txt")):
        raise InvalidInputError("the zip holds no YOLO .txt file", field="predictions")
    return folder


def _upload_name(upload: UploadFile, default: str) -> str:
    """How messages name the upload: its file name as the client sent it (no folder of the client's, never one
    of the server's), cut to 100 characters."""
    return Path((upload.filename or "").replace("\\", "/")).name[:100] or default


@router.post(
    "/evaluations/monocular", response_model=MonocularReportOut, openapi_extra={UPLOAD_LIMIT: PREDICTIONS_LIMIT},
    responses={422: {"model": InvalidOut, "description": "Unreadable predictions (file and line named), or no "
                                                       "view with a 3D ball among the selected systems."},
               **SHARE_SPENT},
)
def evaluate_monocular(
    session: SessionDep, settings: SettingsDep, principal: AnnotatorDep, share: ShareDep,
    predictions: Annotated[UploadFile, File(description="A zip of YOLO txt files (`class cx cy w h conf`) "
                                                        "or a COCO results JSON.")],
    include_all: AllQuery = False,
    ball_class: Annotated[Optional[int], Query(description="Ball class (YOLO) or category id (COCO).")] = None,
    estimator: Annotated[Optional[Literal["paper", "exact"]], Query(
        description="Monocular ball from a box; default: the one matching the optimised boxes.")] = None,
) -> MonocularReportOut:
    """The monocular 3D ball benchmark (``app.services.evaluation.monocular``) of the uploaded detections against
    the curated labels: AP50, MAE_m, MAE_pct, P_2m, the precision-threshold curve and counts, for the
    whole set and per split. 429 while the user's share of computations is in use (``app.api.share``); the
    evaluation holds no database connection while it computes."""
    est = estimator or monocular.default_estimator(settings.optimised_box_method)
    with share.turn(principal.name, "evaluation"), tempfile.TemporaryDirectory(prefix="v3d-predictions-") as tmp:
        path = _unpack(predictions, Path(tmp), settings)
        default = "predictions.zip" if path.is_dir() else "predictions.json"
        report = monocular.evaluate_predictions(session, path, include_all, ball_class, settings.ball_diameter_m, est,
                                                ball_box=settings.export_ball_box,
                                                name=_upload_name(predictions, default),
                                                max_coco_bytes=int(settings.max_predictions_mb * MB),
                                                per_frame=settings.max_predictions_per_frame)
    return MonocularReportOut.model_validate({**report, "estimator": est})


@router.get(
    "/evaluations/monocular", response_model=MonocularReportOut,
    responses={422: {"model": InvalidOut, "description": "No predictions of that source are stored, or no view with "
                                                       "a 3D ball among the selected systems."}, **SHARE_SPENT},
)
def evaluate_monocular_source(
    session: SessionDep, settings: SettingsDep, principal: AnnotatorDep, share: ShareDep,
    source: Annotated[QueryText, Query(min_length=1, max_length=100, description=(
        "An imported source's name (v3d import predictions): its stored predictions."))],
    include_all: AllQuery = False,
    estimator: Annotated[Optional[Literal["paper", "exact"]], Query(
        description="Monocular ball from a box; default: the one matching the optimised boxes.")] = None,
) -> MonocularReportOut:
    """The monocular 3D ball benchmark of an imported detector source's stored predictions (no upload): the same
    report as ``POST /api/evaluations/monocular``."""
    est = estimator or monocular.default_estimator(settings.optimised_box_method)
    with share.turn(principal.name, "evaluation"):
        report = monocular.evaluate_source(session, source, include_all, settings.ball_diameter_m, est,
                                           settings.export_ball_box, per_frame=settings.max_predictions_per_frame)
    return MonocularReportOut.model_validate({**report, "estimator": est})


@router.get("/evaluations/boxes", response_model=BoxesReportOut, dependencies=[Depends(require_role("annotator"))])
def evaluate_boxes(session: SessionDep, settings: SettingsDep, include_all: AllQuery = False) -> BoxesReportOut:
    """IoU and size error (% of the precise box's diagonal) of the original, optimised and refined ball boxes
    against the stored precise boxes (``v3d import precise-boxes``), over the views of accepted systems (every
    system with ``all=true``) that have one."""
    return BoxesReportOut.model_validate(boxes_report(session, include_all, settings.ball_diameter_m))


@router.get("/stats", response_model=StatsOut, dependencies=[Depends(require_role("annotator"))])
def stats(session: SessionDep, settings: SettingsDep) -> StatsOut:
    """Systems and images (calibrated, admitted) per kind and split, systems kept against the JaC admission
    threshold (the paper's Fig. 3) and distributions of JaC, pair reprojection error, ball distance and box size."""
    return StatsOut.model_validate(dataset_stats(session, settings))
