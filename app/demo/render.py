"""OpenCV rendering of a demo frame: stands, striped grass, pitch lines, goals, boards, players, ball.

Everything is drawn from 3D geometry through the frame's true :class:`~app.geometry.camera.Camera`
(no distortion), so that the image, the labels and the truth agree:

* pitch lines are ribbons 0.12 m wide on the ground plane, built from densely sampled model
  polylines, clipped against the camera's near plane in 3D, rasterised 2-4x supersampled and
  averaged down (anti-aliased, correct width at every depth);
* the ball is ray-cast (sphere intersection per sub-pixel, Lambert shading), so its image has
  exactly the size and shape of the true sphere's silhouette;
* objects (players, goals, boards, ball) are painted far to near.

Pixels: continuous coordinates with the origin at the top-left corner of the image (pixel ``i``
covers ``[i, i + 1)``); OpenCV draws integer coordinates at pixel centres, hence the 0.5 shifts.
World: SoccerNet frame (metres, z down). Colours are BGR ``uint8``.
"""
from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache
from typing import Callable, Sequence

import cv2
import numpy as np

from app.demo.scene import BALL_RADIUS_M, PLAYER_HEIGHT_M, Person, precise_ball_box
from app.geometry.camera import Camera
from app.geometry.pitch import (
    CIRCLES,
    GOAL_HEIGHT_M,
    GOAL_LENGTH_M,
    KEY_POINTS,
    LINE_EXTREMITY_KEYS,
    PITCH_LENGTH_M,
    PITCH_WIDTH_M,
    circle_arc_angles,
)

#: Near plane (metres of camera depth) against which 3D polygons are clipped before projection.
NEAR_M = 0.5
LINE_WIDTH_M = 0.12
_SHIFT = 4
_ONE = float(1 << _SHIFT)

_HALF_L, _HALF_W = PITCH_LENGTH_M / 2.0, PITCH_WIDTH_M / 2.0
#: Advertising boards: distance beyond the touch lines and goal lines, height (m).
BOARD_OFFSET_SIDE_M, BOARD_OFFSET_END_M, BOARD_HEIGHT_M = 4.0, 6.0, 0.9

GRASS = ((62, 146, 58), (52, 128, 48))
SURROUND = (44, 104, 46)
STAND = (78, 66, 62)
LINE_COLOUR = np.array([238, 242, 240], float)
BOARD_COLOURS = ((190, 90, 20), (30, 30, 200), (240, 240, 240), (20, 150, 230))
KITS: dict[str, tuple[tuple[int, int, int], tuple[int, int, int]]] = {  # shirt, shorts
    "Player team left": ((200, 70, 30), (245, 245, 245)),
    "Player team right": ((40, 40, 200), (25, 25, 25)),
    "Goalkeeper team left": ((30, 220, 230), (30, 30, 30)),
    "Goalkeeper team right": ((60, 200, 60), (30, 30, 30)),
    "Main referee": ((30, 30, 30), (30, 30, 30)),
}
SKIN = (120, 160, 205)


# ----- 3D polygons -----------------------------------------------------------------------------
def clip_polygon_near(points_cam: np.ndarray, near: float = NEAR_M) -> np.ndarray:
    """Clip a planar polygon (camera frame) to the half-space ``z >= near`` (Sutherland-Hodgman).

    Args:
        points_cam: (N, 3) polygon vertices in camera coordinates, metres.
        near: depth of the clipping plane, metres.

    Returns:
        (M, 3) clipped polygon (M = 0 when entirely behind the plane).

    >>> clip_polygon_near(np.array([[0, 0, -1.0], [1, 0, 1.0], [0, 1, 1.0]]), near=0.0).shape
    (4, 3)
    """
    out: list[np.ndarray] = []
    n = len(points_cam)
    for i in range(n):
        a, b = points_cam[i], points_cam[(i + 1) % n]
        a_in, b_in = a[2] >= near, b[2] >= near
        if a_in:
            out.append(a)
        if a_in != b_in:
            t = (near - a[2]) / (b[2] - a[2])
            out.append(a + t * (b - a))
    return np.array(out) if out else np.zeros((0, 3))


def _to_pixels(camera: Camera, points_cam: np.ndarray) -> np.ndarray:
    xy = points_cam[:, :2] / points_cam[:, 2:3]
    return xy @ camera.K[:2, :2].T + camera.K[:2, 2]


def _cv_points(uv: np.ndarray, scale: float = 1.0) -> np.ndarray:
    """Continuous pixels -> OpenCV fixed-point vertices (pixel centres at integers)."""
    return np.round((uv * scale - 0.5) * _ONE).astype(np.int32)


def project_polygon(camera: Camera, polygon_world: np.ndarray) -> np.ndarray:
    """Project a planar world polygon after clipping it to the near plane.

    Args:
        camera: the camera (no distortion is applied: the demo cameras have none).
        polygon_world: (N, 3) vertices, world metres.

    Returns:
        (M, 2) pixel polygon, M = 0 when nothing is in front of the camera.
    """
    clipped = clip_polygon_near(camera.points_in_camera(polygon_world))
    return _to_pixels(camera, clipped) if len(clipped) >= 3 else np.zeros((0, 2))


def _visible(uv: np.ndarray, width: float, height: float, margin: float = 2.0) -> bool:
    if len(uv) < 3:
        return False
    lo, hi = uv.min(axis=0), uv.max(axis=0)
    return bool(hi[0] >= -margin and hi[1] >= -margin and lo[0] <= width + margin and lo[1] <= height + margin)


def fill_world_polygon(img: np.ndarray, camera: Camera, polygon_world: np.ndarray,
                       colour: Sequence[int], alpha: float = 1.0) -> None:
    """Draw a convex planar world polygon (anti-aliased; blended with ``alpha`` < 1)."""
    uv = project_polygon(camera, polygon_world)
    if not _visible(uv, img.shape[1], img.shape[0]):
        return
    if alpha >= 1.0:
        cv2.fillConvexPoly(img, _cv_points(uv), tuple(int(c) for c in colour), cv2.LINE_AA, _SHIFT)
        return
    x0, y0 = np.maximum(np.floor(uv.min(0)).astype(int) - 1, 0)
    x1, y1 = np.minimum(np.ceil(uv.max(0)).astype(int) + 2, [img.shape[1], img.shape[0]])
    if x1 <= x0 or y1 <= y0:
        return
    roi = img[y0:y1, x0:x1]
    layer = roi.copy()
    cv2.fillConvexPoly(layer, _cv_points(uv - [x0, y0]), tuple(int(c) for c in colour), cv2.LINE_AA, _SHIFT)
    cv2.addWeighted(layer, alpha, roi, 1.0 - alpha, 0.0, dst=roi)


def _rect(x0: float, x1: float, y0: float, y1: float, z: float = 0.0) -> np.ndarray:
    return np.array([[x0, y0, z], [x1, y0, z], [x1, y1, z], [x0, y1, z]], float)


# ----- background, grass, lines ------------------------------------------------------------------
def _stand(img: np.ndarray, camera: Camera, a: np.ndarray, b: np.ndarray, outward: np.ndarray,
           colours: tuple[tuple[int, int, int], tuple[int, int, int]], depth: float = 22.0, rise: float = 11.0,
           tiers: int = 12) -> None:
    """A stand rising away from the pitch from the ground edge ``a``-``b`` (world, z = -0.5), drawn
    as ``tiers`` rows of seats in two alternating colours."""
    for k in range(tiers):
        f0, f1 = k / tiers, (k + 1) / tiers
        lo = np.array([0.0, 0.0, -0.5]) + outward * depth * f0 + np.array([0.0, 0.0, -(rise - 0.5) * f0])
        hi = np.array([0.0, 0.0, -0.5]) + outward * depth * f1 + np.array([0.0, 0.0, -(rise - 0.5) * f1])
        fill_world_polygon(img, camera, np.array([a + lo, b + lo, b + hi, a + hi]), colours[k % 2])


def _background(camera: Camera, width: int, height: int) -> np.ndarray:
    """Roof shadow darkening towards the top of the picture, and four tiered stands around the pitch."""
    rows = np.linspace(0.0, 1.0, height)[:, None]
    top, bottom = np.array([52, 46, 44], float), np.array(STAND, float)
    col = top + (bottom - top) * rows
    img = np.ascontiguousarray(np.broadcast_to(col.astype(np.uint8)[:, None, :], (height, width, 3)))
    ys, xs = _HALF_W + BOARD_OFFSET_SIDE_M + 2.0, _HALF_L + BOARD_OFFSET_END_M + 3.0
    side_colours = ((90, 76, 72), (80, 68, 64))
    end_colours = ((86, 72, 76), (76, 64, 68))
    for sgn in (1.0, -1.0):
        _stand(img, camera, np.array([-xs, sgn * ys, 0.0]), np.array([xs, sgn * ys, 0.0]),
               np.array([0.0, sgn, 0.0]), side_colours)
        _stand(img, camera, np.array([sgn * xs, -ys, 0.0]), np.array([sgn * xs, ys, 0.0]),
               np.array([sgn, 0.0, 0.0]), end_colours)
    return img


def _ground(img: np.ndarray, camera: Camera) -> None:
    fill_world_polygon(img, camera, _rect(-(_HALF_L + 9), _HALF_L + 9, -(_HALF_W + 6), _HALF_W + 6), SURROUND)
    fill_world_polygon(img, camera, _rect(-(_HALF_L + 5.5), _HALF_L + 5.5, -(_HALF_W + 3.5), _HALF_W + 3.5),
                       GRASS[1])
    bands = 20
    edges = np.linspace(-_HALF_L, _HALF_L, bands + 1)
    for i in range(0, bands, 2):
        fill_world_polygon(img, camera, _rect(edges[i], edges[i + 1], -(_HALF_W + 3.5), _HALF_W + 3.5), GRASS[0])


def ground_line_ribbons(step_m: float = 0.25) -> np.ndarray:
    """Quads of every ground marking (lines and arcs, 0.12 m wide) as (M, 4, 3) world points.

    Straight elements and arcs are cut every ``step_m`` metres; goal frames are not included
    (they stand off the ground, see :func:`goal_parts`).
    """
    quads: list[np.ndarray] = []

    def ribbon(pts: np.ndarray, normals: np.ndarray) -> None:
        half = LINE_WIDTH_M / 2.0
        left, right = pts + normals * half, pts - normals * half
        quads.append(np.stack([left[:-1], left[1:], right[1:], right[:-1]], axis=1))

    for cls, (k0, k1) in LINE_EXTREMITY_KEYS.items():
        if cls.startswith("Goal") or cls.startswith("Circle"):
            continue
        a, b = KEY_POINTS[k0], KEY_POINTS[k1]
        n = max(2, int(np.ceil(np.linalg.norm(b - a) / step_m)) + 1)
        pts = a + np.linspace(0.0, 1.0, n)[:, None] * (b - a)
        d = (b - a) / np.linalg.norm(b - a)
        ribbon(pts, np.broadcast_to(np.array([-d[1], d[0], 0.0]), pts.shape))
    for cls in ("Circle central", "Circle left", "Circle right"):
        centre, radius = CIRCLES[cls]
        a0, a1 = circle_arc_angles(cls)
        n = max(2, int(np.ceil(radius * (a1 - a0) / step_m)) + 1)
        ang = np.linspace(a0, a1, n)
        radial = np.stack([np.cos(ang), np.sin(ang), np.zeros_like(ang)], axis=1)
        ribbon(centre + radial * radius, radial)
    for name in ("CENTER_MARK", "L_PENALTY_MARK", "R_PENALTY_MARK"):  # spots, 0.22 m across
        c = KEY_POINTS[name]
        ang = np.linspace(0.0, 2.0 * np.pi, 9)
        ring = c + 0.055 * np.stack([np.cos(ang), np.sin(ang), np.zeros_like(ang)], axis=1)
        radial = np.stack([np.cos(ang), np.sin(ang), np.zeros_like(ang)], axis=1)
        ribbon(ring, radial)
    return np.concatenate(quads, axis=0)


def _draw_lines(img: np.ndarray, camera: Camera, ribbons: np.ndarray) -> None:
    """Paint the ground markings: (M, 4, 3) world quads rasterised supersampled, then blended by
    their covered fraction of each pixel."""
    h, w = img.shape[:2]
    ss = 4 if w <= 1280 else 2
    mask = np.zeros((h * ss, w * ss), np.uint8)
    cam_pts = camera.points_in_camera(ribbons.reshape(-1, 3)).reshape(ribbons.shape)
    depth = cam_pts[:, :, 2]
    front = np.all(depth >= NEAR_M, axis=1)
    uv_front = (cam_pts[front, :, :2] / cam_pts[front, :, 2:3]) @ camera.K[:2, :2].T + camera.K[:2, 2]
    lo, hi = uv_front.min(axis=1), uv_front.max(axis=1)
    on_screen = (hi[:, 0] >= -2) & (hi[:, 1] >= -2) & (lo[:, 0] <= w + 2) & (lo[:, 1] <= h + 2)
    fixed = _cv_points(uv_front[on_screen], ss)
    for quad in fixed:
        cv2.fillConvexPoly(mask, quad, 255, cv2.LINE_8, _SHIFT)
    for i in np.flatnonzero(~front & np.any(depth >= NEAR_M, axis=1)):  # straddling the near plane
        clipped = clip_polygon_near(cam_pts[i])
        if len(clipped) >= 3 and _visible(uv := _to_pixels(camera, clipped), w, h):
            cv2.fillConvexPoly(mask, _cv_points(uv, ss), 255, cv2.LINE_8, _SHIFT)
    alpha = cv2.resize(mask, (w, h), interpolation=cv2.INTER_AREA).astype(np.float32)[:, :, None] / 255.0
    img[:] = np.round(img * (1.0 - alpha) + LINE_COLOUR * alpha).astype(np.uint8)


# ----- objects painted far to near -------------------------------------------------------------
def _polygon_drawer(camera: Camera, poly: np.ndarray, colour: tuple[int, int, int]) -> Callable[[np.ndarray], None]:
    """``draw(img)`` of one world polygon, its camera, points and colour fixed now."""
    return lambda img: fill_world_polygon(img, camera, poly, colour)


@dataclass(frozen=True)
class Drawable:
    """An object painted in depth order: ``depth`` metres along the optical axis, ``draw(img)``."""

    depth: float
    draw: Callable[[np.ndarray], None]


def _bar(img: np.ndarray, camera: Camera, a: np.ndarray, b: np.ndarray, diameter: float,
         colour: Sequence[int]) -> None:
    """A cylinder between two world points, drawn as a quad of the projected width at each end."""
    pc = camera.points_in_camera(np.stack([a, b]))
    if np.any(pc[:, 2] < NEAR_M):
        return
    uv = _to_pixels(camera, pc)
    d = uv[1] - uv[0]
    n = np.array([-d[1], d[0]]) / max(np.linalg.norm(d), 1e-9)
    half = camera.K[0, 0] * diameter / 2.0 / pc[:, 2]
    quad = np.array([uv[0] + n * half[0], uv[1] + n * half[1], uv[1] - n * half[1], uv[0] - n * half[0]])
    if _visible(quad, img.shape[1], img.shape[0]):
        cv2.fillConvexPoly(img, _cv_points(quad), tuple(int(c) for c in colour), cv2.LINE_AA, _SHIFT)


def goal_parts(side: int) -> dict[str, np.ndarray]:
    """World corner points of the goal at ``x = side * 52.5`` (side = -1 left, +1 right).

    Returns:
        Dict with ``posts`` (2, 2, 3) bottom/top of each post, ``net`` list-like (K, 4, 3) net panels.
    """
    x, g, hgt = side * _HALF_L, GOAL_LENGTH_M / 2.0, -GOAL_HEIGHT_M
    xt, xb = x + side * 1.0, x + side * 2.0
    posts = np.array([[[x, -g, 0.0], [x, -g, hgt]], [[x, g, 0.0], [x, g, hgt]]])
    net = np.array([
        [[x, -g, hgt], [x, g, hgt], [xt, g, hgt], [xt, -g, hgt]],  # roof
        [[xt, -g, hgt], [xt, g, hgt], [xb, g, 0.0], [xb, -g, 0.0]],  # back
        [[x, -g, 0.0], [x, -g, hgt], [xt, -g, hgt], [xb, -g, 0.0]],  # side
        [[x, g, 0.0], [x, g, hgt], [xt, g, hgt], [xb, g, 0.0]],  # side
    ])
    return {"posts": posts, "net": net}


def _goal(camera: Camera, side: int) -> Drawable:
    parts = goal_parts(side)

    def draw(img: np.ndarray) -> None:
        for panel in parts["net"]:
            fill_world_polygon(img, camera, panel, (225, 225, 225), alpha=0.22)
        for panel in parts["net"][1:]:  # a coarse mesh on the back and the sides
            for t in np.linspace(0.0, 1.0, 9)[1:-1]:
                _bar(img, camera, panel[0] + t * (panel[3] - panel[0]), panel[1] + t * (panel[2] - panel[1]),
                     0.02, (205, 205, 205))
        (b0, t0), (b1, t1) = parts["posts"]
        for a, b in ((b0, t0), (b1, t1), (t0, t1)):
            _bar(img, camera, a, b, 0.12, (250, 250, 250))

    centre = np.array([[side * (_HALF_L + 0.5), 0.0, -1.2]])
    return Drawable(float(camera.points_in_camera(centre)[0, 2]), draw)


def _boards(camera: Camera) -> list[Drawable]:
    out: list[Drawable] = []
    panel_len = 6.0
    ys, xs = _HALF_W + BOARD_OFFSET_SIDE_M, _HALF_L + BOARD_OFFSET_END_M
    runs = [((-xs, ys), (xs, ys)), ((-xs, -ys), (xs, -ys)), ((xs, -ys), (xs, ys)), ((-xs, -ys), (-xs, ys))]
    k = 0
    for (x0, y0), (x1, y1) in runs:
        length = float(np.hypot(x1 - x0, y1 - y0))
        n = int(np.ceil(length / panel_len))
        for i in range(n):
            a = np.array([x0, y0]) + (np.array([x1, y1]) - [x0, y0]) * i / n
            b = np.array([x0, y0]) + (np.array([x1, y1]) - [x0, y0]) * (i + 1) / n
            poly = np.array([[a[0], a[1], 0.0], [b[0], b[1], 0.0], [b[0], b[1], -BOARD_HEIGHT_M],
                             [a[0], a[1], -BOARD_HEIGHT_M]])
            colour = BOARD_COLOURS[k % len(BOARD_COLOURS)]
            k += 1
            mid = poly.mean(axis=0, keepdims=True)
            z = float(camera.points_in_camera(mid)[0, 2])
            if z > NEAR_M:
                out.append(Drawable(z, _polygon_drawer(camera, poly, colour)))
    return out


#: A player figure in units of its image height: polygons of (across, up) points, up from the feet.
_FIGURE: tuple[tuple[str, tuple[tuple[float, float], ...]], ...] = (
    ("skin", ((-0.11, 0.0), (-0.03, 0.0), (-0.02, 0.46), (-0.10, 0.46))),
    ("skin", ((0.03, 0.0), (0.11, 0.0), (0.10, 0.46), (0.02, 0.46))),
    ("socks", ((-0.115, 0.0), (-0.025, 0.0), (-0.025, 0.2), (-0.105, 0.2))),
    ("socks", ((0.025, 0.0), (0.115, 0.0), (0.105, 0.2), (0.025, 0.2))),
    ("shorts", ((-0.125, 0.38), (0.125, 0.38), (0.12, 0.53), (-0.12, 0.53))),
    ("shirt", ((-0.12, 0.51), (0.12, 0.51), (0.15, 0.82), (-0.15, 0.82))),
    ("shirt", ((-0.15, 0.82), (-0.12, 0.77), (-0.19, 0.6), (-0.22, 0.62))),
    ("shirt", ((0.15, 0.82), (0.12, 0.77), (0.19, 0.6), (0.22, 0.62))),
    ("skin", ((-0.19, 0.6), (-0.22, 0.62), (-0.22, 0.5), (-0.19, 0.5))),
    ("skin", ((0.19, 0.6), (0.22, 0.62), (0.22, 0.5), (0.19, 0.5))),
    ("skin", tuple((0.065 * np.cos(a), 0.9 + 0.075 * np.sin(a)) for a in np.linspace(0, 2 * np.pi, 14)[:-1])),
)


def person_outline(camera: Camera, person: Person) -> list[tuple[str, np.ndarray]] | None:
    """Image polygons (part name, (K, 2) pixels) of a person's figure; None when behind the camera."""
    x, y = person.xy
    pc = camera.points_in_camera(np.array([[x, y, 0.0], [x, y, -PLAYER_HEIGHT_M]]))
    if np.any(pc[:, 2] < NEAR_M):
        return None
    feet, head = _to_pixels(camera, pc)
    up = head - feet
    across = np.array([-up[1], up[0]])
    if across[0] < 0:
        across = -across
    return [(part, feet + np.array(pts)[:, :1] * across + np.array(pts)[:, 1:] * up) for part, pts in _FIGURE]


def person_box(camera: Camera, person: Person) -> np.ndarray | None:
    """Tight box ``[x1, y1, x2, y2]`` (pixels) of a person's drawn figure, not clipped to the image."""
    parts = person_outline(camera, person)
    if parts is None:
        return None
    pts = np.concatenate([p for _, p in parts])
    return np.concatenate([pts.min(0), pts.max(0)])


def _person(camera: Camera, person: Person) -> Drawable | None:
    parts = person_outline(camera, person)
    if parts is None:
        return None
    shirt, shorts = KITS.get(person.role, KITS["Main referee"])
    colours = {"skin": SKIN, "socks": shirt, "shirt": shirt, "shorts": shorts}

    def draw(img: np.ndarray) -> None:
        for part, poly in parts:
            if _visible(poly, img.shape[1], img.shape[0]):
                cv2.fillConvexPoly(img, _cv_points(poly), colours[part], cv2.LINE_AA, _SHIFT)

    depth = float(camera.points_in_camera(np.array([[person.xy[0], person.xy[1], -0.9]]))[0, 2])
    return Drawable(depth, draw)


def _shadow(img: np.ndarray, camera: Camera, xy: Sequence[float] | np.ndarray, radius: float, alpha: float) -> None:
    ang = np.linspace(0.0, 2.0 * np.pi, 24, endpoint=False)
    poly = np.stack([xy[0] + 0.25 * radius + radius * np.cos(ang), xy[1] - 0.15 * radius + radius * np.sin(ang),
                     np.zeros_like(ang)], axis=1)
    fill_world_polygon(img, camera, poly, (20, 40, 20), alpha=alpha)


#: Direction towards the light (world frame, z down: the sun is above, slightly to the left).
LIGHT_DIR = np.array([-0.35, 0.25, -1.0]) / np.linalg.norm([-0.35, 0.25, -1.0])


def render_ball(img: np.ndarray, camera: Camera, centre: np.ndarray, radius: float = BALL_RADIUS_M,
                supersample: int = 6) -> None:
    """Ray-cast a shaded ball into ``img`` in place.

    Every pixel near the ball is split into ``supersample``^2 sub-pixels; each sub-pixel ray is
    intersected with the sphere; hits are shaded (ambient + Lambert + a small highlight) and the
    pixel takes the mean colour weighted by its covered fraction. The drawn disc therefore has the
    exact size and shape of the sphere's image (an ellipse off the optical axis).

    Args:
        img: (H, W, 3) uint8 BGR image.
        camera: the camera (no distortion).
        centre: (3,) ball centre, world metres.
        radius: metres.
        supersample: sub-pixels per pixel along each axis.
    """
    h, w = img.shape[:2]
    box = precise_ball_box(camera, centre, radius)
    x0, y0 = max(int(np.floor(box[0])) - 1, 0), max(int(np.floor(box[1])) - 1, 0)
    x1, y1 = min(int(np.ceil(box[2])) + 1, w), min(int(np.ceil(box[3])) + 1, h)
    if x1 <= x0 or y1 <= y0:
        return
    s = supersample
    us = x0 + (np.arange((x1 - x0) * s) + 0.5) / s
    vs = y0 + (np.arange((y1 - y0) * s) + 0.5) / s
    uu, vv = np.meshgrid(us, vs)
    kinv = np.linalg.inv(camera.K)
    d_cam = np.stack([uu.ravel(), vv.ravel(), np.ones(uu.size)], axis=1) @ kinv.T
    d = d_cam @ camera.R  # rows: R^T d
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    oc = camera.C - centre
    bq = d @ oc
    disc = bq**2 - (oc @ oc - radius**2)
    hit = disc >= 0
    t = -bq - np.sqrt(np.where(hit, disc, 0.0))
    normal = (camera.C + d * t[:, None] - centre) / radius
    lambert = np.clip(normal @ LIGHT_DIR, 0.0, 1.0)
    refl = 2.0 * lambert[:, None] * normal - LIGHT_DIR
    spec = np.clip(-(refl * d).sum(axis=1), 0.0, 1.0) ** 24
    shade = 0.38 + 0.6 * lambert
    colour = np.array([228.0, 236.0, 240.0])[None, :] * shade[:, None] + 40.0 * spec[:, None]
    colour = np.where(hit[:, None], np.clip(colour, 0, 255), 0.0)
    ph, pw = (y1 - y0), (x1 - x0)
    cov = hit.reshape(ph, s, pw, s).mean(axis=(1, 3))[:, :, None]
    col = colour.reshape(ph, s, pw, s, 3).sum(axis=(1, 3)) / np.maximum(hit.reshape(ph, s, pw, s).sum(axis=(1, 3)),
                                                                         1)[:, :, None]
    roi = img[y0:y1, x0:x1].astype(float)
    img[y0:y1, x0:x1] = np.round(roi * (1.0 - cov) + col * cov).astype(np.uint8)


def render_frame(camera: Camera, width: int, height: int, ball: np.ndarray, people: Sequence[Person]) -> np.ndarray:
    """Render one demo frame.

    Args:
        camera: true camera at the frame's resolution (no distortion).
        width, height: image size, pixels.
        ball: (3,) ball centre, world metres.
        people: players and referees.

    Returns:
        (height, width, 3) uint8 BGR image.
    """
    img = _background(camera, width, height)
    _ground(img, camera)
    _draw_lines(img, camera, _ribbons())
    for p in people:
        _shadow(img, camera, p.xy, 0.35, 0.35)
    _shadow(img, camera, ball[:2], BALL_RADIUS_M, 0.45 if ball[2] > -0.5 else 0.25)
    objects: list[Drawable] = [_goal(camera, -1), _goal(camera, 1), *_boards(camera)]
    objects += [d for p in people if (d := _person(camera, p)) is not None]
    ball_depth = float(camera.points_in_camera(ball[None, :])[0, 2])
    objects.append(Drawable(ball_depth, lambda im: render_ball(im, camera, ball)))
    for obj in sorted(objects, key=lambda o: -o.depth):
        if obj.depth > NEAR_M:
            obj.draw(img)
    return img


@lru_cache(maxsize=1)
def _ribbons() -> np.ndarray:
    quads = ground_line_ribbons()
    quads.setflags(write=False)
    return quads
