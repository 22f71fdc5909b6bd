"""The typed objects of the v3d API, as the server answers them (pydantic models).

One class per answer the client reads, named by what it is (a :class:`System`, its :class:`View` s and
:class:`Doubt` s, a :class:`Job`, a :class:`Release` ...). Coordinates are the server's: image pixels from the
top-left corner (boxes ``[x1, y1, x2, y2]``), world metres in SoccerNet's frame (origin at the centre spot, z
down). Kinds and statuses are plain strings (the server's words: a newer server's new status is read, not refused);
a field the server adds is kept (``extra="allow"``), and the drift test (``tests/test_client_drift.py`` in the
server's repository) fails when the server answers a field that no model here names.
"""
from __future__ import annotations

from datetime import datetime
from typing import Any, Optional

from pydantic import BaseModel, ConfigDict, Field

Box = tuple[float, float, float, float]
Point2 = tuple[float, float]
Point3 = tuple[float, float, float]


class Model(BaseModel):
    """The base of every answer: fields the server adds are kept, names as the server writes them."""

    model_config = ConfigDict(extra="allow", populate_by_name=True)


# ----- systems, views, doubts ---------------------------------------------------------------------------------------
class GameRef(Model):
    """A game's identity."""

    id: int
    league: str
    season: str
    match: str


class Game(GameRef):
    """A game and its number of systems."""

    systems: int


class CalibrationReview(Model):
    """A reviewer's decision on a view's calibration."""

    status: str = "pending"
    comment: str = ""
    decided_at: Optional[datetime] = None
    reset_reason: Optional[str] = None


class Review(Model):
    """A review decision (of a system or a view): ``pending`` with no time when never decided."""

    status: str = "pending"
    comment: str = ""
    decided_at: Optional[datetime] = None
    excluded: bool = False
    reset_reason: Optional[str] = None
    calibration: Optional[CalibrationReview] = None
    #: A system's decision only: the batch that accepted it after a random sample (None: a person's decision).
    batch_id: Optional[int] = None


class Decision(Review):
    """A system decision's answer; for ``needs_fix`` / ``fixed`` the hand-off it made."""

    returned_to: Optional[str] = None
    handoff: Optional[str] = None


class Assignment(Model):
    """Who a system is assigned to (``assignee`` None: nobody)."""

    assignee: Optional[str]
    assigned_at: Optional[datetime]
    assigned_by: Optional[str]


class Presence(Model):
    """Someone who has a system open now."""

    name: str
    since: datetime
    seconds_open: int
    expires_at: datetime


class SystemSummary(Model):
    """A row of the review queue (``GET /api/systems``): the figures of the system's last recomputation."""

    id: int
    name: str
    kind: str
    game: GameRef
    review: Review
    ball3d: Optional[Point3] = Field(description="The 3D ball, metres (SoccerNet world frame); None: none.")
    ball_sigma_m: Optional[float] = Field(None, description="The 3D ball's sigma, metres along its least certain "
                                          "direction; None without one.")
    ball_evidence: str = Field("none", description="What backs the 3D ball: vouched, unconfirmed, doubted or none "
                               "(docs/review.md).")
    ball_evidence_reasons: list[str] = Field([], description="Why, as short phrases.")
    views_total: int
    views_calibrated: int
    views_admitted: int
    views_labelled: int
    lowest_jac: Optional[float]
    worst_error_px: Optional[float]
    views_flagged: int
    views_above_tau: int
    doubt_counts: dict[str, int]
    label_doubts: int
    assignment: Optional[Assignment] = None
    open_by: list[Presence] = []


class SystemPage(Model):
    """A page of the queue; ``counts`` per review status over the filters other than ``status``."""

    items: list[SystemSummary]
    total: int
    limit: int
    offset: Optional[int]
    counts: dict[str, int]
    next_cursor: Optional[str] = None
    prev_cursor: Optional[str] = None


class Ball(Model):
    """A view's ball label (a box or a point, pixels) and the imported original."""

    kind: Optional[str] = None
    box: Optional[Box] = None
    point: Optional[Point2] = None
    original_box: Optional[Box] = None
    original_point: Optional[Point2] = None
    edited: bool = False
    provenance: Optional[dict[str, Any]] = None


class Calibration(Model):
    """A view's camera (SoccerNet-calibration JSON) and its quality (JaC per gamma, admission, flags)."""

    status: str
    source: str
    camera: Optional[dict[str, Any]]
    jac: dict[str, Optional[float]]
    admitted: bool
    reason: Optional[str]
    flags: list[str]
    residuals_px: dict[str, Any]
    mirror_evidence: Optional[dict[str, Any]] = None
    uncertainty: Optional[dict[str, Any]] = None
    players: Optional[dict[str, Any]] = None
    probably_mirrored: bool


class OptimisedBox(Model):
    """A view's optimised box (pixels), its diameter (pixels) and the depth error it implies (metres)."""

    box: Box
    d_px: float
    error_m: float


class Pair(Model):
    """One triangulation pair, its views named by frame id."""

    view_a: int
    view_b: int
    point: Optional[Point3]
    error_px: Optional[float]
    parallax_deg: Optional[float]
    baseline_m: float
    kept: bool
    reason: Optional[str]


class Triangulation(Model):
    """A system's triangulation and the settings it was made with."""

    status: str
    sigma_m: Optional[float] = None
    tau_px: float
    rule: str
    min_baseline_m: float
    pairs: list[Pair]
    reference_width_px: Optional[float]


class PitchLine(Model):
    """One in-image run of a projected pitch element (pixels)."""

    class_: str = Field(alias="class")
    points: list[Point2]


class _ViewFacts(Model):
    """What a view and a frame share: its image, calibration, ball label, errors and decision."""

    name: str
    role: str
    width: int
    height: int
    image_url: Optional[str]
    calibration: Optional[Calibration]
    ball: Ball
    reprojection_error_px: Optional[float]
    review: Review


class View(_ViewFacts):
    """One view of a system, as the system page draws it; ``etag`` is its frame's version (what an edit sends)."""

    frame_id: int
    pitch_lines_url: Optional[str]
    field_lines: dict[str, list[list[Point2]]]
    optimised_box: Optional[OptimisedBox]
    precise_box: Optional[Box] = None
    reprojected_ball: Optional[Point2]
    reprojection_error_scaled_px: Optional[float]
    error_above_tau: bool
    camera_position: Optional[Point3]
    etag: str


class Frame(View):
    """``GET /api/frames/{id}``: a view with its system's id and its projected pitch; ``etag`` the version read."""

    system_id: int
    pitch_lines: list[PitchLine]


class FrameRow(_ViewFacts):
    """A row of ``GET /api/frames``."""

    id: int
    system_id: int


class FramePage(Model):
    """A page of frames."""

    items: list[FrameRow]
    total: int
    limit: int
    offset: int


class Doubt(Model):
    """A doubt of a system: a label problem the geometry sees (``accuses_label``) or a note; ``suggestion`` its fix
    (``action``, and ``request``: the one request its key sends), None when it has none."""

    kind: str
    frame_id: Optional[int]
    frame: Optional[str]
    accuses_label: bool
    message: str
    evidence: dict[str, Any]
    suggestion: Optional[dict[str, Any]]

    @property
    def fix_action(self) -> Optional[str]:
        """What the one-key fix does (snap_box, snap_point, exclude_view, mirror_labels), None without one."""
        action = (self.suggestion or {}).get("action")
        return action if isinstance(action, str) and self.fix_request is not None else None

    @property
    def fix_request(self) -> Optional[dict[str, Any]]:
        """The one-key fix as a request (``method``, ``path``, ``body``), or None when the doubt has none."""
        request = (self.suggestion or {}).get("request")
        return request if isinstance(request, dict) else None


class BatchAcceptance(Model):
    """How a batch accepted a system after a random sample: the batch, who made and accepted it, when, and its plan
    (fractions, the sample's and the batch's sizes, and in words)."""

    batch_id: int
    created_by: str
    decided_by: Optional[str] = None
    decided_at: Optional[datetime] = None
    confidence: float
    max_wrong_share: float
    sample: int
    systems: int
    plan: str


class System(Model):
    """A system as its page draws it (``GET /api/systems/{id}``): every view, its doubts, its triangulation;
    ``etag`` is the system's version (what a decision sends)."""

    id: int
    name: str
    kind: str
    frame_index: Optional[int] = None
    game: GameRef
    review: Review
    etag: str
    prev_id: Optional[int]
    next_id: Optional[int]
    ball3d: Optional[Point3]
    ball_sigma_m: Optional[float] = None
    #: What backs the 3D ball (vouched, unconfirmed, doubted, none) and why, as short phrases.
    ball_evidence: str = "none"
    ball_evidence_reasons: list[str] = []
    triangulation: Optional[Triangulation]
    views: list[View]
    doubts: list[Doubt]
    assignment: Assignment
    open_by: list[Presence]
    #: When a batch accepted the system after a sample: that batch and its plan (None: a person's decision).
    accepted_in_batch: Optional[BatchAcceptance] = None

    def view(self, frame_id: int) -> View:
        """The view of frame ``frame_id``. Raises KeyError when the system has none."""
        for v in self.views:
            if v.frame_id == frame_id:
                return v
        raise KeyError(f"system {self.id} has no view of frame {frame_id}")


class SystemState(Model):
    """A system's decision as a stale decision (412) answers it."""

    id: int
    etag: str
    review: Review


# ----- the audit ----------------------------------------------------------------------------------------------------
class AuditEntry(Model):
    """One audited write: who, when, what, the edited part before and after, in one line (``summary``)."""

    id: int
    at: datetime
    actor: str
    action: str
    frame_id: Optional[int]
    system_id: Optional[int]
    game_id: Optional[int]
    before: Optional[dict[str, Any]]
    after: Optional[dict[str, Any]]
    reverts_id: Optional[int]
    summary: Optional[str] = None
    revertible: bool


class AuditPage(Model):
    """A page of the audit log, newest first."""

    items: list[AuditEntry]
    total: int
    limit: int
    offset: int
    next_offset: Optional[int] = None


class Stale(Model):
    """A 412's body: the resource now (a :class:`Frame` or a :class:`SystemState`), its ETag, its last change and,
    for a system, the changes since the version the write named."""

    detail: str
    etag: str
    current: Optional[Frame | SystemState]
    last_change: Optional[AuditEntry]
    changes_since: list[AuditEntry] = []


# ----- jobs -------------------------------------------------------------------------------------------------------
class Job(Model):
    """A background job (import, recompute, export): its progress while it runs, its result when done."""

    id: int
    kind: str
    params: dict[str, Any]
    state: str
    stage: Optional[str]
    done: int
    total: int
    message: Optional[str]
    result: Optional[dict[str, Any]]
    owner: Optional[str]
    attempts: int
    created_at: datetime
    started_at: Optional[datetime]
    finished_at: Optional[datetime]
    heartbeat_at: Optional[datetime]
    url: str
    result_url: Optional[str]

    @property
    def finished(self) -> bool:
        """Done or failed: nothing more will change."""
        return self.state in ("done", "failed")


class JobPage(Model):
    """A page of jobs, newest first."""

    items: list[Job]
    total: int
    limit: int
    offset: int


# ----- batches ----------------------------------------------------------------------------------------------------
class BatchStop(Model):
    """A system that stops a batch's accept, in words; ``final``: for good (a rejection, a change), else the batch
    waits for it (a sampled system not decided yet)."""

    system_id: int
    words: str
    final: bool


class Batch(Model):
    """A batch of pending vouched systems accepted after a random sample: ``systems`` it holds, the ``sample`` a
    person reviews, the ``plan`` in words, its ``state`` (open, accepted, refused, undone) and, while open, what stops
    its accept now (``stops``)."""

    id: int
    created_by: str
    created_at: datetime
    filter: dict[str, Any]
    confidence: float
    max_wrong_share: float
    systems: list[int]
    sample: list[int]
    plan: str
    state: str
    refusal: Optional[str] = None
    accepted: int
    decided_by: Optional[str] = None
    decided_at: Optional[datetime] = None
    stops: list[BatchStop] = []


class BatchAccepted(Model):
    """How many systems a batch's accept accepted."""

    accepted: int


class BatchUndone(Model):
    """A batch undone: ``undone`` systems back to pending; ``kept``: those decided by a person since."""

    undone: int
    kept: list[BatchStop] = []


# ----- releases -------------------------------------------------------------------------------------------------
class Release(Model):
    """A release: the accepted systems as they were when it was made, immutably, under a name and a hash."""

    name: str
    note: str
    created_at: datetime
    created_by: str
    made_by: str
    systems: int
    #: of those, the systems accepted with no 3D ball
    without_ball3d: int
    views: int
    hash: str


class Releases(Model):
    """Every release, oldest first."""

    items: list[Release]


class DiffEnd(Model):
    """A release at one end of a diff."""

    name: str
    hash: str


class DiffSystem(Model):
    """A system added by the newer release."""

    system_id: int
    name: str
    game: str


class DiffRemoved(DiffSystem):
    """A system the newer release lost, and why."""

    why: str


class DiffView(Model):
    """What changed in one view."""

    frame_id: int
    view: str
    changes: list[str]


class DiffChanged(DiffSystem):
    """A system in both releases that changed: how far its 3D ball moved (metres) and per view what changed."""

    ball3d_moved_m: Optional[float]
    views: list[DiffView]


class ReleaseDiff(Model):
    """What changed from one release (``from_``) to another (``to``)."""

    from_: DiffEnd = Field(alias="from")
    to: DiffEnd
    added: list[DiffSystem]
    removed: list[DiffRemoved]
    changed: list[DiffChanged]
    unchanged: int


# ----- comments, predictions, users, statistics ---------------------------------------------------------------
class Comment(Model):
    """A comment pinned on a view (``point`` in its pixels, or None)."""

    id: int
    system_id: int
    frame_id: int
    point: Optional[list[float]]
    text: str
    author: str
    created_at: datetime
    resolved: bool
    resolved_by: Optional[str] = None
    resolved_at: Optional[datetime] = None


class CommentPage(Model):
    """A page of a system's comments, oldest first."""

    items: list[Comment]
    total: int
    limit: int
    offset: int
    next_offset: Optional[int] = None


class ScoreSpread(Model):
    """The spread of a detector's scores."""

    min: Optional[float]
    q1: Optional[float]
    median: Optional[float]
    q3: Optional[float]
    max: Optional[float]


class PredictionSource(Model):
    """One detector's stored predictions."""

    source: str
    predictions: int
    frames: int
    systems: int
    scores: ScoreSpread
    imported_at: Optional[datetime]
    imported_by: Optional[str]


class PredictionSources(Model):
    """Every stored detector source."""

    items: list[PredictionSource]


class PredictionsRemoved(Model):
    """What removing a source did."""

    source: str
    removed: int


class User(Model):
    """A user: role, whether disabled, how many API tokens work."""

    name: str
    role: str
    created_at: datetime
    tokens: int
    disabled: bool
    demo: bool


class Token(Model):
    """An API token, shown this once, with the id that lists and revokes it."""

    name: str
    token: str
    id: int
    label: Optional[str]
    expires_at: Optional[datetime]


class TokenSummary(Model):
    """An API token as listed (never the token itself)."""

    id: int
    label: Optional[str]
    created_at: datetime
    last_used_at: Optional[datetime]
    expires_at: Optional[datetime]
    revoked_at: Optional[datetime]
    state: str


class Me(Model):
    """Who the client is logged in as."""

    name: str
    role: str
    roles: list[str]
    via: str
    csrf_token: Optional[str]


class Health(Model):
    """``GET /api/health``: the server answers, and its version."""

    status: str
    version: Optional[str] = None


class Annotator(Model):
    """One person's figures as an annotator and as a reviewer (times in seconds, distances in pixels)."""

    name: str
    edits: int
    systems_touched: int
    systems_decided: int
    needs_fix_received: int
    accepted_first_review: int
    median_edit_to_review_s: Optional[float]
    median_label_distance_px: Optional[float]
    accused_share: Optional[float]
    decisions: int
    accepted: int
    rejected: int
    needs_fix: int
    re_reviews: int


class Annotators(Model):
    """Every person's figures, by name."""

    items: list[Annotator]


class CountsPerSplit(Model):
    """Systems and images of one split."""

    systems: int
    images: int
    calibrated_images: int
    admitted_images: int


class KindStats(CountsPerSplit):
    """Systems and images of one kind of system, and per split."""

    splits: dict[str, CountsPerSplit]


class SweepPoint(Model):
    """Systems kept at one admission threshold."""

    threshold: float
    systems_kept: int


class Admission(Model):
    """The admission threshold in force: JaC at ``gamma`` (a fraction of the image diagonal) above ``jac_min``."""

    gamma: float
    jac_min: float


class Histogram(Model):
    """Equal bins (``edges``, ``counts``); ``n`` values in all, ``above`` of them beyond the last edge."""

    edges: list[float]
    counts: list[int]
    n: int
    above: int = 0


class Stats(Model):
    """The dataset at a glance."""

    kinds: dict[str, KindStats]
    jac_sweep: list[SweepPoint]
    jac_sweep_by_kind: dict[str, list[SweepPoint]]
    admission: Admission
    stale_systems: int
    #: Systems per tier of what backs their 3D ball (vouched, unconfirmed, doubted, none).
    ball_evidence: dict[str, int]
    distributions: dict[str, Histogram]
