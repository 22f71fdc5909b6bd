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
  of ``data.yaml`` as the dataset root, so the export works wherever it is unpacked or moved. ``val`` is drawn from
  the train split, per system, seeded (:func:`yolo_split`: :data:`YOLO_VAL_FRACTION` of the train systems). Every
  split folder always exists; a split without images is said so in a comment of ``data.yaml`` and in the
  report (``empty_splits``). Every class keeps its id (a comment names those no box uses).
* COCO: ``<split>/<stem>.<ext>`` and ``<split>/instances.json`` beside them (boxes ``[x, y, w, h]``
  pixels, category ids = class id + 1: the ball is category 1).
* both: ``manifest.csv`` and ``manifest.json`` at the root (:func:`write_manifest`), one row per image joining it
  back to its league, season, game, image name, frame and system ids, COCO image id, split, 3D ball (world m) and
  reprojection error (px).

Systems are read in batches of :data:`_CHUNK` and images copied one at a time from their archive or
file (never all in memory); the COCO metadata of a split (numbers only) is kept until its JSON is
written.
"""
from __future__ import annotations

import csv
import hashlib
import json
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Iterable, Iterator, Literal

import numpy as np
from sqlalchemy.orm import Session, selectinload

from app.datasets.csv_cells import inert_row
from app.db.models import Frame, Game, System, Triangulation
from app.geometry.ball import box_centre_and_diameter
from app.geometry.camera import Camera
from app.geometry.pitch import BALL_DIAMETER_M
from app.geometry.refined_box import refine_box
from app.services.images.serving import ImageUnavailable, frame_has_image, frame_image
from app.services.kinds import kind_of
from app.services.storage.datasets import DatasetFiles
from app.services.transfer.exporting import exported_systems

BALL_CLASS = "Ball"
#: SoccerNet-v3 box classes other than the ball, in class-id order after it.
OTHER_CLASSES = (
    "Player team left", "Player team right", "Goalkeeper team left", "Goalkeeper team right",
    "Main referee", "Side referee", "Staff members", "Player", "Goalkeeper",
)
CLASSES = (BALL_CLASS, *OTHER_CLASSES)
SPLITS = ("train", "test")
#: The YOLO export's splits: a validation split drawn from the train split (:func:`yolo_split`), then the kinds'.
YOLO_SPLITS = ("train", "val", "test")
#: The share of the train split's systems a YOLO export puts in its validation split, and the seed of the draw.
YOLO_VAL_FRACTION = 0.1
YOLO_VAL_SEED = 0
#: The columns of a detector export's ``manifest.csv`` (the same keys in ``manifest.json``'s ``images``).
MANIFEST_COLUMNS = ("file", "split", "league", "season", "game", "image", "frame_id", "system_id", "coco_image_id",
                    "ball3d_x_m", "ball3d_y_m", "ball3d_z_m", "reprojection_error_px")
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
    splits: tuple[str, ...] = SPLITS
    images: dict[str, int] = field(default_factory=dict)
    ball_boxes: dict[str, int] = field(default_factory=dict)
    other_boxes: dict[str, int] = field(default_factory=dict)
    optimised_ball_boxes: int = 0
    refined_ball_boxes: int = 0
    skipped_without_image: int = 0
    skipped_point_only: int = 0
    unknown_classes: Counter = field(default_factory=Counter)
    #: Class ids of the boxes written.
    used_classes: set[int] = field(default_factory=set)

    def __post_init__(self) -> None:
        for counts in (self.images, self.ball_boxes, self.other_boxes):
            for split in self.splits:
                counts.setdefault(split, 0)

    @property
    def empty_splits(self) -> list[str]:
        """The splits that received no image (their folders exist, empty)."""
        return [s for s in self.splits if not self.images[s]]

    def as_dict(self) -> dict[str, Any]:
        return {"out_dir": str(self.out_dir), "format": self.format, "images": self.images,
                "used_classes": [CLASSES[i] for i in sorted(self.used_classes)],
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
    yield from views_of(session.scalars(query.execution_options(yield_per=_CHUNK)), report, ball_diameter_m, ball_box)


def image_source(frame: Any) -> Frame:
    """The stored frame whose image a view's file copies: the frame itself, or, for a view read from a release
    (``app.services.releases.export``), the stored frame it names (``frame.image_source``)."""
    return getattr(frame, "image_source", frame)


def views_of(systems: Iterable[Any], report: DetectorExportReport, ball_diameter_m: float = BALL_DIAMETER_M,
             ball_box: str = "refined") -> Iterator[ExportView]:
    """The exported views of ``systems`` (stored systems with their game, frames, labels, calibrations and
    triangulation loaded, or a release's stand-ins of them), in order (:func:`iter_export_views`)."""
    stems: set[str] = set()
    for system in systems:
        game = system.game
        balls = ball_boxes(system, ball_diameter_m, ball_box)
        for frame in system.frames:
            if not frame_has_image(image_source(frame)):
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


def _copy_image(frame: Frame, dest_without_ext: Path, files: DatasetFiles | None = None) -> Path | None:
    try:
        img = frame_image(image_source(frame), files=files)
    except ImageUnavailable:
        return None
    ext = ".jpg" if img.media_type == "image/jpeg" else ".png"  # the type checked from its header, not its name
    dest = dest_without_ext.with_suffix(ext)
    with dest.open("wb") as fh:
        for chunk in img.chunks():
            fh.write(chunk)
    return dest


def _count(report: DetectorExportReport, view: ExportView, split: str | None = None) -> None:
    split = split or view.split
    report.images[split] += 1
    report.ball_boxes[split] += sum(1 for c, _ in view.boxes if c == 0)
    report.other_boxes[split] += sum(1 for c, _ in view.boxes if c != 0)
    report.used_classes.update(c for c, _ in view.boxes)


def yolo_split(view: ExportView, fraction: float = YOLO_VAL_FRACTION, seed: int = YOLO_VAL_SEED) -> str:
    """The YOLO split of a view: ``val`` for the train split's systems whose draw falls below ``fraction`` (the first
    8 bytes of the SHA-256 of ``"<seed>:<league/season/match>:<system name>"`` as a fraction of 2**64, so every view of
    a system goes to one split and a game's other systems are unaffected by adding one), else the kind's split."""
    if view.split != "train":
        return view.split
    key = f"{seed}:{view.game.path}:{view.system.name}".encode("utf-8")
    return "val" if int.from_bytes(hashlib.sha256(key).digest()[:8], "big") < fraction * 2.0 ** 64 else "train"


def manifest_row(view: ExportView, file: str, split: str) -> dict[str, Any]:
    """One image of a detector export joined back to its data (:data:`MANIFEST_COLUMNS`): the file (relative to the
    export's root), split, league, season, game (match), image (the frame's name in its dataset), ``frame_id`` and
    ``system_id`` (this database's), ``coco_image_id`` (:func:`coco_image_id` of the stem), the system's 3D ball
    (world metres, SoccerNet frame, z down; empty without one) and the view's reprojection error of it (px)."""
    tri = view.system.triangulation
    ball = list(tri.ball3d) if tri is not None and tri.ball3d is not None else [None, None, None]
    rep = view.frame.reprojection
    return {"file": file, "split": split, "league": view.game.league, "season": view.game.season,
            "game": view.game.match, "image": view.frame.name, "frame_id": view.frame.id,
            "system_id": view.system.id, "coco_image_id": coco_image_id(view.stem),
            "ball3d_x_m": ball[0], "ball3d_y_m": ball[1], "ball3d_z_m": ball[2],
            "reprojection_error_px": rep.error_px if rep is not None else None}


def write_manifest(out: Path, rows: list[dict[str, Any]], fmt: str, release: dict[str, str] | None = None) -> None:
    """``manifest.csv`` and ``manifest.json`` (``{"format", "columns", "images"}``, and ``release``: ``{"name",
    "hash"}`` of the release exported, when one is) at the export's root, one row per image written, by file name.
    CSV cells a spreadsheet would run as a formula are escaped."""
    rows = sorted(rows, key=lambda r: r["file"])
    with (out / "manifest.csv").open("w", newline="", encoding="utf-8") as fh:
        writer = csv.writer(fh, lineterminator="\n")
        writer.writerow(MANIFEST_COLUMNS)
        writer.writerows(inert_row("" if r[c] is None else repr(r[c]) if isinstance(r[c], float) else str(r[c])
                                   for c in MANIFEST_COLUMNS) for r in rows)
    doc: dict[str, Any] = {"format": fmt, "columns": list(MANIFEST_COLUMNS), "images": rows}
    if release is not None:
        doc["release"] = dict(release)
    (out / "manifest.json").write_text(json.dumps(doc, sort_keys=True, indent=1))


def export_yolo(session: Session, out_dir: str | Path, include_all: bool = False,
                ball_diameter_m: float = BALL_DIAMETER_M, ball_box: str = "refined", *,
                systems: Iterable[Any] | None = None, release: dict[str, str] | None = None,
                files: DatasetFiles | None = None) -> DetectorExportReport:
    """Write the Ultralytics YOLO layout under ``out_dir`` (module docstring); existing files of the
    same names are overwritten. ``systems``: the systems to write instead of the database's (a release's stand-ins,
    ``app.services.releases.export.release_detector_systems``); ``release``: ``{"name", "hash"}`` of that release,
    named in ``data.yaml`` and ``manifest.json``; ``files``: where the images' references lead (default: the
    process's settings').

    Returns:
        A :class:`DetectorExportReport` (images and boxes per split, skipped views).
    """
    out = Path(out_dir)
    report = DetectorExportReport(out, "yolo", splits=YOLO_SPLITS)
    for split in YOLO_SPLITS:
        (out / "images" / split).mkdir(parents=True, exist_ok=True)
        (out / "labels" / split).mkdir(parents=True, exist_ok=True)
    manifest = []
    views = (views_of(systems, report, ball_diameter_m, ball_box) if systems is not None
             else iter_export_views(session, "yolo", include_all, report, ball_diameter_m, ball_box))
    for view in views:
        split = yolo_split(view)
        dest = _copy_image(view.frame, out / "images" / split / view.stem, files)
        if dest is None:
            report.skipped_without_image += 1
            continue
        w, h = view.frame.width, view.frame.height
        lines = [f"{c} {(b[0] + b[2]) / 2 / w:.8f} {(b[1] + b[3]) / 2 / h:.8f} {(b[2] - b[0]) / w:.8f} "
                 f"{(b[3] - b[1]) / h:.8f}" for c, b in view.boxes]
        (out / "labels" / split / f"{view.stem}.txt").write_text("".join(s + "\n" for s in lines))
        _count(report, view, split)
        manifest.append(manifest_row(view, dest.relative_to(out).as_posix(), split))
    named = f"# release {release['name']} (hash {release['hash']})\n" if release else ""
    (out / "data.yaml").write_text(named + yolo_data_yaml(report))
    write_manifest(out, manifest, "yolo", release)
    return report


def yolo_data_yaml(report: DetectorExportReport) -> str:
    """The ``data.yaml`` of a YOLO export: no ``path:`` key (Ultralytics resolves the relative ``train``,
    ``val`` and ``test`` folders from the folder of ``data.yaml``: the export is relocatable); ``val`` is the
    validation split drawn from the train split (:func:`yolo_split`); a comment naming any split without images, and
    one naming the classes no box uses (every SoccerNet-v3 class keeps its id, so that a detector trained on one
    export reads another's labels and predictions)."""
    names = "\n".join(f"  {i}: {json.dumps(n)}" for i, n in enumerate(CLASSES))
    empty = "".join(f"# split {s!r} has no image: images/{s} and labels/{s} are empty\n" for s in report.empty_splits)
    unused = [n for i, n in enumerate(CLASSES) if i not in report.used_classes]
    unused_note = (f"# classes no box uses here: {', '.join(unused)} (listed so that every class keeps its id in "
                   "every export)\n") if unused else ""
    return ("# v3d export: ball = class 0 (refined, else optimised, else annotated box)\n"
            "# no 'path:' key: the dataset root is the folder of this file (relocatable)\n"
            f"# val: {YOLO_VAL_FRACTION:.0%} of the train split's systems (seed {YOLO_VAL_SEED}, every view of a "
            "system in one split); test: the kinds' test split\n"
            f"{empty}{unused_note}train: images/train\nval: images/val\ntest: images/test\nnc: {len(CLASSES)}\n"
            f"names:\n{names}\n")


def export_coco(session: Session, out_dir: str | Path, include_all: bool = False,
                ball_diameter_m: float = BALL_DIAMETER_M, ball_box: str = "refined", *,
                systems: Iterable[Any] | None = None, release: dict[str, str] | None = None,
                files: DatasetFiles | None = None) -> DetectorExportReport:
    """Write the COCO layout under ``out_dir``: per split the images and ``instances.json``. ``systems`` and
    ``release`` as :func:`export_yolo` (the release named in each ``info`` and in ``manifest.json``).

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
    manifest = []
    views = (views_of(systems, report, ball_diameter_m, ball_box) if systems is not None
             else iter_export_views(session, "coco", include_all, report, ball_diameter_m, ball_box))
    for view in views:
        image_id = coco_image_id(view.stem)
        if ids.setdefault(image_id, view.stem) != view.stem:
            raise RuntimeError(f"views {ids[image_id]!r} and {view.stem!r} share the COCO image id {image_id}")
        dest = _copy_image(view.frame, out / view.split / view.stem, files)
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
        manifest.append(manifest_row(view, dest.relative_to(out).as_posix(), view.split))
    categories = [{"id": i + 1, "name": n, "supercategory": "ball" if i == 0 else "person"}
                  for i, n in enumerate(CLASSES)]
    for split, doc in docs.items():
        (out / split / "instances.json").write_text(json.dumps(
            {"info": _coco_info(split, release), "licenses": [], "categories": categories, **doc}))
    write_manifest(out, manifest, "coco", release)
    return report


def _coco_info(split: str, release: dict[str, str] | None) -> dict[str, Any]:
    """A COCO file's ``info``: what it is and, from a release, the release (``version`` its name, ``v3d_release``
    its name and hash)."""
    if release is None:
        return {"description": f"v3d export ({split})"}
    return {"description": f"v3d export ({split}) of release {release['name']}", "version": release["name"],
            "v3d_release": dict(release)}


def export_detector(session: Session, fmt: Literal["yolo", "coco"], out_dir: str | Path,
                    include_all: bool = False, ball_diameter_m: float = BALL_DIAMETER_M,
                    ball_box: str = "refined", *, systems: Iterable[Any] | None = None,
                    release: dict[str, str] | None = None, files: DatasetFiles | None = None) -> DetectorExportReport:
    """:func:`export_yolo` or :func:`export_coco` by name (``ball_box``: ``Settings.export_ball_box``; ``files``:
    where the images' references lead, default the process's settings')."""
    return (export_yolo if fmt == "yolo" else export_coco)(session, out_dir, include_all, ball_diameter_m, ball_box,
                                                           systems=systems, release=release, files=files)
