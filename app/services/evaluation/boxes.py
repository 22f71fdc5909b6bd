"""The paper's Table 1 from the service: ball boxes against precise boxes (``v3d import precise-boxes``,
``v3d evaluate boxes``).

Precise boxes come as a CSV with the columns ``league,season,match,image,x1,y1,x2,y2`` (pixels of that image,
``x2 > x1``, ``y2 > y1``), one row per view, the image named as its kind names it (``KindPolicy.image_name``: a
SoccerNet frame's name such as ``12_1.png``; an ISSIA view ``cam<k>_<frame index, 6 digits>``);
:func:`store_precise_boxes` stores them on the frames (``frames.precise_box``) in one transaction, refusing the
whole file when a row names an unknown game or image.

:func:`evaluate_boxes` compares, over the views of the chosen systems (accepted by default, every system with
``include_all``) that have a precise box, three boxes with it (means over the ``n`` views that have each):

* ``original``: the ball box as imported (``ball_labels.original_box``);
* ``optimised``: v3d's optimised box (paper Eq. min_diametre, ``optimised_boxes.box``);
* ``refined``: v3d's refined box where the 3D ball is well constrained
  (``app.services.transfer.detector_export.refined_boxes``).

Figures: IoU (:func:`app.geometry.metrics.box_iou`) and size error, ``|diag(box) - diag(precise)| /
diag(precise)`` in percent (:func:`app.geometry.metrics.box_size_error_pct`, the paper's Table 1).
"""
from __future__ import annotations

import csv
import io
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import sqlalchemy as sa
from sqlalchemy.orm import Session, selectinload

from app.core.errors import DatasetError
from app.datasets.csv_cells import read_cell
from app.datasets.files import read_text_file
from app.datasets.labels import LabelError, check_box
from app.db.models import Frame, Game, ReviewDecision, ReviewStatus, System
from app.db.unit import write_unit
from app.geometry.metrics import box_iou, box_size_error_pct
from app.geometry.pitch import BALL_DIAMETER_M
from app.services.kinds import kind_of
from app.services.transfer.detector_export import BALL_BOX_LOADS, refined_boxes

PRECISE_COLUMNS = ("league", "season", "match", "image", "x1", "y1", "x2", "y2")
BOX_KINDS = ("original", "optimised", "refined")
#: Largest precise-box file read (bytes).
MAX_PRECISE_FILE_BYTES = 64 << 20


@dataclass(frozen=True)
class PreciseBox:
    """One row of a precise-box CSV: the view and its box ``(x1, y1, x2, y2)`` px."""

    league: str
    season: str
    match: str
    image: str
    box: tuple[float, float, float, float]
    row: int


def read_precise_boxes(path: str | Path) -> list[PreciseBox]:
    """The rows of a precise-box CSV (module docstring).

    Raises:
        DatasetError: unreadable file, a missing column, a coordinate that is not a finite number, or a box
            with no area (the message names the row and column).
    """
    path = Path(path)
    text = read_text_file(path, MAX_PRECISE_FILE_BYTES, "CSV")
    reader = csv.DictReader(io.StringIO(text))
    missing = [c for c in PRECISE_COLUMNS if c not in (reader.fieldnames or [])]
    if missing:
        raise DatasetError(path, missing[0], "column missing")
    out = []
    for n, r in enumerate(reader, start=2):
        try:
            box = (float(r["x1"]), float(r["y1"]), float(r["x2"]), float(r["y2"]))
        except (TypeError, ValueError):
            raise DatasetError(path, f"row {n} x1..y2", "not numbers") from None
        if not all(math.isfinite(v) for v in box):
            raise DatasetError(path, f"row {n} x1..y2", "not finite")
        if box[2] <= box[0] or box[3] <= box[1]:
            raise DatasetError(path, f"row {n} x1..y2", "the box has no area (needs x2 > x1 and y2 > y1)")
        # as a v3d CSV escaped them
        league, season, match, image = (read_cell(r[c] or "") for c in ("league", "season", "match", "image"))
        out.append(PreciseBox(league, season, match, image, box, n))
    return out


def store_precise_boxes(session: Session, path: str | Path) -> int:
    """Store the precise boxes of the CSV ``path`` on their frames (``frames.precise_box``), all or none;
    commits. Returns the number of frames set.

    Raises:
        DatasetError: the file cannot be read (:func:`read_precise_boxes`), a row names a game or image
            that is not stored, or its box is no ball box of that image (``app.datasets.labels.check_box``; nothing
            stored).
    """
    rows = read_precise_boxes(path)
    games = {(g.league, g.season, g.match): g.id for g in session.scalars(sa.select(Game))}
    frames: dict[tuple[int, str], list[Frame]] = {}
    wanted_games = {games.get((r.league, r.season, r.match)) for r in rows} - {None}
    for f in session.scalars(sa.select(Frame).join(System).where(System.game_id.in_(wanted_games))
                             .options(selectinload(Frame.system))):
        frames.setdefault((f.system.game_id, kind_of(f.system).image_name(f)), []).append(f)
    updates: list[tuple[Any, list[float]]] = []
    for r in rows:
        gid = games.get((r.league, r.season, r.match))
        if gid is None:
            raise DatasetError(path, f"row {r.row} match", f"no stored game {r.league}/{r.season}/{r.match}")
        found = frames.get((gid, r.image))
        if not found:
            raise DatasetError(path, f"row {r.row} image", f"no stored image {r.image!r} in {r.match}")
        for f in found:  # the one check of every ball box that enters (its image's plausible range included)
            try:
                updates.append((f, check_box(list(r.box), f.width, f.height)))
            except LabelError as exc:
                raise DatasetError(path, f"row {r.row} x1..y2", str(exc)) from None
    with write_unit(session, lock=False):
        for f, box in updates:
            f.precise_box = box
    return len(updates)


def _summary(boxes: list[np.ndarray], precise: list[np.ndarray]) -> dict[str, Any]:
    if not boxes:
        return {"n": 0, "iou": None, "size_error_pct": None}
    a, b = np.asarray(boxes, float), np.asarray(precise, float)
    return {"n": len(boxes), "iou": float(np.mean(box_iou(a, b))),
            "size_error_pct": float(np.mean(box_size_error_pct(a, b)))}


def evaluate_boxes(session: Session, include_all: bool = False,
                   ball_diameter_m: float = BALL_DIAMETER_M) -> dict[str, Any]:
    """``{"original": {"n", "iou", "size_error_pct"}, "optimised": {...}, "refined": {...}, "views": n}``
    over the views with a precise box of the chosen systems (module docstring); ``iou`` and
    ``size_error_pct`` are None where ``n`` is 0."""
    query = (sa.select(System).outerjoin(ReviewDecision, ReviewDecision.system_id == System.id)
             .where(System.id.in_(sa.select(Frame.system_id).where(Frame.precise_box.is_not(None))))
             .options(*BALL_BOX_LOADS, selectinload(System.game)).order_by(System.id))
    if not include_all:
        query = query.where(ReviewDecision.status == ReviewStatus.ACCEPTED)
    pairs: dict[str, tuple[list[np.ndarray], list[np.ndarray]]] = {k: ([], []) for k in BOX_KINDS}
    views = 0
    for system in session.scalars(query):
        refined = refined_boxes(system, ball_diameter_m)
        for f in system.frames:
            if f.precise_box is None:
                continue
            views += 1
            p = np.asarray(f.precise_box, float)
            label = f.ball_label
            candidates = {
                "original": label.original_box if label is not None else None,
                "optimised": f.optimised_box.box if f.optimised_box is not None else None,
                "refined": refined.get(f.id),
            }
            for k, box in candidates.items():
                if box is not None:
                    pairs[k][0].append(np.asarray(box, float))
                    pairs[k][1].append(p)
    out: dict[str, Any] = {k: _summary(*pairs[k]) for k in BOX_KINDS}
    out["views"] = views
    return out
