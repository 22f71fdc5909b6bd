"""Monocular 3D ball benchmark of detector predictions against the curated labels (paper, Experiments).

Ground truth: every view of the selected systems (accepted unless ``include_all``) that has a 3D ball
(system triangulated, view calibrated, optimised box stored): its box as exported
(:func:`app.services.transfer.detector_export.ball_boxes`: the refined box where the 3D ball is well
constrained, else the optimised box), the system's 3D ball and the view's camera. Predictions in other images are
ignored (counted).

Predictions: YOLO txt files (``class cx cy w h conf``, normalised; one file per image, matched to views
by file stem as written by :mod:`app.services.transfer.detector_export`, searched recursively) or a COCO
results JSON (``image_id`` = the COCO export's image id, ``detector_export.coco_image_id`` of the stem), read by
:mod:`app.services.transfer.detector_files`.

Reported per split and for the whole set (:func:`evaluate`): ``AP50`` (Pascal VOC all-point AP at
IoU 0.5, :func:`app.geometry.metrics.average_precision`), ``MAE_m``, ``MAE_pct`` (percent of the
camera-to-ball distance), ``P_2m`` (fraction within 2 m) and ``curve`` (precision-threshold curve),
all from :func:`app.geometry.metrics.monocular_metrics`. The monocular ball of a detection
(:data:`ESTIMATORS`) is paper Eq. ball3Destimation (``"paper"``: :func:`app.geometry.ball.ball_from_box`,
d = mean of width and height, method.md section 6) or its exact inverse of the sphere's silhouette
(``"exact"``: :func:`app.geometry.ball.ball_from_box_exact`). The default follows the optimised boxes
the labels are made with (:func:`default_estimator`): v3d's default boxes are exact silhouettes
(``exact_ray``), on which the paper formula has an off-axis bias (synthetic dev set, reference boxes
themselves as detections: MAE 0.80 m / 1.96 % with ``paper``, 0.36 m / 0.77 % with ``exact``). Each
ground-truth view is scored with its most confident detection whose IoU with the reference box is
> 0 (paper: only such detections count), so duplicate detections do not count twice.
"""
from __future__ import annotations

from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any, Hashable

import numpy as np
from sqlalchemy.orm import Session

from app.core.errors import DatasetError, InvalidInputError
from app.db.session import end_reads
from app.geometry.ball import ball_from_box, ball_from_box_exact
from app.geometry.camera import Camera
from app.geometry.metrics import (
    MAX_COCO_FILE_BYTES,
    BestDetections,
    Detections,
    average_precision,
    box_iou,
    monocular_metrics,
    precision_curve,
)
from app.geometry.pitch import BALL_DIAMETER_M
from app.services.kinds import kind_of
from app.services.transfer.cameras_export import read_cameras
from app.services.transfer.detector_export import BALL_BOX_LOADS, SPLITS, ball_boxes
from app.services.transfer.detector_files import load_predictions
from app.services.transfer.exporting import exported_systems

#: Thresholds (metres) of the precision-threshold curve.
CURVE_THRESHOLDS_M = tuple(float(t) for t in np.round(np.arange(0.0, 10.0001, 0.25), 2))
TAU_M = 2.0
#: Monocular ball estimators: box -> 3D ball.
ESTIMATORS = {"paper": ball_from_box, "exact": ball_from_box_exact}


def default_estimator(optimised_box_method: str) -> str:
    """The estimator consistent with the optimised boxes: ``"paper"`` for the paper's square box,
    ``"exact"`` for the exact silhouette boxes.

    >>> default_estimator("paper"), default_estimator("exact_ray")
    ('paper', 'exact')
    """
    return "paper" if optimised_box_method == "paper" else "exact"


@dataclass(frozen=True)
class ReferenceView:
    """A ground-truth view: reference (exported) box (4,) px, 3D ball (3,) world m, its camera."""

    frame_id: int
    stem: str
    split: str
    width: int
    height: int
    box: np.ndarray
    ball: np.ndarray
    camera: Camera
    #: ``league/season/match`` of the view's game and the frame's name (where a cameras tree holds its camera).
    game_path: str = ""
    frame_name: str = ""


def with_cameras(views: list[ReferenceView], cameras_dir: str | Path) -> tuple[list[ReferenceView], int]:
    """The views scored with the cameras given in ``cameras_dir`` instead of the stored ones: a cameras export
    (``v3d export cameras``: ``cameras.json`` and per image size ``<W>x<H>/predictions.zip`` of
    SoccerNet-calibration cameras, ``app.services.transfer.cameras_export.read_cameras``), pixels of the
    view's image. The reference box and 3D ball stay the stored ones (the "given cameras" rows of the paper's
    Table 2). Views without a camera are left out.

    Returns:
        ``(views with their given camera, number of views left out for want of a camera)``.

    Raises:
        InvalidInputError: ``cameras_dir`` is not a folder (field ``cameras``).
        DatasetError: no ``cameras.json``, a zip that leads out of the folder or cannot be read, a camera file
            that is not JSON or not a SoccerNet camera (naming it).
    """
    root = Path(cameras_dir)
    if not root.is_dir():
        raise InvalidInputError(f"not a folder: {root}", field="cameras")
    given = read_cameras(root)
    out, missing = [], 0
    for v in views:
        raw = given.get((v.game_path, v.frame_name))
        if raw is None:
            missing += 1
            continue
        try:
            camera = Camera.from_soccernet(raw)
        except (ValueError, TypeError, KeyError) as exc:
            raise DatasetError(root, f"{v.game_path}/{v.frame_name}", f"not a SoccerNet camera: {exc}") from exc
        out.append(replace(v, camera=camera))
    return out, missing


def reference_views(session: Session, include_all: bool = False, ball_diameter_m: float = BALL_DIAMETER_M,
                    ball_box: str = "refined") -> list[ReferenceView]:
    """The views of the selected systems (accepted unless ``include_all``) whose label made their
    system's 3D ball: views in at least one kept triangulation pair, with an optimised box. A view whose
    label disagrees with the 3D ball (in no kept pair: a wrong box, a desynchronised replay, an excluded
    view) has no trustworthy reference there and is left out."""
    query = exported_systems("monocular", include_all, *BALL_BOX_LOADS)
    out = []
    for system in session.scalars(query):
        tri = system.triangulation
        if tri is None or tri.ball3d is None:
            continue
        boxes = ball_boxes(system, ball_diameter_m, ball_box)
        contributing = {f for p in tri.pairs if p.kept for f in (p.frame_a_id, p.frame_b_id)}
        for frame in system.frames:
            cal = frame.calibration
            if frame.optimised_box is None or cal is None or cal.camera is None or frame.id not in contributing:
                continue
            kind = kind_of(system)
            out.append(ReferenceView(frame.id, kind.view_stem(system.game, frame), kind.split(system, frame),
                                     frame.width, frame.height, np.asarray(boxes[frame.id][0], float),
                                     np.asarray(tri.ball3d, float), Camera.from_soccernet(cal.camera),
                                     system.game.path, frame.name))
    return out


def _report(views: list[ReferenceView], dets: Detections, ball_diameter_m: float, estimator: str) -> dict[str, Any]:
    gt: dict[Hashable, np.ndarray] = {v.stem: v.box[None, :] for v in views}
    idx = [i for i, k in enumerate(dets.image_ids) if k in gt]
    d = Detections(tuple(dets.image_ids[i] for i in idx), dets.boxes[idx], dets.scores[idx])
    ap = average_precision(d, gt, 0.5) if views else float("nan")
    by_image: dict[Hashable, list[int]] = {}
    for i, k in enumerate(d.image_ids):
        by_image.setdefault(k, []).append(i)
    pred, ref, cams, ious = [], [], [], []
    for v in views:
        cand = by_image.get(v.stem, [])
        if not cand:
            continue
        iou = box_iou(d.boxes[cand], v.box[None, :])
        ok = [c for c, o in zip(cand, iou, strict=True) if o > 0]
        if not ok:
            continue
        best = max(ok, key=lambda c: d.scores[c])
        box = d.boxes[best]
        if not (box[2] > box[0] and box[3] > box[1]):
            continue
        pred.append(ESTIMATORS[estimator](v.camera, box, ball_diameter_m)[0])
        ref.append(v.ball)
        cams.append(v.camera.C)
        ious.append(float(box_iou(box, v.box)))
    m = monocular_metrics(np.array(pred).reshape(-1, 3), np.array(ref).reshape(-1, 3),
                          np.array(cams).reshape(-1, 3), np.array(ious), TAU_M)
    errors = np.linalg.norm(np.array(pred).reshape(-1, 3) - np.array(ref).reshape(-1, 3), axis=1)
    curve = precision_curve(errors, np.array(CURVE_THRESHOLDS_M))

    def num(x: float) -> float | None:
        return None if not np.isfinite(x) else float(x)

    return {
        "AP50": num(ap), "MAE_m": num(m.mae_m), "MAE_pct": num(m.mae_pct), "P_2m": num(m.precision_at_tau),
        "curve": {"thresholds_m": list(CURVE_THRESHOLDS_M), "precision": [num(c) for c in curve]},
        "counts": {"reference_views": len(views), "detections": len(d.scores),
                   "views_with_detection": len(by_image), "localised": m.n},
    }


def evaluate(views: list[ReferenceView], detections: Detections, ignored: int = 0,
             ball_diameter_m: float = BALL_DIAMETER_M, estimator: str = "exact") -> dict[str, Any]:
    """The benchmark report: the whole set's figures at the top level and ``splits`` {split: figures}.

    Args:
        views: :func:`reference_views`.
        detections: ball detections keyed by view stem (:func:`load_predictions`).
        ignored: detections dropped because their image is not a reference view (reported).
        ball_diameter_m: phi, metres.
        estimator: a key of :data:`ESTIMATORS`.

    Raises:
        InvalidInputError: no reference view (nothing to evaluate against), unknown estimator.
    """
    if estimator not in ESTIMATORS:
        raise InvalidInputError(f"unknown estimator {estimator!r}; choose one of {sorted(ESTIMATORS)}",
                                field="estimator")
    if not views:
        raise InvalidInputError("no view with a 3D ball among the selected systems (accept systems, or use --all)",
                                field="systems")
    out = _report(views, detections, ball_diameter_m, estimator)
    out["counts"]["ignored_detections"] = ignored
    out["splits"] = {s: _report([v for v in views if v.split == s], detections, ball_diameter_m, estimator)
                     for s in SPLITS if any(v.split == s for v in views)}
    return out


def source_detections(session: Session, source: str, views: list[ReferenceView],
                      per_frame: int) -> tuple[Detections, int]:
    """The stored predictions of ``source`` (``v3d import predictions``) keyed by view stem, as
    :func:`load_predictions` reads a file, and the number on images that are not reference views (ignored):
    at most ``per_frame`` (``V3D_MAX_PREDICTIONS_PER_FRAME``) of a frame, the best by score, chosen by the query
    (``app.db.models.predictions.ranked_predictions``), so that a frame flooded before the cap never reaches memory
    whole.

    Raises:
        InvalidInputError: no predictions of that source are stored (field ``source``).
    """
    import sqlalchemy as sa

    from app.db.models import Prediction
    from app.db.models.predictions import ranked_predictions

    stems = {v.frame_id: v.stem for v in views}
    ids, boxes, scores, ignored = [], [], [], 0
    if session.scalar(sa.select(Prediction.id).where(Prediction.source == source).limit(1)) is None:
        raise InvalidInputError(f"no predictions of source {source!r} are stored (v3d predictions list)",
                                field="source")
    r = ranked_predictions(Prediction.source == source)
    for fid, x1, y1, x2, y2, score in session.execute(
            sa.select(r.c.frame_id, r.c.x1, r.c.y1, r.c.x2, r.c.y2, r.c.score).where(r.c.rank <= per_frame)
            .order_by(r.c.id)):
        if fid not in stems:
            ignored += 1
            continue
        ids.append(stems[fid])
        boxes.append((x1, y1, x2, y2))
        scores.append(score)
    return Detections(tuple(ids), np.array(boxes, float).reshape(-1, 4), np.array(scores, float)), ignored


def evaluate_source(session: Session, source: str, include_all: bool = False,
                    ball_diameter_m: float = BALL_DIAMETER_M, estimator: str = "exact",
                    ball_box: str = "refined", *, per_frame: int) -> dict[str, Any]:
    """:func:`evaluate` of an imported source's stored predictions (:func:`source_detections`: at most ``per_frame``
    a frame, ``V3D_MAX_PREDICTIONS_PER_FRAME``) against the curated labels with the stored cameras, as
    :func:`evaluate_predictions` scores a file: no second upload.

    Raises:
        InvalidInputError: no such source, or no reference view.
    """
    views = reference_views(session, include_all, ball_diameter_m, ball_box)
    dets, ignored = source_detections(session, source, views, per_frame)
    end_reads(session)
    out = evaluate(views, dets, ignored, ball_diameter_m, estimator)
    out["counts"]["views_without_camera"] = 0
    out["cameras"] = "stored"
    return out


def evaluate_predictions(session: Session, predictions: str | Path, include_all: bool = False,
                         ball_class: int | None = None, ball_diameter_m: float = BALL_DIAMETER_M,
                         estimator: str = "exact", cameras_dir: str | Path | None = None,
                         ball_box: str = "refined", *, name: str | None = None,
                         max_coco_bytes: int = MAX_COCO_FILE_BYTES, per_frame: int) -> dict[str, Any]:
    """:func:`evaluate` of the predictions at ``predictions`` against the database's curated labels, with the
    stored cameras (the "oracle" row: cameras fitted on the annotated lines) or, with ``cameras_dir``, the
    cameras given there (:func:`with_cameras`; ``counts.views_without_camera`` says how many views had none);
    the reference boxes are the exported ones (``ball_box``, :func:`reference_views`); ``name`` and
    ``max_coco_bytes`` as :func:`load_predictions`; at most ``per_frame`` detections of an image, the best by score
    (``V3D_MAX_PREDICTIONS_PER_FRAME``, as COCO's ``maxDets``), the others counted in ``counts.capped_detections``."""
    views = reference_views(session, include_all, ball_diameter_m, ball_box)
    end_reads(session)  # the reference views are plain values: no connection is held while the predictions are scored
    missing = 0
    if cameras_dir is not None:
        views, missing = with_cameras(views, cameras_dir)
    if not views:
        return evaluate(views, Detections((), np.zeros((0, 4)), np.zeros(0)))  # raises, naming the cause
    keep = BestDetections(per_frame)
    dets, ignored = load_predictions(predictions, views, ball_class, name=name, max_coco_bytes=max_coco_bytes,
                                     keep=keep)
    out = evaluate(views, dets, ignored, ball_diameter_m, estimator)
    out["counts"]["capped_detections"] = keep.dropped
    out["counts"]["views_without_camera"] = missing
    out["cameras"] = "given" if cameras_dir is not None else "stored"
    return out
