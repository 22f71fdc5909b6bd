"""Pydantic schemas of the REST API: request bodies, query parameters and responses.

Separate from the ORM models (``app.db.models``); only the enums are shared. Units: pixels of the
frame's own image (continuous coordinates, origin at the top-left corner), world metres (z down), JaC
as fractions in [0, 1]. The system view (:class:`SystemView`) is the UI contract of
``docs/architecture.md``.
"""
from __future__ import annotations

from datetime import datetime
from typing import Any, Literal, Optional

from pydantic import BaseModel, ConfigDict, Field, model_validator

from app.db.models import ReviewStatus
from app.geometry.doubts import INFO_KINDS, LABEL_KINDS, SUGGESTION_ACTIONS
from app.services.views import DEFAULT_SORT, FrameFilters, FrameSort, SystemFilters, SystemSort

Point2 = tuple[float, float]
#: The ``doubt`` filter of the queue: a doubt kind, ``any`` label-accusing doubt, or ``none``.
DoubtFilter = Literal[LABEL_KINDS + INFO_KINDS + ("any", "none")]  # type: ignore[valid-type]
Box = tuple[float, float, float, float]
Point3 = tuple[float, float, float]


class _In(BaseModel):
    """Request bodies reject unknown fields, so a misspelt field is an error, not a no-op."""

    model_config = ConfigDict(extra="forbid")


# ----- query parameters ----------------------------------------------------------------------------
class QueueQuery(BaseModel):
    """Filters and order of the review queue (``GET /api/systems``; ``GET /api/systems/{id}`` takes
    them too, so that ``prev_id`` / ``next_id`` follow the queue the reviewer came from).

    Unknown query parameters are ignored (a page may forward its own state), unlike unknown fields
    of request bodies."""

    game_id: Optional[int] = Field(None, description="Only this game's systems.")
    status: Optional[ReviewStatus] = Field(None, description="Only systems with this review status.")
    jac_min: Optional[float] = Field(None, ge=0.0, le=1.0, description="Lowest JaC@0.5% of the admitted views >= this.")
    jac_max: Optional[float] = Field(None, ge=0.0, le=1.0, description="Lowest JaC@0.5% of the admitted views <= this.")
    error_min: Optional[float] = Field(None, ge=0.0, description="Worst reprojection error (px) >= this.")
    error_max: Optional[float] = Field(None, ge=0.0, description="Worst reprojection error (px) <= this.")
    doubt: Optional[DoubtFilter] = Field(
        None, description="Only systems with a doubt of this kind; 'any': with a label-accusing doubt; "
        "'none': without one.")
    sort: SystemSort = Field(DEFAULT_SORT, description="Order; a leading '-' means descending. Missing values last.")

    def filters(self) -> SystemFilters:
        """The service-level filters."""
        return SystemFilters(game_id=self.game_id, status=self.status, jac_min=self.jac_min,
                             jac_max=self.jac_max, error_min=self.error_min, error_max=self.error_max,
                             doubt=self.doubt)

    @model_validator(mode="after")
    def _ranges(self) -> "QueueQuery":
        for lo, hi in (("jac_min", "jac_max"), ("error_min", "error_max")):
            a, b = getattr(self, lo), getattr(self, hi)
            if a is not None and b is not None and a > b:
                raise ValueError(f"{lo} ({a}) is larger than {hi} ({b})")
        return self


class SystemListQuery(QueueQuery):
    """:class:`QueueQuery` and the page."""

    limit: int = Field(50, ge=1, le=500)
    offset: int = Field(0, ge=0)


class FrameListQuery(BaseModel):
    """Filters, order and page of ``GET /api/frames``."""

    game_id: Optional[int] = None
    system_id: Optional[int] = None
    calibration: Optional[Literal["calibrated", "refused", "none"]] = Field(
        None, description="Calibration status; 'none' for frames never calibrated.")
    admitted: Optional[bool] = Field(None, description="Admitted into their system's triangulation.")
    jac_min: Optional[float] = Field(None, ge=0.0, le=1.0, description="JaC@0.5% >= this.")
    jac_max: Optional[float] = Field(None, ge=0.0, le=1.0, description="JaC@0.5% <= this.")
    error_min: Optional[float] = Field(None, ge=0.0, description="Reprojection error (px) >= this.")
    error_max: Optional[float] = Field(None, ge=0.0, description="Reprojection error (px) <= this.")
    sort: FrameSort = Field("name", description="Order; a leading '-' means descending. Missing values last.")
    limit: int = Field(50, ge=1, le=500)
    offset: int = Field(0, ge=0)

    def filters(self) -> FrameFilters:
        """The service-level filters."""
        return FrameFilters(game_id=self.game_id, system_id=self.system_id, calibration=self.calibration,
                            admitted=self.admitted, jac_min=self.jac_min, jac_max=self.jac_max,
                            error_min=self.error_min, error_max=self.error_max)


# ----- request bodies ------------------------------------------------------------------------------
class BallEdit(_In):
    """A new ball label: exactly one of ``box`` and ``point``. ``{"box": null}`` (or
    ``{"point": null}``) removes the label: the ball is not visible in this view."""

    box: Optional[Box] = Field(None, description="[x1, y1, x2, y2] px; x1 < x2, y1 < y2, not entirely outside.")
    point: Optional[Point2] = Field(None, description="[x, y] px inside the image (point-only datasets).")

    @model_validator(mode="after")
    def _one_of(self) -> "BallEdit":
        given = self.model_fields_set & {"box", "point"}
        if len(given) != 1:
            raise ValueError("give exactly one of 'box' and 'point' (null removes the label)")
        return self


class FieldLinesEdit(_In):
    """The frame's complete new field lines, SoccerNet class -> polylines of [x, y] px."""

    lines: dict[str, list[list[Point2]]]


class ReviewIn(_In):
    """A review decision."""

    status: ReviewStatus
    comment: str = Field("", max_length=4000)


class ExclusionIn(_In):
    """Exclude a view from its system's triangulation (true) or restore it (false)."""

    excluded: bool = Field(strict=True, description="true: exclude the view; false: restore it.")


class ImportIn(_In):
    """A dataset on the server's disk to import (for scripts)."""

    kind: Literal["soccernet-v3", "soccernet-v3d", "sn-calibration", "issia"]
    path: str = Field(min_length=1, description="Folder or archive on the server.")
    width: Optional[int] = Field(None, gt=0, description="sn-calibration only: image width when there are no images.")
    height: Optional[int] = Field(None, gt=0, description="sn-calibration only: image height when there are no images.")
    from_lines: bool = Field(False, description="issia only: calibrate each static camera from issia_lines.json "
                                                "even when issia_calibration.json is present.")
    flip: list[str] = Field(default_factory=list, description="issia only: camera ids ('1'..'6') whose footage is "
                                                              "mirrored horizontally (images only).")

    @model_validator(mode="after")
    def _size_for_calibration_only(self) -> "ImportIn":
        if self.kind != "sn-calibration" and (self.width is not None or self.height is not None):
            raise ValueError("width and height apply to kind 'sn-calibration' only")
        if self.kind != "issia" and (self.from_lines or self.flip):
            raise ValueError("from_lines and flip apply to kind 'issia' only")
        return self


# ----- responses -----------------------------------------------------------------------------------
class ErrorOut(BaseModel):
    """A domain error: 404 (the message names the missing id or file), 400 (a dataset that cannot be
    imported) or 422 (invalid input; ``field`` names it when known)."""

    detail: str
    field: Optional[str] = None


#: OpenAPI ``responses`` of routes that look a row up by id.
NOT_FOUND = {404: {"model": ErrorOut, "description": "No row has this id (the message names it)."}}
#: OpenAPI ``responses`` of routes that store input the services validate.
INVALID = {422: {"description": "Invalid input: `{detail, field}` from the services, or FastAPI's "
                                "`{detail: [{loc, msg, type}]}` for a malformed body."}}

class GameRef(BaseModel):
    """A game's identity."""

    id: int
    league: str
    season: str
    match: str


class GameOut(GameRef):
    """A game and its number of systems."""

    systems: int


class ReviewOut(BaseModel):
    """A review decision; pending with no time when never decided."""

    status: ReviewStatus
    comment: str = ""
    decided_at: Optional[datetime] = None
    excluded: bool = Field(False, description="Views only: excluded from the system's triangulation by a reviewer.")


class DoubtOut(BaseModel):
    """A doubt of a system (``app.geometry.doubts``): a label problem the geometry sees, or information."""

    kind: str = Field(description=f"Label-accusing: {', '.join(LABEL_KINDS)}; information: {', '.join(INFO_KINDS)}.")
    frame_id: Optional[int] = Field(description="The view it names; null for the system as a whole.")
    frame: Optional[str] = Field(description="That view's image name.")
    accuses_label: bool
    message: str = Field(description="One sentence with its numbers.")
    evidence: dict[str, Any] = Field(description="The numbers behind the sentence (pixels of the named view, metres, degrees).")
    suggestion: Optional[dict[str, Any]] = Field(
        description=f"The fix: {{'action': one of {', '.join(SUGGESTION_ACTIONS)}, 'box': [x1, y1, x2, y2] px for "
        "snap_box}; null when nothing can be suggested.")


class SystemSummaryOut(BaseModel):
    """A row of the review queue: figures stored by the system's last recomputation (aggregates over the
    admitted views, ``app.services.recompute.update_summary``)."""

    id: int
    name: str
    kind: str
    game: GameRef
    review: ReviewOut
    ball3d: Optional[Point3]
    views_total: int
    views_calibrated: int
    views_admitted: int
    views_labelled: int
    lowest_jac: Optional[float] = Field(description="Lowest JaC@0.5% among admitted views.")
    worst_error_px: Optional[float] = Field(description="Largest reprojection error among admitted views, px.")
    views_flagged: int = Field(description="Views whose field-line labels are flagged probably mirrored.")
    views_above_tau: int = Field(
        description="Admitted labelled views whose reprojection error is above tau (the system view's "
        "error_above_tau rule: error scaled to the rule's reference width, compared with the stored tau).")
    doubt_counts: dict[str, int] = Field(description="Stored doubts of the system per kind.")
    label_doubts: int = Field(description="How many of its doubts accuse a label.")


class SystemPageOut(BaseModel):
    """A page of the queue; ``counts`` per review status over the filters other than ``status``."""

    items: list[SystemSummaryOut]
    total: int
    limit: int
    offset: int
    counts: dict[ReviewStatus, int]


class CalibrationOut(BaseModel):
    """A view's camera (SoccerNet JSON) and its quality."""

    status: str
    source: str
    camera: Optional[dict[str, Any]]
    jac: dict[str, Optional[float]] = Field(description='JaC at gamma = "0.005", "0.01", "0.02" of the diagonal.')
    admitted: bool
    reason: Optional[str]
    flags: list[str]
    residuals_px: dict[str, Any]
    mirror_evidence: Optional[dict[str, Any]] = Field(
        None, description="Evidence on mirrored labels (app.geometry.mirror.MirrorVerdict.as_dict): verdict, "
        "margin, camera y, side and rig votes and distances, pair errors as labelled and mirrored, and a sentence; "
        "the flag 'probably_mirrored' follows the verdict. Null when never judged.")


class BallOut(BaseModel):
    """A view's ball label and the imported original."""

    kind: Optional[Literal["box", "point"]]
    box: Optional[Box]
    point: Optional[Point2]
    original_box: Optional[Box]
    original_point: Optional[Point2]
    edited: bool


class FrameOut(BaseModel):
    """A row of ``GET /api/frames``."""

    id: int
    system_id: int
    name: str
    role: str
    width: int
    height: int
    image_url: Optional[str]
    calibration: Optional[CalibrationOut]
    ball: BallOut
    reprojection_error_px: Optional[float]
    review: ReviewOut


class FramePageOut(BaseModel):
    """A page of frames."""

    items: list[FrameOut]
    total: int
    limit: int
    offset: int


class PitchLineOut(BaseModel):
    """One in-image run of a projected pitch element."""

    model_config = ConfigDict(populate_by_name=True, serialize_by_alias=True)

    class_: str = Field(alias="class")
    points: list[Point2]


class OptimisedBoxOut(BaseModel):
    """The view's optimised box (paper Eq. min_diametre, drawn by ``Settings.optimised_box_method``): by
    default (``exact_ray``) the box of the exact image of the 0.22 m sphere at the 3D ball's depth on the
    labelled ray (an ellipse's box off-axis); ``paper``: the square of side ``d_px`` on the labelled centre.
    ``d_px`` is the diameter d_opt (px) and ``error_m`` the paper's ``optimized_error`` (metres)."""

    box: Box
    d_px: float
    error_m: float


class ViewOut(BaseModel):
    """One view of a system, everything the overlay draws."""

    frame_id: int
    name: str
    role: Literal["action", "replay", "camera", "static"]
    width: int
    height: int
    image_url: Optional[str] = Field(description="None when the dataset ships no image: draw a blank canvas.")
    calibration: Optional[CalibrationOut]
    pitch_lines: list[PitchLineOut]
    field_lines: dict[str, list[list[Point2]]]
    ball: BallOut
    optimised_box: Optional[OptimisedBoxOut]
    reprojected_ball: Optional[Point2]
    reprojection_error_px: Optional[float]
    error_above_tau: bool = Field(
        description="The reprojection error, scaled to the rule's reference width, is above the stored tau "
        "(app.geometry.triangulation.error_above_tau; the queue's views_above_tau counts by the same rule).")
    camera_position: Optional[Point3]
    review: ReviewOut


class PairOut(BaseModel):
    """One triangulation pair; views named by frame id."""

    view_a: int
    view_b: int
    point: Optional[Point3]
    error_px: Optional[float]
    parallax_deg: Optional[float]
    baseline_m: float
    kept: bool
    reason: Optional[str]


class TriangulationOut(BaseModel):
    """A system's triangulation and the settings it was made with."""

    status: str
    tau_px: float
    rule: str
    reference_width_px: Optional[float] = Field(
        description="Width (px) the rule scales a view's error to before comparing it with tau; null: raw px.")
    min_baseline_m: float
    pairs: list[PairOut]


class SystemView(BaseModel):
    """The system view of ``docs/architecture.md`` (the UI contract)."""

    id: int
    name: str
    kind: str = Field("soccernet-v3", description="soccernet-v3, single-view or issia (a frame of a sequence).")
    frame_index: Optional[int] = Field(None, description="issia: the frame's index in its sequence.")
    game: GameRef
    review: ReviewOut
    prev_id: Optional[int]
    next_id: Optional[int]
    ball3d: Optional[Point3]
    triangulation: Optional[TriangulationOut]
    views: list[ViewOut]
    doubts: list[DoubtOut] = Field(description="The system's doubts, stored with its last recomputation.")


class ImportOut(BaseModel):
    """What an import did (``app.services.importing.ImportReport``)."""

    source: str
    games: int
    systems: int
    frames: int
    systems_new: int
    systems_changed: int
    calibrated: int
    refused: int
    refusal_reasons: dict[str, int]
    triangulated: int
    seconds: float
