"""Export of the curated labels for training ball detectors: Ultralytics YOLO and COCO layouts.

Both exports write every view (frame) of the selected systems that has an image:

* the **ball box** (:func:`ball_boxes`) is, where the system's 3D ball is well constrained (the view
  is in a kept pair and another contributing view has a reprojection error), the **refined box** of
  :mod:`app.geometry.refined_box` (annotated centre and reprojection weighed by their uncertainties);
  else the view's optimised box (paper Eq. min_diametre, consistent with the 3D ball) where it has
  one, else the annotated box. The refined box won against the precise boxes of both synthetic dev
  sets (``benchmarks/refined_boxes.py``, mean IoU, v3d's own calibration: dev 0.567 annotated, 0.630
  paper, 0.634 optimised, 0.642 refined; dev-large 0.565, 0.613, 0.616, 0.640). A view whose ball is
  only a point (or was
  removed by a reviewer) gets no ball box, and a point-only view is skipped altogether (its ball is
  visible but has no box, which would teach a detector a false negative);
* the **other boxes** (players, goalkeepers, referees, ...) are the non-ball ``bboxes`` entries the release
  carries, stored at import (``frames.release``; SoccerNet-v3 trees and SoccerNet-v3D exports), class names
  as imported; no source file is read. Frames without them (SoccerNet-calibration, ISSIA) have balls only.

Class ids: 0 is ``Ball``, then :data:`OTHER_CLASSES` (the SoccerNet-v3 box classes); an unknown
source class is skipped and counted. Image names are ``<game slug>-<hash>_<frame stem>``
(ISSIA: ``<sequence slug>-<hash>_cam<k>_<frame index, 6 digits>``; the kind's ``view_stem``,
``app.services.kinds``), unique across games and views (a repeated name is an error, never an overwrite:
the files written are those the report counts); evaluation (``app.services.evaluation.monocular``) matches
predictions to views by this stem (YOLO) or by the COCO image id, :func:`coco_image_id` of the stem (stable
across databases and exports: a number derived from the name, never a database id).
Splits are the kind's (``split``, ``app.services.kinds``): a SoccerNet game's hash split as in the SoccerNet-v3D
export; ISSIA by camera as in the paper (cameras 1-2 test, 3-6 train).

Layouts:

* YOLO: ``images/<split>/<stem>.<ext>``, ``labels/<split>/<stem>.txt`` (``class cx cy w h``, normalised
  by the image size), ``data.yaml`` (``train``, ``val``, ``test``, ``nc``, ``names``). ``data.yaml`` has no
  ``path:`` key and its split folders are relative: Ultralytics (``check_det_dataset``) then takes the folder
  of ``data.yaml`` as the dataset root, so the export works wherever it is unpacked or moved. Both split
  folders always exist; a split without images is said so in a comment of ``data.yaml`` and in the
  report (``empty_splits``).
* COCO: ``<split>/<stem>.<ext>`` and ``<split>/instances.json`` beside them (boxes ``[x, y, w, h]``
  pixels, category ids = class id + 1).

Systems are read in batches of :data:`_CHUNK` and images copied one at a time from their archive or
file (never all in memory); the COCO metadata of a split (numbers only) is kept until its JSON is
written.
"""
from __future__ import annotations

import hashlib
import json
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Iterator, Literal

import numpy as np
from sqlalchemy.orm import Session, selectinload

from app.db.models import Frame, Game, System, Triangulation
from app.geometry.ball import box_centre_and_diameter
from app.geometry.camera import Camera
from app.geometry.pitch import BALL_DIAMETER_M
from app.geometry.refined_box import refine_box
from app.services.images.serving import ImageUnavailable, frame_image
from app.services.kinds import kind_of
from app.services.transfer.exporting import exported_systems

BALL_CLASS = "Ball"
#: SoccerNet-v3 box classes other than the ball, in class-id order after it.
OTHER_CLASSES = (
    "Player team left", "Player team right", "Goalkeeper team left", "Goalkeeper team right",
    "Main referee", "Side referee", "Staff members", "Player", "Goalkeeper",
)
CLASSES = (BALL_CLASS, *OTHER_CLASSES)
SPLITS = ("train", "test")
#: Standard deviation of an annotated ball centre as a fraction of the annotated box's diameter
#: (a prior: a hand-drawn box is off by a fraction of its size; not fitted to the dev truth).
ANNOTATION_SIGMA_FRACTION = 0.1
#: Smallest standard deviation used for either centre, pixels.
MIN_SIGMA_PX = 0.5
#: Systems read from the database per batch while exporting (the export never holds them all).
_CHUNK = 200


def coco_image_id(stem: str) -> int:
    """The COCO image id of the exported view named ``stem``: the first 12 hex digits (48 bits) of the SHA-256 of
    the stem's UTF-8 bytes, read as an integer.

    Stable across databases, re-imports and exports (a database id is not), and below 2**53 so that every JSON
    reader keeps it exact. Stems are unique within an export; at 48 bits two of a million stems share an id with
    probability about 2e-3, so :func:`export_coco` still refuses a repeated id rather than merging two images.
    """
    return int(hashlib.sha256(stem.encode("utf-8")).hexdigest()[:12], 16)


@dataclass
class DetectorExportReport:
    """What a YOLO or COCO export wrote."""

    out_dir: Path
    format: str
    images: dict[str, int] = field(default_factory=lambda: {s: 0 for s in SPLITS})
    ball_boxes: dict[str, int] = field(default_factory=lambda: {s: 0 for s in SPLITS})
    other_boxes: dict[str, int] = field(default_factory=lambda: {s: 0 for s in SPLITS})
    optimised_ball_boxes: int = 0
    refined_ball_boxes: int = 0
    skipped_without_image: int = 0
    skipped_point_only: int = 0
    unknown_classes: Counter = field(default_factory=Counter)

    @property
    def empty_splits(self) -> list[str]:
        """The splits that received no image (their folders exist, empty)."""
        return [s for s in SPLITS if not self.images[s]]

    def as_dict(self) -> dict[str, Any]:
        return {"out_dir": str(self.out_dir), "format": self.format, "images": self.images,
                "ball_boxes": self.ball_boxes, "other_boxes": self.other_boxes,
                "optimised_ball_boxes": self.optimised_ball_boxes,
                "refined_ball_boxes": self.refined_ball_boxes,
                "skipped_without_image": self.skipped_without_image,
                "skipped_point_only": self.skipped_point_only, "unknown_classes": dict(self.unknown_classes),
                "empty_splits": self.empty_splits}


@dataclass(frozen=True)
class ExportView:
    """One exported view: where it is, its split and its boxes ``(class id, [x1, y1, x2, y2] px)``."""

    frame: Frame
    game: Game
    system: System
    split: str
    stem: str
    boxes: tuple[tuple[int, tuple[float, float, float, float]], ...]


def refined_boxes(system: System, ball_diameter_m: float = BALL_DIAMETER_M,
                  sigma_fraction: float = ANNOTATION_SIGMA_FRACTION) -> dict[int, np.ndarray]:
    """Frame id -> refined ball box (4,) px of the views of ``system`` whose 3D ball is well constrained.

    A view qualifies when it is in a kept pair of the triangulation, has a box label, a calibration and
    an optimised box, and another contributing view has a reprojection error. Sigmas: the annotated
    centre ``sigma_fraction`` x the annotated box diameter; the reprojection the median reprojection
    error of the other contributing views (how far the fused ball lands from independent
    annotations, calibration error included); both at least :data:`MIN_SIGMA_PX`.
    Needs ``triangulation.pairs``, and per frame ``calibration``, ``ball_label``, ``optimised_box``
    and ``reprojection`` (loaded or lazily loadable).
    """
    tri: Triangulation | None = system.triangulation
    if tri is None or tri.ball3d is None:
        return {}
    ball = np.asarray(tri.ball3d, float)
    contributing = {i for p in tri.pairs if p.kept for i in (p.frame_a_id, p.frame_b_id)}
    errors = {f.id: f.reprojection.error_px for f in system.frames
              if f.id in contributing and f.reprojection is not None and f.reprojection.error_px is not None}
    out = {}
    for f in system.frames:
        label, cal = f.ball_label, f.calibration
        if (f.id not in contributing or f.optimised_box is None or label is None or label.box is None
                or cal is None or cal.camera is None):
            continue
        others = [e for i, e in errors.items() if i != f.id]
        if not others:
            continue
        centre, diameter = box_centre_and_diameter(np.asarray(label.box, float))
        try:
            r = refine_box(Camera.from_soccernet(cal.camera), centre[0], ball,
                           max(sigma_fraction * float(diameter[0]), MIN_SIGMA_PX),
                           max(float(np.median(others)), MIN_SIGMA_PX), ball_diameter_m)
        except ValueError:
            continue
        if r.box is not None:
            out[f.id] = r.box
    return out


def ball_boxes(system: System, ball_diameter_m: float = BALL_DIAMETER_M,
               ball_box: str = "refined") -> dict[int, tuple[list[float], str]]:
    """Frame id -> ``(box [x1, y1, x2, y2] px, source)`` of the views of ``system`` that have a ball box
    to export; source is ``"refined"``, ``"optimised"`` or ``"annotated"`` (module docstring). ``ball_box``
    (``Settings.export_ball_box``) "optimised" leaves the refined boxes out (the paper's choice). A view whose
    label is a placement no person has confirmed (``BallLabel.suggested``) has none."""
    refined = refined_boxes(system, ball_diameter_m) if ball_box == "refined" else {}
    out: dict[int, tuple[list[float], str]] = {}
    for f in system.frames:
        if f.ball_label is not None and f.ball_label.suggested:
            continue  # a placement no person has confirmed (a prediction's box, say) is exported by no format
        if f.id in refined:
            out[f.id] = ([float(v) for v in refined[f.id]], "refined")
        elif f.optimised_box is not None:
            out[f.id] = (list(f.optimised_box.box), "optimised")
        elif f.ball_label is not None and f.ball_label.box is not None:
            out[f.id] = (list(f.ball_label.box), "annotated")
    return out


#: What :func:`ball_boxes` reads, for ``selectinload`` on a ``System`` query.
BALL_BOX_LOADS = (
    selectinload(System.triangulation).selectinload(Triangulation.pairs),
    selectinload(System.frames).options(selectinload(Frame.calibration), selectinload(Frame.ball_label),
                                        selectinload(Frame.optimised_box), selectinload(Frame.reprojection)),
)


def _other_boxes(frame: Frame) -> list[Any]:
    """The non-ball ``bboxes`` entries of the frame's release (``frames.release``, as imported; ``[]`` without)."""
    boxes = (frame.release or {}).get("bboxes")
    return [b for b in boxes
            if not (isinstance(b, dict) and b.get("class") == BALL_CLASS)] if isinstance(boxes, list) else []


def _clip(box: list[float], width: int, height: int) -> tuple[float, float, float, float] | None:
    x1, y1, x2, y2 = max(0.0, box[0]), max(0.0, box[1]), min(float(width), box[2]), min(float(height), box[3])
    return (x1, y1, x2, y2) if x2 > x1 and y2 > y1 else None


def iter_export_views(session: Session, export: Literal["yolo", "coco"], include_all: bool,
                      report: DetectorExportReport, ball_diameter_m: float = BALL_DIAMETER_M,
                      ball_box: str = "refined") -> Iterator[ExportView]:
    """The views ``export`` writes, game by game (systems of the kinds that take it, accepted unless
    ``include_all``), with their boxes, split and file stem as the system's kind names them.

    Counts skipped views in ``report``.
    """
    query = exported_systems(export, include_all, *BALL_BOX_LOADS, selectinload(System.frames).undefer(Frame.release))
    stems: set[str] = set()
    for system in session.scalars(query.execution_options(yield_per=_CHUNK)):
        game = system.game
        balls = ball_boxes(system, ball_diameter_m, ball_box)
        for frame in system.frames:
            if not (frame.image_path or (frame.image_zip and frame.image_member)):
                report.skipped_without_image += 1
                continue
            ball, origin = balls.get(frame.id, (None, None))
            label = frame.ball_label
            if ball is None and label is not None and label.kind is not None and not label.suggested:
                report.skipped_point_only += 1
                continue
            boxes: list[tuple[int, tuple[float, float, float, float]]] = []
            if ball is not None and (b := _clip(ball, frame.width, frame.height)) is not None:
                boxes.append((0, b))
                report.optimised_ball_boxes += int(origin == "optimised")
                report.refined_ball_boxes += int(origin == "refined")
            for raw in _other_boxes(frame):
                cls = raw.get("class") if isinstance(raw, dict) else None
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
            kind = kind_of(system)
            stem = kind.view_stem(game, frame)
            if stem in stems:  # one file per view: a repeated name would overwrite a view already written
                raise RuntimeError(f"two exported views named {stem!r} (game {game.path!r}, view {frame.name!r})")
            stems.add(stem)
            yield ExportView(frame, game, system, kind.split(system, frame), stem, tuple(boxes))


def _copy_image(frame: Frame, dest_without_ext: Path) -> Path | None:
    try:
        img = frame_image(frame)
    except ImageUnavailable:
        return None
    ext = ".jpg" if img.media_type == "image/jpeg" else ".png"  # the type checked from its header, not its name
    dest = dest_without_ext.with_suffix(ext)
    with dest.open("wb") as fh:
        for chunk in img.chunks():
            fh.write(chunk)
    return dest


def _count(report: DetectorExportReport, view: ExportView) -> None:
    report.images[view.split] += 1
    report.ball_boxes[view.split] += sum(1 for c, _ in view.boxes if c == 0)
    report.other_boxes[view.split] += sum(1 for c, _ in view.boxes if c != 0)


def export_yolo(session: Session, out_dir: str | Path, include_all: bool = False,
                ball_diameter_m: float = BALL_DIAMETER_M, ball_box: str = "refined") -> DetectorExportReport:
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
    for view in iter_export_views(session, "yolo", include_all, report, ball_diameter_m, ball_box):
        if _copy_image(view.frame, out / "images" / view.split / view.stem) is None:
            report.skipped_without_image += 1
            continue
        w, h = view.frame.width, view.frame.height
        lines = [f"{c} {(b[0] + b[2]) / 2 / w:.8f} {(b[1] + b[3]) / 2 / h:.8f} {(b[2] - b[0]) / w:.8f} "
                 f"{(b[3] - b[1]) / h:.8f}" for c, b in view.boxes]
        (out / "labels" / view.split / f"{view.stem}.txt").write_text("".join(s + "\n" for s in lines))
        _count(report, view)
    (out / "data.yaml").write_text(yolo_data_yaml(report))
    return report


def yolo_data_yaml(report: DetectorExportReport) -> str:
    """The ``data.yaml`` of a YOLO export: no ``path:`` key (Ultralytics resolves the relative ``train``,
    ``val`` and ``test`` folders from the folder of ``data.yaml``: the export is relocatable), val = the test
    split (v3d has no separate validation split), a comment naming any split without images."""
    names = "\n".join(f"  {i}: {json.dumps(n)}" for i, n in enumerate(CLASSES))
    empty = "".join(f"# split {s!r} has no image: images/{s} and labels/{s} are empty\n" for s in report.empty_splits)
    return ("# v3d export: ball = class 0 (refined, else optimised, else annotated box)\n"
            "# no 'path:' key: the dataset root is the folder of this file (relocatable)\n"
            f"{empty}train: images/train\nval: images/test\ntest: images/test\nnc: {len(CLASSES)}\nnames:\n{names}\n")


def export_coco(session: Session, out_dir: str | Path, include_all: bool = False,
                ball_diameter_m: float = BALL_DIAMETER_M, ball_box: str = "refined") -> DetectorExportReport:
    """Write the COCO layout under ``out_dir``: per split the images and ``instances.json``.

    COCO image ids are :func:`coco_image_id` of the view's stem; category ids are the class ids + 1.

    Raises:
        RuntimeError: two views' stems give one image id (never silently merged).
    """
    out = Path(out_dir)
    report = DetectorExportReport(out, "coco")
    docs: dict[str, dict[str, list]] = {s: {"images": [], "annotations": []} for s in SPLITS}
    ids: dict[int, str] = {}
    for split in SPLITS:
        (out / split).mkdir(parents=True, exist_ok=True)
    for view in iter_export_views(session, "coco", include_all, report, ball_diameter_m, ball_box):
        image_id = coco_image_id(view.stem)
        if ids.setdefault(image_id, view.stem) != view.stem:
            raise RuntimeError(f"views {ids[image_id]!r} and {view.stem!r} share the COCO image id {image_id}")
        dest = _copy_image(view.frame, out / view.split / view.stem)
        if dest is None:
            report.skipped_without_image += 1
            continue
        doc = docs[view.split]
        doc["images"].append({"id": image_id, "file_name": dest.name, "width": view.frame.width,
                              "height": view.frame.height})
        for c, b in view.boxes:
            w, h = b[2] - b[0], b[3] - b[1]
            doc["annotations"].append({"id": len(doc["annotations"]) + 1, "image_id": image_id,
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
                    include_all: bool = False, ball_diameter_m: float = BALL_DIAMETER_M,
                    ball_box: str = "refined") -> DetectorExportReport:
    """:func:`export_yolo` or :func:`export_coco` by name (``ball_box``: ``Settings.export_ball_box``)."""
    return (export_yolo if fmt == "yolo" else export_coco)(session, out_dir, include_all, ball_diameter_m, ball_box)
