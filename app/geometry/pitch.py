"""SoccerNet pitch model: line classes, mirror map, key points and 3D polylines.

World frame (SoccerNet): metres, origin at the centre spot, x along the length (x = +52.5 is the
right goal line), y along the width (y = -34 is "Side line top"), z points down (the crossbar is at
z = -2.44). Dimensions and class names follow SoccerNet's ``src/soccerpitch.py``
(repository SoccerNet/sn-calibration); the sampling in :func:`sample_pitch_polylines` reproduces its
``sample_field_points`` point for point, which the official JaC depends on.
"""
from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property, lru_cache
from types import MappingProxyType
from typing import Mapping

import numpy as np

PITCH_LENGTH_M = 105.0
PITCH_WIDTH_M = 68.0
GOAL_LINE_TO_PENALTY_MARK_M = 11.0
PENALTY_AREA_WIDTH_M = 40.32
PENALTY_AREA_LENGTH_M = 16.5
GOAL_AREA_WIDTH_M = 18.32
GOAL_AREA_LENGTH_M = 5.5
CENTER_CIRCLE_RADIUS_M = 9.15
GOAL_HEIGHT_M = 2.44
GOAL_LENGTH_M = 7.32
#: phi, the diameter of a size-5 ball (FIFA Laws of the Game, law 2: 68-70 cm round), metres; the paper's 0.22 m.
BALL_DIAMETER_M = 0.22
#: A view with fewer distinct field-line classes is few-lined: its camera may fit its own lines perfectly (JaC 1.0)
#: yet turn its ball ray by degrees. The calibration flags it ``few_lines``; the doubts take it out of their checks
#: (``V3D_DOUBT_MIN_LINE_CLASSES`` defaults to it).
MIN_LINE_CLASSES = 4

#: Every class a SoccerNet field-line annotation may carry (note the trailing space of
#: "Goal left post left "). "Goal unknown" and "Line unknown" are valid labels with no model element.
LINE_CLASSES: tuple[str, ...] = (
    "Big rect. left bottom", "Big rect. left main", "Big rect. left top",
    "Big rect. right bottom", "Big rect. right main", "Big rect. right top",
    "Circle central", "Circle left", "Circle right",
    "Goal left crossbar", "Goal left post left ", "Goal left post right",
    "Goal right crossbar", "Goal right post left", "Goal right post right",
    "Goal unknown", "Line unknown",
    "Middle line",
    "Side line bottom", "Side line left", "Side line right", "Side line top",
    "Small rect. left bottom", "Small rect. left main", "Small rect. left top",
    "Small rect. right bottom", "Small rect. right main", "Small rect. right top",
)

#: Classes without a pitch-model element (kept in annotations, ignored by geometry).
UNKNOWN_CLASSES: frozenset[str] = frozenset({"Goal unknown", "Line unknown"})

#: The 180-degree rotation of the pitch about the vertical axis through the centre spot, as a
#: relabelling (SoccerNet's ``symetric_classes``): left <-> right and top <-> bottom.
MIRROR_CLASSES: Mapping[str, str] = MappingProxyType({
    "Side line top": "Side line bottom", "Side line bottom": "Side line top",
    "Side line left": "Side line right", "Side line right": "Side line left",
    "Middle line": "Middle line",
    "Big rect. left top": "Big rect. right bottom", "Big rect. left bottom": "Big rect. right top",
    "Big rect. left main": "Big rect. right main",
    "Big rect. right top": "Big rect. left bottom", "Big rect. right bottom": "Big rect. left top",
    "Big rect. right main": "Big rect. left main",
    "Small rect. left top": "Small rect. right bottom", "Small rect. left bottom": "Small rect. right top",
    "Small rect. left main": "Small rect. right main",
    "Small rect. right top": "Small rect. left bottom", "Small rect. right bottom": "Small rect. left top",
    "Small rect. right main": "Small rect. left main",
    "Circle left": "Circle right", "Circle central": "Circle central", "Circle right": "Circle left",
    "Goal left crossbar": "Goal right crossbar",
    # Posts: left post left (y = +3.66) turns into right post left (y = -3.66), as in the official
    # evaluator's ``symetric_classes`` (PyPI SoccerNet, ``utils_calibration.py``) and method.md s3.
    "Goal left post left ": "Goal right post left", "Goal left post right": "Goal right post right",
    "Goal right crossbar": "Goal left crossbar",
    "Goal right post left": "Goal left post left ", "Goal right post right": "Goal left post right",
    "Goal unknown": "Goal unknown", "Line unknown": "Line unknown",
})


@dataclass(frozen=True)
class PlayVolume:
    """The volume a ball in a game can occupy: the pitch with ``margin_m`` beyond the touch and goal lines, from
    ``max_height_m`` above the grass to ``max_below_m`` below it (a ball centre under the grass is triangulation
    noise). Metres, SoccerNet world (origin at the centre spot, z down)."""

    margin_m: float
    max_height_m: float
    max_below_m: float

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """``(lo, hi)``: the volume's corners, (3,) world metres each (z of ``lo`` is the highest ball); computed
        once per volume (the trajectory's plausibility asks for them at every candidate piece), read-only."""
        return self._corners

    @cached_property
    def _corners(self) -> tuple[np.ndarray, np.ndarray]:
        x, y = PITCH_LENGTH_M / 2 + self.margin_m, PITCH_WIDTH_M / 2 + self.margin_m
        lo, hi = np.array([-x, -y, -self.max_height_m]), np.array([x, y, self.max_below_m])
        lo.flags.writeable = hi.flags.writeable = False
        return lo, hi


#: The one play volume: the triangulation drops a pair whose point lies outside it, the mirror evidence
#: and the doubts count no agreement outside it, the ISSIA trajectory fits no piece that leaves it. Chosen by
#: measurement among the three it replaced (benchmarks/DOUBTS.md, "One play volume").
PLAY_VOLUME = PlayVolume(margin_m=15.0, max_height_m=40.0, max_below_m=0.5)


def within_play_volume(points_m: np.ndarray, volume: PlayVolume = PLAY_VOLUME) -> np.ndarray:
    """Which ball positions a game could hold: inside ``volume`` (:data:`PLAY_VOLUME` unless given).

    Args:
        points_m: (N, 3) or (3,) world points, metres (SoccerNet: origin at the centre spot, z down).

    Returns:
        (N,) bool.
    """
    p = np.asarray(points_m, float).reshape(-1, 3)
    lo, hi = volume.bounds()
    return np.all((p >= lo) & (p <= hi), axis=1)


def distance_to_play_volume(point_m: np.ndarray, volume: PlayVolume = PLAY_VOLUME) -> float:
    """How far (metres) the world point ``point_m`` ((3,), SoccerNet: origin at the centre spot, z down) lies from
    ``volume`` (:data:`PLAY_VOLUME` unless given): 0 inside, else the distance to its nearest point."""
    p = np.asarray(point_m, float).reshape(3)
    lo, hi = volume.bounds()
    return float(np.linalg.norm(p - np.clip(p, lo, hi)))


def _key_points() -> dict[str, np.ndarray]:
    half_l, half_w = PITCH_LENGTH_M / 2.0, PITCH_WIDTH_M / 2.0
    pa_x = half_l - PENALTY_AREA_LENGTH_M
    ga_x = half_l - GOAL_AREA_LENGTH_M
    arc_dx = PENALTY_AREA_LENGTH_M - GOAL_LINE_TO_PENALTY_MARK_M
    arc_y = float(np.sqrt(CENTER_CIRCLE_RADIUS_M**2 - arc_dx**2))
    g, h = GOAL_LENGTH_M / 2.0, -GOAL_HEIGHT_M
    p = {
        "CENTER_MARK": (0.0, 0.0, 0.0),
        "L_PENALTY_MARK": (-half_l + GOAL_LINE_TO_PENALTY_MARK_M, 0.0, 0.0),
        "R_PENALTY_MARK": (half_l - GOAL_LINE_TO_PENALTY_MARK_M, 0.0, 0.0),
        "TL_PITCH_CORNER": (-half_l, -half_w, 0.0),
        "BL_PITCH_CORNER": (-half_l, half_w, 0.0),
        "TR_PITCH_CORNER": (half_l, -half_w, 0.0),
        "BR_PITCH_CORNER": (half_l, half_w, 0.0),
        "L_PENALTY_AREA_TL_CORNER": (-half_l, -PENALTY_AREA_WIDTH_M / 2, 0.0),
        "L_PENALTY_AREA_TR_CORNER": (-pa_x, -PENALTY_AREA_WIDTH_M / 2, 0.0),
        "L_PENALTY_AREA_BL_CORNER": (-half_l, PENALTY_AREA_WIDTH_M / 2, 0.0),
        "L_PENALTY_AREA_BR_CORNER": (-pa_x, PENALTY_AREA_WIDTH_M / 2, 0.0),
        "R_PENALTY_AREA_TL_CORNER": (pa_x, -PENALTY_AREA_WIDTH_M / 2, 0.0),
        "R_PENALTY_AREA_TR_CORNER": (half_l, -PENALTY_AREA_WIDTH_M / 2, 0.0),
        "R_PENALTY_AREA_BL_CORNER": (pa_x, PENALTY_AREA_WIDTH_M / 2, 0.0),
        "R_PENALTY_AREA_BR_CORNER": (half_l, PENALTY_AREA_WIDTH_M / 2, 0.0),
        "L_GOAL_AREA_TL_CORNER": (-half_l, -GOAL_AREA_WIDTH_M / 2, 0.0),
        "L_GOAL_AREA_TR_CORNER": (-ga_x, -GOAL_AREA_WIDTH_M / 2, 0.0),
        "L_GOAL_AREA_BL_CORNER": (-half_l, GOAL_AREA_WIDTH_M / 2, 0.0),
        "L_GOAL_AREA_BR_CORNER": (-ga_x, GOAL_AREA_WIDTH_M / 2, 0.0),
        "R_GOAL_AREA_TL_CORNER": (ga_x, -GOAL_AREA_WIDTH_M / 2, 0.0),
        "R_GOAL_AREA_TR_CORNER": (half_l, -GOAL_AREA_WIDTH_M / 2, 0.0),
        "R_GOAL_AREA_BL_CORNER": (ga_x, GOAL_AREA_WIDTH_M / 2, 0.0),
        "R_GOAL_AREA_BR_CORNER": (half_l, GOAL_AREA_WIDTH_M / 2, 0.0),
        # Posts, named as SoccerNet does (its "left"/"right" post naming differs per goal).
        "L_GOAL_TL_POST": (-half_l, g, h),
        "L_GOAL_TR_POST": (-half_l, -g, h),
        "L_GOAL_BL_POST": (-half_l, g, 0.0),
        "L_GOAL_BR_POST": (-half_l, -g, 0.0),
        "R_GOAL_TL_POST": (half_l, -g, h),
        "R_GOAL_TR_POST": (half_l, g, h),
        "R_GOAL_BL_POST": (half_l, -g, 0.0),
        "R_GOAL_BR_POST": (half_l, g, 0.0),
        "T_TOUCH_AND_HALFWAY_LINES_INTERSECTION": (0.0, -half_w, 0.0),
        "B_TOUCH_AND_HALFWAY_LINES_INTERSECTION": (0.0, half_w, 0.0),
        "T_HALFWAY_LINE_AND_CENTER_CIRCLE_INTERSECTION": (0.0, -CENTER_CIRCLE_RADIUS_M, 0.0),
        "B_HALFWAY_LINE_AND_CENTER_CIRCLE_INTERSECTION": (0.0, CENTER_CIRCLE_RADIUS_M, 0.0),
        "TL_16M_LINE_AND_PENALTY_ARC_INTERSECTION": (-pa_x, -arc_y, 0.0),
        "BL_16M_LINE_AND_PENALTY_ARC_INTERSECTION": (-pa_x, arc_y, 0.0),
        "TR_16M_LINE_AND_PENALTY_ARC_INTERSECTION": (pa_x, -arc_y, 0.0),
        "BR_16M_LINE_AND_PENALTY_ARC_INTERSECTION": (pa_x, arc_y, 0.0),
    }
    return {k: np.array(v, dtype=float) for k, v in p.items()}


#: Named 3D key points of the pitch (world frame, metres), read-only.
KEY_POINTS: Mapping[str, np.ndarray] = MappingProxyType(_key_points())
for _v in KEY_POINTS.values():
    _v.setflags(write=False)

#: Straight elements: class -> (name of start key point, name of end key point), in SoccerNet's
#: order (the order fixes the sampling). The two penalty arcs appear here with their end points.
LINE_EXTREMITY_KEYS: Mapping[str, tuple[str, str]] = MappingProxyType({
    "Big rect. left bottom": ("L_PENALTY_AREA_BL_CORNER", "L_PENALTY_AREA_BR_CORNER"),
    "Big rect. left top": ("L_PENALTY_AREA_TL_CORNER", "L_PENALTY_AREA_TR_CORNER"),
    "Big rect. left main": ("L_PENALTY_AREA_TR_CORNER", "L_PENALTY_AREA_BR_CORNER"),
    "Big rect. right bottom": ("R_PENALTY_AREA_BL_CORNER", "R_PENALTY_AREA_BR_CORNER"),
    "Big rect. right top": ("R_PENALTY_AREA_TL_CORNER", "R_PENALTY_AREA_TR_CORNER"),
    "Big rect. right main": ("R_PENALTY_AREA_TL_CORNER", "R_PENALTY_AREA_BL_CORNER"),
    "Small rect. left bottom": ("L_GOAL_AREA_BL_CORNER", "L_GOAL_AREA_BR_CORNER"),
    "Small rect. left top": ("L_GOAL_AREA_TL_CORNER", "L_GOAL_AREA_TR_CORNER"),
    "Small rect. left main": ("L_GOAL_AREA_TR_CORNER", "L_GOAL_AREA_BR_CORNER"),
    "Small rect. right bottom": ("R_GOAL_AREA_BL_CORNER", "R_GOAL_AREA_BR_CORNER"),
    "Small rect. right top": ("R_GOAL_AREA_TL_CORNER", "R_GOAL_AREA_TR_CORNER"),
    "Small rect. right main": ("R_GOAL_AREA_TL_CORNER", "R_GOAL_AREA_BL_CORNER"),
    "Side line top": ("TL_PITCH_CORNER", "TR_PITCH_CORNER"),
    "Side line bottom": ("BL_PITCH_CORNER", "BR_PITCH_CORNER"),
    "Side line left": ("TL_PITCH_CORNER", "BL_PITCH_CORNER"),
    "Side line right": ("TR_PITCH_CORNER", "BR_PITCH_CORNER"),
    "Middle line": ("T_TOUCH_AND_HALFWAY_LINES_INTERSECTION", "B_TOUCH_AND_HALFWAY_LINES_INTERSECTION"),
    "Goal left crossbar": ("L_GOAL_TR_POST", "L_GOAL_TL_POST"),
    "Goal left post left ": ("L_GOAL_TL_POST", "L_GOAL_BL_POST"),
    "Goal left post right": ("L_GOAL_TR_POST", "L_GOAL_BR_POST"),
    "Goal right crossbar": ("R_GOAL_TL_POST", "R_GOAL_TR_POST"),
    "Goal right post left": ("R_GOAL_TL_POST", "R_GOAL_BL_POST"),
    "Goal right post right": ("R_GOAL_TR_POST", "R_GOAL_BR_POST"),
    "Circle right": ("TR_16M_LINE_AND_PENALTY_ARC_INTERSECTION", "BR_16M_LINE_AND_PENALTY_ARC_INTERSECTION"),
    "Circle left": ("TL_16M_LINE_AND_PENALTY_ARC_INTERSECTION", "BL_16M_LINE_AND_PENALTY_ARC_INTERSECTION"),
})

#: Circular elements: class -> (centre (3,), radius m). Arcs are limited as in
#: :func:`circle_arc_angles`.
CIRCLES: Mapping[str, tuple[np.ndarray, float]] = MappingProxyType({
    "Circle central": (KEY_POINTS["CENTER_MARK"], CENTER_CIRCLE_RADIUS_M),
    "Circle left": (KEY_POINTS["L_PENALTY_MARK"], CENTER_CIRCLE_RADIUS_M),
    "Circle right": (KEY_POINTS["R_PENALTY_MARK"], CENTER_CIRCLE_RADIUS_M),
})

#: Classes whose element lies off the ground plane (goal frames, z < 0 in the world frame).
GOAL_CLASSES: frozenset[str] = frozenset(c for c in LINE_CLASSES if c.startswith("Goal ") and c not in UNKNOWN_CLASSES)

#: Classes with a model element (everything but the unknowns), in SoccerNet's order.
MODEL_CLASSES: tuple[str, ...] = tuple(c for c in LINE_CLASSES if c not in UNKNOWN_CLASSES)


def circle_arc_angles(line_class: str) -> tuple[float, float]:
    """Start and end angle (radians, counter-clockwise in the world x-y plane) of a circle element.

    The central circle is whole (0 to 2 pi); the penalty arcs run between their intersections with
    the 16.5 m line, outside the penalty area, as in SoccerNet's ``sample_field_points``.

    Raises:
        KeyError: ``line_class`` is not a circle class.

    >>> a, b = circle_arc_angles("Circle central"); round(b - a, 6) == round(2 * np.pi, 6)
    True
    """
    centre, _ = CIRCLES[line_class]
    if line_class == "Circle central":
        return 0.0, 2.0 * np.pi
    top = KEY_POINTS[LINE_EXTREMITY_KEYS[line_class][0]]
    bottom = KEY_POINTS[LINE_EXTREMITY_KEYS[line_class][1]]
    ang_top = float(np.arctan2(top[1] - centre[1], top[0] - centre[0]) + 2 * np.pi)
    ang_bottom = float(np.arctan2(bottom[1] - centre[1], bottom[0] - centre[0]) + 2 * np.pi)
    start, end = (ang_bottom, ang_top) if line_class == "Circle right" else (ang_top, ang_bottom)
    if end < start:
        end += 2 * np.pi
    return start, end


@lru_cache(maxsize=8)
def sample_pitch_polylines(dist: float = 0.1, dist_circles: float = 0.2) -> Mapping[str, np.ndarray]:
    """3D polylines of every pitch element, sampled as SoccerNet's ``sample_field_points``.

    Straight elements get a point every ``dist`` metres from their start (accumulated as SoccerNet
    does) plus their end point; the penalty arcs a point every ``dist_circles`` metres of arc plus
    both ends; the central circle ``int(2 pi r / dist_circles)`` points from angle 0, not closed.
    The official evaluator calls it as ``sample_field_points(0.9)``: 0.9 m on straight elements,
    the default 0.2 m on circles.

    Args:
        dist: spacing on straight elements, metres.
        dist_circles: spacing on circles, metres.

    Returns:
        Read-only mapping class -> array (N, 3) of world points (metres, z down), for every class of
        :data:`MODEL_CLASSES`, in SoccerNet's insertion order ("Circle central" first).

    >>> lines = sample_pitch_polylines()
    >>> lines["Side line top"].shape
    (1051, 3)
    >>> float(lines["Goal left crossbar"][:, 2].max())
    -2.44
    """
    out: dict[str, np.ndarray] = {}
    centre, radius = CIRCLES["Circle central"]
    n = int(radius * 2 * np.pi / dist_circles)
    ang = np.arange(0, n) * (dist_circles / radius)
    out["Circle central"] = np.stack(
        [centre[0] + np.cos(ang) * radius, centre[1] + np.sin(ang) * radius, np.zeros_like(ang)], axis=1
    )
    for cls, (k0, k1) in LINE_EXTREMITY_KEYS.items():
        if cls.startswith("Circle"):
            centre, radius = CIRCLES[cls]
            a0, a1 = circle_arc_angles(cls)
            n = int(radius * (a1 - a0) / dist_circles)
            ang = np.concatenate([[a0], a0 + np.arange(1, n + 1) * (dist_circles / radius), [a1]])
            out[cls] = np.stack(
                [centre[0] + np.cos(ang) * radius, centre[1] + np.sin(ang) * radius, np.zeros_like(ang)], axis=1
            )
        else:
            start, end = KEY_POINTS[k0], KEY_POINTS[k1]
            total = float(np.sqrt(np.sum(np.square(start - end))))
            n = int(total / dist - 1)
            v = (end - start) / np.linalg.norm(end - start)
            steps = np.concatenate([start[None, :], np.repeat((dist * v)[None, :], n, axis=0)])
            out[cls] = np.concatenate([np.cumsum(steps, axis=0), end[None, :]])
    for arr in out.values():
        arr.setflags(write=False)
    return MappingProxyType(out)


def mirror_world_points(points: np.ndarray) -> np.ndarray:
    """Rotate world points 180 degrees about the vertical axis through the centre spot.

    Args:
        points: (N, 3) world points, metres.

    Returns:
        (N, 3) points with x and y negated (z unchanged).
    """
    pts = np.asarray(points, dtype=float)
    if pts.ndim != 2 or pts.shape[1] != 3:
        raise ValueError(f"points must have shape (N, 3), got {pts.shape}")
    return pts * np.array([-1.0, -1.0, 1.0])
