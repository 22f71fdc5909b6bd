"""A detector's predictions as files: YOLO txt files (``class cx cy w h conf``, normalised; one file per image,
matched to views by file stem as :mod:`app.services.transfer.detector_export` names them, searched recursively, the
ball class from a ``data.yaml``) or a COCO results JSON (``image_id`` = the COCO export's image id,
``detector_export.coco_image_id`` of the stem), read with bounds into ball detections keyed by view stem
(:func:`load_predictions`). Read by the import of a detector's predictions (``app.services.transfer.predictions``)
and by the monocular benchmark (``app.services.evaluation.monocular``) above it.
"""
from __future__ import annotations

from pathlib import Path
from typing import Hashable, Iterable, Iterator, Protocol, Sequence

import numpy as np

from app.core.errors import InvalidInputError
from app.geometry.metrics import MAX_COCO_FILE_BYTES, BestDetections, Detections, coco_results, yolo_detections
from app.services.transfer.detector_export import BALL_CLASS, coco_image_id

#: Most bytes a ``data.yaml`` of predictions may hold (Ultralytics writes a few hundred).
MAX_DATA_YAML_BYTES = 64 << 10
#: Most detections one evaluation keeps (the ball class, in reference views): Ultralytics keeps at most 300 an
#: image, and a benchmark has a few thousand reference views.
MAX_DETECTIONS = 1_000_000


def _unquoted(value: str) -> str:
    value = value.strip()
    return value[1:-1] if len(value) >= 2 and value[0] == value[-1] and value[0] in "'\"" else value


def _uncommented(line: str) -> str:
    """``line`` without a YAML comment (``#`` at its start or after a blank)."""
    if line.lstrip().startswith("#"):
        return ""
    cut = min((i for i in (line.find(" #"), line.find("\t#")) if i >= 0), default=-1)
    return line if cut < 0 else line[:cut]


def ball_class_of_yaml(lines: Iterable[str], ball: str = BALL_CLASS) -> int | None:
    """The class id of ``ball`` (any case, quoted or not) in the lines of a YOLO ``data.yaml``, read one line at a
    time (linear in the text; no YAML library, no regular expression): a line ``N: Ball`` (Ultralytics' ``names``
    mapping; the first one anywhere), else its index in ``names: [a, b, Ball]``, else in a block list ``names:``
    followed by ``- a`` lines; None when it names no ball.

    >>> ball_class_of_yaml(["path: x", "names:", "  0: Player", "  3: 'ball'  # the ball"])
    3
    >>> ball_class_of_yaml(["names: [player, 'Ball']"]), ball_class_of_yaml(["names:", "- player", "- Ball"])
    (1, 1)
    """
    target = ball.lower()
    numbered = flow = block = None
    in_block, block_index = False, 0
    for raw in lines:
        if not raw or raw.isspace():
            continue
        line = _uncommented(raw).rstrip()
        text = line.strip()
        if not text:
            continue
        top = line == text
        if in_block and text.startswith("-"):
            if block is None and _unquoted(text[1:]).lower() == target:
                block = block_index
            block_index += 1
            continue
        in_block = in_block and not top
        key, colon, value = text.partition(":")
        key = key.strip()
        if colon and numbered is None and key.isascii() and key.isdigit() and len(key) < 10 \
                and _unquoted(value).lower() == target:
            numbered = int(key)
        if top and colon and key == "names":
            value = value.strip()
            if value.startswith("[") and value.endswith("]") and flow is None:
                names = [_unquoted(n).lower() for n in value[1:-1].split(",")]
                flow = names.index(target) if target in names else None
            elif not value:
                in_block, block_index = True, 0
    return numbered if numbered is not None else flow if flow is not None else block


def _ball_class_from_yaml(root: Path, name: str) -> int | None:
    """:func:`ball_class_of_yaml` of the first ``data.yaml`` under ``root`` (sorted) that names the ball; each
    read to at most :data:`MAX_DATA_YAML_BYTES` (ValueError naming it, as ``name/<path inside root>``, beyond)."""
    for path in sorted(root.rglob("data.yaml")) if root.is_dir() else []:
        if not path.is_file():
            continue
        with open(path, "rb") as fh:
            raw = fh.read(MAX_DATA_YAML_BYTES + 1)
        if len(raw) > MAX_DATA_YAML_BYTES:
            raise ValueError(f"{_inner_name(name, root, path)}: more than {MAX_DATA_YAML_BYTES:,} bytes, more than a "
                             "data.yaml may hold")
        found = ball_class_of_yaml(raw.decode("utf-8", errors="replace").splitlines())
        if found is not None:
            return found
    return None


def _inner_name(name: str, root: Path, path: Path) -> str:
    """How messages name ``path`` inside the folder ``root`` that messages call ``name``: ``name!inner`` for an
    unpacked zip (``name`` ending in ``.zip``), else ``name/inner``."""
    inner = path.relative_to(root).as_posix()
    return f"{name}!{inner}" if name.lower().endswith(".zip") else f"{name}/{inner}"


class SizedView(Protocol):
    """What :func:`load_predictions` reads of a view: its file stem and image size (px)."""

    @property
    def stem(self) -> str: ...
    @property
    def width(self) -> int: ...
    @property
    def height(self) -> int: ...


def load_predictions(path: str | Path, views: Sequence[SizedView], ball_class: int | None = None, *,
                     name: str | None = None, max_coco_bytes: int = MAX_COCO_FILE_BYTES,
                     keep: BestDetections | None = None) -> tuple[Detections, int]:
    """Ball detections of ``path`` keyed by view stem, and the number of detections ignored (images
    that are not ground-truth views).

    Every file is read with bounds, as a stream (:func:`app.geometry.metrics.yolo_detections`: 1 MiB a
    ``.txt``; :func:`app.geometry.metrics.coco_results`: ``max_coco_bytes``; ``data.yaml``:
    :data:`MAX_DATA_YAML_BYTES`), and at most :data:`MAX_DETECTIONS` detections are kept, or with ``keep`` the best
    ``keep.per_image`` of each view by score, chosen while reading (``keep.dropped`` counts the others).

    Args:
        path: a folder of YOLO txt files (searched recursively; the ball class from ``ball_class``,
            else from a ``data.yaml`` found there naming ``Ball``, else 0) or a COCO results JSON
            (category ``ball_class``, default 1 as in the COCO export).
        views: :func:`reference_views` (or any views with a stem and a size: an import of a detector's predictions
            reads them for every stored view, ``app.services.transfer.predictions``).
        name: how messages name ``path`` (default: the path itself): an upload's file name, so that no
            message shows the server's folders; a file inside the folder is ``name!inner/path`` when ``name``
            ends in ``.zip``, else ``name/inner/path``.
        max_coco_bytes: the largest COCO results file read (``V3D_MAX_PREDICTIONS_MB`` over HTTP).
        keep: the per-view bound (``V3D_MAX_PREDICTIONS_PER_FRAME``): memory O(views x bound) whatever the file holds.

    Raises:
        InvalidInputError: no such file or folder, or a malformed or too large file (field ``predictions``; the
            message names the file, the line or entry, and quotes at most a short excerpt).
    """
    p = Path(path)
    label = str(p) if name is None else name
    by_stem = {v.stem: v for v in views}
    ids: list[str] = []
    boxes: list[Sequence[float]] = []
    scores: list[float] = []

    def take(stem: str, box: Sequence[float], score: float) -> None:
        if keep is not None:
            keep.add(stem, box, score)
            return
        if len(scores) >= MAX_DETECTIONS:
            raise ValueError(f"{label}: more than {MAX_DETECTIONS:,} detections of the ball in reference views")
        ids.append(stem)
        boxes.append(box)
        scores.append(score)

    def taken() -> Detections:
        if keep is not None:
            return keep.detections()
        return Detections(tuple(ids), np.array(boxes, float).reshape(-1, 4), np.array(scores, float))

    try:
        if p.is_dir():
            cls = ball_class if ball_class is not None else _ball_class_from_yaml(p, label)
            found = _yolo_files(p, label, by_stem, 0 if cls is None else cls)
        elif p.is_file():
            found = _coco_file(p, label, views, 1 if ball_class is None else ball_class, max_coco_bytes)
        else:
            found = None
        if found is not None:
            ignored = 0
            for stem, box, score in found:
                if stem is None:
                    ignored += 1
                else:
                    take(stem, box, score)
            return taken(), ignored
    except (ValueError, OSError) as exc:
        raise InvalidInputError(str(exc) if isinstance(exc, ValueError) else f"{label}: cannot read ({exc.strerror})",
                                field="predictions") from None
    raise InvalidInputError(f"no such file or folder: {p}", field="predictions")


def _yolo_files(root: Path, label: str, by_stem: dict[str, SizedView], cls: int
                ) -> Iterator[tuple[str | None, Sequence[float], float]]:
    """Every detection of class ``cls`` in the YOLO txt files under ``root`` as ``(view stem, box px, confidence)``, in
    file order; the stem is None for a file of an image that is no view of ``by_stem`` (its boxes read at size 1)."""
    for txt in sorted(root.rglob("*.txt")):
        if not txt.is_file():
            continue
        view = by_stem.get(txt.stem)
        for box, conf in yolo_detections(txt, view.width if view else 1.0, view.height if view else 1.0, cls,
                                         name=_inner_name(label, root, txt)):
            yield (None if view is None else view.stem), box, conf


def _coco_file(path: Path, label: str, views: Sequence[SizedView], category: int, max_coco_bytes: int
               ) -> Iterator[tuple[str | None, Sequence[float], float]]:
    """Every result of ``category`` in the COCO results JSON ``path`` as ``(view stem, box px, score)``, in file order;
    the stem is None for an image id of none of ``views`` (their stems' ``coco_image_id``)."""
    by_id: dict[Hashable, str] = {coco_image_id(v.stem): v.stem for v in views}
    for image_id, cat, box, score in coco_results(path, name=label, max_bytes=max_coco_bytes):
        if cat == category:
            yield by_id.get(image_id), box, score
