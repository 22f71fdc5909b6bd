"""Field-line annotations of one frame: parsing, validation, pixel conventions, mirroring.

A frame's annotation is a :class:`FieldLines`: line class -> list of polylines, each an (N, 2)
float array of **pixels** of that frame (continuous coordinates, origin at the top-left corner).
A class may appear more than once (a circle cut by the image border gives two polylines), so every
class maps to a list.

Two sources:

* SoccerNet-calibration JSON: ``{"<class>": [{"x": .., "y": ..}, ...]}`` normalised to the image.
  Normalised points become pixels as ``x (W - 1), y (H - 1)``, the conversion of SoccerNet's official
  evaluator (``src/evaluate_extremities.py``, ``scale_points``), so that JaC computed on v3d pixels is
  the official JaC. Points slightly outside [0, 1] are kept as they are (method.md section 11).
* SoccerNet-v3 ``Labels-v3.json``: ``lines: [{"class": .., "points": [x1, y1, x2, y2, ...]}]`` in
  pixels of that image; taken as given.
"""
from __future__ import annotations

import math
from typing import Any, Iterable, Mapping

import numpy as np

from app.geometry.pitch import LINE_CLASSES, MIRROR_CLASSES

FieldLines = dict[str, list[np.ndarray]]

_VALID = frozenset(LINE_CLASSES)


class AnnotationError(ValueError):
    """A field-line annotation is malformed; the message names the class and point at fault."""


def _check_class(line_class: Any, where: str) -> str:
    if not isinstance(line_class, str) or line_class not in _VALID:
        raise AnnotationError(f"{where}: unknown line class {line_class!r}")
    return line_class


def _check_points(points: np.ndarray, where: str) -> np.ndarray:
    if points.ndim != 2 or points.shape[1] != 2 or len(points) == 0:
        raise AnnotationError(f"{where}: a polyline needs at least one (x, y) point")
    if not np.all(np.isfinite(points)):
        raise AnnotationError(f"{where}: coordinates must be finite numbers (found NaN or infinity)")
    return points


def from_soccernet_calibration(data: Mapping[str, Any], width: int, height: int) -> FieldLines:
    """Parse a SoccerNet-calibration frame JSON (normalised points) into pixel polylines.

    Args:
        data: ``{"<class>": [{"x": float, "y": float}, ...]}``; a value may also be a list of such
            lists (several polylines of one class, as v3d writes them).
        width, height: image size in pixels; points become ``x (W - 1), y (H - 1)``.

    Returns:
        :data:`FieldLines` in pixels.

    Raises:
        AnnotationError: unknown class, a point without numeric ``x``/``y``, NaN or infinity, an
        image smaller than 2 x 2 (or NaN). An empty point list is dropped, as SoccerNet's evaluator
        drops it.

    >>> fl = from_soccernet_calibration({"Middle line": [{"x": 0.5, "y": 0.0}, {"x": 0.5, "y": 1.0}]}, 961, 541)
    >>> fl["Middle line"][0].tolist()
    [[480.0, 0.0], [480.0, 540.0]]
    """
    if not isinstance(data, Mapping):
        raise AnnotationError("field-line annotation must be a JSON object of class -> points")
    if not (width >= 2 and height >= 2):  # NaN fails too
        raise AnnotationError(f"image size must be at least 2x2 pixels, got {width}x{height}")
    out: FieldLines = {}
    scale = np.array([width - 1.0, height - 1.0])
    for cls, value in data.items():
        _check_class(cls, "field lines")
        groups = value if value and isinstance(value, list) and isinstance(value[0], list) else [value]
        for gi, group in enumerate(groups):
            where = f"field lines, class {cls!r}, polyline {gi}"
            if not isinstance(group, list):
                raise AnnotationError(f"{where}: expected a list of {{'x', 'y'}} points")
            if not group:
                continue  # an empty class carries no constraint; SoccerNet's evaluator drops it too
            try:
                pts = np.array([[float(p["x"]), float(p["y"])] for p in group], dtype=float).reshape(-1, 2)
            except (TypeError, KeyError, ValueError) as exc:
                raise AnnotationError(f"{where}: every point needs numeric 'x' and 'y'") from exc
            out.setdefault(cls, []).append(_check_points(pts, where) * scale)
    return out


def to_soccernet_calibration(lines: FieldLines, width: int, height: int) -> dict[str, Any]:
    """Inverse of :func:`from_soccernet_calibration`. A class with one polyline is written as a
    plain list of points (the SoccerNet form); several polylines as a list of lists."""
    scale = np.array([width - 1.0, height - 1.0])
    out: dict[str, Any] = {}
    for cls, polys in lines.items():
        conv = [[{"x": float(x), "y": float(y)} for x, y in (p / scale)] for p in polys]
        out[cls] = conv[0] if len(conv) == 1 else conv
    return out


def from_soccernet_v3(lines: Iterable[Mapping[str, Any]], width: int, height: int) -> FieldLines:
    """Parse the ``lines`` list of a SoccerNet-v3 frame (pixels, flat ``[x1, y1, x2, y2, ...]``).

    Repeated classes are kept as separate polylines.

    Raises:
        AnnotationError: unknown class, odd number of coordinates, non-numeric or non-finite values.
    """
    out: FieldLines = {}
    for i, item in enumerate(lines):
        if not isinstance(item, Mapping):
            raise AnnotationError(f"lines[{i}]: expected an object with 'class' and 'points'")
        cls = _check_class(item.get("class"), f"lines[{i}]")
        flat = item.get("points")
        where = f"lines[{i}] ({cls!r})"
        if not isinstance(flat, list) or len(flat) % 2:
            raise AnnotationError(f"{where}: 'points' must be a flat list [x1, y1, x2, y2, ...]")
        try:
            pts = np.array([float(v) for v in flat], dtype=float).reshape(-1, 2)
        except (TypeError, ValueError) as exc:
            raise AnnotationError(f"{where}: coordinates must be numbers") from exc
        out.setdefault(cls, []).append(_check_points(pts, where))
    return out


def mirror_lines(lines: FieldLines) -> FieldLines:
    """Relabel every class by the pitch's 180-degree rotation (SoccerNet ``mirror_labels``).

    The points stay where they are in the image; only the class names change. This is the fix
    offered for a frame whose labels are probably mirrored.
    """
    out: FieldLines = {}
    for cls, polys in lines.items():
        out.setdefault(MIRROR_CLASSES[cls], []).extend(p.copy() for p in polys)
    return out


def lines_from_json_lists(data: Mapping[str, Any]) -> FieldLines:
    """Pixel polylines from ``{"<class>": [[[x, y], ...], ...]}`` (the form v3d stores and the API
    takes; a polyline may also be a flat ``[x1, y1, x2, y2, ...]`` list).

    Raises:
        AnnotationError: unknown class, a polyline that is not a list of [x, y] number pairs, or
            non-finite coordinates; the message names the class and polyline at fault.

    >>> lines_from_json_lists({"Middle line": [[[480.0, 0.0], [470.0, 539.0]]]})["Middle line"][0].shape
    (2, 2)
    """
    if not isinstance(data, Mapping):
        raise AnnotationError("field lines must be an object of class -> list of polylines")
    out: FieldLines = {}
    for cls, polys in data.items():
        _check_class(cls, "field lines")
        if not isinstance(polys, list):
            raise AnnotationError(f"field lines, class {cls!r}: expected a list of polylines")
        for gi, poly in enumerate(polys):
            where = f"field lines, class {cls!r}, polyline {gi}"
            try:
                pts = np.array(poly, dtype=float)
            except (TypeError, ValueError) as exc:
                raise AnnotationError(f"{where}: expected [[x, y], ...] numbers") from exc
            if pts.ndim == 1 and pts.size % 2 == 0:
                pts = pts.reshape(-1, 2)  # a flat [x1, y1, x2, y2, ...] list, as SoccerNet-v3 writes points
            if pts.ndim != 2 or pts.shape[1] != 2:
                raise AnnotationError(f"{where}: expected [[x, y], ...] pixel pairs, got shape {pts.shape}")
            out.setdefault(cls, []).append(_check_points(pts, where))
    return out


def lines_to_json_lists(lines: FieldLines) -> dict[str, list[list[list[float]]]]:
    """Inverse of :func:`lines_from_json_lists`."""
    return {cls: [p.tolist() for p in polys] for cls, polys in lines.items()}


def image_diagonal(width: float, height: float) -> float:
    """Image diagonal in pixels; JaC@gamma uses ``gamma * diagonal`` as its threshold (method.md s4)."""
    return math.hypot(width, height)
