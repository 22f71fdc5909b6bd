"""What a dataset brings: games, multi-view systems, frames and their labels (field lines, ball label), and
an ISSIA frame's place on its sequence's trajectory.

Units: pixels of the frame's own image (origin top-left), world metres in SoccerNet's frame (z down).
"""
from __future__ import annotations

from datetime import datetime
from typing import TYPE_CHECKING, Any, Optional

import sqlalchemy as sa
from sqlalchemy.orm import Mapped, mapped_column, relationship

from app.db.models.base import Base
from app.db.models.enums import BallEvidence, BallKind, FrameRole, ReviewStatus, SystemKind
from app.db.types import enum_by_value, utcnow

if TYPE_CHECKING:  # the relationships name these; the registry resolves them at run time
    from app.db.models.derived import BallReprojection, Calibration, Doubt, OptimisedBox, Triangulation
    from app.db.models.predictions import Prediction
    from app.db.models.review import ReviewDecision


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
    #: A calibration dataset's learned camera prior (``CameraPrior.to_json``): learned by its import
    #: from its own confident fits, used by every later recalibration of its frames; None when none was learned.
    camera_prior: Mapped[Optional[dict[str, Any]]] = mapped_column(default=None)
    #: Bumped in the same transaction by every change of what an edit of one of the game's systems reads beyond
    #: that system: a calibration that makes the game's camera rig (``apply_calibration``) or the camera prior.
    #: An edit that read the rig compares it under its lock (``app.services.curation.writing``).
    version: Mapped[int] = mapped_column(default=1, server_default="1")
    #: The time of the newest change of the game a SoccerNet-v3D export it was imported from held
    #: (``GameMetadata.v3d_as_of``), when later than the changes of its own; None when it came from no such file.
    #: Its exports say it again (``app.services.transfer.exporting``): a database that imported the file holds
    #: the game as of then.
    as_of: Mapped[Optional[datetime]]

    systems: Mapped[list[System]] = relationship(
        back_populates="game", cascade="all, delete-orphan", passive_deletes=True, order_by="System.id"
    )

    @property
    def path(self) -> str:
        """``league/season/match``: the game's folder in SoccerNet trees and its key in exports."""
        return f"{self.league}/{self.season}/{self.match}"


#: The review statuses that are work still to do: nobody decided yet, or the annotator a needs-fix went to says it is
#: fixed. The review queue's default order puts them first (``app.services.curation.queue``).
TO_REVIEW: tuple[ReviewStatus, ...] = (ReviewStatus.PENDING, ReviewStatus.FIXED)
#: SQL: 0 for a system of :data:`TO_REVIEW`, 1 for a decided one, the statuses written as literals: the first key
#: of the queue's default order, and of its index, which a query uses only when it writes the same expression
#: (a bound parameter in its place would not match the index's literal on either engine). Written line by line as
#: PostgreSQL prints it back, so that ``alembic check`` finds the index it reflects equal to this one.
REVIEW_ORDER_SQL = "\n".join(["CASE review_status", *(f"WHEN '{s.value}' THEN 0" for s in TO_REVIEW), "ELSE 1", "END"])


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
        # the default order within a review status, the id included: the pending queue's page is a seek
        sa.Index("ix_systems_review_status_severity_error_doubts_id", "review_status", "label_severity",
                 "worst_error_px", "label_doubts", "id"),
        sa.Index("ix_systems_review_status_lowest_jac", "review_status", "lowest_jac"),
        # the queue's ``ball_evidence=`` filter and sort within a review status (the pending vouched systems a batch
        # of accepted-after-a-sample draws from) as an index seek
        sa.Index("ix_systems_review_status_ball_evidence", "review_status", "ball_evidence"),
        # keyset pages of the queue (app.services.curation.queue._slices, migration 0013): the numeric name
        # order within a game as an index walk
        sa.Index("ix_systems_game_id_name_length_name", "game_id", sa.text("length(name)"), "name"),
        # the queue's default order (work to do first, then severity, error, doubts; the id last for PostgreSQL,
        # whose indexes do not end with it as SQLite's do): a page and a system's neighbours are seeks in it
        sa.Index("ix_systems_review_order_severity", sa.text(f"(\n{REVIEW_ORDER_SQL})"), "label_severity",
                 "worst_error_px", "label_doubts", "id"),
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
    #: The largest ``app.geometry.doubts.LABEL_KIND_SEVERITY`` of its doubts (0 without a label doubt), written with
    #: them: the queue's default order reads it from the row instead of aggregating every system's doubts per page.
    label_severity: Mapped[int] = mapped_column(default=0, server_default="0")
    #: What backs the system's 3D ball (``app.geometry.ball_evidence.ball_evidence``): vouched, unconfirmed, doubted,
    #: or none without a ball; written with the ball and its doubts, so that the queue filters and sorts by it.
    ball_evidence: Mapped[BallEvidence] = mapped_column(
        enum_by_value(BallEvidence, "system_ball_evidence"), default=BallEvidence.NONE, server_default="none")
    #: Why it is in its tier, as short phrases a reviewer reads ("three views agree", "only two views: nothing else
    #: checks it"); empty without a ball.
    ball_evidence_reasons: Mapped[list[str]] = mapped_column(default=list, server_default="[]")
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
    #: (``app.geometry.pair_error.error_above_tau``).
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
    #: The system's version (its strong ETag, ``app.services.curation.versions``): bumped in the same transaction by
    #: every write of the rows an edit of the system reads (``app.db.scope``: labels, lines,
    #: exclusions, calibrations, decisions, derived rows). SQLAlchemy's version counter: every ORM ``UPDATE`` of the
    #: row compares it (``WHERE version = <as loaded>``; ``StaleDataError`` when another transaction changed it),
    #: which is the edit path's optimistic concurrency check.
    version: Mapped[int] = mapped_column(default=1)
    #: ISSIA systems: the frame's place on the sequence's trajectory (``app.services.issia.sequences``).
    trajectory_point: Mapped[Optional[TrajectoryPoint]] = relationship(
        back_populates="system", cascade="all, delete-orphan", passive_deletes=True
    )
    # ----- work assignment (``app.services.curation.assignment``): who should review the system.
    #: The id of the user the system is assigned to (None: nobody). A plain indexed id, as the audit log's: a
    #: foreign key would need SQLite to rebuild ``systems`` (migration 0020); users are disabled, never deleted.
    assignee_id: Mapped[Optional[int]] = mapped_column(index=True)
    #: When it was last assigned (or unassigned), UTC; None when never.
    assigned_at: Mapped[Optional[datetime]]
    #: Who assigned it (the audit log's actor name, so that it outlives the user); None when never.
    assigned_by: Mapped[Optional[str]] = mapped_column(sa.String(200))

    # the application bumps the version itself (``scope.changed``), only for writes of what an edit reads: an
    # assignment leaves it as it is, yet every ORM UPDATE of the row still compares it
    __mapper_args__ = {"version_id_col": version, "version_id_generator": False}


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
    #: A ball detector's predictions on this view (read only here: written and removed by source,
    #: ``app.services.transfer.predictions``; the doubts check them). Loaded only by
    #: ``app.services.derivation.loading``, which takes at most ``V3D_MAX_PREDICTIONS_PER_FRAME`` of them, the best:
    #: a lazy load would take them all, so it raises instead.
    predictions: Mapped[list[Prediction]] = relationship(viewonly=True, order_by="Prediction.id", lazy="raise_on_sql")
    #: The players its dataset boxed (class and ID across the views of the system), as imported.
    players: Mapped[list[PlayerBox]] = relationship(
        back_populates="frame", cascade="all, delete-orphan", passive_deletes=True, order_by="PlayerBox.id"
    )

    # the frame's version is SQLAlchemy's version counter too (bumped by the guarded write): a view decision changes
    # the frame alone (not its system's version, which a system decision's If-Match compares), so an edit of the
    # same view written meanwhile is caught by this compare (``WHERE edit_version = <as read>``)
    __mapper_args__ = {"version_id_col": edit_version, "version_id_generator": False}


class PlayerBox(Base):
    """A person a dataset boxed in a frame besides the ball (SoccerNet-v3 ``bboxes``: a player, a goalkeeper, a
    referee), with its class and ID, which name the same person across the views of a system. Written by the import
    as they came (the release keeps the file's ``bboxes`` themselves, ``Frame.release``); read by the calibration of
    the views the lines cannot calibrate (``app.services.calibration.players``) and, on views with predictions, by the
    detector's check (a lone ray's box on a head or feet, ``app.geometry.doubts.pairings._told_from_players``). Box
    ``x1, y1, x2, y2`` in pixels of the frame's image; ``ident`` None when the file gave no ID."""

    __tablename__ = "player_boxes"
    __table_args__ = (sa.Index("ix_player_boxes_frame_id", "frame_id"),)

    id: Mapped[int] = mapped_column(primary_key=True)
    frame_id: Mapped[int] = mapped_column(sa.ForeignKey("frames.id", ondelete="CASCADE"))
    cls: Mapped[str] = mapped_column(sa.String(200))
    ident: Mapped[Optional[str]] = mapped_column(sa.String(200))
    x1: Mapped[float]
    y1: Mapped[float]
    x2: Mapped[float]
    y2: Mapped[float]

    frame: Mapped[Frame] = relationship(back_populates="players")


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
