"""Validation of ball labels shared by the importers and the editor.

Boxes are ``[x1, y1, x2, y2]`` and points ``[x, y]``, pixels of the frame (continuous coordinates,
origin at the top-left corner). A box partly outside the image is legitimate (a ball at the border);
a box entirely outside it, a degenerate box, a non-finite coordinate, or a box reaching farther than
:data:`BOX_REACH` image sizes beyond the image (no ball is seen so: ``[0, 0, 1e308, 1e308]`` made the 3D ball's
computation fail) is not. One check for every label that enters: edits and every importer.
"""
from __future__ import annotations

import math
from typing import Any, Sequence

#: How far beyond the image a ball box may reach, in image sizes (its width for x, its height for y): a ball at the
#: border is partly outside, a ball box is never larger than the image it is seen in.
BOX_REACH = 1.0


class LabelError(ValueError):
    """A ball label that cannot be stored; the message says why (the caller adds where)."""


def _numbers(values: Any, n: int, what: str) -> list[float]:
    if not isinstance(values, Sequence) or isinstance(values, (str, bytes)) or len(values) != n:
        raise LabelError(f"a {what} needs {n} numbers, got {values!r}")
    out: list[float] = []
    for v in values:
        if isinstance(v, bool):
            raise LabelError(f"a {what} needs numbers, got {values!r}")
        try:
            f = float(v)
        except (TypeError, ValueError):
            raise LabelError(f"a {what} needs numbers, got {values!r}") from None
        if not math.isfinite(f):
            raise LabelError(f"{what} coordinates must be finite numbers (found NaN or infinity): {values!r}")
        out.append(f)
    return out


def check_box(box: Any, width: int, height: int) -> list[float]:
    """A validated ball box ``[x1, y1, x2, y2]`` (floats, pixels).

    Raises:
        LabelError: not four finite numbers, ``x2 <= x1`` or ``y2 <= y1``, entirely outside the ``width`` x
            ``height`` image, or reaching farther than :data:`BOX_REACH` image sizes beyond it.

    >>> check_box([950, 10, 970, 30], 960, 540)  # partly outside: kept
    [950.0, 10.0, 970.0, 30.0]
    >>> check_box([970, 10, 990, 30], 960, 540)
    Traceback (most recent call last):
    ...
    app.datasets.labels.LabelError: box [970.0, 10.0, 990.0, 30.0] lies entirely outside the 960x540 image
    >>> check_box([0, 0, 1e308, 1e308], 960, 540)  # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    app.datasets.labels.LabelError: box [0.0, 0.0, 1e+308, 1e+308] reaches farther than ... no plausible ball label
    """
    x1, y1, x2, y2 = _numbers(box, 4, "box")
    if not (x2 > x1 and y2 > y1):
        raise LabelError(f"box {[x1, y1, x2, y2]} must have x2 > x1 and y2 > y1")
    if x2 <= 0 or y2 <= 0 or x1 >= width or y1 >= height:
        raise LabelError(f"box {[x1, y1, x2, y2]} lies entirely outside the {width}x{height} image")
    mx, my = BOX_REACH * width, BOX_REACH * height
    if x1 < -mx or y1 < -my or x2 > width + mx or y2 > height + my:
        raise LabelError(f"box {[x1, y1, x2, y2]} reaches farther than {BOX_REACH:g} image size beyond the "
                         f"{width}x{height} image (x in [{-mx:g}, {width + mx:g}], y in [{-my:g}, {height + my:g}]): "
                         "no plausible ball label")
    return [x1, y1, x2, y2]


def check_point(point: Any, width: int, height: int) -> list[float]:
    """A validated ball point ``[x, y]`` (floats, pixels) inside the image.

    Raises:
        LabelError: not two finite numbers, or outside ``[0, width] x [0, height]``.
    """
    x, y = _numbers(point, 2, "point")
    if not (0.0 <= x <= width and 0.0 <= y <= height):
        raise LabelError(f"point {[x, y]} lies outside the {width}x{height} image")
    return [x, y]


#: Edited field-line points may lie this fraction of the image's width or height outside it (annotated
#: points lie slightly outside: down to -0.4 % and up to 1.7 % in SoccerNet's sn22 test, method.md s11).
LINE_MARGIN = 0.05


def check_line_point_count(lines: dict[str, list[list[list[float]]]], max_points: int) -> int:
    """The number of points of a line set (every class and polyline; finite JSON lists, parsed already), or
    :class:`LabelError` when it exceeds ``max_points`` (``V3D_MAX_LINE_POINTS_PER_FRAME``: what one edit of a
    view may ask the calibration to fit).

    >>> check_line_point_count({"Middle line": [[[0, 0], [1, 1]], [[2, 2]]]}, 3)
    3
    >>> check_line_point_count({"Middle line": [[[0, 0], [1, 1]], [[2, 2]]]}, 2)
    Traceback (most recent call last):
    ...
    app.datasets.labels.LabelError: 3 points in all; at most 2 per view (V3D_MAX_LINE_POINTS_PER_FRAME)
    """
    n = sum(len(polyline) for polylines in lines.values() for polyline in polylines)
    if n > max_points:
        raise LabelError(f"{n} points in all; at most {max_points} per view (V3D_MAX_LINE_POINTS_PER_FRAME)")
    return n


def check_line_points(lines: dict[str, list[list[list[float]]]], width: int, height: int) -> None:
    """Refuse a line set with a point farther than :data:`LINE_MARGIN` of the image's size outside the
    ``width`` x ``height`` image (pixels); ``lines`` are finite JSON lists (parsed already).

    Raises:
        LabelError: naming the class, the polyline and the point.

    >>> check_line_points({"Middle line": [[[0, 0], [-60, 10]]]}, 960, 540)  # doctest: +NORMALIZE_WHITESPACE
    Traceback (most recent call last):
    ...
    app.datasets.labels.LabelError: class 'Middle line', polyline 0, point 1: [-60, 10] lies more than 5 % of the
    image's size outside the 960x540 image
    """
    mx, my = LINE_MARGIN * width, LINE_MARGIN * height
    for name, polylines in lines.items():
        for i, polyline in enumerate(polylines):
            for j, (x, y) in enumerate(polyline):
                if not (-mx <= x <= width + mx and -my <= y <= height + my):
                    raise LabelError(f"class {name!r}, polyline {i}, point {j}: {[x, y]} lies more than "
                                     f"{LINE_MARGIN * 100:g} % of the image's size outside the {width}x{height} image")
