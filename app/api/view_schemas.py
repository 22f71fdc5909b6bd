"""Response models of the review views, shaped from ORM objects: the games, the frame list and the system view of
``docs/api.md`` (the UI contract); the review queue's rows are ``app.api.queue_schemas``'.

Every answer is built by these models from the rows the services load (``app.services.curation.queue``,
``app.services.curation.system_page``): fields whose ORM attribute has the same meaning and name are read from it
(``from_attributes``), the others by each model's ``of(...)``; no dict is built by hand. Units: pixels of the frame's
own image (continuous coordinates, origin at the top-left corner), world metres (SoccerNet: origin at the centre spot, z
down), JaC as fractions in [0, 1].
"""
from __future__ import annotations

from datetime import datetime
from typing import Any, Optional

from pydantic import AliasChoices, BaseModel, ConfigDict, Field, computed_field

from app.api.assignment_schemas import AssignmentOut, PresenceOut
from app.api.audit_schemas import AuditEntryOut
from app.api.batch_schemas import BatchAcceptanceOut
from app.api.evidence_schemas import BallEvidenceFields, evidence_fields
from app.db.models import (
    BallKind,
    BallLabel,
    Calibration,
    CalibrationSource,
    CalibrationStatus,
    Doubt,
    Frame,
    FrameRole,
    OptimisedBox,
    ReviewDecision,
    ReviewStatus,
    System,
    SystemKind,
    Triangulation,
    TriangulationStatus,
)
from app.db.types import utcnow
from app.geometry.calibration.result import MIRROR_FLAG
from app.geometry.doubts import INFO_KINDS, LABEL_KINDS, SUGGESTION_ACTIONS
from app.geometry.jac import JAC_GAMMAS
from app.geometry.pair_error import error_above_tau, rule_reference_width_px, scaled_error_px
from app.services.curation.system_page import SystemPageData, pitch_lines, pitch_lines_key, round_px
from app.services.curation.versions import frame_etag, system_etag
from app.services.derivation.doubts import doubt_provenance, suggestion_json
from app.services.images.serving import frame_has_image

Box = tuple[float, float, float, float]
Point2 = tuple[float, float]
Point3 = tuple[float, float, float]

_ORM = ConfigDict(from_attributes=True)


class GameRef(BaseModel):
    """A game's identity."""

    model_config = _ORM

    id: int
    league: str
    season: str
    match: str


class GameOut(GameRef):
    """A game and its number of systems."""

    systems: int


class ReviewOut(BaseModel):
    """A review decision; pending with no time when never decided."""

    model_config = _ORM

    status: ReviewStatus = ReviewStatus.PENDING
    comment: str = ""
    decided_at: Optional[datetime] = None
    excluded: bool = Field(False, description="Views only: excluded from the system's triangulation by a reviewer.")
    reset_reason: Optional[str] = Field(None, description="Why the decision is pending again (an edit changed the "
                                        "system's labels or 3D result after it was decided: a ball label, an "
                                        "exclusion, field lines, an undo); null otherwise.")
    calibration: Optional["CalibrationReviewOut"] = Field(
        None, description="Views only: the decision on the view's calibration, beside the decision on its ball.")
    batch_id: Optional[int] = Field(None, description=(
        "Systems only: the batch that accepted the system after a random sample (POST /api/batches/{id}/accept); "
        "null for a person's decision (any person's later decision clears it)."))

    @classmethod
    def of(cls, decision: Optional[ReviewDecision]) -> "ReviewOut":
        """The decision, or pending when there is none (a view's with its calibration decision)."""
        if decision is None:
            return cls()
        out = cls.model_validate(decision)
        if decision.frame_id is not None:
            out.calibration = CalibrationReviewOut.of(decision)
        return out

    @classmethod
    def of_view(cls, decision: Optional[ReviewDecision]) -> "ReviewOut":
        """A view's decision: as :meth:`of`, with its calibration decision even when never decided."""
        out = cls.of(decision)
        if out.calibration is None:
            out.calibration = CalibrationReviewOut()
        return out


class CalibrationReviewOut(BaseModel):
    """The reviewer's decision on a view's calibration (its field lines and the camera fitted to them)."""

    status: ReviewStatus = ReviewStatus.PENDING
    comment: str = ""
    decided_at: Optional[datetime] = None
    reset_reason: Optional[str] = Field(None, description="Why it is pending again: an edit of the view's field "
                                        "lines recalibrated it after it was decided; null otherwise.")

    @classmethod
    def of(cls, decision: Optional[ReviewDecision]) -> "CalibrationReviewOut":
        """The calibration decision held by a view's decision row, or pending when there is none."""
        if decision is None:
            return cls()
        return cls(status=decision.calibration_status, comment=decision.calibration_comment or "",
                   decided_at=decision.calibration_decided_at, reset_reason=decision.calibration_reset_reason)


class DoubtOut(BaseModel):
    """A doubt of a system (``app.geometry.doubts``): a label problem the geometry sees, or information."""

    kind: str = Field(description=f"Label-accusing: {', '.join(LABEL_KINDS)}; information: {', '.join(INFO_KINDS)}.")
    frame_id: Optional[int] = Field(description="The view it names; null for the system as a whole.")
    frame: Optional[str] = Field(description="That view's image name.")
    accuses_label: bool
    message: str = Field(description="One sentence with its numbers.")
    evidence: dict[str, Any] = Field(description="The numbers behind the sentence (pixels of the named view, metres, "
                                                 "degrees).")
    suggestion: Optional[dict[str, Any]] = Field(
        description=f"The fix: {{'action': one of {', '.join(SUGGESTION_ACTIONS)}, 'box': [x1, y1, x2, y2] px for "
        "snap_box, 'box_sigma_px' (or 'point_sigma_px' for snap_point): the uncertainty of that box or point, px of "
        "the view, one standard deviation (the box the other views agree on: their RMS reprojection error and the "
        "view's calibration sigma in quadrature), 'alternatives': the other fixes that apply (e.g. ['exclude_view']), "
        "'request': {'method', 'path', 'body'}: the exact request the page's fix key sends (add the "
        "frame's If-Match ETag)}; null when nothing can be suggested.")

    @classmethod
    def of(cls, doubt: Doubt, frame_names: dict[int, str]) -> "DoubtOut":
        """A stored doubt; ``frame`` is the named view's image name (from ``frame_names``, id -> name)."""
        return cls(kind=doubt.kind, frame_id=doubt.frame_id,
                   frame=frame_names.get(doubt.frame_id) if doubt.frame_id is not None else None,
                   accuses_label=doubt.accuses_label, message=doubt.message, evidence=doubt.evidence,
                   suggestion=suggestion_json(doubt.frame_id, doubt.suggestion, doubt_provenance(doubt)))


class CalibrationOut(BaseModel):
    """A view's camera (SoccerNet JSON) and its quality."""

    model_config = _ORM

    status: CalibrationStatus
    source: CalibrationSource
    camera: Optional[dict[str, Any]]
    jac: dict[str, Optional[float]] = Field(
        description="JaC at each gamma of the diagonal, keyed by the gamma as text, in increasing order: "
        + ", ".join(f'"{g:g}"' for g in JAC_GAMMAS) + ".")
    admitted: bool
    reason: Optional[str]
    flags: list[str]
    residuals_px: dict[str, Any]
    mirror_evidence: Optional[dict[str, Any]] = Field(
        None, description="Evidence on mirrored labels (app.geometry.mirror.MirrorVerdict.as_dict): verdict, "
        "margin, camera y, side and rig votes and distances, pair errors as labelled and mirrored, and a sentence; "
        f"the flag '{MIRROR_FLAG}' follows the verdict. Null when never judged.")
    uncertainty: Optional[dict[str, Any]] = Field(
        None, description="Standard deviations of the camera's parameters from the line fit (the fit's Jacobian "
        "times the line noise): position_m {x, y, z} (metres, SoccerNet world), pan_deg, tilt_deg, roll_deg "
        "(degrees), focal_px (pixels), line_noise_px, points; a parameter the lines leave undetermined is null. "
        "Position 0 for a rig-assisted fit (centre fixed). Null when not fitted from lines here (refused, "
        "imported, or calibrated before this was stored).")

    players: Optional[dict[str, Any]] = Field(
        None, description="A camera the players placed (flag player_assisted): feet (class, id, px [x, y] in the "
        "view, grass_m [x, y] where the player stands, metres), rig (index, centre_m, frames; null for a full pose), "
        "rms_px, sigma_px (px at 1920 width), players. Null for a camera from lines.")

    @computed_field(  # type: ignore[prop-decorator]  # pydantic: a decorator over @property
        description="The field-line labels are probably mirrored (the flag in flags): offer the mirrored labelling.")
    @property
    def probably_mirrored(self) -> bool:
        return MIRROR_FLAG in self.flags

    @classmethod
    def of(cls, cal: Optional[Calibration]) -> Optional["CalibrationOut"]:
        """The calibration row, or None when the frame was never calibrated."""
        if cal is None:
            return None
        return cls.model_validate({"status": cal.status, "source": cal.source, "camera": cal.camera, "jac": cal.jac(),
                                   "admitted": cal.admitted, "reason": cal.reason, "flags": cal.flags or [],
                                   "residuals_px": cal.residuals_px or {}, "mirror_evidence": cal.mirror_evidence,
                                   "uncertainty": cal.uncertainty, "players": cal.players})


class BallOut(BaseModel):
    """A view's ball label and the imported original."""

    model_config = _ORM

    kind: Optional[BallKind] = None
    box: Optional[Box] = None
    point: Optional[Point2] = None
    original_box: Optional[Box] = None
    original_point: Optional[Point2] = None
    edited: bool = False
    provenance: Optional[dict[str, Any]] = Field(
        None, description="Set while the label is a doubt's suggestion no person has placed: {source, doubt, code, "
                          "from_views}. It makes no 3D ball until confirmed (an edit without provenance).")

    @classmethod
    def of(cls, label: Optional[BallLabel]) -> "BallOut":
        """The label, or no ball when the frame never had one."""
        return cls() if label is None else cls.model_validate(label)


class _FrameFields(BaseModel):
    """What every answer about a frame shows: its image, calibration, ball label, reprojection error and review."""

    name: str
    role: FrameRole
    width: int
    height: int
    image_url: Optional[str] = Field(description="None when the dataset ships no image: draw a blank canvas.")
    calibration: Optional[CalibrationOut]
    ball: BallOut
    reprojection_error_px: Optional[float]
    review: ReviewOut

    @staticmethod
    def frame_fields(frame: Frame) -> dict[str, Any]:
        """These fields of a frame loaded with its calibration, ball label, reprojection and review."""
        rep = frame.reprojection
        return {"name": frame.name, "role": frame.role, "width": frame.width, "height": frame.height,
                "image_url": image_url(frame), "calibration": CalibrationOut.of(frame.calibration),
                "ball": BallOut.of(frame.ball_label),
                "reprojection_error_px": rep.error_px if rep is not None else None,
                "review": ReviewOut.of_view(frame.review)}


class FrameOut(_FrameFields):
    """A row of ``GET /api/frames``."""

    id: int
    system_id: int

    @classmethod
    def of(cls, frame: Frame) -> "FrameOut":
        """A frame loaded with its calibration, ball label, reprojection and review."""
        return cls(**cls.frame_fields(frame), id=frame.id, system_id=frame.system_id)


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


class PitchLinesOut(BaseModel):
    """``GET /api/frames/{id}/pitch-lines``: the pitch model projected by the frame's current camera and clipped
    to its image (px), fetched once per calibration: ``camera`` is the version a view's ``pitch_lines_url`` names."""

    frame_id: int
    camera: Optional[str] = Field(description="The version of these lines (app.services.curation.system_page."
                                              "pitch_lines_key): camera and image size; null without a camera.")
    lines: list[PitchLineOut]


class CalibrationPreviewOut(BaseModel):
    """``POST /api/frames/{id}/calibration-preview``: the calibration a field-line edit with these lines would
    store, computed as the commit computes it and stored nowhere (``app.services.curation.calibration_preview``)."""

    frame_id: int
    status: CalibrationStatus
    camera: Optional[dict[str, Any]] = Field(description="SoccerNet camera JSON (world metres, z down); null when "
                                                         "refused.")
    jac: dict[str, Optional[float]] = Field(description="JaC at each gamma of the diagonal, keyed as the view's "
                                                        "calibration.jac.")
    admitted: bool = Field(description="Whether the system's triangulation would admit the view.")
    reason: Optional[str] = Field(description="Why the lines do not calibrate the view, when refused.")
    flags: list[str]
    residuals_px: dict[str, Any] = Field(description="Per-class mean distance of the annotated points to the "
                                                     "projected model element, px.")
    retry: Optional[str] = Field(description='"rig" or "prior" when that retry made the camera, as the commit would.')
    differs: Optional[str] = Field(description="When the commit computes more than this preview (an ISSIA camera "
                                               "refined with the ball's labels), what; else null.")
    pitch_lines: list[PitchLineOut] = Field(description="The pitch model projected by this camera, clipped to the "
                                                        "image (px).")
    elapsed_ms: float = Field(description="The server's time for the calibration and the projection, ms.")

    @classmethod
    def of(cls, preview: Any) -> "CalibrationPreviewOut":
        """Shape an ``app.services.curation.calibration_preview.CalibrationPreview``."""
        f = preview.fields
        return cls(frame_id=preview.frame_id, status=f.status, camera=f.camera,
                   jac=preview.jac, admitted=preview.admitted, reason=f.reason,
                   flags=list(f.flags), residuals_px=f.residuals_px or {}, retry=preview.retry,
                   differs=preview.differs, elapsed_ms=round(preview.elapsed_ms, 2),
                   pitch_lines=[PitchLineOut(class_=c, points=p) for c, p in preview.pitch_lines])


def calibrated_camera(frame: Frame) -> Optional[dict[str, Any]]:
    """The frame's stored camera (SoccerNet JSON) when it is calibrated, else None."""
    cal = frame.calibration
    return cal.camera if cal is not None and cal.status is CalibrationStatus.CALIBRATED and cal.camera else None


def pitch_lines_url(frame: Frame) -> Optional[str]:
    """Where the view's projected pitch is fetched, versioned by its camera (None without one)."""
    key = pitch_lines_key(calibrated_camera(frame), frame.width, frame.height)
    return None if key is None else f"/api/frames/{frame.id}/pitch-lines?camera={key}"


class OptimisedBoxOut(BaseModel):
    """The view's optimised box (paper Eq. min_diametre, drawn by ``Settings.optimised_box_method``): by
    default (``exact_ray``) the box of the exact image of the 0.22 m sphere at the 3D ball's depth on the
    labelled ray (an ellipse's box off-axis); ``paper``: the square of side ``d_px`` on the labelled centre.
    ``d_px`` is the diameter d_opt (px) and ``error_m`` the paper's ``optimized_error`` (metres)."""

    box: Box
    d_px: float
    error_m: float

    @classmethod
    def of(cls, opt: Optional[OptimisedBox]) -> Optional["OptimisedBoxOut"]:
        """The stored optimised box (px rounded), or None."""
        return None if opt is None else cls(box=round_px(opt.box), d_px=opt.d_opt_px, error_m=opt.error_m)


def image_url(frame: Frame) -> Optional[str]:
    """The API address of the frame's image, None when it has none (the UI draws a blank canvas)."""
    return f"/api/frames/{frame.id}/image" if frame_has_image(frame) else None


class ViewOut(_FrameFields):
    """One view of a system, everything the overlay draws."""

    frame_id: int
    pitch_lines_url: Optional[str] = Field(description=(
        "GET it for the pitch model projected by the view's camera (PitchLinesOut); the address changes with the "
        "camera, so its answer may be kept as long as it is named; null without a camera."))
    field_lines: dict[str, list[list[Point2]]]
    optimised_box: Optional[OptimisedBoxOut]
    precise_box: Optional[Box] = Field(None, description="The view's precise ball box (px; the paper's Table 1 "
                                       "reference, ``v3d import precise-boxes``), null without one.")
    reprojected_ball: Optional[Point2]
    reprojection_error_scaled_px: Optional[float] = Field(
        description="The same error in the scale the pair rule compares with tau (px of a 1920-px-wide image "
        "for max_scaled_1920; app.geometry.pair_error.scaled_error_px); null without a triangulation.")
    error_above_tau: bool = Field(
        description="The reprojection error, scaled to the rule's reference width, is above the stored tau "
        "(app.geometry.pair_error.error_above_tau; the queue's views_above_tau counts by the same rule).")
    camera_position: Optional[Point3]
    etag: str = Field(description="The frame's strong ETag: the version of its ball label, field lines, review and "
                                  "exclusion (send it as If-Match with a write to the frame).")

    @classmethod
    def fields_of(cls, frame: Frame, tri: Optional[Triangulation]) -> dict[str, Any]:
        """The fields of a frame's view, from the frame (loaded as ``app.services.curation.system_page`` does) and its
        system's triangulation (the rule and tau its reprojection error is judged by)."""
        camera = calibrated_camera(frame)
        rep = frame.reprojection
        error = rep.error_px if rep is not None else None
        judged = rep is not None and tri is not None
        return {
            **cls.frame_fields(frame), "frame_id": frame.id, "pitch_lines_url": pitch_lines_url(frame),
            "field_lines": frame.field_lines.lines if frame.field_lines is not None else {},
            "optimised_box": OptimisedBoxOut.of(frame.optimised_box),
            "precise_box": frame.precise_box,
            "reprojected_ball": round_px(rep.point) if rep is not None else None,
            "reprojection_error_scaled_px": scaled_error_px(error, frame.width, tri.rule) if tri and judged else None,
            "error_above_tau": judged and tri is not None and error_above_tau(error, frame.width, tri.tau_px, tri.rule),
            "camera_position": camera["position_meters"] if camera is not None else None,
            "etag": frame_etag(frame),
        }

    @classmethod
    def of(cls, frame: Frame, tri: Optional[Triangulation]) -> "ViewOut":
        """A view of the system view (:meth:`fields_of`)."""
        return cls(**cls.fields_of(frame, tri))


class FrameView(ViewOut):
    """``GET /api/frames/{id}``: the frame as the system view draws it, its system, and its projected pitch."""

    system_id: int
    pitch_lines: list[PitchLineOut] = Field(description="The pitch model projected by the view's camera (as "
                                                        "pitch_lines_url answers it); empty without a camera.")

    @classmethod
    def of_frame(cls, frame: Frame) -> "FrameView":
        """A frame loaded by ``app.services.curation.system_page.load_frame``."""
        return cls(**cls.fields_of(frame, frame.system.triangulation), system_id=frame.system_id,
                   pitch_lines=projected_pitch_of(frame))


def projected_pitch_of(frame: Frame) -> list[PitchLineOut]:
    """The pitch model projected by the frame's calibrated camera, clipped to its image (px)."""
    return [PitchLineOut(class_=c, points=points) for c, points in pitch_lines(calibrated_camera(frame), frame.width,
                                                                                  frame.height)]


class PairOut(BaseModel):
    """One triangulation pair; views named by frame id."""

    model_config = _ORM

    view_a: int = Field(validation_alias=AliasChoices("view_a", "frame_a_id"))
    view_b: int = Field(validation_alias=AliasChoices("view_b", "frame_b_id"))
    point: Optional[Point3]
    error_px: Optional[float]
    parallax_deg: Optional[float]
    baseline_m: float
    kept: bool
    reason: Optional[str]


class TriangulationOut(BaseModel):
    """A system's triangulation and the settings it was made with."""

    model_config = _ORM

    status: TriangulationStatus
    sigma_m: Optional[float] = Field(None, description="The 3D ball's sigma: one standard deviation along its least "
                                     "certain direction, metres (evidence.kept_pairs_sigma_m); null without a ball.")
    tau_px: float
    rule: str
    min_baseline_m: float
    pairs: list[PairOut]

    @computed_field(  # type: ignore[prop-decorator]  # pydantic: a decorator over @property
        description="Width (px) the rule scales a view's error to before comparing it with tau; null: raw px.")
    @property
    def reference_width_px(self) -> Optional[float]:
        return rule_reference_width_px(self.rule)


class SystemView(BallEvidenceFields):
    """The system view of ``docs/api.md`` (the UI contract)."""

    id: int
    name: str
    kind: SystemKind = Field(description="soccernet-v3, single-view or issia (a frame of a sequence).")
    frame_index: Optional[int] = Field(None, description="issia: the frame's index in its sequence.")
    game: GameRef
    review: ReviewOut
    etag: str = Field(description="The strong ETag of the system's review decision (If-Match of a system review).")
    prev_id: Optional[int]
    next_id: Optional[int]
    ball3d: Optional[Point3]
    ball_sigma_m: Optional[float] = Field(None, description="The 3D ball's sigma, metres (triangulation.sigma_m).")
    triangulation: Optional[TriangulationOut]
    views: list[ViewOut]
    doubts: list[DoubtOut] = Field(description="The system's doubts, stored with its last recomputation.")
    assignment: AssignmentOut = Field(description="Who the system is assigned to (POST /api/assignments).")
    open_by: list[PresenceOut] = Field(
        description="Everyone who has the system open now, the caller included (live presence claims, oldest first; "
                    "PUT /api/systems/{id}/presence).")
    accepted_in_batch: Optional[BatchAcceptanceOut] = Field(None, description=(
        "When the system's acceptance is a batch's, after a random sample of it (review.batch_id): the batch and its "
        "plan in words, as a release's document (version 2) says it; null for a person's decision."))

    @classmethod
    def of(cls, page: SystemPageData) -> "SystemView":
        """The system view of a system loaded for its page (``app.services.curation.system_page.system_page``)."""
        system, tri = page.system, page.system.triangulation
        names = {f.id: f.name for f in system.frames}
        now = utcnow()
        return cls(
            id=system.id, name=system.name, kind=system.kind, frame_index=system.frame_index,
            game=GameRef.model_validate(system.game), review=ReviewOut.of(system.review), etag=system_etag(system),
            prev_id=page.prev_id, next_id=page.next_id, ball3d=tri.ball3d if tri is not None else None,
            triangulation=TriangulationOut.model_validate(tri) if tri is not None else None,
            ball_sigma_m=tri.sigma_m if tri is not None else None, views=[ViewOut.of(f, tri) for f in system.frames],
            doubts=[DoubtOut.of(d, names) for d in system.doubts], **evidence_fields(system),
            assignment=AssignmentOut.of(page.assignment), open_by=[PresenceOut.of(p, now) for p in page.open_by],
            accepted_in_batch=BatchAcceptanceOut.of(page.batch) if page.batch is not None else None,
        )


class SystemStateOut(BaseModel):
    """A system's review decision as a stale write (412) answers it: the current state and its ETag."""

    id: int
    etag: str
    review: ReviewOut

    @classmethod
    def of(cls, system: System) -> "SystemStateOut":
        """The system's decision now."""
        return cls(id=system.id, etag=system_etag(system), review=ReviewOut.of(system.review))


class StaleOut(BaseModel):
    """412: the write's ``If-Match`` is stale. ``current`` is the resource now (a frame as
    ``GET /api/frames/{id}`` answers it, or :class:`SystemStateOut` of a system), ``etag`` its ETag (also
    in the ``ETag`` header) and ``last_change`` its newest audit entry (who changed it), when any. For a system,
    ``changes_since`` are the audit entries written after the version the ``If-Match`` named (its views' edits and
    its decisions, oldest first; at most the 20 newest), also said in words in ``detail``."""

    detail: str
    etag: str
    current: Optional[FrameView | SystemStateOut]
    last_change: Optional[AuditEntryOut]
    changes_since: list[AuditEntryOut] = Field(default_factory=list, description=(
        "A system's changes after the version the If-Match named, oldest first: who changed what it covers (a "
        "view's ball, field lines, exclusion, calibration; its decision) since that version was read."))
