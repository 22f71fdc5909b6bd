"""What the recomputation derives from the labels: a frame's calibration, the system's triangulation and its
pairs, each view's reprojected ball and optimised box, the doubts.

Units: pixels of the frame's own image, world metres in SoccerNet's frame (z down).
"""
from __future__ import annotations

from datetime import datetime
from typing import TYPE_CHECKING, Any, Optional

import sqlalchemy as sa
from sqlalchemy.orm import Mapped, mapped_column, relationship

from app.db.models.base import JAC_COLUMNS, Base
from app.db.models.enums import CalibrationSource, CalibrationStatus, TriangulationStatus
from app.db.types import enum_by_value, utcnow

if TYPE_CHECKING:  # the relationships name these; the registry resolves them at run time
    from app.db.models.labels import Frame, System


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
    #: A camera the players placed (flag ``"player_assisted"``, ``app.services.calibration.players``): the players'
    #: foot points it was fitted to (``feet``: class, ID, pixel, where the player stands in metres), the rig position
    #: its centre was fixed at (``rig``: index and centre, None for a full pose), its residual and pixel uncertainty;
    #: None for a camera from lines alone.
    players: Mapped[Optional[dict[str, Any]]] = mapped_column(default=None)
    updated_at: Mapped[datetime] = mapped_column(default=utcnow, onupdate=utcnow)

    frame: Mapped[Frame] = relationship(back_populates="calibration")

    def jac(self) -> dict[str, Optional[float]]:
        """JaC per gamma of :data:`JAC_COLUMNS`, keyed by the gamma as text in increasing order
        (``{"0.005": .., "0.01": .., "0.02": ..}``: the keys of the API and of exports)."""
        return {f"{g:g}": getattr(self, column) for g, column in JAC_COLUMNS.items()}


class Triangulation(Base):
    """The fused 3D ball of a system (method.md section 5) and the settings it was made with."""

    __tablename__ = "triangulations"

    system_id: Mapped[int] = mapped_column(sa.ForeignKey("systems.id", ondelete="CASCADE"), primary_key=True)
    status: Mapped[TriangulationStatus] = mapped_column(enum_by_value(TriangulationStatus, "triangulation_status"))
    #: World metres ``[x, y, z]`` (z down), or None when not triangulated.
    ball3d: Mapped[Optional[list[float]]]
    #: The ball's sigma, metres along its least certain direction (``app.geometry.evidence.kept_pairs_sigma_m``), or
    #: None without a ball (or where its views fix no point).
    sigma_m: Mapped[Optional[float]] = mapped_column(default=None)
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
    #: How far the view's ball label lies from the ball the system's other views agree on (px of a 1920-wide image;
    #: ``app.geometry.doubts.judge.consensus_without``), None without a label, a camera or an agreed ball: stored by
    #: the recomputation so that the per-annotator figures read it (``app.services.evaluation.annotators``).
    others_distance_px: Mapped[Optional[float]]

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
