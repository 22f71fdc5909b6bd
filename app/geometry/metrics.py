"""Box and 3D-ball metrics (method.md section 8; paper sections Experiments and Metrics).

* :func:`box_iou` and :func:`box_size_error_pct` compare boxes ``[x1, y1, x2, y2]`` in continuous
  pixels (no "+1" pixel-inclusive convention: a box's width is ``x2 - x1``).
* :func:`average_precision`: Pascal VOC AP at an IoU threshold (all-point interpolation, VOC 2010
  onwards, Everingham et al. 2010), with loaders for YOLO txt and COCO results JSON detections.
* :func:`monocular_metrics`: MAE_m, MAE_%, P@tau3D and :func:`precision_curve`, counting only
  detections whose IoU with the reference box is > 0 (paper, section Metrics).
"""
from __future__ import annotations

import codecs
import heapq
import json
import math
import os
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any, BinaryIO, Hashable, Iterator, Mapping, Sequence

import numpy as np

from app.geometry.camera import as_points


def box_iou(boxes_a: np.ndarray, boxes_b: np.ndarray) -> np.ndarray:
    """Intersection over union of boxes, broadcasting over leading dimensions.

    Args:
        boxes_a: (..., 4) ``[x1, y1, x2, y2]`` pixels.
        boxes_b: (..., 4), broadcastable against ``boxes_a`` (e.g. ``a[:, None]`` and ``b[None]``
            give the (N, M) IoU matrix).

    Returns:
        (...) IoU in [0, 1]; 0 where the union is empty.

    Raises:
        ValueError: last dimension is not 4.

    >>> box_iou(np.array([0.0, 0.0, 2.0, 2.0]), np.array([1.0, 0.0, 3.0, 2.0])).round(6).item()
    0.333333
    """
    a, b = _boxes(boxes_a, "boxes_a"), _boxes(boxes_b, "boxes_b")
    iw = np.clip(np.minimum(a[..., 2], b[..., 2]) - np.maximum(a[..., 0], b[..., 0]), 0.0, None)
    ih = np.clip(np.minimum(a[..., 3], b[..., 3]) - np.maximum(a[..., 1], b[..., 1]), 0.0, None)
    inter = iw * ih
    area_a = np.clip(a[..., 2] - a[..., 0], 0.0, None) * np.clip(a[..., 3] - a[..., 1], 0.0, None)
    area_b = np.clip(b[..., 2] - b[..., 0], 0.0, None) * np.clip(b[..., 3] - b[..., 1], 0.0, None)
    union = area_a + area_b - inter
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(union > 0, inter / np.where(union > 0, union, 1.0), 0.0)


def box_size_error_pct(boxes: np.ndarray, references: np.ndarray) -> np.ndarray:
    """Box size error ``|diag(box) - diag(ref)| / diag(ref)`` in percent (paper Table bboxopt).

    Args:
        boxes: (..., 4) ``[x1, y1, x2, y2]`` pixels.
        references: (..., 4), broadcastable, with a positive diagonal.

    Returns:
        (...) percent.

    Raises:
        ValueError: bad shapes or a reference with a zero diagonal.

    >>> box_size_error_pct(np.array([0.0, 0.0, 3.0, 4.0]), np.array([0.0, 0.0, 6.0, 8.0])).item()
    50.0
    """
    a, b = _boxes(boxes, "boxes"), _boxes(references, "references")
    da = np.hypot(a[..., 2] - a[..., 0], a[..., 3] - a[..., 1])
    db = np.hypot(b[..., 2] - b[..., 0], b[..., 3] - b[..., 1])
    if np.any(db <= 0):
        raise ValueError("references must have a positive diagonal")
    return 100.0 * np.abs(da - db) / db


@dataclass(frozen=True)
class Detections:
    """Scored detections of one class over a set of images.

    Attributes:
        image_ids: (N,) image identifiers (any hashable, compared with the ground truth's keys).
        boxes: (N, 4) ``[x1, y1, x2, y2]`` pixels.
        scores: (N,) confidences (higher = more confident).
    """

    image_ids: tuple[Hashable, ...]
    boxes: np.ndarray
    scores: np.ndarray

    def __post_init__(self) -> None:
        boxes = _boxes(np.asarray(self.boxes, float).reshape(-1, 4), "Detections.boxes")
        scores = np.asarray(self.scores, float).reshape(-1)
        if not (len(self.image_ids) == len(boxes) == len(scores)):
            raise ValueError(f"Detections: image_ids, boxes and scores differ in length "
                             f"({len(self.image_ids)}, {len(boxes)}, {len(scores)})")
        if not np.all(np.isfinite(scores)):
            raise ValueError("Detections.scores must be finite")
        object.__setattr__(self, "image_ids", tuple(self.image_ids))
        object.__setattr__(self, "boxes", boxes)
        object.__setattr__(self, "scores", scores)

    @classmethod
    def concat(cls, parts: Sequence["Detections"]) -> "Detections":
        """All detections of several parts, in order."""
        return cls(tuple(i for p in parts for i in p.image_ids),
                   np.concatenate([p.boxes for p in parts]) if parts else np.zeros((0, 4)),
                   np.concatenate([p.scores for p in parts]) if parts else np.zeros(0))


class BestDetections:
    """The ``per_image`` highest-scored detections of each image, kept while they stream in, and how many were
    dropped: a min-heap per image (``heapq``: the worst kept on top, replaced by a better one), so the memory is
    O(images x ``per_image``) whatever the number read (a detector run without non-maximum suppression writes a
    million boxes on one image). Of equal scores the one read first is kept. What an import of a detector's
    predictions stores per frame and what a YOLO or COCO file is read as (``V3D_MAX_PREDICTIONS_PER_FRAME``).

    >>> best = BestDetections(2)
    >>> for score in (0.2, 0.9, 0.5, 0.9):
    ...     best.add("a", (0.0, 0.0, 1.0, 1.0), score)
    >>> [s for _, s in best.best("a")], best.dropped
    ([0.9, 0.9], 2)
    """

    def __init__(self, per_image: int) -> None:
        """Raises ValueError: ``per_image`` below 1."""
        if per_image < 1:
            raise ValueError(f"BestDetections: per_image must be at least 1, got {per_image}")
        self.per_image = per_image
        self.dropped = 0
        self._heaps: dict[Hashable, list[tuple[float, int, tuple[float, float, float, float]]]] = {}
        self._read = 0

    def add(self, image_id: Hashable, box: Sequence[float], score: float) -> None:
        """Offer one detection (``box`` ``[x1, y1, x2, y2]`` px, its score): kept while it is among the image's best."""
        self._read += 1
        score = float(score)
        heap = self._heaps.get(image_id)
        if heap is None:
            heap = self._heaps[image_id] = []
        elif len(heap) >= self.per_image:
            self.dropped += 1
            if score <= heap[0][0]:  # no better than the worst kept (of equal scores the earlier stays)
                return
            heapq.heapreplace(heap, (score, -self._read, (float(box[0]), float(box[1]), float(box[2]), float(box[3]))))
            return
        heapq.heappush(heap, (score, -self._read, (float(box[0]), float(box[1]), float(box[2]), float(box[3]))))

    def images(self) -> list[Hashable]:
        """The images holding a kept detection, in the order they were first offered one."""
        return list(self._heaps)

    def best(self, image_id: Hashable) -> list[tuple[tuple[float, float, float, float], float]]:
        """The kept ``(box, score)`` of ``image_id``, best first (none: an empty list)."""
        return [(box, score) for score, _, box in sorted(self._heaps.get(image_id, ()), reverse=True)]

    def kept(self) -> int:
        """How many detections are kept, all images together."""
        return sum(len(h) for h in self._heaps.values())

    def detections(self) -> "Detections":
        """Every kept detection, image by image (:meth:`images`' order), best first."""
        ids: list[Hashable] = []
        boxes: list[tuple[float, float, float, float]] = []
        scores: list[float] = []
        for image in self._heaps:
            for box, score in self.best(image):
                ids.append(image)
                boxes.append(box)
                scores.append(score)
        return Detections(tuple(ids), np.array(boxes, float).reshape(-1, 4), np.array(scores, float))


def average_precision(detections: Detections, ground_truth: Mapping[Hashable, np.ndarray],
                      iou_threshold: float = 0.5) -> float:
    """Pascal VOC average precision (all-point interpolation, VOC 2010 onwards).

    Detections are taken by decreasing score (ties keep input order); each is a true positive when
    its best-overlapping ground-truth box in the same image has IoU >= ``iou_threshold`` (the
    official MATLAB devkit's ``>=``) and has not been matched yet, otherwise a false positive. AP is
    the area under the precision-recall curve made monotone (precision at recall r = max precision
    at recall >= r), summed where recall changes.

    Args:
        detections: the scored detections (:class:`Detections`).
        ground_truth: image id -> (M, 4) reference boxes (M may be 0); images absent here have none.
        iou_threshold: IoU for a match (0.5 for AP@0.5).

    Returns:
        AP in [0, 1].

    Raises:
        ValueError: no ground-truth box at all (AP is undefined), or a bad box shape.

    >>> gt = {"a": np.array([[0.0, 0.0, 10.0, 10.0]]), "b": np.array([[0.0, 0.0, 10.0, 10.0]])}
    >>> det = Detections(("a", "b", "a"), np.array([[0, 0, 10, 10], [50, 50, 60, 60], [1, 1, 10, 10]]),
    ...                  np.array([0.9, 0.8, 0.7]))
    >>> average_precision(det, gt)   # TP, FP, duplicate FP: recall 1/2 at precision 1
    0.5
    """
    gts = {k: _boxes(np.asarray(v, float).reshape(-1, 4), f"ground_truth[{k!r}]") for k, v in ground_truth.items()}
    n_gt = sum(len(v) for v in gts.values())
    if n_gt == 0:
        raise ValueError("ground_truth holds no box: average precision is undefined")
    order = np.argsort(-detections.scores, kind="stable")
    used = {k: np.zeros(len(v), bool) for k, v in gts.items()}
    tp = np.zeros(len(order))
    for rank, i in enumerate(order):
        ref = gts.get(detections.image_ids[i])
        if ref is None or len(ref) == 0:
            continue
        ious = box_iou(detections.boxes[i][None, :], ref)
        j = int(np.argmax(ious))
        if ious[j] >= iou_threshold and not used[detections.image_ids[i]][j]:
            used[detections.image_ids[i]][j] = True
            tp[rank] = 1.0
    ctp = np.cumsum(tp)
    recall = ctp / n_gt
    precision = ctp / np.arange(1, len(order) + 1)
    return voc_ap(recall, precision)


def voc_ap(recall: np.ndarray, precision: np.ndarray) -> float:
    """All-point interpolated AP from a precision-recall curve (VOC 2010+ ``VOCap``).

    Args:
        recall: (N,) non-decreasing recall of the top-k detections.
        precision: (N,) precision of the top-k detections.

    >>> voc_ap(np.array([0.5, 0.5, 1.0]), np.array([1.0, 0.5, 2 / 3]))  # doctest: +ELLIPSIS
    0.833...
    """
    mrec = np.concatenate([[0.0], np.asarray(recall, float), [1.0]])
    mpre = np.concatenate([[0.0], np.asarray(precision, float), [0.0]])
    mpre = np.maximum.accumulate(mpre[::-1])[::-1]
    i = np.nonzero(mrec[1:] != mrec[:-1])[0]
    return float(np.sum((mrec[i + 1] - mrec[i]) * mpre[i + 1]))


#: Most bytes one YOLO predictions file may hold (one image's detections: Ultralytics keeps at most 300 by default,
#: some 50 bytes each); a longer one is refused, never read whole.
MAX_YOLO_FILE_BYTES = 1 << 20
#: Longest line of a YOLO predictions file (six numbers).
MAX_YOLO_LINE_BYTES = 1024
#: Default bound of a COCO results file (bytes; ``V3D_MAX_PREDICTIONS_MB`` for the HTTP benchmark).
MAX_COCO_FILE_BYTES = 64 << 20
#: Longest entry of a COCO results list (characters): a detection is some 100, a segmentation a few thousand.
MAX_COCO_ENTRY_CHARS = 64 << 10
#: Deepest nesting of a COCO results entry (the entry's object is depth 1, its ``bbox`` 2, a polygon list 3).
MAX_JSON_DEPTH = 16
#: Characters of an input quoted in a message, at most.
EXCERPT_CHARS = 40
_READ_BYTES = 1 << 20
_WHITESPACE = re.compile(r"[ \t\n\r]*")


def excerpt(text: str | bytes, limit: int = EXCERPT_CHARS) -> str:
    """``text`` quoted for a message: its ``repr``, the text cut to ``limit`` characters with ``...`` after.

    >>> excerpt("0 0.5 0.5"), excerpt("x" * 100, 5)
    ("'0 0.5 0.5'", "'xxxxx'...")
    """
    if isinstance(text, bytes):
        text = text.decode("utf-8", errors="replace")
    return repr(text[:limit]) + ("..." if len(text) > limit else "")


def _finite(value: object) -> float | None:
    """``value`` as a float when it is a finite number (a float or an int, not a boolean), else None."""
    kind = type(value)
    if kind is float:
        return value if math.isfinite(value) else None  # type: ignore[arg-type,return-value]  # type(value) is float, checked above
    if kind is not int:
        return None
    try:
        return float(value)  # type: ignore[arg-type]  # type(value) is int, checked above
    except OverflowError:
        return None


def load_yolo_detections(path: str | Path, width: float, height: float, class_id: int | None = None,
                         image_id: Hashable | None = None, *, name: str | None = None,
                         max_bytes: int = MAX_YOLO_FILE_BYTES) -> Detections:
    """Detections of one image from a YOLO txt file (``class cx cy w h conf`` per line, normalised), read line
    by line (never more than ``max_bytes`` nor a line longer than :data:`MAX_YOLO_LINE_BYTES`).

    Box in pixels: ``x1 = (cx - w/2) width``, ``y1 = (cy - h/2) height``, and so on (continuous
    pixels; the image spans [0, width] x [0, height]).

    Args:
        path: the txt file (empty file: no detection).
        width, height: image size in pixels.
        class_id: keep only this class (``None``: all).
        image_id: id given to the detections (default: the file's stem).
        name: how messages name the file (default: ``path``), e.g. its path inside an upload.
        max_bytes: the most the file may hold.

    Raises:
        ValueError: ``name:line: problem`` for a line that is not 6 finite numbers (quoting at most
            :data:`EXCERPT_CHARS` of it), too long or not UTF-8, or ``name: problem`` for a file above ``max_bytes``.
    """
    path = Path(path)
    ident = path.stem if image_id is None else image_id
    boxes, scores = [], []
    for box, conf in yolo_detections(path, width, height, class_id, name=name, max_bytes=max_bytes):
        boxes.append(box)
        scores.append(conf)
    return Detections((ident,) * len(boxes), np.array(boxes, float).reshape(-1, 4), np.array(scores, float))


def yolo_detections(path: str | Path, width: float, height: float, class_id: int | None = None, *,
                    name: str | None = None, max_bytes: int = MAX_YOLO_FILE_BYTES
                    ) -> Iterator[tuple[list[float], float]]:
    """The detections of a YOLO txt file one at a time, ``([x1, y1, x2, y2] px, conf)``, as
    :func:`load_yolo_detections` reads them (same arguments, same errors), holding none of them: a caller that keeps
    only the best (:class:`BestDetections`) reads a file of any length in bounded memory."""
    path = Path(path)
    label = str(path) if name is None else name
    size = n = 0
    with open(path, "rb") as fh:
        while raw := fh.readline(MAX_YOLO_LINE_BYTES + 1):
            n += 1
            size += len(raw)
            if size > max_bytes:
                raise ValueError(f"{label}: more than {max_bytes:,} bytes, more than a predictions file may hold")
            if len(raw) > MAX_YOLO_LINE_BYTES:
                raise ValueError(f"{label}:{n}: a line longer than {MAX_YOLO_LINE_BYTES} bytes, "
                                 f"starting {excerpt(raw)}")
            try:
                line = raw.decode("utf-8")
            except UnicodeDecodeError:
                raise ValueError(f"{label}:{n}: not UTF-8 text: {excerpt(raw)}") from None
            if not line.strip():
                continue
            values = [_finite(v) for v in _floats(line.split())]
            if len(values) != 6 or any(v is None for v in values):
                raise ValueError(f"{label}:{n}: expected 'class cx cy w h conf' (6 finite numbers), "
                                 f"got {excerpt(line.strip())}")
            cls, cx, cy, w, h, conf = [v for v in values if v is not None]  # all are: checked above
            if class_id is not None and int(cls) != class_id:
                continue
            yield [(cx - w / 2) * width, (cy - h / 2) * height, (cx + w / 2) * width, (cy + h / 2) * height], conf


def _floats(words: list[str]) -> list[float | None]:
    out: list[float | None] = []
    for w in words[:7]:  # one beyond six is enough to say the line is wrong
        try:
            out.append(float(w))
        except ValueError:
            out.append(None)
    return out if len(words) <= 7 else out + [None]


def coco_results(path: str | Path, *, name: str | None = None, max_bytes: int = MAX_COCO_FILE_BYTES
                 ) -> Iterator[tuple[Hashable, Any, list[float], float]]:
    """The entries of a COCO results JSON (a list of ``{"image_id", "category_id", "bbox": [x, y, w, h],
    "score"}``), one at a time: ``(image_id, category_id, [x1, y1, x2, y2] px, score)``. The file is read as a
    stream (1 MiB at a time, each entry parsed alone), never beyond ``max_bytes``; an entry holds at most
    :data:`MAX_COCO_ENTRY_CHARS` characters nested at most :data:`MAX_JSON_DEPTH` deep. Other keys of an entry
    (``segmentation``, ...) are ignored.

    Raises:
        ValueError: ``name: entry N: problem`` (quoting at most :data:`EXCERPT_CHARS` of it): not a JSON list,
            an entry that is not an object, lacks a field, has an ``image_id`` that is neither an integer nor a
            string, a ``bbox`` that is not 4 finite numbers or a ``score`` that is not one, is too long or too
            deep, or not JSON; the file above ``max_bytes`` or not UTF-8.
    """
    label = str(path) if name is None else name
    with open(path, "rb") as fh:
        if os.fstat(fh.fileno()).st_size > max_bytes:  # a regular file says so at once; any stream is counted
            raise ValueError(f"{label}: more than {max_bytes:,} bytes, more than a results file may hold "
                             "(V3D_MAX_PREDICTIONS_MB)")
        for n, entry in _json_list(fh, label, max_bytes):
            yield _coco_entry(entry, label, n)


def _coco_entry(r: Any, label: str, n: int) -> tuple[Hashable, Any, list[float], float]:
    for key in ("image_id", "bbox", "score"):
        if key not in r:
            raise ValueError(f"{label}: entry {n} lacks {key!r}")
    image_id = r["image_id"]
    if isinstance(image_id, bool) or not isinstance(image_id, (int, str)):
        raise ValueError(f"{label}: entry {n}: image_id must be an integer or a string, got "
                         f"{excerpt(json.dumps(image_id))}")
    bbox = r["bbox"]
    values = [_finite(v) for v in bbox] if isinstance(bbox, list) and len(bbox) == 4 else [None]
    if any(v is None for v in values):
        raise ValueError(f"{label}: entry {n}: bbox must be [x, y, w, h] (4 finite numbers), "
                         f"got {excerpt(json.dumps(bbox))}")
    score = _finite(r["score"])
    if score is None:
        raise ValueError(f"{label}: entry {n}: score must be a finite number, got {excerpt(json.dumps(r['score']))}")
    x, y, w, h = [v for v in values if v is not None]  # all are: checked above
    return image_id, r.get("category_id"), [x, y, x + w, y + h], score


def _json_list(fh: BinaryIO, label: str, max_bytes: int) -> Iterator[tuple[int, dict[str, Any]]]:
    """``(index, object)`` of each entry of the JSON list in the binary stream ``fh``, parsed one entry at a
    time from a buffer of at most one read plus one entry (messages as :func:`coco_results`)."""
    decoder, text = json.JSONDecoder(), codecs.getincrementaldecoder("utf-8-sig")()
    buf, pos, read, eof = "", 0, 0, False

    def more() -> bool:
        nonlocal buf, pos, read, eof
        if eof:
            return False
        raw = fh.read(_READ_BYTES)
        read += len(raw)
        if read > max_bytes:
            raise ValueError(f"{label}: more than {max_bytes:,} bytes, more than a results file may hold "
                             "(V3D_MAX_PREDICTIONS_MB)")
        try:
            chunk = text.decode(raw, final=not raw)
        except UnicodeDecodeError as exc:
            raise ValueError(f"{label}: not UTF-8 text (at byte {read - len(raw) + max(exc.start, 0)})") from None
        buf, pos, eof = buf[pos:] + chunk, 0, not raw
        return True

    def skip() -> str:
        """The next character after whitespace ("" at the end of the file)."""
        nonlocal pos
        while True:
            pos = _WHITESPACE.match(buf, pos).end()  # type: ignore[union-attr]  # the pattern matches the empty string: never None
            if pos < len(buf) or not more():
                return buf[pos:pos + 1]

    if skip() != "[":
        got = excerpt(buf[pos:]) if pos < len(buf) else "the end of the file"
        raise ValueError(f"{label}: a COCO results file is a JSON list, starting with '[': got {got}")
    pos += 1
    n = 0
    while True:
        c = skip()
        if c == "]" and n == 0:
            return
        if c != "{":
            got = excerpt(buf[pos:]) if c else "the end of the file"
            raise ValueError(f"{label}: entry {n}: expected an object {{\"image_id\", \"bbox\", \"score\", ...}}, "
                             f"got {got}")
        while True:
            try:
                value, end = decoder.raw_decode(buf, pos)
            except RecursionError:
                raise ValueError(f"{label}: entry {n}: nested deeper than {MAX_JSON_DEPTH}") from None
            except ValueError as exc:  # incomplete (read on) or not JSON
                if len(buf) - pos <= MAX_COCO_ENTRY_CHARS and more():
                    continue
                if len(buf) - pos > MAX_COCO_ENTRY_CHARS:
                    raise ValueError(f"{label}: entry {n}: longer than {MAX_COCO_ENTRY_CHARS:,} characters, "
                                     f"starting {excerpt(buf[pos:])}") from None
                msg = str(getattr(exc, "msg", exc))[:100]
                raise ValueError(f"{label}: entry {n}: not JSON ({msg}), starting {excerpt(buf[pos:])}") from None
            break
        if end - pos > MAX_COCO_ENTRY_CHARS:
            raise ValueError(f"{label}: entry {n}: longer than {MAX_COCO_ENTRY_CHARS:,} characters, "
                             f"starting {excerpt(buf[pos:])}")
        if buf.count("[", pos, end) + buf.count("{", pos, end) > MAX_JSON_DEPTH and _depth(value) > MAX_JSON_DEPTH:
            raise ValueError(f"{label}: entry {n}: nested deeper than {MAX_JSON_DEPTH}")
        pos = end
        yield n, value
        n += 1
        c = skip()
        if c == "]":
            pos += 1
            if skip():
                raise ValueError(f"{label}: text after the list: {excerpt(buf[pos:])}")
            return
        if c != ",":
            got = excerpt(buf[pos:]) if c else "the end of the file"
            raise ValueError(f"{label}: after entry {n - 1}: expected ',' or ']', got {got}")
        pos += 1


def _depth(value: Any) -> int:
    """Nesting depth of a parsed JSON value (a scalar is 0, ``[]`` 1), walked without recursion."""
    deepest, stack = 0, [(value, 1)]
    while stack:
        v, d = stack.pop()
        if isinstance(v, (list, dict)):
            deepest = max(deepest, d)
            stack.extend((c, d + 1) for c in (v.values() if isinstance(v, dict) else v))
    return deepest


@dataclass(frozen=True)
class MonocularMetrics:
    """3D localisation metrics of monocular ball estimates (paper, section Metrics).

    Attributes:
        n: detections counted (IoU > 0 with the reference box).
        mae_m: mean 3D distance to the reference ball, metres (MAE_m).
        mae_pct: mean of that distance divided by the camera-to-reference-ball distance, % (MAE_%).
        precision_at_tau: fraction (0..1) of counted detections within ``tau_m`` (P@tau3D).
        tau_m: the threshold, metres.
    """

    n: int
    mae_m: float
    mae_pct: float
    precision_at_tau: float
    tau_m: float


def monocular_metrics(predicted: np.ndarray, reference: np.ndarray, camera_centres: np.ndarray,
                      ious: np.ndarray, tau_m: float = 2.0) -> MonocularMetrics:
    """MAE_m, MAE_% and P@tau3D over detections with IoU > 0 against their reference box.

    Args:
        predicted: (N, 3) monocular ball centres, world metres.
        reference: (N, 3) reference (triangulated) ball centres, world metres.
        camera_centres: (N, 3) centre of each detection's camera, world metres.
        ious: (N,) IoU of each detection with its reference box.
        tau_m: P@tau threshold, metres (paper: 2 m).

    Returns:
        :class:`MonocularMetrics`; NaN figures when no detection counts.

    Raises:
        ValueError: an array that is not (N, 3) (a single (3,) point is N = 1), ``ious`` not (N,),
            lengths that differ, or non-finite values.
    """
    pred, ref, cams = (np.zeros((0, 3)) if np.size(a) == 0 else as_points(a, 3, name)
                       for a, name in ((predicted, "predicted"), (reference, "reference"),
                                       (camera_centres, "camera_centres")))
    iou = np.asarray(ious, float)
    if iou.ndim > 1:
        raise ValueError(f"ious must have shape (N,), got {iou.shape}")
    iou = iou.reshape(-1)
    if not (len(pred) == len(ref) == len(cams) == len(iou)):
        raise ValueError("predicted, reference, camera_centres and ious must have the same length")
    if not all(np.all(np.isfinite(a)) for a in (pred, ref, cams, iou)):
        raise ValueError("predicted, reference, camera_centres and ious must be finite")
    keep = iou > 0
    err = np.linalg.norm(pred[keep] - ref[keep], axis=1)
    rel = err / np.linalg.norm(ref[keep] - cams[keep], axis=1)
    n = int(keep.sum())
    nan = float("nan")
    return MonocularMetrics(n, float(err.mean()) if n else nan, 100.0 * float(rel.mean()) if n else nan,
                            float(precision_curve(err, np.array([tau_m]))[0]), float(tau_m))


def precision_curve(errors_m: np.ndarray, thresholds_m: np.ndarray) -> np.ndarray:
    """Precision-threshold curve: fraction of errors strictly below each threshold.

    Args:
        errors_m: (N,) 3D errors of the counted detections, metres.
        thresholds_m: (T,) thresholds, metres.

    Returns:
        (T,) fractions in [0, 1] (NaN when N = 0).

    >>> precision_curve(np.array([0.5, 1.5, 3.0]), np.array([1.0, 2.0, 4.0])).round(3).tolist()
    [0.333, 0.667, 1.0]
    """
    e = np.sort(np.asarray(errors_m, float).reshape(-1))
    t = np.asarray(thresholds_m, float).reshape(-1)
    if len(e) == 0:
        return np.full(len(t), np.nan)
    return np.searchsorted(e, t, side="left") / len(e)


def _boxes(a: np.ndarray, name: str) -> np.ndarray:
    arr = np.asarray(a, dtype=float)
    if arr.shape[-1:] != (4,):
        raise ValueError(f"{name} must have a last dimension of 4 ([x1, y1, x2, y2]), got shape {arr.shape}")
    return arr
