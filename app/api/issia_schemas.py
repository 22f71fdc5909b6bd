"""Pydantic responses of the ISSIA-3D routes (``app.api.routes.issia``); world metres, z down."""
from __future__ import annotations

from typing import Literal, Optional

from pydantic import BaseModel, Field

from app.db.models import ReviewStatus, System
from app.services.issia.export import SequenceData
from app.services.issia.trajectory import FPS

Point3 = tuple[float, float, float]


class TrajectoryPieceOut(BaseModel):
    """A stretch of frames under one motion model (``app.geometry.trajectory.Piece``)."""

    kind: Literal["flight", "roll"]
    first_frame: int
    last_frame: int


class TrajectoryFrameOut(BaseModel):
    """One frame of the sequence: its system, the observed and the fitted 3D ball."""

    frame_index: int
    system_id: int
    ball3d: Optional[Point3] = Field(None, description="The frame's own triangulation (ISSIA-3D ball_3D), m.")
    ball3d_smoothed: Optional[Point3] = Field(None, description="The trajectory's position (ball_3D_smoothed), m.")
    source: Optional[Literal["triangulated", "fitted", "interpolated"]] = None
    cam_list: list[str] = Field(description="Views whose labels the frame keeps.")
    flagged: list[str] = Field(description="Views whose labels break the trajectory (ball_off_consensus doubts).")
    label_doubts: int
    status: ReviewStatus = Field(description="The system's review status.")

    @classmethod
    def of(cls, system: System) -> "TrajectoryFrameOut":
        """One frame's system (frames, review and trajectory point loaded); views named by image name."""
        tp = system.trajectory_point
        by_id = {f.id: f.name for f in system.frames}
        return cls(frame_index=system.frame_index, system_id=system.id,
                   ball3d=tp.ball3d if tp else None, ball3d_smoothed=tp.ball3d_smoothed if tp else None,
                   source=tp.source if tp else None,
                   cam_list=[by_id[i] for i in (tp.cam_list if tp else []) if i in by_id],
                   flagged=[by_id[i] for i in (tp.flagged if tp else []) if i in by_id],
                   label_doubts=system.label_doubts,
                   status=system.review.status if system.review is not None else ReviewStatus.PENDING)


class TrajectoryOut(BaseModel):
    """A sequence's trajectory over time (``app.services.issia.export.sequence_data``), world metres, z down."""

    game_id: int
    game: str
    fps: float
    cameras: list[str]
    camera_set: dict[str, str] = Field(description="View name -> 'train' or 'test' (the paper's split by camera).")
    pieces: list[TrajectoryPieceOut]
    frames: list[TrajectoryFrameOut]

    @classmethod
    def of(cls, seq: SequenceData) -> "TrajectoryOut":
        """The trajectory of a stored sequence: its frames in order and its motion pieces (each once)."""
        pieces: dict[tuple[int, int], TrajectoryPieceOut] = {}
        for s in seq.systems:
            piece = s.trajectory_point.piece if s.trajectory_point is not None else None
            if piece:
                pieces.setdefault((piece["first_frame"], piece["last_frame"]), TrajectoryPieceOut.model_validate(piece))
        return cls(game_id=seq.game.id, game=seq.game.path, fps=FPS, cameras=seq.cameras, camera_set=seq.camera_set,
                   pieces=sorted(pieces.values(), key=lambda p: p.first_frame),
                   frames=[TrajectoryFrameOut.of(s) for s in seq.systems])
