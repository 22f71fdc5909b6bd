"""The demo game's scenes: multi-view systems, ball, players, and the exact image of the ball.

World frame: SoccerNet (metres, origin at the centre spot, z down). A ball on the grass has its
centre at z = -0.11 (diameter 0.22 m).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from app.geometry.camera import Camera
from app.geometry.pitch import BALL_DIAMETER_M

BALL_RADIUS_M = BALL_DIAMETER_M / 2.0
#: Height of a player figure, metres.
PLAYER_HEIGHT_M = 1.8

#: The deliberate problems a reviewer should catch, by the name used in ``demo-truth.json``.
PROBLEM_KINDS: tuple[str, ...] = ("wrong_ball_box", "mirrored_lines", "near_duplicate_viewpoint", "missing_ball")


@dataclass(frozen=True)
class ReplaySpec:
    """A replay view of a system: rig camera name and an optional deliberate problem."""

    rig: str
    problem: str | None = None
    #: Output size (width, height) in pixels.
    size: tuple[int, int] = (960, 540)


@dataclass(frozen=True)
class SystemSpec:
    """One multi-view system: the action (main camera) and its replays at the same instant.

    Attributes:
        ball: (x, y, z) nominal ball centre, world metres (jittered by the seed, height kept).
        replays: the replay views.
        action_size: (width, height) of the action frame, pixels.
        story: one line telling what happens (kept in the truth file for people reading it).
    """

    ball: tuple[float, float, float]
    replays: tuple[ReplaySpec, ...]
    action_size: tuple[int, int] = (960, 540)
    story: str = ""


#: The nine systems of the demo game. Balls near the boxes (where replays are cut), on the
#: ground (z = -0.11) or in the air, each seen by the main camera and 1-3 replays; four replays
#: carry the deliberate problems.
SYSTEMS: tuple[SystemSpec, ...] = (
    SystemSpec((38.0, 8.0, -0.11), (ReplaySpec("behind_goal_right_high"), ReplaySpec("same_18_right"),
                                    ReplaySpec("pitchside_right")),
               (1920, 1080), "ground pass into the right penalty area"),
    SystemSpec((-40.0, -5.0, -4.6), (ReplaySpec("behind_goal_left_high"), ReplaySpec("opposite_18_left"),
                                     ReplaySpec("behind_goal_left_low")), story="header duel in the left box"),
    SystemSpec((-4.0, 12.0, -0.11), (ReplaySpec("opposite_centre"),), story="midfield tackle"),
    SystemSpec((45.0, 2.0, -6.5), (ReplaySpec("behind_goal_right_low"), ReplaySpec("same_18_right", "missing_ball"),
                                   ReplaySpec("opposite_18_right")),
               story="cross into the right six-yard box (one replay sees the ball but has no ball label)"),
    SystemSpec((-30.0, 22.0, -0.11), (ReplaySpec("same_18_left"), ReplaySpec("pitchside_left"),
                                      ReplaySpec("main", "near_duplicate_viewpoint")),
               story="left-wing dribble (replay from the main platform: near-duplicate viewpoint)"),
    SystemSpec((47.0, -6.0, -1.9), (ReplaySpec("behind_goal_right_high", "wrong_ball_box"),
                                    ReplaySpec("opposite_18_right")),
               story="volley at the right goal (one ball box misplaced)"),
    SystemSpec((-42.0, 3.0, -0.11), (ReplaySpec("behind_goal_left_low"), ReplaySpec("same_18_left", "mirrored_lines")),
               story="penalty-spot scramble, left (one replay with mirrored line labels)"),
    SystemSpec((8.0, -14.0, -9.0), (ReplaySpec("opposite_centre"), ReplaySpec("same_18_right")),
               story="long ball at its apex"),
    SystemSpec((32.0, -17.0, -0.11), (ReplaySpec("opposite_18_right"), ReplaySpec("behind_goal_right_high")),
               story="edge-of-the-box shot, right"),
)


@dataclass(frozen=True)
class Person:
    """A player or referee standing on the pitch.

    Attributes:
        role: SoccerNet-v3 box class ("Player team left", "Goalkeeper team right", "Main referee", ...).
        jersey: ID written in the box (string; SoccerNet-v3 uses the jersey number).
        xy: (x, y) foot position, world metres (z = 0).
    """

    role: str
    jersey: str
    xy: tuple[float, float]


def sample_people(rng: np.random.Generator, ball: np.ndarray, count: int) -> list[Person]:
    """Players around the ball (at least 1.2 m from its ground point) and a goalkeeper when the
    ball is near a goal.

    Args:
        rng: random generator (the only source of randomness).
        ball: (3,) ball centre, world metres.
        count: number of outfield players (split between the teams).

    Returns:
        People with distinct ``(role, jersey)`` pairs, feet inside the pitch.
    """
    people: list[Person] = []
    used: dict[str, set[int]] = {}

    def jersey(role: str) -> str:
        taken = used.setdefault(role, set())
        n = int(rng.integers(2, 24))
        while n in taken:
            n = n % 23 + 2
        taken.add(n)
        return str(n)

    spots: list[np.ndarray] = []
    for i in range(count):
        for _ in range(50):
            p = ball[:2] + rng.normal(0.0, 7.0, size=2)
            p = np.clip(p, [-51.5, -33.0], [51.5, 33.0])
            if np.hypot(*(p - ball[:2])) > 1.2 and all(np.hypot(*(p - q)) > 1.0 for q in spots):
                break
        spots.append(p)
        role = "Player team left" if i % 2 == 0 else "Player team right"
        people.append(Person(role, jersey(role), (float(p[0]), float(p[1]))))
    if abs(ball[0]) > 25:
        side = "left" if ball[0] < 0 else "right"
        gx = float(np.sign(ball[0]) * (52.5 - rng.uniform(0.8, 3.5)))
        people.append(Person(f"Goalkeeper team {side}", "1", (gx, float(rng.uniform(-3.0, 3.0)))))
    ref = ball[:2] + rng.normal(0.0, 6.0, size=2) + np.array([0.0, 8.0])
    people.append(Person("Main referee", "1", (float(np.clip(ref[0], -50, 50)), float(np.clip(ref[1], -32, 32)))))
    return people


def sphere_silhouette(camera: Camera, centre: np.ndarray, radius: float = BALL_RADIUS_M,
                      samples: int = 720) -> np.ndarray:
    """Exact image outline of a sphere: the projection of its circle of tangency with the viewing cone.

    Off the optical axis the outline is an ellipse stretched away from the principal point, and
    its centre is not the projection of the sphere's centre (method.md section 7).

    Args:
        camera: the camera.
        centre: (3,) sphere centre, world metres.
        radius: sphere radius, metres.
        samples: points on the outline.

    Returns:
        (samples, 2) pixel coordinates of the outline.

    Raises:
        ValueError: the camera is inside the sphere or the sphere is not entirely in front of it.

    >>> from app.demo.rig import framing_camera
    >>> cam = framing_camera(np.array([0.0, 40.0, -5.0]), np.array([0.0, 0.0, -0.11]), 10.0, 960, 540)
    >>> uv = sphere_silhouette(cam, np.array([0.0, 0.0, -0.11]))
    >>> d = uv.max(0) - uv.min(0)    # on the axis: a circle of diameter 2 f tan(asin(r / D))
    >>> D = float(np.linalg.norm(cam.C - [0.0, 0.0, -0.11])); f = cam.K[0, 0]
    >>> bool(np.allclose(d, 2 * f * np.tan(np.arcsin(0.11 / D)), atol=1e-3))
    True
    """
    c = np.asarray(centre, float).reshape(3)
    v = camera.C - c
    dist = float(np.linalg.norm(v))
    if dist <= radius:
        raise ValueError("the camera is inside the sphere")
    n = v / dist
    # Tangency circle: centre on the segment towards the camera, radius r sqrt(D^2 - r^2) / D.
    circle_centre = c + n * radius**2 / dist
    circle_radius = radius * np.sqrt(dist**2 - radius**2) / dist
    a = np.cross(n, [0.0, 0.0, 1.0])
    if np.linalg.norm(a) < 1e-9:
        a = np.cross(n, [1.0, 0.0, 0.0])
    a /= np.linalg.norm(a)
    b = np.cross(n, a)
    t = np.linspace(0.0, 2.0 * np.pi, samples, endpoint=False)
    pts = circle_centre + circle_radius * (np.cos(t)[:, None] * a + np.sin(t)[:, None] * b)
    uv, ok = camera.project(pts)
    if not ok.all():
        raise ValueError("the sphere is not entirely in front of the camera")
    return uv


def precise_ball_box(camera: Camera, centre: np.ndarray, radius: float = BALL_RADIUS_M) -> np.ndarray:
    """Tight axis-aligned box ``[x1, y1, x2, y2]`` (pixels, continuous) of the exact ball image."""
    uv = sphere_silhouette(camera, centre, radius)
    return np.concatenate([uv.min(axis=0), uv.max(axis=0)])
