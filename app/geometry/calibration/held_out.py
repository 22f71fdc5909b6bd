"""Held-out-class measure of a calibration: does the camera put the lines it has not seen where they are?

JaC rewards fitting the very lines it scores. The held-out-class measure asks instead: with
one labelled class removed, does the camera fitted on the others project that class onto its
annotated points? For every frame with at least :data:`MIN_CLASSES` eligible classes (model classes
with two points or more, counted before removal, goal posts and crossbars included), one class is
drawn by a seeded random choice (:func:`draw_held_out_class`), the frame is fitted without it, and
every annotated point of that class is measured against that class's projection
(:func:`class_point_distances`). The figure of a set is the share of all held-out points within
5 px (960x540) and their median distance.

Distances: a point on a straight element (side lines, box lines, goal posts, crossbars) is measured
to the projected 3D segment (its line distance and its distance beyond the projected ends); a point
on a circle by Sampson's first-order distance to the projected conic; with the camera's ``k1`` the
annotated (distorted) points are undistorted first (:mod:`.residuals`, the fit's own distances).

Image: pixels of the frame; world: SoccerNet (metres, centre spot origin, z down).
"""
from __future__ import annotations

import zlib

import numpy as np

from app.geometry.annotations import FieldLines
from app.geometry.calibration.observations import Observations, build_observations
from app.geometry.calibration.residuals import point_distances, projection_matrix, undistort_radial_k1
from app.geometry.camera import Camera
from app.geometry.pitch import UNKNOWN_CLASSES

#: Fewest eligible classes a frame needs to take part in the measure.
MIN_CLASSES = 5
#: Fewest annotated points of an eligible class.
MIN_POINTS = 2


def eligible_classes(lines: FieldLines) -> list[str]:
    """Model classes of ``lines`` with at least :data:`MIN_POINTS` annotated points, sorted.

    ``lines``: :data:`~app.geometry.annotations.FieldLines` (class -> list of (N, 2) pixel arrays).
    "Line unknown" and "Goal unknown" have no model element and are never eligible.
    """
    return sorted(c for c, polys in lines.items()
                  if c not in UNKNOWN_CLASSES and sum(len(np.asarray(p).reshape(-1, 2)) for p in polys) >= MIN_POINTS)


def draw_held_out_class(frame: str, lines: FieldLines, seed: int) -> str | None:
    """The class held out of ``frame`` for class-draw ``seed``, or ``None`` when the frame has fewer
    than :data:`MIN_CLASSES` eligible classes (:func:`eligible_classes`).

    The draw depends only on ``(seed, frame, eligible classes)``: ``numpy.random.default_rng`` seeded
    with ``[seed, crc32(frame)]``, so that a subset of a set draws what the whole set draws.
    """
    classes = eligible_classes(lines)
    if len(classes) < MIN_CLASSES:
        return None
    rng = np.random.default_rng([int(seed), zlib.crc32(frame.encode("utf-8"))])
    return classes[int(rng.integers(len(classes)))]


def class_point_distances(camera: Camera, lines: FieldLines) -> dict[str, np.ndarray]:
    """Distance (px, >= 0) of every annotated point of each model class to that class's projection.

    Args:
        camera: pinhole camera with at most SoccerNet's ``k1`` radial term (pixels of the frame).
        lines: :data:`~app.geometry.annotations.FieldLines` in the same pixels.

    Returns:
        ``{class: (N,) distances}`` for every model class of ``lines`` with points (unknown classes
        left out), in the order of the class's points.
    """
    return distances_by_class(camera, build_observations(lines))


def distances_by_class(camera: Camera, obs: Observations) -> dict[str, np.ndarray]:
    """:func:`class_point_distances` of already paired observations (:class:`~.observations.Observations`)."""
    f = float(camera.K[0, 0])
    pp = camera.K[:2, 2]
    k1 = float(camera.radial[0])
    P = projection_matrix(f, pp, camera.R, camera.C)
    d_seg, d_cir = point_distances(P, obs, undistort_radial_k1(obs.seg_points, f, pp, k1),
                                   undistort_radial_k1(obs.circle_points, f, pp, k1))
    out: dict[str, np.ndarray] = {}
    for classes, d, idx in ((obs.seg_classes, d_seg, obs.seg_index), (obs.circle_classes, d_cir, obs.circle_index)):
        for i, c in enumerate(classes):
            out[c] = np.abs(d[idx == i])
    return out


def without_class(lines: FieldLines, cls: str) -> FieldLines:
    """``lines`` without class ``cls`` (a new mapping; the arrays are shared)."""
    return {c: v for c, v in lines.items() if c != cls}
