"""``ISSIA-3D.csv`` (:data:`ISSIA3D_COLUMNS`): one row per frame, per camera K ``x_camK, y_camK,
err_camK`` (reprojection error of ``ball_3D``, px), ``opt_d_camK`` (optimised box diameter, px),
``opt_e_camK`` (its ``optimized_error``, m), then ``num_cameras`` (labels in the frame), ``ball_3D``
(JSON ``[x, y, z]`` m, the frame's own triangulation, empty with fewer than two kept cameras),
``cam_list`` (JSON list of those camera numbers), and v3d's ``ball_3D_smoothed`` (trajectory
position) and ``ball_3D_source`` (``triangulated``, ``fitted``, ``interpolated``). Numbers are
written with Python's shortest round-trip repr, so export -> import is exact.
"""
from __future__ import annotations

import csv
import functools
import json
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Iterable, Mapping, Sequence

import numpy as np

from app.core.errors import DatasetError
from app.datasets.csv_cells import inert_cell, read_cell
from app.datasets.files import json_problem
from app.datasets.issia import CAMERA_IDS, IssiaSequence
from app.geometry.ball import optimise_box
from app.geometry.camera import Camera
from app.geometry.pitch import BALL_DIAMETER_M

_PER_CAMERA = ("x", "y", "err", "opt_d", "opt_e")
ISSIA3D_COLUMNS = ("frame", *(f"{c}_cam{k}" for k in CAMERA_IDS for c in _PER_CAMERA), "num_cameras", "ball_3D",
                   "cam_list", "ball_3D_smoothed", "ball_3D_source")


@dataclass(frozen=True)
class Issia3DRow:
    """One frame of ``ISSIA-3D.csv``; camera numbers are 1..6 and ``per_camera[k]`` holds
    ``(x, y, err, opt_d, opt_e)`` with ``None`` for empty cells."""

    frame: int
    per_camera: dict[int, tuple[float | None, ...]]
    num_cameras: int
    ball_3d: tuple[float, float, float] | None
    cam_list: tuple[int, ...]
    ball_3d_smoothed: tuple[float, float, float] | None
    ball_3d_source: str | None


def _num(v: float | None) -> str:
    return "" if v is None or not math.isfinite(v) else repr(float(v))


def _vec(v: Sequence[float] | None) -> str:
    return "" if v is None else "[" + ", ".join(repr(float(x)) for x in v) + "]"


def issia3d_row_cells(row: Issia3DRow) -> dict[str, str]:
    """The cells of one row, keyed by :data:`ISSIA3D_COLUMNS`."""
    cells = {"frame": str(int(row.frame))}
    for k in CAMERA_IDS:
        vals = row.per_camera.get(int(k), (None,) * 5)
        for c, v in zip(_PER_CAMERA, vals, strict=False):
            cells[f"{c}_cam{k}"] = _num(v)
    cells.update(num_cameras=str(int(row.num_cameras)), ball_3D=_vec(row.ball_3d),
                 cam_list="[" + ", ".join(str(int(c)) for c in row.cam_list) + "]",
                 ball_3D_smoothed=_vec(row.ball_3d_smoothed), ball_3D_source=row.ball_3d_source or "")
    return cells


def write_issia3d_csv(path: str | Path, rows: Iterable[Issia3DRow]) -> None:
    """Write ``ISSIA-3D.csv`` (UTF-8, header :data:`ISSIA3D_COLUMNS`; every cell through
    ``app.datasets.csv_cells.inert_cell``: numbers stay numbers, no text cell is ever a formula)."""
    with open(path, "w", newline="", encoding="utf-8") as fh:
        w = csv.DictWriter(fh, fieldnames=ISSIA3D_COLUMNS)
        w.writeheader()
        for row in rows:
            w.writerow({k: inert_cell(v) for k, v in issia3d_row_cells(row).items()})


def read_issia3d_csv(path: str | Path) -> list[Issia3DRow]:
    """Read ``ISSIA-3D.csv`` back into rows (exact inverse of :func:`write_issia3d_csv`).

    Raises:
        DatasetError: missing columns, or a cell that does not parse (names row and column).
    """
    path = Path(path)
    with open(path, newline="", encoding="utf-8") as fh:
        reader = csv.DictReader(fh)
        missing = [c for c in ISSIA3D_COLUMNS if c not in (reader.fieldnames or [])]
        if missing:
            raise DatasetError(path, missing[0], "column missing")
        out = []
        for n, r in enumerate(reader, start=2):
            cell = functools.partial(_cell, path, n, r)
            source = read_cell(r["ball_3D_source"] or "").strip() or None
            if source not in (None, "triangulated", "fitted", "interpolated"):
                raise DatasetError(path, f"row {n} ball_3D_source", f"unknown source {source!r}")
            out.append(Issia3DRow(
                frame=cell("frame", int),
                per_camera={int(k): tuple(cell(f"{c}_cam{k}", float) for c in _PER_CAMERA) for k in CAMERA_IDS},
                num_cameras=cell("num_cameras", int) or 0, ball_3d=cell("ball_3D", _parsed_vec),
                cam_list=tuple(int(c) for c in (cell("cam_list", json.loads) or [])),
                ball_3d_smoothed=cell("ball_3D_smoothed", _parsed_vec), ball_3d_source=source))
    return out


def _cell(path: Path, n: int, row: Mapping[str, Any], col: str, parse: Any) -> Any:
    """Cell ``col`` of ``row`` (line ``n`` of ``path``) parsed by ``parse``; None when empty."""
    text = read_cell(row[col] or "").strip()
    try:
        return parse(text) if text else None
    except (ValueError, TypeError, RecursionError) as exc:
        said = json_problem(exc) or str(exc)
        raise DatasetError(path, f"row {n} {col}", f"cannot parse {text[:60]!r}: {said}") from None


def _parsed_vec(text: str) -> tuple[float, float, float]:
    v = json.loads(text)
    if not (isinstance(v, list) and len(v) == 3):
        raise ValueError("expected [x, y, z]")
    return (float(v[0]), float(v[1]), float(v[2]))


def issia3d_rows(seq: IssiaSequence, cameras: Mapping[str, Camera], fit: Any, *,
                 ball_diameter_m: float = BALL_DIAMETER_M,
                 box_method: str = "paper") -> list[Issia3DRow]:
    """Build the ``ISSIA-3D.csv`` rows of ``seq`` from a :class:`app.geometry.trajectory.TrajectoryFit`.

    ``fit`` was made on ``seq.dense_points()`` with cameras in ``seq.camera_ids`` order; ``cameras``
    are those cameras by id. Per label: ``err`` is the reprojection error (px) of the frame's
    ``ball_3D``, ``opt_d``/``opt_e`` the optimised box (method.md section 7,
    :func:`app.geometry.ball.optimise_box`) for that ball; all empty when the frame has no ``ball_3D``.
    """
    rows = []
    for i, frame in enumerate(seq.frames):
        ball = fit.ball_3d[frame]
        has_ball = bool(np.all(np.isfinite(ball)))
        per_camera: dict[int, tuple[float | None, ...]] = {}
        for k, cid in enumerate(seq.camera_ids):
            p = seq.points[i, k]
            if not np.all(np.isfinite(p)):
                per_camera[int(cid)] = (None,) * 5
                continue
            err = d = e = None
            cam = cameras.get(cid)
            if has_ball and cam is not None:
                uv, front = cam.project(ball.reshape(1, 3))
                err = float(np.linalg.norm(uv[0] - p)) if front[0] else None
                box = optimise_box(cam, p, ball, ball_diameter_m, method=box_method)
                d, e = box.d_px, box.error_m
            per_camera[int(cid)] = (float(p[0]), float(p[1]), err, d, e)
        smoothed = fit.positions[frame]
        rows.append(Issia3DRow(
            frame=int(frame), per_camera=per_camera,
            num_cameras=int(np.sum(np.all(np.isfinite(seq.points[i]), axis=1))),
            ball_3d=(float(ball[0]), float(ball[1]), float(ball[2])) if has_ball else None,
            cam_list=tuple(int(seq.camera_ids[k]) for k in fit.cam_lists[frame]),
            ball_3d_smoothed=((float(smoothed[0]), float(smoothed[1]), float(smoothed[2]))
                              if np.all(np.isfinite(smoothed)) else None),
            ball_3d_source=fit.sources[frame]))
    return rows


