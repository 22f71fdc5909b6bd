"""Where the players stand: a player box's foot pixel, its point on the grass (z = 0, SoccerNet world, metres)
through a calibrated camera, and the same player seen by several well-calibrated views fused into one point with
its covariance; what :mod:`~app.geometry.calibration.players` fits a view's camera to."""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Mapping, Sequence

import numpy as np

from app.geometry.camera import Camera
from app.geometry.pair_error import REFERENCE_WIDTH_PX
from app.geometry.pitch import PITCH_LENGTH_M, PITCH_WIDTH_M

#: A player's identity across the views of a system: its box's class and its ID (SoccerNet-v3 ``bboxes``).
PlayerKey = tuple[str, str]


@dataclass(frozen=True)
class GrassPlayer:
    """Where one player stands, from the well-calibrated views: ``point_m`` (x, y) on the ground ``z = 0``
    (metres), the number of views that saw it and the largest distance (m) of a view's point from it."""

    point_m: tuple[float, float]
    views: int
    spread_m: float
    #: (2, 2) covariance of ``point_m`` (m^2): each view's foot-pixel noise (:data:`FOOT_SIGMA_PX`) carried to the
    #: ground through its camera, with the footprint's own (:data:`FOOT_OFFSET_SIGMA_M`), fused by information.
    cov_m2: tuple[tuple[float, float], tuple[float, float]] = ((0.01, 0.0), (0.0, 0.01))


def foot_pixel(box: Sequence[float], width: int, height: int, border_px: float = 2.0) -> np.ndarray | None:
    """The foot point of a player's box ``(x1, y1, x2, y2)`` (px): the bottom centre, or None when the box reaches
    within ``border_px`` of the bottom, left or right edge of a ``width`` x ``height`` image (the player is cut off:
    its feet, or half of it, which moves the centre)."""
    x1, y1, x2, y2 = map(float, box)
    # each finite, written out: a recomputation reads every player box of its views (a few dozen an edit)
    if not (math.isfinite(x1) and math.isfinite(y1) and math.isfinite(x2) and math.isfinite(y2)) or y2 <= y1:
        return None
    if y2 >= height - 1 - border_px or x1 <= border_px or x2 >= width - 1 - border_px:
        return None
    return np.array([(x1 + x2) / 2.0, y2])


def head_pixel(box: Sequence[float], width: int, height: int, border_px: float = 2.0) -> np.ndarray | None:
    """The head point of a player's box ``(x1, y1, x2, y2)`` (px): the top centre, or None when the box reaches
    within ``border_px`` of the top, left or right edge of a ``width`` x ``height`` image (the player is cut off: its
    head, or half of it, which moves the centre). A box the bottom edge cuts keeps its head point: a close view that
    shows players without their feet still shows where their heads are."""
    x1, y1, x2, y2 = (float(v) for v in box)
    if not all(math.isfinite(v) for v in (x1, y1, x2, y2)) or y2 <= y1:
        return None
    if y1 <= border_px or x1 <= border_px or x2 >= width - 1 - border_px:
        return None
    return np.array([(x1 + x2) / 2.0, y1])


#: How far (m) the lowest point of a player's box lies in front of where the player stands, towards the camera: a
#: standing body is no line but a solid about 0.8 m across, and its box's bottom edge is the near edge of its
#: footprint. The median over the views of ``soccernet-v3-dev-large`` against its true players (0.39-0.42 m at every
#: distance from the camera, 899 boxes of 3 games); without it a foot point is 5-10 px@1920 off below the player.
FOOT_OFFSET_M = 0.4


#: Standard deviation of a foot pixel (px@1920): the box's noise and the bottom edge's wobble with the pose.
FOOT_SIGMA_PX = 2.0
#: Standard deviation (m) of where a player stands beyond :data:`FOOT_OFFSET_M` (stance, footprint).
FOOT_OFFSET_SIGMA_M = 0.1


#: Where the top of a standing player's box is: :data:`HEAD_HEIGHT_M` above the grass and :data:`HEAD_OFFSET_M` beyond
#: where the player stands, away from the camera (the far top edge of a body about 0.8 m across). Measured on
#: ``soccernet-v3-dev-large`` against its true players and cameras (7,609 boxes not cut by the image: the box top's
#: ray meets the player's vertical at 1.85 m + 0.35 m tan(elevation), the same at every elevation from 0 to 40 deg).
HEAD_HEIGHT_M = 1.85
HEAD_OFFSET_M = 0.35
#: Standard deviation (m) of the box top's height: players' statures and poses (a generator's players vary by 0.04 m;
#: real ones by about 0.07 m, more when they jump or bend).
HEAD_SIGMA_M = 0.1


def head_world(grass_m: np.ndarray, centre: np.ndarray, height_m: float = HEAD_HEIGHT_M,
               offset_m: float = HEAD_OFFSET_M) -> np.ndarray:
    """The world points (n, 3) whose projections are the head points (:func:`head_pixel`) of players standing at
    ``grass_m`` (n, 2) seen from a camera at ``centre`` (3,): ``height_m`` up (z = -height, z down) and ``offset_m``
    away from the camera along the ground."""
    g = np.asarray(grass_m, float)
    away = g - np.asarray(centre, float)[:2]
    norm = np.linalg.norm(away, axis=1, keepdims=True)
    p = g + offset_m * away / np.where(norm > 1e-9, norm, 1.0)
    return np.column_stack([p, np.full(len(g), -height_m)])


def grass_point(camera: Camera, pixel: np.ndarray, offset_m: float = FOOT_OFFSET_M) -> np.ndarray | None:
    """Where a player stands whose foot point is ``pixel`` (2,): the ray's point on the ground ``z = 0``, moved
    ``offset_m`` away from the camera along the ground (:data:`FOOT_OFFSET_M`); world metres, (2,) x, y. None when
    the ray never meets the ground ahead of the camera."""
    p = grass_points(camera, np.asarray(pixel, float).reshape(1, 2), offset_m)[0]
    return None if np.isnan(p[0]) else p


def grass_points(camera: Camera, pixels: np.ndarray, offset_m: float = FOOT_OFFSET_M) -> np.ndarray:
    """:func:`grass_point` of the foot points ``pixels`` (n, 2) at once: world metres (n, 2), a row of NaN where the
    ray never meets the ground ahead of the camera."""
    d = camera.rays(np.asarray(pixels, float).reshape(-1, 2))
    with np.errstate(divide="ignore", invalid="ignore"):
        t = -camera.C[2] / d[:, 2]
    ok = (np.abs(d[:, 2]) >= 1e-9) & (t > 0)
    p = camera.C[:2] + np.where(ok, t, 0.0)[:, None] * d[:, :2]
    away = p - camera.C[:2]
    norm = np.linalg.norm(away, axis=1, keepdims=True)
    p = np.where(norm > 1e-9, p + offset_m * away / np.where(norm > 1e-9, norm, 1.0), p)
    p[~ok] = np.nan
    return p


def foot_world(grass_m: np.ndarray, centre: np.ndarray, offset_m: float = FOOT_OFFSET_M) -> np.ndarray:
    """The world points (n, 3), on the ground, whose projections are the foot points of players standing at
    ``grass_m`` (n, 2) seen from a camera at ``centre`` (3,): each moved ``offset_m`` towards the camera along the
    ground (the inverse of :func:`grass_point`'s offset)."""
    g = np.asarray(grass_m, float)
    towards = np.asarray(centre, float)[:2] - g
    norm = np.linalg.norm(towards, axis=1, keepdims=True)
    p = g + offset_m * towards / np.where(norm > 1e-9, norm, 1.0)
    return np.column_stack([p, np.zeros(len(g))])


_EYE2 = np.eye(2)


def players_on_grass(views: Sequence[tuple[Camera, Mapping[PlayerKey, np.ndarray]]], max_spread_m: float = 1.5
                     ) -> dict[PlayerKey, GrassPlayer]:
    """Where each player stands, fused over well-calibrated views.

    Args:
        views: per view its camera and its players' foot pixels (key -> (2,) px, :func:`foot_pixel`).
        max_spread_m: a player whose views put it farther than this (m) from their median is left out (a wrong
            ID or a box on two players).

    Returns:
        key -> :class:`GrassPlayer` (the views' ground points weighted by their inverse covariances, and that
        covariance), players inside the pitch and a margin of 5 m only.
    """
    seen: dict[PlayerKey, list[tuple[np.ndarray, np.ndarray]]] = {}  # key -> (ground point, its information)
    for camera, feet in views:
        sigma = FOOT_SIGMA_PX * float(camera.K[0, 2] * 2 + 1) / REFERENCE_WIDTH_PX  # px of this view
        if not feet:
            continue
        keys = list(feet)
        uv = np.array([np.asarray(feet[k], float) for k in keys])
        # Each foot point and its two half-pixel neighbours (the ground Jacobian), one back-projection per view.
        g = grass_points(camera, np.concatenate([uv, uv + [0.5, 0.0], uv + [0.0, 0.5]])).reshape(3, len(keys), 2)
        ok = ~(np.isnan(g[0, :, 0]) | np.isnan(g[1, :, 0]) | np.isnan(g[2, :, 0]))
        if not ok.any():
            continue
        # The view's players at once (each matrix product and inverse the one a player alone would get).
        J = np.stack([(g[1, ok] - g[0, ok]) / 0.5, (g[2, ok] - g[0, ok]) / 0.5], axis=-1)  # metres per pixel
        infos = np.linalg.inv(sigma**2 * J @ np.swapaxes(J, 1, 2) + FOOT_OFFSET_SIGMA_M**2 * _EYE2)
        for key, p, i in zip([k for k, kept in zip(keys, ok, strict=True) if kept], g[0, ok], infos, strict=True):
            seen.setdefault(key, []).append((p, i))
    return _fused(seen, max_spread_m)


def _fused(seen: Mapping[PlayerKey, list[tuple[np.ndarray, np.ndarray]]], max_spread_m: float
           ) -> dict[PlayerKey, GrassPlayer]:
    """Each player's ground points (m) and their information matrices (1/m^2) fused by information; a player whose
    points lie farther than ``max_spread_m`` from the fused one, or outside the pitch and 5 m, left out."""
    out: dict[PlayerKey, GrassPlayer] = {}
    # The players one view saw (most of them, and every player of one view's grass) at once: each matrix product and
    # inverse the one the loop below would give, to the bit.
    single = [k for k, points in seen.items() if len(points) == 1]
    if single:
        P = np.array([seen[k][0][0] for k in single])
        info = np.array([seen[k][0][1] for k in single])
        covs = np.linalg.inv(info)
        centres = (covs @ (info @ P[..., None]))[..., 0]
        spreads = np.linalg.norm(P - centres, axis=1)
        inside = ((np.abs(centres[:, 0]) <= PITCH_LENGTH_M / 2 + 5.0)
                  & (np.abs(centres[:, 1]) <= PITCH_WIDTH_M / 2 + 5.0))
        for j, key in enumerate(single):
            if inside[j]:
                c = covs[j]
                out[key] = GrassPlayer(point_m=(float(centres[j, 0]), float(centres[j, 1])), views=1,
                                       spread_m=float(spreads[j]),
                                       cov_m2=((float(c[0, 0]), float(c[0, 1])), (float(c[1, 0]), float(c[1, 1]))))
    for key, points in seen.items():
        if len(points) == 1:
            continue
        P = np.array([p for p, _ in points])
        cov = np.linalg.inv(sum(i for _, i in points))
        centre = cov @ sum(i @ p for p, i in points)
        spread = float(np.max(np.linalg.norm(P - centre, axis=1)))
        if len(points) > 1 and spread > max_spread_m:
            continue
        if abs(centre[0]) > PITCH_LENGTH_M / 2 + 5.0 or abs(centre[1]) > PITCH_WIDTH_M / 2 + 5.0:
            continue
        out[key] = GrassPlayer(point_m=(float(centre[0]), float(centre[1])), views=len(points), spread_m=spread,
                               cov_m2=((float(cov[0, 0]), float(cov[0, 1])), (float(cov[1, 0]), float(cov[1, 1]))))
    return {key: out[key] for key in seen if key in out}  # in the order the players were seen


def head_grass_points(camera: Camera, pixels: np.ndarray, height_m: float = HEAD_HEIGHT_M,
                      offset_m: float = HEAD_OFFSET_M) -> np.ndarray:
    """Where players stand whose head points (:func:`head_pixel`) are ``pixels`` (n, 2) px: each ray's point at
    ``height_m`` above the grass (z = -height_m, SoccerNet world, z down), moved ``offset_m`` back towards the camera
    along the ground (the inverse of :func:`head_world`); world metres (n, 2), a row of NaN where the ray never meets
    that height ahead of the camera or the camera is not above it."""
    d = camera.rays(np.asarray(pixels, float).reshape(-1, 2))
    with np.errstate(divide="ignore", invalid="ignore"):
        t = (-height_m - camera.C[2]) / d[:, 2]
    ok = (np.abs(d[:, 2]) >= 1e-9) & (t > 0) & (camera.C[2] < -height_m)
    p = camera.C[:2] + np.where(ok, t, 0.0)[:, None] * d[:, :2]
    towards = camera.C[:2] - p
    norm = np.linalg.norm(towards, axis=1, keepdims=True)
    p = np.where(norm > 1e-9, p + offset_m * towards / np.where(norm > 1e-9, norm, 1.0), p)
    p[~ok] = np.nan
    return p


def players_on_grass_by_heads(views: Sequence[tuple[Camera, Mapping[PlayerKey, np.ndarray]]],
                              max_spread_m: float = 1.5) -> dict[PlayerKey, GrassPlayer]:
    """Where players stand whom well-calibrated views see only by their heads (the image cuts their feet), fused as
    :func:`players_on_grass` fuses foot points: each head point (key -> (2,) px, :func:`head_pixel`) carried to the
    ground by :func:`head_grass_points`. Its covariance adds to the pixel noise (:data:`FOOT_SIGMA_PX`) and the
    footprint's (:data:`FOOT_OFFSET_SIGMA_M`) the stature's (:data:`HEAD_SIGMA_M`) along the ray: a head
    ``HEAD_SIGMA_M`` higher is ``HEAD_SIGMA_M * d / h`` farther, d the ground distance from the camera, h the
    camera's height above the head (similar triangles)."""
    seen: dict[PlayerKey, list[tuple[np.ndarray, np.ndarray]]] = {}
    for camera, heads in views:
        sigma = FOOT_SIGMA_PX * float(camera.K[0, 2] * 2 + 1) / REFERENCE_WIDTH_PX
        keys = list(heads)
        if not keys:
            continue
        uv = np.array([np.asarray(heads[k], float) for k in keys])
        g = head_grass_points(camera, np.concatenate([uv, uv + [0.5, 0.0], uv + [0.0, 0.5]])).reshape(3, len(keys), 2)
        ok = ~(np.isnan(g[0, :, 0]) | np.isnan(g[1, :, 0]) | np.isnan(g[2, :, 0]))
        above = -float(camera.C[2]) - HEAD_HEIGHT_M
        for k, kept, p, p1, p2 in zip(keys, ok, g[0], g[1], g[2], strict=True):
            if not kept:
                continue
            J = np.column_stack([(p1 - p) / 0.5, (p2 - p) / 0.5])
            away = p - camera.C[:2]
            dist = float(np.linalg.norm(away))
            u = away / max(dist, 1e-9)
            cov = (sigma**2 * J @ J.T + FOOT_OFFSET_SIGMA_M**2 * _EYE2
                   + (HEAD_SIGMA_M * dist / above) ** 2 * np.outer(u, u))
            seen.setdefault(k, []).append((p, np.linalg.inv(cov)))
    return _fused(seen, max_spread_m)
