"""SQLAlchemy 2 typed models of v3d.

Entity graph (``->`` is "has many", ``-`` is "has one")::

    Game -> System -> Frame - FieldLineAnnotation      (current + imported original, pixels)
                 |          - Calibration              (SoccerNet camera JSON, JaC@gamma, admitted)
                 |          - BallLabel                (box or point, current + imported original)
                 |          - BallReprojection         (fused 3D ball projected into the view)
                 |          - OptimisedBox             (paper Eq. min_diametre)
                 |          - ReviewDecision           (frame level)
                 - Triangulation -> TriangulationPair  (per pair e_ij, parallax, baseline, kept)
                 - ReviewDecision                      (system level)
                 -> Doubt                              (label problems the geometry sees, with fixes)
                 - TrajectoryPoint                     (ISSIA: the frame on the sequence's trajectory)

    User -> ApiToken                                   (people and their API tokens, hashed)
    System - User (assignee), SystemPresence           (work assignment; who has a system open, expiring)
    ServerSecret                                       (the session-signing key, shared by every worker)
    AuditEntry                                         (append-only log of accepted writes; ids, no FKs)
    Job                                                (a background import, full recompute or export)

Units: pixels of the frame's own image (continuous coordinates, origin at the top-left corner),
world metres in SoccerNet's frame (z down), timestamps timezone-aware UTC. Boxes are
``[x1, y1, x2, y2]`` and points ``[x, y]`` JSON lists. Enums are stored by value.
The schema is created by the Alembic migrations (``migrations/``), never by ``create_all``.

Size (over 400 lines): one typed model per table, in one registry so that relationships and the entity graph
above read in one place.
"""
from __future__ import annotations

import enum
from datetime import datetime
from typing import Any, Optional

import sqlalchemy as sa
from sqlalchemy.orm import DeclarativeBase, Mapped, mapped_column, relationship

from app.db.types import JSONDoc, UTCDateTime, enum_by_value, utcnow
from app.geometry.jac import JAC_GAMMAS

#: The column of each stored JaC gamma (``app.geometry.jac.JAC_GAMMAS``, fractions of the image diagonal).
JAC_COLUMNS: dict[float, str] = dict(zip(JAC_GAMMAS, ("jac_0005", "jac_001", "jac_002"), strict=True))

#: Constraint names Alembic can rely on (same on SQLite and PostgreSQL).
NAMING_CONVENTION = {
    "ix": "ix_%(column_0_label)s",
    "uq": "uq_%(table_name)s_%(column_0_N_name)s",
    "ck": "ck_%(table_name)s_%(constraint_name)s",
    "fk": "fk_%(table_name)s_%(column_0_name)s_%(referred_table_name)s",
    "pk": "pk_%(table_name)s",
}


class Base(DeclarativeBase):
    """Declarative base: float columns are DOUBLE PRECISION, datetimes UTC, dicts and lists JSON."""

    metadata = sa.MetaData(naming_convention=NAMING_CONVENTION)
    type_annotation_map = {
        float: sa.Double(),
        datetime: UTCDateTime(),
        dict[str, Any]: JSONDoc,
        list[Any]: JSONDoc,
        list[float]: JSONDoc,
        list[str]: JSONDoc,
    }


# ----- enums ---------------------------------------------------------------------------------------
class SystemKind(str, enum.Enum):
    """How a multi-view system was formed."""

    SOCCERNET_V3 = "soccernet-v3"  # an action frame and its linked replays
    SINGLE_VIEW = "single-view"  # one frame of a calibration dataset, reviewed for its calibration
    ISSIA = "issia"  # one frame index of a sequence of synchronised static cameras (ISSIA-3D)


class FrameRole(str, enum.Enum):
    """The frame's part in its system."""

    ACTION = "action"
    REPLAY = "replay"
    CAMERA = "camera"  # the only view of a single-view system
    STATIC = "static"  # one static camera of a synchronised sequence (ISSIA-3D)


class CalibrationSource(str, enum.Enum):
    """Where a frame's camera comes from."""

    IMPORTED = "imported"  # read from a SoccerNet-v3D export, never recomputed on import
    COMPUTED = "computed"  # app.geometry.calibration.calibrate_frame on the current field lines
    EDITED = "edited"  # set by a reviewer


class CalibrationStatus(str, enum.Enum):
    """Outcome of calibration: a camera, or a refusal with its reason."""

    CALIBRATED = "calibrated"
    REFUSED = "refused"


class BallKind(str, enum.Enum):
    """A ball label is a box (SoccerNet-v3) or a point (ISSIA)."""

    BOX = "box"
    POINT = "point"


class TriangulationStatus(str, enum.Enum):
    """Outcome of a system's triangulation (method.md section 5)."""

    TRIANGULATED = "triangulated"  # at least one pair kept; ``ball3d`` is the mean of the kept points
    INSUFFICIENT_VIEWS = "insufficient_views"  # fewer than two admitted views with a ball label
    NO_PAIR_KEPT = "no_pair_kept"  # every pair dropped (tau, baseline, cheirality or degenerate)


class JobState(str, enum.Enum):
    """Where a background job is (``app.services.jobs.runner``)."""

    QUEUED = "queued"  # waiting for a runner
    RUNNING = "running"  # claimed by the runner named in ``Job.owner``, which beats ``heartbeat_at``
    DONE = "done"
    FAILED = "failed"  # ``Job.message`` says why


class ReviewStatus(str, enum.Enum):
    """A reviewer's decision on a system or a frame."""

    PENDING = "pending"
    ACCEPTED = "accepted"
    REJECTED = "rejected"
    NEEDS_FIX = "needs_fix"


class UserRole(str, enum.Enum):
    """A user's role, least trusted first (``app.api.auth.ROLES``: a role may do what a lower one may)."""

    ANNOTATOR = "annotator"  # edits labels and field lines, takes per-view decisions
    REVIEWER = "reviewer"  # also takes system decisions and reverts audited writes
    ADMIN = "admin"  # also imports, exports and manages users


# ----- entities ------------------------------------------------------------------------------------
class Game(Base):
    """One game (SoccerNet-v3) or one calibration dataset (its frames are single-view systems)."""

    __tablename__ = "games"
    __table_args__ = (sa.UniqueConstraint("league", "season", "match"),)

    id: Mapped[int] = mapped_column(primary_key=True)
    league: Mapped[str] = mapped_column(sa.String(200))
    season: Mapped[str] = mapped_column(sa.String(200))
    match: Mapped[str] = mapped_column(sa.String(400))
    #: Folder or archive the game was imported from (absolute path at import time).
    source_path: Mapped[str] = mapped_column(sa.Text)
    created_at: Mapped[datetime] = mapped_column(default=utcnow)
    #: What the imported labels file carries beside its systems, as it came (``GameRecord.release``: its
    #: top-level keys but ``actions`` and ``replays``, e.g. ``GameMetadata`` with ``UrlYoutube``, and the
    #: replays no action links), written back by the SoccerNet-v3D export; None for formats without one.
    #: Deferred: read by the exports only.
    release: Mapped[Optional[dict[str, Any]]] = mapped_column(deferred=True)
    #: A calibration dataset's learned camera prior (``CameraPrior.to_json``, issue 17): learned by its import
    #: from its own confident fits, used by every later recalibration of its frames; None when none was learned.
    camera_prior: Mapped[Optional[dict[str, Any]]] = mapped_column(default=None)

    systems: Mapped[list[System]] = relationship(
        back_populates="game", cascade="all, delete-orphan", passive_deletes=True, order_by="System.id"
    )

    @property
    def path(self) -> str:
        """``league/season/match``: the game's folder in SoccerNet trees and its key in exports."""
        return f"{self.league}/{self.season}/{self.match}"


class System(Base):
    """A multi-view system: an action frame and its linked replays, or one single-view frame."""

    __tablename__ = "systems"
    __table_args__ = (
        sa.UniqueConstraint("game_id", "name"),
        sa.Index("ix_systems_label_doubts_worst_error_px", "label_doubts", "worst_error_px"),
        # the sort keys within a review status: the "pending" queue and its neighbours are index seeks
        sa.Index("ix_systems_review_status_label_doubts_worst_error_px", "review_status", "label_doubts",
                 "worst_error_px"),
        sa.Index("ix_systems_review_status_worst_error_px", "review_status", "worst_error_px"),
        sa.Index("ix_systems_review_status_lowest_jac", "review_status", "lowest_jac"),
        # keyset pages of the queue (app.services.curation.queue._slices, migration 0013): the numeric name
        # order within a game as an index walk
        sa.Index("ix_systems_game_id_name_length_name", "game_id", sa.text("length(name)"), "name"),
    )

    id: Mapped[int] = mapped_column(primary_key=True)
    game_id: Mapped[int] = mapped_column(sa.ForeignKey("games.id", ondelete="CASCADE"), index=True)
    #: The action frame's name ("12.png") or the calibration frame's file stem ("00002").
    name: Mapped[str] = mapped_column(sa.String(200))
    kind: Mapped[SystemKind] = mapped_column(enum_by_value(SystemKind, "system_kind"))
    created_at: Mapped[datetime] = mapped_column(default=utcnow)

    game: Mapped[Game] = relationship(back_populates="systems")
    frames: Mapped[list[Frame]] = relationship(
        back_populates="system", cascade="all, delete-orphan", passive_deletes=True, order_by="Frame.position"
    )
    triangulation: Mapped[Optional[Triangulation]] = relationship(
        back_populates="system", cascade="all, delete-orphan", passive_deletes=True
    )
    review: Mapped[Optional[ReviewDecision]] = relationship(
        back_populates="system", cascade="all, delete-orphan", passive_deletes=True
    )
    doubts: Mapped[list[Doubt]] = relationship(
        back_populates="system", cascade="all, delete-orphan", passive_deletes=True, order_by="Doubt.id"
    )
    # ----- the review queue's figures, written by every recomputation of the system
    # (``app.services.derivation.recompute.update_summary``) so that the queue reads them instead of aggregating
    # on every request. Aggregates are over the **admitted** views, the ones the 3D ball is made of.
    #: Doubts per kind (``{kind: n}``, every kind present), written with the doubts.
    doubt_counts: Mapped[dict[str, Any]] = mapped_column(default=dict)
    #: How many doubts accuse a label (``app.geometry.doubts.LABEL_KINDS``): the queue sorts by it.
    label_doubts: Mapped[int] = mapped_column(default=0)
    views_total: Mapped[int] = mapped_column(default=0)
    views_calibrated: Mapped[int] = mapped_column(default=0)
    views_admitted: Mapped[int] = mapped_column(default=0)
    #: Views with a current ball label.
    views_labelled: Mapped[int] = mapped_column(default=0)
    #: Lowest JaC@0.5 % among admitted views (None without one).
    lowest_jac: Mapped[Optional[float]] = mapped_column(index=True)
    #: Largest reprojection error (px, the view's own) of the fused ball among admitted labelled views.
    worst_error_px: Mapped[Optional[float]] = mapped_column(index=True)
    #: Views (admitted or not) whose field-line labels are flagged probably mirrored.
    views_flagged: Mapped[int] = mapped_column(default=0)
    #: Admitted labelled views whose reprojection error is above tau
    #: (``app.geometry.triangulation.error_above_tau``).
    views_above_tau: Mapped[int] = mapped_column(default=0)
    #: The system's review status (a copy of ``review.status``, pending without a decision), kept in the
    #: transaction of every decision and recomputation: the queue filters and counts by it.
    review_status: Mapped[ReviewStatus] = mapped_column(
        enum_by_value(ReviewStatus, "system_review_status"), default=ReviewStatus.PENDING, index=True)
    #: Version of the derived rows and figures (``app.services.derivation.recompute.DERIVED_VERSION``); a system
    #: stored by an older version is recomputed before it is served (``refresh_stale_systems``).
    derived_version: Mapped[int] = mapped_column(default=0)
    #: The fingerprint of the settings the derived rows were computed with (``Settings.derived_fingerprint``,
    #: e.g. ``V3D_PROFILE``'s choices); None before it was recorded. A different one: stale for ``v3d recompute``.
    derived_settings: Mapped[Optional[str]] = mapped_column(sa.String(16))
    #: ISSIA systems: the frame index in the sequence (frame ``i`` at ``t = i / fps``); None otherwise.
    frame_index: Mapped[Optional[int]] = mapped_column(index=True)
    #: Version of the system's review decision, bumped by every decision on the system (its strong ETag,
    #: ``app.services.curation.versions``); recomputations never touch it.
    review_version: Mapped[int] = mapped_column(default=1)
    #: ISSIA systems: the frame's place on the sequence's trajectory (``app.services.issia.sequences``).
    trajectory_point: Mapped[Optional[TrajectoryPoint]] = relationship(
        back_populates="system", cascade="all, delete-orphan", passive_deletes=True
    )
    # ----- work assignment (issue 28, ``app.services.curation.assignment``): who should review the system.
    #: The id of the user the system is assigned to (None: nobody). A plain indexed id, as the audit log's: a
    #: foreign key would need SQLite to rebuild ``systems`` (migration 0020); users are disabled, never deleted.
    assignee_id: Mapped[Optional[int]] = mapped_column(index=True)
    #: When it was last assigned (or unassigned), UTC; None when never.
    assigned_at: Mapped[Optional[datetime]]
    #: Who assigned it (the audit log's actor name, so that it outlives the user); None when never.
    assigned_by: Mapped[Optional[str]] = mapped_column(sa.String(200))


class Frame(Base):
    """One image of a system and where its pixels are read from.

    The image is either a member of a zip archive (``image_zip`` + ``image_member``, read without
    extracting) or a file (``image_path``), both relative (POSIX) to the imported dataset's folder
    ``image_root`` and checked to resolve inside it when imported and when served
    (``app.services.images.serving.stored_image_file``); all empty when the dataset ships no images.
    """

    __tablename__ = "frames"
    __table_args__ = (
        sa.UniqueConstraint("system_id", "name"),
        sa.CheckConstraint("width > 0 AND height > 0", name="positive_size"),
    )

    id: Mapped[int] = mapped_column(primary_key=True)
    system_id: Mapped[int] = mapped_column(sa.ForeignKey("systems.id", ondelete="CASCADE"), index=True)
    name: Mapped[str] = mapped_column(sa.String(200))
    role: Mapped[FrameRole] = mapped_column(enum_by_value(FrameRole, "frame_role"))
    #: Order of the views in the system (the action first, then replays in file order).
    position: Mapped[int] = mapped_column(default=0)
    width: Mapped[int]
    height: Mapped[int]
    image_zip: Mapped[Optional[str]] = mapped_column(sa.Text)
    image_member: Mapped[Optional[str]] = mapped_column(sa.Text)
    image_path: Mapped[Optional[str]] = mapped_column(sa.Text)
    #: The imported dataset's folder (absolute, resolved) that ``image_zip`` / ``image_path`` are relative to.
    image_root: Mapped[Optional[str]] = mapped_column(sa.Text)
    #: The image's type checked from its header at import ("png" or "jpeg"); served with that media type.
    image_type: Mapped[Optional[str]] = mapped_column(sa.String(16))
    #: Frame number inside ``image_path`` when that is a video or a folder of numbered frames
    #: (ISSIA); the image is decoded on demand and resized to ``width`` x ``height``.
    media_frame: Mapped[Optional[int]]
    #: The footage is mirrored horizontally relative to the labels: flipped back when read.
    media_flipped: Mapped[bool] = mapped_column(default=False)
    #: The split a release gives the image ("train" or "test", ``v3d import split``); None: the kind's own
    #: (``app.services.kinds.KindPolicy.split``).
    split: Mapped[Optional[str]] = mapped_column(sa.String(8))
    #: A precise ball box ``[x1, y1, x2, y2]`` px of this image (paper Table 1, ``v3d import precise-boxes``), or None.
    precise_box: Mapped[Optional[list[float]]]
    #: What a release carries of the frame that v3d does not edit, as it came (``FrameRecord.release``: the
    #: frame's entry of the labels file, every key: ``imageMetadata``, every ``bboxes`` entry (players,
    #: goalkeepers, referees, the imported ball), the links; ``lines`` only where the stored field lines do not
    #: give them back). The SoccerNet-v3D export writes it with the curated lines and ball box, the detector
    #: exports take their other boxes from it: no export reads the source files again. None for formats without
    #: one (SoccerNet-calibration, ISSIA). Deferred: read by the exports only.
    release: Mapped[Optional[dict[str, Any]]] = mapped_column(deferred=True)
    #: Version of what people edit on the frame (ball label, field lines, its review and exclusion),
    #: bumped by each such write and by an import that changes them (its strong ETag,
    #: ``app.services.curation.versions``); a recomputation caused by a sibling view's edit never touches it.
    edit_version: Mapped[int] = mapped_column(default=1)

    system: Mapped[System] = relationship(back_populates="frames")
    field_lines: Mapped[Optional[FieldLineAnnotation]] = relationship(
        back_populates="frame", cascade="all, delete-orphan", passive_deletes=True
    )
    calibration: Mapped[Optional[Calibration]] = relationship(
        back_populates="frame", cascade="all, delete-orphan", passive_deletes=True
    )
    ball_label: Mapped[Optional[BallLabel]] = relationship(
        back_populates="frame", cascade="all, delete-orphan", passive_deletes=True
    )
    reprojection: Mapped[Optional[BallReprojection]] = relationship(
        back_populates="frame", cascade="all, delete-orphan", passive_deletes=True
    )
    optimised_box: Mapped[Optional[OptimisedBox]] = relationship(
        back_populates="frame", cascade="all, delete-orphan", passive_deletes=True
    )
    review: Mapped[Optional[ReviewDecision]] = relationship(
        back_populates="frame", cascade="all, delete-orphan", passive_deletes=True
    )


class FieldLineAnnotation(Base):
    """A frame's field lines: ``{class: [[[x, y], ...], ...]}`` in pixels (repeated classes kept).

    ``original_lines`` is what the dataset said; ``lines`` is the current value (equal until edited).
    """

    __tablename__ = "field_lines"

    frame_id: Mapped[int] = mapped_column(sa.ForeignKey("frames.id", ondelete="CASCADE"), primary_key=True)
    lines: Mapped[dict[str, Any]]
    original_lines: Mapped[dict[str, Any]]
    edited_at: Mapped[Optional[datetime]]

    frame: Mapped[Frame] = relationship(back_populates="field_lines")

    @property
    def edited(self) -> bool:
        """True when the current lines differ from the imported ones."""
        return self.lines != self.original_lines


class Calibration(Base):
    """A frame's camera (SoccerNet-calibration JSON, method.md section 2) and its quality.

    ``jac_0005``, ``jac_001``, ``jac_002`` are JaC at gamma = 0.5 %, 1 %, 2 % of the image diagonal
    (method.md section 4), computed at the frame's own resolution. ``admitted`` says whether the frame
    joined its system's triangulation under the settings of the last recomputation.
    ``mirror_evidence`` is the evidence on mirrored labels (``app.geometry.mirror``,
    ``MirrorVerdict.as_dict``): written by the system recomputation for a calibrated frame, by the
    rig retry for a refused one; the flag ``"probably_mirrored"`` in ``flags`` follows its verdict.
    ``uncertainty`` is the camera's standard deviations from the line fit
    (``app.geometry.calibration.CalibrationUncertainty.to_json``); null when not fitted from lines here.
    """

    __tablename__ = "calibrations"

    frame_id: Mapped[int] = mapped_column(sa.ForeignKey("frames.id", ondelete="CASCADE"), primary_key=True)
    source: Mapped[CalibrationSource] = mapped_column(enum_by_value(CalibrationSource, "calibration_source"))
    status: Mapped[CalibrationStatus] = mapped_column(enum_by_value(CalibrationStatus, "calibration_status"))
    camera: Mapped[Optional[dict[str, Any]]]
    reason: Mapped[Optional[str]] = mapped_column(sa.Text)
    flags: Mapped[list[str]] = mapped_column(default=list)
    residuals_px: Mapped[dict[str, Any]] = mapped_column(default=dict)
    jac_0005: Mapped[Optional[float]]
    jac_001: Mapped[Optional[float]]
    jac_002: Mapped[Optional[float]]
    admitted: Mapped[bool] = mapped_column(default=False)
    mirror_evidence: Mapped[Optional[dict[str, Any]]]
    uncertainty: Mapped[Optional[dict[str, Any]]]
    updated_at: Mapped[datetime] = mapped_column(default=utcnow, onupdate=utcnow)

    frame: Mapped[Frame] = relationship(back_populates="calibration")

    def jac(self) -> dict[str, Optional[float]]:
        """JaC per gamma of :data:`JAC_COLUMNS`, keyed by the gamma as text in increasing order
        (``{"0.005": .., "0.01": .., "0.02": ..}``: the keys of the API and of exports)."""
        return {f"{g:g}": getattr(self, column) for g, column in JAC_COLUMNS.items()}


class BallLabel(Base):
    """A frame's ball label: a box ``[x1, y1, x2, y2]`` or a point ``[x, y]`` in pixels.

    The imported original is kept beside the current value. ``kind`` None means a reviewer removed
    the label (the ball is not visible) while the original is kept; a frame that never had a label
    has no row. ``provenance`` marks a label made from a doubt's suggestion (:attr:`suggested`).
    """

    __tablename__ = "ball_labels"

    frame_id: Mapped[int] = mapped_column(sa.ForeignKey("frames.id", ondelete="CASCADE"), primary_key=True)
    kind: Mapped[Optional[BallKind]] = mapped_column(enum_by_value(BallKind, "ball_kind"))
    box: Mapped[Optional[list[float]]]
    point: Mapped[Optional[list[float]]]
    original_kind: Mapped[Optional[BallKind]] = mapped_column(enum_by_value(BallKind, "ball_original_kind"))
    original_box: Mapped[Optional[list[float]]]
    original_point: Mapped[Optional[list[float]]]
    edited_at: Mapped[Optional[datetime]]
    #: Where a label made from a doubt's suggestion came from (migration 0017): ``{"source": "suggestion",
    #: "doubt", "code", "from_views": [frame ids]}``; None for a label a person placed. A suggested label is not
    #: independent evidence (it lies where the other views put the ball by construction): it joins no
    #: triangulation and no doubt vote until a person places it (moves or confirms it: any edit without a
    #: provenance clears it).
    provenance: Mapped[Optional[dict[str, Any]]]

    frame: Mapped[Frame] = relationship(back_populates="ball_label")

    @property
    def suggested(self) -> bool:
        """True while the current label is a suggestion no person has placed."""
        return self.kind is not None and bool(self.provenance)

    @property
    def edited(self) -> bool:
        """True when the current label differs from the imported one."""
        return (self.kind, self.box, self.point) != (self.original_kind, self.original_box, self.original_point)

    @property
    def centre(self) -> list[float] | None:
        """The labelled ball centre ``[x, y]`` in pixels (the box centre or the point), or None when
        the current label was removed."""
        return BallLabel.centre_of(self.box, self.point)

    @staticmethod
    def centre_of(box: list[float] | None, point: list[float] | None) -> list[float] | None:
        """:attr:`centre` of stored ``box`` / ``point`` columns (read without the ORM object)."""
        if box is not None:
            x1, y1, x2, y2 = box
            return [(x1 + x2) / 2.0, (y1 + y2) / 2.0]
        return None if point is None else list(point)


class Triangulation(Base):
    """The fused 3D ball of a system (method.md section 5) and the settings it was made with."""

    __tablename__ = "triangulations"

    system_id: Mapped[int] = mapped_column(sa.ForeignKey("systems.id", ondelete="CASCADE"), primary_key=True)
    status: Mapped[TriangulationStatus] = mapped_column(enum_by_value(TriangulationStatus, "triangulation_status"))
    #: World metres ``[x, y, z]`` (z down), or None when not triangulated.
    ball3d: Mapped[Optional[list[float]]]
    tau_px: Mapped[float]
    rule: Mapped[str] = mapped_column(sa.String(40))
    min_baseline_m: Mapped[float]
    computed_at: Mapped[datetime] = mapped_column(default=utcnow, onupdate=utcnow)

    system: Mapped[System] = relationship(back_populates="triangulation")
    pairs: Mapped[list[TriangulationPair]] = relationship(
        back_populates="triangulation", cascade="all, delete-orphan", passive_deletes=True,
        order_by="TriangulationPair.id",
    )


class TriangulationPair(Base):
    """One pair (i, j) of admitted views: its DLT point, e_ij, parallax beta_ij, baseline, verdict."""

    __tablename__ = "triangulation_pairs"

    id: Mapped[int] = mapped_column(primary_key=True)
    system_id: Mapped[int] = mapped_column(
        sa.ForeignKey("triangulations.system_id", ondelete="CASCADE"), index=True
    )
    frame_a_id: Mapped[int] = mapped_column(sa.ForeignKey("frames.id", ondelete="CASCADE"))
    frame_b_id: Mapped[int] = mapped_column(sa.ForeignKey("frames.id", ondelete="CASCADE"))
    #: World metres ``[x, y, z]``; None when the pair is degenerate.
    point: Mapped[Optional[list[float]]]
    error_px: Mapped[Optional[float]]
    parallax_deg: Mapped[Optional[float]]
    baseline_m: Mapped[float]
    kept: Mapped[bool]
    reason: Mapped[Optional[str]] = mapped_column(sa.Text)

    triangulation: Mapped[Triangulation] = relationship(back_populates="pairs")
    frame_a: Mapped[Frame] = relationship(foreign_keys=[frame_a_id])
    frame_b: Mapped[Frame] = relationship(foreign_keys=[frame_b_id])


class BallReprojection(Base):
    """The system's 3D ball projected into one calibrated view; ``error_px`` is the distance to the
    labelled centre (SoccerNet-v3D's ``rep_error``), None when the view has no ball label."""

    __tablename__ = "ball_reprojections"

    frame_id: Mapped[int] = mapped_column(sa.ForeignKey("frames.id", ondelete="CASCADE"), primary_key=True)
    point: Mapped[list[float]]
    error_px: Mapped[Optional[float]]

    frame: Mapped[Frame] = relationship(back_populates="reprojection")


class OptimisedBox(Base):
    """A view's optimised box (paper Eq. min_diametre; ``app.geometry.ball.optimise_box`` with
    ``Settings.optimised_box_method``): by default (``exact_ray``) the box of the exact image of the ball
    at the 3D ball's depth along the labelled ray, an ellipse's box off the optical axis; with ``paper``,
    the square of side ``d_opt_px`` on the labelled centre. ``d_opt_px`` is the diameter d_opt (px) and
    ``error_m`` (metres) the remaining distance between the 3D ball and the monocular estimate."""

    __tablename__ = "optimised_boxes"

    frame_id: Mapped[int] = mapped_column(sa.ForeignKey("frames.id", ondelete="CASCADE"), primary_key=True)
    box: Mapped[list[float]]
    d_opt_px: Mapped[float]
    error_m: Mapped[float]

    frame: Mapped[Frame] = relationship(back_populates="optimised_box")


class ReviewDecision(Base):
    """The current review decision on a system or on a frame (exactly one of the two); a frame's holds two: its
    ball's (``status``, ``comment``) and its calibration's (``calibration_*``). ``reset_reason`` and
    ``calibration_reset_reason`` say why a decision is pending again (an edit recalibrated a view after it was
    decided: ``app.services.curation.resets.reset_decisions_after_recalibration``)."""

    __tablename__ = "review_decisions"
    __table_args__ = (
        sa.CheckConstraint("(system_id IS NULL) <> (frame_id IS NULL)", name="one_subject"),
    )

    id: Mapped[int] = mapped_column(primary_key=True)
    system_id: Mapped[Optional[int]] = mapped_column(
        sa.ForeignKey("systems.id", ondelete="CASCADE"), unique=True
    )
    frame_id: Mapped[Optional[int]] = mapped_column(sa.ForeignKey("frames.id", ondelete="CASCADE"), unique=True)
    status: Mapped[ReviewStatus] = mapped_column(enum_by_value(ReviewStatus, "review_status"),
                                                 default=ReviewStatus.PENDING)
    comment: Mapped[str] = mapped_column(sa.Text, default="")
    decided_at: Mapped[Optional[datetime]]
    #: Frame decisions only: the reviewer excluded this view from its system's triangulation
    #: (reversible; the view keeps its labels and calibration).
    excluded: Mapped[bool] = mapped_column(default=False)
    #: Why ``status`` is pending again (a system's: one of its views was recalibrated after the decision);
    #: None when decided or never reset. Cleared by the next decision.
    reset_reason: Mapped[Optional[str]] = mapped_column(sa.Text)
    #: Frame decisions only: the reviewer's decision on the view's calibration (its field lines and the
    #: camera fitted to them), apart from the decision on its ball (``status``).
    calibration_status: Mapped[ReviewStatus] = mapped_column(
        enum_by_value(ReviewStatus, "calibration_review_status"), default=ReviewStatus.PENDING)
    calibration_comment: Mapped[str] = mapped_column(sa.Text, default="")
    calibration_decided_at: Mapped[Optional[datetime]]
    #: Why ``calibration_status`` is pending again (an edit of the field lines recalibrated the view).
    calibration_reset_reason: Mapped[Optional[str]] = mapped_column(sa.Text)

    system: Mapped[Optional[System]] = relationship(back_populates="review", foreign_keys=[system_id])
    frame: Mapped[Optional[Frame]] = relationship(back_populates="review", foreign_keys=[frame_id])


class Doubt(Base):
    """One doubt of a system (``app.geometry.doubts.Doubt``): a label problem the geometry sees, or
    information on a view, with its evidence and fix. Replaced as a whole by every recomputation of
    the system, in the edit's transaction; ``frame_id`` None names the system as a whole."""

    __tablename__ = "doubts"
    __table_args__ = (sa.Index("ix_doubts_kind_system_id", "kind", "system_id"),)

    id: Mapped[int] = mapped_column(primary_key=True)
    system_id: Mapped[int] = mapped_column(sa.ForeignKey("systems.id", ondelete="CASCADE"), index=True)
    frame_id: Mapped[Optional[int]] = mapped_column(sa.ForeignKey("frames.id", ondelete="CASCADE"))
    kind: Mapped[str] = mapped_column(sa.String(40))
    accuses_label: Mapped[bool]
    message: Mapped[str] = mapped_column(sa.Text)
    evidence: Mapped[dict[str, Any]] = mapped_column(default=dict)
    suggestion: Mapped[Optional[dict[str, Any]]]

    system: Mapped[System] = relationship(back_populates="doubts")
    frame: Mapped[Optional[Frame]] = relationship()


class TrajectoryPoint(Base):
    """An ISSIA system's frame on its sequence's fitted trajectory (``app.geometry.trajectory``).

    ``ball3d`` is the frame's own triangulation (``triangulate_frame`` of the labels the trajectory
    keeps; ISSIA-3D's ``ball_3D``), ``ball3d_smoothed`` the trajectory's position and ``source`` how
    it was obtained (``triangulated``, ``fitted``, ``interpolated``), all world metres (z down) or
    None. ``cam_list`` holds the frame ids of the kept labels, ``residuals_px`` frame id (str) -> the
    label's distance to the trajectory's projection (px at 1920 width).
    """

    __tablename__ = "trajectory_points"

    system_id: Mapped[int] = mapped_column(sa.ForeignKey("systems.id", ondelete="CASCADE"), primary_key=True)
    ball3d: Mapped[Optional[list[float]]]
    ball3d_smoothed: Mapped[Optional[list[float]]]
    source: Mapped[Optional[str]] = mapped_column(sa.String(20))
    #: The motion piece the frame lies in (``Piece``: kind, first_frame, last_frame, params, cost).
    piece: Mapped[Optional[dict[str, Any]]]
    cam_list: Mapped[list[Any]] = mapped_column(default=list)
    residuals_px: Mapped[dict[str, Any]] = mapped_column(default=dict)
    #: Frame ids of the labels that break the trajectory (residual above ``flag_px``).
    flagged: Mapped[list[Any]] = mapped_column(default=list)
    computed_at: Mapped[datetime] = mapped_column(default=utcnow, onupdate=utcnow)

    system: Mapped[System] = relationship(back_populates="trajectory_point")


# ----- people -----------------------------------------------------------------------------------------
class User(Base):
    """A person (or a script's owner) who may log in: ``name`` is unique and is what the audit log records.

    ``password_hash`` is an argon2 PHC string (``app.services.accounts.users``, via pwdlib), never the password;
    ``disabled`` users can neither log in nor use their tokens; ``demo`` marks the account
    ``v3d serve --demo`` made (its password is public: the login page shows it).
    ``session_generation`` is stored in every session cookie; logging out raises it, which ends every
    browser session of the user at once (the cookie itself cannot be recalled).
    """

    __tablename__ = "users"

    id: Mapped[int] = mapped_column(primary_key=True)
    name: Mapped[str] = mapped_column(sa.String(100), unique=True)
    role: Mapped[UserRole] = mapped_column(enum_by_value(UserRole, "user_role"))
    password_hash: Mapped[str] = mapped_column(sa.Text)
    created_at: Mapped[datetime] = mapped_column(default=utcnow)
    disabled: Mapped[bool] = mapped_column(default=False)
    demo: Mapped[bool] = mapped_column(default=False)
    session_generation: Mapped[int] = mapped_column(default=0)

    tokens: Mapped[list[ApiToken]] = relationship(
        back_populates="user", cascade="all, delete-orphan", passive_deletes=True, order_by="ApiToken.id"
    )


class SystemPresence(Base):
    """A soft claim: ``user_id`` has system ``system_id`` open in a page (``app.services.curation.presence``).

    ``since`` is when the page opened it (kept by every refresh), ``expires_at`` when the claim lapses
    unless refreshed (UTC). A claim past ``expires_at`` counts as absent: readers filter on it, and the next
    claim written by anyone deletes the lapsed rows, so no cleanup job is needed. Written when a page opens a
    system and refreshed at most once per ``presence.REFRESH_AFTER``, never per heartbeat."""

    __tablename__ = "system_presence"

    system_id: Mapped[int] = mapped_column(sa.ForeignKey("systems.id", ondelete="CASCADE"), primary_key=True)
    user_id: Mapped[int] = mapped_column(sa.ForeignKey("users.id", ondelete="CASCADE"), primary_key=True)
    since: Mapped[datetime]
    expires_at: Mapped[datetime] = mapped_column(index=True)


class ApiToken(Base):
    """An API token of a user (``Authorization: Bearer <token>``). Only the SHA-256 of the token is
    stored (hex, 64 characters): the token itself is shown once, when it is issued. ``id`` names it in
    listings and revocations; ``label`` says what it is for. ``last_used_at`` is refreshed at most once a
    minute (``app.services.accounts.users.TOKEN_USE_RESOLUTION``). A token works until ``expires_at`` (None:
    no expiry) unless ``revoked_at`` is set (revoked alone, or with every token of a disabled user)."""

    __tablename__ = "api_tokens"

    id: Mapped[int] = mapped_column(primary_key=True)
    user_id: Mapped[int] = mapped_column(sa.ForeignKey("users.id", ondelete="CASCADE"), index=True)
    token_hash: Mapped[str] = mapped_column(sa.String(64), unique=True)
    created_at: Mapped[datetime] = mapped_column(default=utcnow)
    last_used_at: Mapped[Optional[datetime]]
    label: Mapped[Optional[str]] = mapped_column(sa.String(100))
    expires_at: Mapped[Optional[datetime]]
    revoked_at: Mapped[Optional[datetime]]

    user: Mapped[User] = relationship(back_populates="tokens")


class RateLimitCounter(Base):
    """One fixed-window counter of ``app.services.accounts.throttle`` (the storage of the ``limits`` library
    that every server process shares): ``key`` names the limit and who it counts (e.g. failed logins of one
    name from one address), ``hits`` what was counted in the window, which ends at ``expires_at`` (Unix
    seconds); an expired row counts as zero and is reused."""

    __tablename__ = "rate_limit_counters"

    key: Mapped[str] = mapped_column(sa.String(300), primary_key=True)
    hits: Mapped[int] = mapped_column(default=0)
    expires_at: Mapped[float] = mapped_column(sa.Float, index=True)


class ServerSecret(Base):
    """A secret of the server by name, generated once and shared by every worker and restart:
    ``session`` signs the browser's session cookies (``V3D_SESSION_SECRET`` overrides it)."""

    __tablename__ = "server_secrets"

    name: Mapped[str] = mapped_column(sa.String(40), primary_key=True)
    value: Mapped[str] = mapped_column(sa.Text)
    created_at: Mapped[datetime] = mapped_column(default=utcnow)


class AuditEntry(Base):
    """One accepted write (``app.services.audit.log``): who (``actor``, the user's name as text, so the log
    outlives users), when (``at``, UTC), what (``action``: ``ball.edit``, ``field_lines.replace``,
    ``field_lines.mirror``, ``view.exclusion``, ``view.review``, ``view.calibration_review``, ``system.review``, ``import``,
    ``recompute``, ``revert``) and the state of the edited part before and after (JSON; an import or a
    recompute stores its counts in ``after``). ``frame_id`` / ``system_id`` / ``game_id`` are plain indexed
    ids without foreign keys: deleting or re-importing data never deletes its history. Append-only: the
    migration adds triggers refusing UPDATE and DELETE.
    """

    __tablename__ = "audit_entries"

    id: Mapped[int] = mapped_column(primary_key=True)
    at: Mapped[datetime] = mapped_column(default=utcnow)
    actor: Mapped[str] = mapped_column(sa.String(200), index=True)
    action: Mapped[str] = mapped_column(sa.String(40))
    frame_id: Mapped[Optional[int]] = mapped_column(index=True)
    system_id: Mapped[Optional[int]] = mapped_column(index=True)
    game_id: Mapped[Optional[int]] = mapped_column(index=True)
    before: Mapped[Optional[dict[str, Any]]]
    after: Mapped[Optional[dict[str, Any]]]
    #: A revert: the entry it undid.
    reverts_id: Mapped[Optional[int]] = mapped_column(sa.ForeignKey("audit_entries.id"))
    #: The change in one line of words ("ball of V2 moved 12.3 px"; ``app.services.audit.summaries``),
    #: written with the entry; None for entries recorded before the column (computed when read).
    summary: Mapped[Optional[str]] = mapped_column(sa.String(300))

class Job(Base):
    """A background job (``app.services.jobs.runner``): an import, a full recompute or an export.

    ``params`` is what the job needs to run again from the start (a job interrupted by a killed process
    is resumed by running it again: imports are idempotent); ``stage``, ``done`` and ``total`` are its
    progress (``total`` 0: unknown); ``owner`` names the process running it (``host:pid:token``) and
    ``heartbeat_at`` when that process last showed it was alive; ``attempts`` counts claims (a claim is
    a compare-and-set on it). ``result`` is the job's report (an import's counts, an export's file).
    """

    __tablename__ = "jobs"
    __table_args__ = (sa.Index("ix_jobs_state_id", "state", "id"),)

    id: Mapped[int] = mapped_column(primary_key=True)
    kind: Mapped[str] = mapped_column(sa.String(20))
    params: Mapped[dict[str, Any]] = mapped_column(default=dict)
    state: Mapped[JobState] = mapped_column(enum_by_value(JobState, "job_state"), default=JobState.QUEUED)
    stage: Mapped[Optional[str]] = mapped_column(sa.String(40))
    done: Mapped[int] = mapped_column(default=0)
    total: Mapped[int] = mapped_column(default=0)
    message: Mapped[Optional[str]] = mapped_column(sa.Text)
    result: Mapped[Optional[dict[str, Any]]]
    owner: Mapped[Optional[str]] = mapped_column(sa.String(200))
    attempts: Mapped[int] = mapped_column(default=0)
    created_at: Mapped[datetime] = mapped_column(default=utcnow)
    started_at: Mapped[Optional[datetime]]
    finished_at: Mapped[Optional[datetime]]
    heartbeat_at: Mapped[Optional[datetime]]


class ReviewPass(Base):
    """A review pass (issue 28, ``app.services.curation.passes``): the frozen list of the systems of a review
    queue (``filters`` as ``app.services.curation.queue.SystemFilters`` fields, ``sort``) in its order as it
    stood when ``user_name`` began it, across all its pages; ``position`` is the index in ``system_ids`` of
    the system the user last opened. Statuses are not copied: they are read from the systems."""

    __tablename__ = "review_passes"
    __table_args__ = (sa.Index("ix_review_passes_user_name_id", "user_name", "id"),)

    id: Mapped[int] = mapped_column(primary_key=True)
    user_name: Mapped[str] = mapped_column(sa.String(200))
    filters: Mapped[dict[str, Any]] = mapped_column(default=dict)
    sort: Mapped[str] = mapped_column(sa.String(20))
    system_ids: Mapped[list[Any]] = mapped_column(default=list)
    position: Mapped[int] = mapped_column(default=0)
    created_at: Mapped[datetime] = mapped_column(default=utcnow)
    visited_at: Mapped[datetime] = mapped_column(default=utcnow)
