"""Pydantic responses of the ISSIA-3D routes (``app.api.routes.issia``); world metres, z down."""
from __future__ import annotations

from typing import Literal, Optional

from pydantic import BaseModel, Field

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
    status: str = Field(description="The system's review status.")


class TrajectoryOut(BaseModel):
    """A sequence's trajectory over time (``app.services.issia_export.trajectory_view``)."""

    game_id: int
    game: str
    fps: float
    cameras: list[str]
    camera_set: dict[str, str] = Field(description="View name -> 'train' or 'test' (the paper's split by camera).")
    pieces: list[TrajectoryPieceOut]
    frames: list[TrajectoryFrameOut]
