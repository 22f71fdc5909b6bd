"""Schemas of the detector data and the benchmarks read from the labels (``app.api.routes.detectors``): the monocular
3D ball benchmark's report, the paper's Table 1 of ball boxes, and the dataset at a glance (``GET /api/stats``)."""
from __future__ import annotations

from typing import Optional

from pydantic import BaseModel, Field


class CurveOut(BaseModel):
    thresholds_m: list[float]
    precision: list[Optional[float]]


class CountsOut(BaseModel):
    reference_views: int
    detections: int
    views_with_detection: int
    localised: int
    ignored_detections: Optional[int] = None
    capped_detections: Optional[int] = Field(None, description="Detections of an uploaded file beyond "
                                                               "V3D_MAX_PREDICTIONS_PER_FRAME on their image, "
                                                               "left out (the best by score are kept).")


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


class BoxFiguresOut(BaseModel):
    """Means over the ``n`` views with both boxes; null where ``n`` is 0."""

    n: int
    iou: Optional[float]
    size_error_pct: Optional[float]


class BoxesReportOut(BaseModel):
    """The paper's Table 1 against the stored precise boxes (``app.services.evaluation.boxes``)."""

    views: int
    original: BoxFiguresOut
    optimised: BoxFiguresOut
    refined: BoxFiguresOut


class HistogramOut(BaseModel):
    """Equal bins (``edges``, ``counts``); ``n`` values in all, ``above`` of them beyond the last edge (a long tail)."""

    edges: list[float]
    counts: list[int]
    n: int
    above: int = 0


class CountsPerSplitOut(BaseModel):
    systems: int
    images: int
    calibrated_images: int
    admitted_images: int


class KindStatsOut(CountsPerSplitOut):
    splits: dict[str, CountsPerSplitOut]


class SweepPointOut(BaseModel):
    threshold: float
    systems_kept: int


class AdmissionOut(BaseModel):
    """The admission threshold in force: JaC at ``gamma`` (fraction of the image diagonal) above ``jac_min``."""

    gamma: float
    jac_min: float


class StatsOut(BaseModel):
    """The dataset at a glance (``app.services.evaluation.stats``)."""

    kinds: dict[str, KindStatsOut]
    jac_sweep: list[SweepPointOut]
    jac_sweep_by_kind: dict[str, list[SweepPointOut]]
    admission: AdmissionOut
    stale_systems: int = Field(description="Systems computed with other settings (a changed V3D_PROFILE): stale "
                                           "until `v3d recompute`.")
    ball_evidence: dict[str, int] = Field(description="Systems per tier of what backs their 3D ball: vouched, "
                                          "unconfirmed, doubted, none (app.geometry.ball_evidence).")
    distributions: dict[str, HistogramOut]
