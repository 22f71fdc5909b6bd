"""Broadcast camera rig of the demo game: where the cameras stand and how they frame the ball.

World frame: SoccerNet, metres, origin at the centre spot, x along the length (x = +52.5 is the right
goal line), y along the width (y = +34 is "Side line bottom", the main camera's side), z points
down (a camera 20 m up has z = -20).

A game's cameras stay where they are (method.md section 3): every view of the demo is taken from
one of the fixed positions of :data:`RIG`, except the deliberate near-duplicate viewpoint, which
stands less than a metre from the main camera. Per view, only the aim and the zoom change.
"""
from __future__ import annotations

from dataclasses import dataclass
from types import MappingProxyType
from typing import Mapping

import numpy as np

from app.geometry.camera import Camera, look_at_rotation


@dataclass(frozen=True)
class RigCamera:
    """A fixed camera position of the demo game.

    Attributes:
        name: rig key (``"main"``, ``"behind_goal_right_high"``, ...).
        description: what a broadcast director would call it.
        position_m: (3,) camera centre, world frame, metres (z < 0 above the ground).
        framing_m: (min, max) horizontal extent of the scene (metres, measured at the ball's
            distance) that the operator frames; the zoom of a view is drawn in this range.
        roll_deg: small constant roll of the head (SoccerNet ``roll_degrees``).
    """

    name: str
    description: str
    position_m: tuple[float, float, float]
    framing_m: tuple[float, float]
    roll_deg: float = 0.0


def _rig(*cams: RigCamera) -> Mapping[str, RigCamera]:
    return MappingProxyType({c.name: c for c in cams})


#: The demo game's camera positions. The main camera is on the y > 0 side, 20 m up and 45 m back
#: from the touch line (y = 34); replay cameras stand behind both goals (high and low), on the
#: opposite side, level with the 18-yard lines on both sides, and pitch-side.
RIG: Mapping[str, RigCamera] = _rig(
    RigCamera("main", "main camera, halfway line, main stand", (-1.5, 79.0, -20.0), (46.0, 62.0), -0.2),
    RigCamera("behind_goal_left_high", "high behind the left goal", (-71.0, -2.5, -15.0), (30.0, 42.0), 0.3),
    RigCamera("behind_goal_right_high", "high behind the right goal", (70.0, 3.0, -14.0), (30.0, 42.0), -0.4),
    RigCamera("behind_goal_right_low", "low behind the right goal", (57.5, 6.0, -2.2), (22.0, 30.0), 0.5),
    RigCamera("behind_goal_left_low", "low behind the left goal", (-57.5, -5.0, -2.4), (22.0, 30.0), -0.3),
    RigCamera("opposite_centre", "opposite side, halfway line", (2.0, -46.0, -11.0), (36.0, 48.0), 0.2),
    RigCamera("opposite_18_left", "opposite side, left 18-yard line", (-36.5, -43.0, -8.0), (26.0, 36.0), -0.2),
    RigCamera("opposite_18_right", "opposite side, right 18-yard line", (36.0, -42.5, -7.5), (26.0, 36.0), 0.3),
    RigCamera("same_18_left", "main side, left 18-yard line", (-36.0, 41.0, -9.0), (26.0, 36.0), 0.1),
    RigCamera("same_18_right", "main side, right 18-yard line", (36.5, 40.5, -8.5), (26.0, 36.0), -0.1),
    RigCamera("pitchside_left", "pitch-side, main side, left half", (-22.0, 37.0, -1.7), (20.0, 28.0), 0.6),
    RigCamera("pitchside_right", "pitch-side, main side, right half", (24.0, 37.0, -1.7), (20.0, 28.0), -0.5),
)

#: Offset (metres) of the near-duplicate viewpoint from the main camera: a second camera on the
#: same platform, well under the 1 m baseline that triangulation requires.
NEAR_DUPLICATE_OFFSET_M: tuple[float, float, float] = (0.45, -0.3, 0.25)




def framing_camera(position: np.ndarray, target: np.ndarray, framing_m: float, width: int, height: int,
                   roll_deg: float = 0.0) -> Camera:
    """Undistorted camera at ``position`` aimed at ``target`` whose image spans ``framing_m`` metres
    horizontally at the target's distance.

    The focal length is ``f = W * distance / framing_m`` pixels (square pixels) and the principal
    point is the image centre ``(W / 2, H / 2)`` (continuous pixel coordinates).

    Args:
        position: (3,) camera centre, world metres.
        target: (3,) aimed world point, metres.
        framing_m: horizontal extent of the view at the target, metres.
        width, height: image size, pixels.
        roll_deg: roll about the optical axis, degrees.

    >>> cam = framing_camera(np.array([0.0, 60.0, -20.0]), np.array([0.0, 0.0, 0.0]), 40.0, 960, 540)
    >>> uv, _ = cam.project(np.array([[0.0, 0.0, 0.0]]))
    >>> np.round(uv, 6).tolist()
    [[480.0, 270.0]]
    """
    if framing_m <= 0:
        raise ValueError(f"framing_m must be positive, got {framing_m}")
    c, t = np.asarray(position, float).reshape(3), np.asarray(target, float).reshape(3)
    f = width * float(np.linalg.norm(t - c)) / framing_m
    K = np.array([[f, 0.0, width / 2.0], [0.0, f, height / 2.0], [0.0, 0.0, 1.0]])
    return Camera(K=K, R=look_at_rotation(c, t, roll_deg), C=c)
