"""ISSIA-3D: a folder of six synchronised static cameras -> validated plain records; ISSIA-3D.csv rows.

Folder (method.md section 9):

* ``issia_calibration.json``: camera id -> SoccerNet camera (method.md section 2), and/or
  ``issia_lines.json``: camera id -> field lines in SoccerNet-calibration format (normalised);
* ``ball_points.csv``: ``frame, x_cam1, y_cam1, ..., x_cam6, y_cam6``; an empty cell is no label;
  pixels of the annotation resolution (1920x1080 unless told); or, in its place, the authors' released
  ``ISSIA-3D.csv`` (:func:`read_released_points`: its ``x_camK``, ``y_camK`` columns, a ``frame`` column
  when present, else row order; every other column ignored);
* optionally ``videos/cam<k>.mp4`` or frame folders ``frames/cam<k>/`` (images named by frame
  number), read on demand (:func:`read_frame_image`). Videos may have another resolution than the
  annotation: the image is resized to the annotation resolution, or its scale is reported.
* a per-camera horizontal flip (footage that is mirrored relative to the annotation) is given by
  the caller (``flipped_cameras``) and applied to images, never to the labels.

A sequence is one game; a multi-view system is one frame index across the cameras; frame ``i`` is
at ``t = i / fps``. Errors name the file and the field (:class:`app.core.errors.DatasetError`).

``ISSIA-3D.csv`` rows are read and written by :mod:`app.datasets.issia3d`. Cameras 3-6 are the
training set and 1-2 the test set, as in the paper (:data:`CAMERA_SET`).
"""
from __future__ import annotations

import csv
import io
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Iterable, Optional

import numpy as np

from app.core.errors import DatasetError
from app.datasets.files import (
    MAX_IMAGE_PIXELS,
    dataset_root,
    file_image_header,
    inside_dataset,
    load_json_file,
    read_text_file,
)
from app.geometry.annotations import AnnotationError, FieldLines, from_soccernet_calibration
from app.geometry.camera import Camera

CAMERA_IDS = ("1", "2", "3", "4", "5", "6")
CAMERA_SET = {"1": "test", "2": "test", "3": "train", "4": "train", "5": "train", "6": "train"}
ANNOTATION_SIZE = (1920, 1080)
#: Frame rate of ISSIA sequences (frame ``i`` at ``t = i / FPS`` s): the one home of the 25 fps the services,
#: the API and the exports read.
FPS = 25.0
CALIBRATION_FILE, LINES_FILE, POINTS_FILE = "issia_calibration.json", "issia_lines.json", "ball_points.csv"
#: The authors' released labels, read in place of :data:`POINTS_FILE` when that is absent.
RELEASED_POINTS_FILE = "ISSIA-3D.csv"
#: Largest CSV a sequence may carry: a frame is a row of a few hundred bytes, so an hour at 25 fps is ~20 MB.
MAX_CSV_BYTES = 64 * 1024 * 1024
_IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg")


@dataclass(frozen=True)
class IssiaSequence:
    """A validated ISSIA folder.

    Attributes:
        root: the folder.
        camera_ids: camera ids in ``ball_points.csv`` column order ("1".."6").
        image_size: (width, height) of the annotation, px.
        cameras: id -> :class:`Camera` from ``issia_calibration.json`` (empty when absent).
        lines: id -> :data:`FieldLines` (px of ``image_size``) from ``issia_lines.json`` (empty when absent).
        frames: frame indices of ``ball_points.csv`` rows, ascending.
        points: (len(frames), K, 2) labels, px of ``image_size``; NaN where the cell is empty.
        media: id -> video file or frame folder (only those that exist).
        flipped: ids whose footage is mirrored horizontally relative to the annotation.
    """

    root: Path
    camera_ids: tuple[str, ...]
    image_size: tuple[int, int]
    cameras: dict[str, Camera]
    lines: dict[str, FieldLines]
    frames: tuple[int, ...]
    points: np.ndarray
    media: dict[str, Path] = field(default_factory=dict)
    flipped: frozenset[str] = frozenset()

    def point(self, frame: int, camera_id: str) -> tuple[float, float] | None:
        """The label of ``camera_id`` at ``frame`` (px), or ``None`` when empty."""
        p = self.points[self.frames.index(frame), self.camera_ids.index(camera_id)]
        return None if not np.all(np.isfinite(p)) else (float(p[0]), float(p[1]))

    def dense_points(self) -> np.ndarray:
        """(max frame + 1, K, 2) labels indexed by frame number (NaN rows for absent frames)."""
        out = np.full((self.frames[-1] + 1 if self.frames else 0, len(self.camera_ids), 2), np.nan)
        out[list(self.frames)] = self.points
        return out


def read_issia(root: str | Path, *, image_size: tuple[int, int] = ANNOTATION_SIZE,
               flipped_cameras: Iterable[str] = (), max_pixels: int = MAX_IMAGE_PIXELS) -> IssiaSequence:
    """Read and validate an ISSIA folder (module docstring); nothing is computed. Every file read
    (JSON, CSV, videos, frame images) resolves inside ``root`` (:func:`app.datasets.files.inside_dataset`);
    each video opens with OpenCV with frames of the annotation's aspect and at most ``max_pixels`` pixels
    (:func:`check_video`), each image of a frame folder is a PNG or JPEG within it (read from its header).

    Raises:
        DatasetError: missing folder or files, malformed JSON, a camera or line set that does not
            parse, a CSV whose header or cells are wrong (the message names file, row and column), a
            file or link leading out of the folder, a video or frame image that is not one or too large.
    """
    root = Path(root)
    if not root.is_dir():
        raise DatasetError(root, None, "not a folder")
    top = dataset_root(root)
    w, h = image_size
    cal_path, lines_path, pts_path = root / CALIBRATION_FILE, root / LINES_FILE, root / POINTS_FILE
    released = root / RELEASED_POINTS_FILE
    for name, path in ((CALIBRATION_FILE, cal_path), (LINES_FILE, lines_path), (POINTS_FILE, pts_path),
                       (RELEASED_POINTS_FILE, released)):
        if path.exists() or path.is_symlink():
            inside_dataset(top, path, name)
    if not cal_path.is_file() and not lines_path.is_file():
        raise DatasetError(root, None, f"needs {CALIBRATION_FILE} or {LINES_FILE}")
    if pts_path.is_file():
        camera_ids, frames, points = _read_points(pts_path)
    elif released.is_file():
        camera_ids, frames, points = read_released_points(released)
    else:
        raise DatasetError(pts_path, None, f"missing (and no {RELEASED_POINTS_FILE} in its place)")
    cameras: dict[str, Camera] = {}
    for cid, data in _read_json_object(cal_path).items() if cal_path.is_file() else ():
        try:
            cameras[cid] = Camera.from_soccernet(data)
        except (ValueError, TypeError, KeyError) as exc:
            raise DatasetError(cal_path, cid, f"not a SoccerNet camera: {exc}") from exc
    lines: dict[str, FieldLines] = {}
    for cid, data in _read_json_object(lines_path).items() if lines_path.is_file() else ():
        try:
            lines[cid] = from_soccernet_calibration(data, w, h)
        except AnnotationError as exc:
            raise DatasetError(lines_path, cid, str(exc)) from exc
    for table, path in ((cameras, cal_path), (lines, lines_path)):
        unknown = sorted(set(table) - set(camera_ids))
        if unknown:
            raise DatasetError(path, unknown[0], f"camera id not among the {POINTS_FILE} columns {list(camera_ids)}")
    flipped = frozenset(str(c) for c in flipped_cameras)
    if flipped - set(camera_ids):
        raise DatasetError(root, "flipped_cameras", f"unknown camera ids {sorted(flipped - set(camera_ids))}")
    media = {}
    for cid in camera_ids:
        for cand in (root / "videos" / f"cam{cid}.mp4", root / "frames" / f"cam{cid}"):
            if cand.exists() or cand.is_symlink():
                media[cid] = inside_dataset(top, cand, f"cam{cid}")
                if media[cid].is_dir():
                    for image in sorted(media[cid].iterdir()):
                        inside_dataset(top, image, f"cam{cid}")
                        if image.suffix.lower() in _IMAGE_SUFFIXES:
                            file_image_header(image, image, max_pixels)
                else:
                    check_video(cand, (int(w), int(h)), max_pixels)
                break
    return IssiaSequence(root, camera_ids, (int(w), int(h)), cameras, lines, frames, points, media, flipped)


def check_video(path: Path, image_size: tuple[int, int], max_pixels: int = MAX_IMAGE_PIXELS) -> tuple[int, int]:
    """``(width, height)`` of the video ``path`` as OpenCV opens it (its container, not its name), when
    it has frames of the annotation's aspect (``image_size``; a 960x540 video of 1920x1080 annotations is
    resized when read) and at most ``max_pixels`` pixels per frame.

    Raises:
        DatasetError: naming the video, when OpenCV cannot open it, it has no frame, a frame is larger
            than ``max_pixels`` (``V3D_MAX_IMAGE_PIXELS``) or of another aspect than the declared size.
    """
    import cv2

    cap = cv2.VideoCapture(str(path))
    try:
        return _checked_capture(cap, path, image_size, max_pixels)
    finally:
        cap.release()


def _checked_capture(cap: Any, path: Path, image_size: tuple[int, int], max_pixels: int) -> tuple[int, int]:
    """The frame size of an open ``cv2.VideoCapture`` after :func:`check_video`'s checks."""
    import cv2

    if not cap.isOpened():
        raise DatasetError(path, None, "not a video OpenCV can open")
    width, height = int(cap.get(cv2.CAP_PROP_FRAME_WIDTH)), int(cap.get(cv2.CAP_PROP_FRAME_HEIGHT))
    if width < 1 or height < 1:
        raise DatasetError(path, None, "a video without frames")
    if width * height > max_pixels:
        raise DatasetError(path, None, f"frames of {width}x{height} = {width * height:,} pixels, above "
                                       f"V3D_MAX_IMAGE_PIXELS ({max_pixels:,})")
    aw, ah = image_size
    if abs(width * ah - height * aw) > 0.01 * aw * height:
        raise DatasetError(path, None, f"frames of {width}x{height}: not the declared {aw}x{ah} (or a scale of it)")
    return width, height


def _read_json_object(path: Path) -> dict[str, Any]:
    data = load_json_file(path)
    if not isinstance(data, dict):
        raise DatasetError(path, None, "must be a JSON object of camera id -> value")
    return {str(k): v for k, v in data.items()}


def _csv_rows(path: Path) -> list[list[str]]:
    """The rows of one of a sequence's CSV files (``ball_points.csv``, a released ``ISSIA-3D.csv``), at most
    :data:`MAX_CSV_BYTES`.

    Raises:
        DatasetError: naming ``path``: missing, too large, not UTF-8, not CSV, or empty.
    """
    text = read_text_file(path, MAX_CSV_BYTES, "CSV")
    try:
        rows = list(csv.reader(io.StringIO(text)))
    except csv.Error as exc:
        raise DatasetError(path, None, f"not a readable CSV: {exc}") from exc
    if not rows:
        raise DatasetError(path, None, "empty file")
    return rows


def _read_points(path: Path) -> tuple[tuple[str, ...], tuple[int, ...], np.ndarray]:
    rows = _csv_rows(path)
    header = [c.strip() for c in rows[0]]
    ids = []
    if not header or header[0] != "frame" or len(header) < 3 or len(header) % 2 == 0:
        raise DatasetError(path, "header", "expected frame, x_cam1, y_cam1, ...")
    for i in range(1, len(header), 2):
        mx, my = re.fullmatch(r"x_cam(\w+)", header[i]), re.fullmatch(r"y_cam(\w+)", header[i + 1])
        if not mx or not my or mx.group(1) != my.group(1):
            raise DatasetError(path, "header", f"columns {header[i]!r}, {header[i + 1]!r} are not x_camK, y_camK")
        ids.append(mx.group(1))
    if len(set(ids)) != len(ids):
        raise DatasetError(path, "header", f"camera ids repeat: {ids}")
    return _label_rows(path, rows, ids, [(1 + 2 * k, 2 + 2 * k) for k in range(len(ids))], 0, int)


def _label_rows(path: Path, rows: list[list[str]], ids: list[str], columns: list[tuple[int, int]],
                frame_col: Optional[int], frame_number: Callable[[str], int]
                ) -> tuple[tuple[str, ...], tuple[int, ...], np.ndarray]:
    """The data rows (after the header) of a ball-point CSV: ``columns[k]`` are the x, y cell indices of camera
    ``ids[k]``; the frame is ``frame_number(row[frame_col])``, or the row order from 0 without a frame column. An
    empty or ``nan`` cell is no label. Returns ids, frames and (F, C, 2) pixels, NaN for no label.

    Raises:
        DatasetError: a row of another length, a frame that is not an integer or not after the one before, a
            coordinate without the other, cells that are not finite numbers (naming row and column).
    """
    frames: list[int] = []
    pts = []
    for n, row in enumerate(rows[1:], start=2):
        if not any(c.strip() for c in row):
            continue
        if len(row) != len(rows[0]):
            raise DatasetError(path, f"row {n}", f"{len(row)} cells, header has {len(rows[0])}")
        if frame_col is None:
            frame = len(frames)
        else:
            try:
                frame = frame_number(row[frame_col])
            except ValueError:
                raise DatasetError(path, f"row {n} frame", f"not an integer: {row[frame_col]!r}") from None
            if frame < 0 or (frames and frame <= frames[-1]):
                raise DatasetError(path, f"row {n} frame",
                                   f"{frame} is negative or not after {frames[-1] if frames else ''}")
        p = np.full((len(ids), 2), np.nan)
        for k, (cid, (xi, yi)) in enumerate(zip(ids, columns, strict=True)):
            x, y = row[xi].strip(), row[yi].strip()
            x, y = ("" if x.lower() == "nan" else x), ("" if y.lower() == "nan" else y)
            if bool(x) != bool(y):
                raise DatasetError(path, f"row {n} x_cam{cid}/y_cam{cid}", "one coordinate without the other")
            if x:
                try:
                    p[k] = float(x), float(y)
                except ValueError:
                    raise DatasetError(path, f"row {n} cam{cid}", f"not numbers: {x!r}, {y!r}") from None
                if not np.all(np.isfinite(p[k])):
                    raise DatasetError(path, f"row {n} cam{cid}", "not finite")
        frames.append(frame)
        pts.append(p)
    return tuple(ids), tuple(frames), np.array(pts).reshape(len(frames), len(ids), 2)


def read_released_points(path: Path) -> tuple[tuple[str, ...], tuple[int, ...], np.ndarray]:
    """The ball labels of a released ``ISSIA-3D.csv``: camera ids (``x_camK`` columns in header order), frame
    indices (the ``frame`` column when there is one, else the row order from 0) and (F, C, 2) pixels, NaN for
    no label (an empty or ``nan`` cell). Other columns (``err_camK``, ``ball_3D``, ...) are ignored: v3d
    recomputes them.

    Raises:
        DatasetError: unreadable file, no ``x_camK``/``y_camK`` pair, a coordinate without the other, cells
            that are not finite numbers, frames not increasing (the message names row and column).
    """
    rows = _csv_rows(path)
    header = [c.strip() for c in rows[0]]
    col = {name: i for i, name in enumerate(header)}
    ids = [m.group(1) for h in header if (m := re.fullmatch(r"x_cam(\w+)", h))]
    if not ids:
        raise DatasetError(path, "header", "no x_camK column")
    for cid in ids:
        if f"y_cam{cid}" not in col:
            raise DatasetError(path, "header", f"x_cam{cid} without y_cam{cid}")
    return _label_rows(path, rows, ids, [(col[f"x_cam{cid}"], col[f"y_cam{cid}"]) for cid in ids], col.get("frame"),
                       lambda cell: int(float(cell)))


@dataclass(frozen=True)
class FrameImage:
    """An image of one camera at one frame.

    Attributes:
        image: (H, W, 3) uint8 BGR, flipped back when the camera's footage is mirrored.
        scale: (sx, sy) that turn this image's pixels into annotation pixels (1.0 after resizing).
    """

    image: np.ndarray
    scale: tuple[float, float]


def read_frame_image(seq: IssiaSequence, camera_id: str, frame: int, *, at_annotation_size: bool = True,
                     max_pixels: int = MAX_IMAGE_PIXELS) -> FrameImage:
    """Read ``frame`` of ``camera_id`` from its video (seek) or frame folder, with OpenCV.

    Args:
        at_annotation_size: resize to ``seq.image_size`` (scale 1); otherwise the native image and
            the scale from its pixels to annotation pixels (e.g. 2.0 for a 960x540 video).

    The image's size is checked before OpenCV decodes it (a frame image's header, a video's frame
    size: at most ``max_pixels`` pixels).

    Raises:
        DatasetError: no media for the camera, the frame cannot be read, or it is too large.
    """
    import cv2

    src = seq.media.get(camera_id)
    if src is None:
        raise DatasetError(seq.root, f"cam{camera_id}", "no video or frame folder")
    if src.is_dir():
        named = {int(m.group(1)): p for p in src.iterdir()
                 if p.suffix.lower() in _IMAGE_SUFFIXES and (m := re.search(r"(\d+)$", p.stem))}
        img = None
        if frame in named:
            file_image_header(named[frame], named[frame], max_pixels)  # bounded before OpenCV decodes it
            img = cv2.imread(str(named[frame]))
    else:
        cap = cv2.VideoCapture(str(src))
        try:
            _checked_capture(cap, src, seq.image_size, max_pixels)  # bounded before OpenCV decodes a frame
            cap.set(cv2.CAP_PROP_POS_FRAMES, int(frame))
            ok, img = cap.read()
        finally:
            cap.release()
        img = img if ok else None
    if img is None:
        raise DatasetError(src, f"frame {frame}", "cannot be read")
    if camera_id in seq.flipped:
        img = cv2.flip(img, 1)
    w, h = seq.image_size
    if at_annotation_size:
        if img.shape[1] != w or img.shape[0] != h:
            img = cv2.resize(img, (w, h), interpolation=cv2.INTER_LINEAR)
        return FrameImage(img, (1.0, 1.0))
    return FrameImage(img, (w / img.shape[1], h / img.shape[0]))
