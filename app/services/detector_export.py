"""Export of the curated labels for training ball detectors: Ultralytics YOLO and COCO layouts.

Both exports write every view (frame) of the selected systems that has an image:

* the **ball box** is the view's optimised box (paper Eq. min_diametre, consistent with the system's
  3D ball) where it has one, else the annotated box; a view whose ball is only a point (or was
  removed by a reviewer) gets no ball box, and a point-only view is skipped altogether (its ball is
  visible but has no box, which would teach a detector a false negative);
* the **other boxes** (players, goalkeepers, referees, ...) are not stored by the importer: they are
  read at export time from the game's source ``Labels-v3.json`` (``Game.source_path``), class names
  as in the source. Games imported from elsewhere (SoccerNet-v3D trees, SoccerNet-calibration) have
  balls only.

Class ids: 0 is ``Ball``, then :data:`OTHER_CLASSES` (the SoccerNet-v3 box classes); an unknown
source class is skipped and counted. Image names are ``<game slug>-<hash>_<frame stem>``
(:func:`image_stem`), unique across games; evaluation (``app.services.monocular``) matches
predictions to views by this stem (YOLO) or by the COCO image id, which is the frame's database id.
Splits are those of the SoccerNet-v3D export (:func:`app.services.exporting.split_of`).

Layouts:

* YOLO: ``images/<split>/<stem>.<ext>``, ``labels/<split>/<stem>.txt`` (``class cx cy w h``, normalised
  by the image size), ``data.yaml`` (``path``, ``train``, ``val``, ``test``, ``names``).
* COCO: ``<split>/<stem>.<ext>`` and ``<split>/instances.json`` beside them (boxes ``[x, y, w, h]``
  pixels, category ids = class id + 1).

Images are copied one at a time from their archive or file (never all in memory); the COCO metadata
of a split (numbers only) is kept until its JSON is written.
"""
from __future__ import annotations

import hashlib
import json
import re
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Iterator, Literal

from sqlalchemy import select
from sqlalchemy.orm import Session, selectinload

from app.db.models import Frame, Game, ReviewDecision, ReviewStatus, System
from app.services.exporting import split_of
from app.services.views import ImageUnavailable, frame_image

BALL_CLASS = "Ball"
#: SoccerNet-v3 box classes other than the ball, in class-id order after it.
OTHER_CLASSES = (
    "Player team left", "Player team right", "Goalkeeper team left", "Goalkeeper team right",
    "Main referee", "Side referee", "Staff members", "Player", "Goalkeeper",
)
CLASSES = (BALL_CLASS, *OTHER_CLASSES)
SPLITS = ("train", "test")
_SOURCE_LABELS = ("Labels-v3.json",)


@dataclass
class DetectorExportReport:
    """What a YOLO or COCO export wrote."""

    out_dir: Path
    format: str
    images: dict[str, int] = field(default_factory=lambda: {s: 0 for s in SPLITS})
    ball_boxes: dict[str, int] = field(default_factory=lambda: {s: 0 for s in SPLITS})
    other_boxes: dict[str, int] = field(default_factory=lambda: {s: 0 for s in SPLITS})
    optimised_ball_boxes: int = 0
    skipped_without_image: int = 0
    skipped_point_only: int = 0
    unknown_classes: Counter = field(default_factory=Counter)

    def as_dict(self) -> dict[str, Any]:
        return {"out_dir": str(self.out_dir), "format": self.format, "images": self.images,
                "ball_boxes": self.ball_boxes, "other_boxes": self.other_boxes,
                "optimised_ball_boxes": self.optimised_ball_boxes,
                "skipped_without_image": self.skipped_without_image,
                "skipped_point_only": self.skipped_point_only, "unknown_classes": dict(self.unknown_classes)}


@dataclass(frozen=True)
class ExportView:
    """One exported view: where it is, its split and its boxes ``(class id, [x1, y1, x2, y2] px)``."""

    frame: Frame
    game: Game
    system: System
    split: str
    stem: str
    boxes: tuple[tuple[int, tuple[float, float, float, float]], ...]


def image_stem(game: Game, frame: Frame) -> str:
    """File stem of a view in the exports, unique across games: a slug of the match name, 8 hex digits
    of a hash of ``league/season/match`` and the frame's stem.

    >>> from app.db.models import Game, Frame
    >>> image_stem(Game(league="l", season="s", match="A 1 - 0 B"), Frame(name="12_3.png"))
    'A_1_-_0_B-80c8c009_12_3'
    """
    slug = re.sub(r"[^A-Za-z0-9-]+", "_", game.match).strip("_")[:40] or "game"
    digest = hashlib.sha256(game.path.encode("utf-8")).hexdigest()[:8]
    stem = Path(frame.name).stem
    return f"{slug}-{digest}_{re.sub(r'[^A-Za-z0-9-]+', '_', stem)}"


def ball_export_box(frame: Frame) -> tuple[list[float] | None, bool]:
    """The ball box a view is exported with: ``(box [x1, y1, x2, y2] px or None, is_optimised)``."""
    if frame.optimised_box is not None:
        return list(frame.optimised_box.box), True
    label = frame.ball_label
    if label is not None and label.box is not None:
        return list(label.box), False
    return None, False


def _source_boxes(game: Game) -> dict[str, list[dict[str, Any]]]:
    """Frame name -> the non-ball ``bboxes`` of the game's source ``Labels-v3.json`` (empty if none)."""
    for name in _SOURCE_LABELS:
        path = Path(game.source_path) / name
        if path.is_file():
            try:
                data = json.loads(path.read_text(encoding="utf-8"))
            except (OSError, ValueError):
                return {}
            out: dict[str, list[dict[str, Any]]] = {}
            for section in ("actions", "replays"):
                for fname, item in (data.get(section) or {}).items():
                    if isinstance(item, dict):
                        out[fname] = [b for b in item.get("bboxes", []) or []
                                      if isinstance(b, dict) and b.get("class") != BALL_CLASS]
            return out
    return {}


def _clip(box: list[float], width: int, height: int) -> tuple[float, float, float, float] | None:
    x1, y1, x2, y2 = max(0.0, box[0]), max(0.0, box[1]), min(float(width), box[2]), min(float(height), box[3])
    return (x1, y1, x2, y2) if x2 > x1 and y2 > y1 else None


def iter_export_views(session: Session, include_all: bool, report: DetectorExportReport) -> Iterator[ExportView]:
    """The views to export, game by game (systems accepted unless ``include_all``), with their boxes.

    Counts skipped views in ``report``.
    """
    query = (
        select(System).join(System.game).outerjoin(ReviewDecision, ReviewDecision.system_id == System.id)
        .options(selectinload(System.game),
                 selectinload(System.frames).selectinload(Frame.ball_label),
                 selectinload(System.frames).selectinload(Frame.optimised_box))
        .order_by(Game.league, Game.season, Game.match, System.id)
    )
    if not include_all:
        query = query.where(ReviewDecision.status == ReviewStatus.ACCEPTED)
    source: dict[int, dict[str, list[dict[str, Any]]]] = {}
    for system in session.scalars(query):
        game = system.game
        if game.id not in source:
            source.clear()  # one game at a time
            source[game.id] = _source_boxes(game)
        for frame in system.frames:
            if not (frame.image_path or (frame.image_zip and frame.image_member)):
                report.skipped_without_image += 1
                continue
            ball, optimised = ball_export_box(frame)
            label = frame.ball_label
            if ball is None and label is not None and label.kind is not None:
                report.skipped_point_only += 1
                continue
            boxes: list[tuple[int, tuple[float, float, float, float]]] = []
            if ball is not None and (b := _clip(ball, frame.width, frame.height)) is not None:
                boxes.append((0, b))
                report.optimised_ball_boxes += int(optimised)
            for raw in source[game.id].get(frame.name, []):
                cls = raw.get("class")
                if cls not in CLASSES:
                    report.unknown_classes[str(cls)] += 1
                    continue
                pts = raw.get("points") or {}
                try:
                    box = [float(pts[k]) for k in ("x1", "y1", "x2", "y2")]
                except (KeyError, TypeError, ValueError):
                    report.unknown_classes["<box without x1, y1, x2, y2>"] += 1
                    continue
                if (b := _clip(box, frame.width, frame.height)) is not None:
                    boxes.append((CLASSES.index(cls), b))
            yield ExportView(frame, game, system, split_of(game.path), image_stem(game, frame), tuple(boxes))


def _copy_image(frame: Frame, dest_without_ext: Path) -> Path | None:
    try:
        img = frame_image(frame)
    except ImageUnavailable:
        return None
    ext = Path(img.member or (img.path.name if img.path else "x.png")).suffix or ".png"
    dest = dest_without_ext.with_suffix(ext)
    with dest.open("wb") as fh:
        for chunk in img.chunks():
            fh.write(chunk)
    return dest


def _count(report: DetectorExportReport, view: ExportView) -> None:
    report.images[view.split] += 1
    report.ball_boxes[view.split] += sum(1 for c, _ in view.boxes if c == 0)
    report.other_boxes[view.split] += sum(1 for c, _ in view.boxes if c != 0)


def export_yolo(session: Session, out_dir: str | Path, include_all: bool = False) -> DetectorExportReport:
    """Write the Ultralytics YOLO layout under ``out_dir`` (module docstring); existing files of the
    same names are overwritten.

    Returns:
        A :class:`DetectorExportReport` (images and boxes per split, skipped views).
    """
    out = Path(out_dir)
    report = DetectorExportReport(out, "yolo")
    for split in SPLITS:
        (out / "images" / split).mkdir(parents=True, exist_ok=True)
        (out / "labels" / split).mkdir(parents=True, exist_ok=True)
    for view in iter_export_views(session, include_all, report):
        if _copy_image(view.frame, out / "images" / view.split / view.stem) is None:
            report.skipped_without_image += 1
            continue
        w, h = view.frame.width, view.frame.height
        lines = [f"{c} {(b[0] + b[2]) / 2 / w:.8f} {(b[1] + b[3]) / 2 / h:.8f} {(b[2] - b[0]) / w:.8f} "
                 f"{(b[3] - b[1]) / h:.8f}" for c, b in view.boxes]
        (out / "labels" / view.split / f"{view.stem}.txt").write_text("".join(s + "\n" for s in lines))
        _count(report, view)
    names = "\n".join(f"  {i}: {json.dumps(n)}" for i, n in enumerate(CLASSES))
    (out / "data.yaml").write_text(
        f"# v3d export: ball = class 0 (optimised box where the view has one)\npath: {json.dumps(str(out.resolve()))}\n"
        f"train: images/train\nval: images/test\ntest: images/test\nnc: {len(CLASSES)}\nnames:\n{names}\n")
    return report


def export_coco(session: Session, out_dir: str | Path, include_all: bool = False) -> DetectorExportReport:
    """Write the COCO layout under ``out_dir``: per split the images and ``instances.json``.

    COCO image ids are the frames' database ids; category ids are the class ids + 1.
    """
    out = Path(out_dir)
    report = DetectorExportReport(out, "coco")
    docs: dict[str, dict[str, list]] = {s: {"images": [], "annotations": []} for s in SPLITS}
    for split in SPLITS:
        (out / split).mkdir(parents=True, exist_ok=True)
    for view in iter_export_views(session, include_all, report):
        dest = _copy_image(view.frame, out / view.split / view.stem)
        if dest is None:
            report.skipped_without_image += 1
            continue
        doc = docs[view.split]
        doc["images"].append({"id": view.frame.id, "file_name": dest.name, "width": view.frame.width,
                              "height": view.frame.height})
        for c, b in view.boxes:
            w, h = b[2] - b[0], b[3] - b[1]
            doc["annotations"].append({"id": len(doc["annotations"]) + 1, "image_id": view.frame.id,
                                       "category_id": c + 1, "bbox": [b[0], b[1], w, h], "area": w * h,
                                       "iscrowd": 0})
        _count(report, view)
    categories = [{"id": i + 1, "name": n, "supercategory": "ball" if i == 0 else "person"}
                  for i, n in enumerate(CLASSES)]
    for split, doc in docs.items():
        (out / split / "instances.json").write_text(json.dumps(
            {"info": {"description": f"v3d export ({split})"}, "licenses": [], "categories": categories, **doc}))
    return report


def export_detector(session: Session, fmt: Literal["yolo", "coco"], out_dir: str | Path,
                    include_all: bool = False) -> DetectorExportReport:
    """:func:`export_yolo` or :func:`export_coco` by name."""
    return (export_yolo if fmt == "yolo" else export_coco)(session, out_dir, include_all)
