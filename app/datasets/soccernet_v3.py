"""SoccerNet-v3 trees (``<league>/<season>/<game>/Labels-v3.json``, images in ``Frames-v3.zip`` or a
folder) -> validated records (:mod:`app.datasets.records`); no database.

A multi-view system is an action and its ``linked_replays``; the ball is the box of class "Ball";
field lines become pixels. What v3d does not edit but a release carries (``GameMetadata``, each frame's
``imageMetadata``, every ``bboxes`` entry, the links) is kept as it came (``release`` of the records,
:func:`release_entry`, :func:`game_release`), so that exports never read the source files again. The SoccerNet-v3D
reader (:mod:`app.datasets.soccernet_v3d`) reads the same layout with its own frame reader (:data:`FrameReader`). Images
are located, never extracted: a record holds the zip path and member name or a file path. Every problem raises
:class:`~app.core.errors.DatasetError` naming the file and the field.
"""
from __future__ import annotations

import math
import zipfile
from collections.abc import Callable, Mapping
from functools import partial
from pathlib import Path
from typing import Any

from app.core.errors import DatasetError, EntryError
from app.datasets.files import (
    MAX_IMAGE_BYTES,
    MAX_IMAGE_PIXELS,
    dataset_relative,
    dataset_root,
    file_image_header,
    image_size_field,
    inside_dataset,
    load_json_file,
    mapping,
    member_image_header,
    no_collections,
    open_zip,
    safe_names,
)
from app.datasets.labels import LabelError, check_box
from app.datasets.records import FrameRecord, GameRecord, SystemRecord
from app.db.models import FrameRole, SystemKind
from app.geometry.annotations import AnnotationError, from_soccernet_v3, lines_to_json_lists

V3_LABELS = "Labels-v3.json"
V3_FRAMES_ZIP = "Frames-v3.zip"
#: The class of the ball's entry in a frame's ``bboxes``.
BALL_CLASS = "Ball"
#: The sections of a labels document that hold frames (the rest is the game's, :func:`game_release`).
FRAME_SECTIONS = ("actions", "replays")
#: ``GameMetadata`` keys that list or count the document's frames: an export writes them for the frames it holds.
LISTING_KEYS = ("list_actions", "list_replays", "num_actions", "num_replays")


def flat_lines(lines: Mapping[str, Any]) -> list[dict[str, Any]]:
    """Field lines as stored (``{class: [[[x, y], ...], ...]}``, pixels) -> SoccerNet-v3's ``lines`` list
    ``[{"class", "points": [x1, y1, x2, y2, ...]}]``, classes in their stored order, unrounded (the inverse of
    :func:`v3_lines` up to the order of interleaved classes).

    >>> flat_lines({"Circle left": [[[1.0, 2.0], [3.0, 4.5]]]})
    [{'class': 'Circle left', 'points': [1.0, 2.0, 3.0, 4.5]}]
    """
    return [{"class": cls, "points": [v for pt in poly for v in pt]} for cls, polys in lines.items() for poly in polys]


#: Key of a stored release entry holding the class of each imported line, in order, where the stored field lines give
#: the lines back but not their order on every backend (PostgreSQL's JSONB sorts an object's keys); exports drop it.
LINE_ORDER_KEY = "v3d_line_order"


def ordered_lines(lines: Mapping[str, Any], order: list[Any] | None) -> list[dict[str, Any]]:
    """:func:`flat_lines` with the lines in ``order`` (a class per line: the k-th line of a class takes its k-th
    polyline); polylines ``order`` does not name follow in stored order. ``order`` None: :func:`flat_lines`.

    >>> ordered_lines({"A": [[[0.0, 0.0]]], "B": [[[1.0, 1.0]], [[2.0, 2.0]]]}, ["B", "A", "B"])
    [{'class': 'B', 'points': [1.0, 1.0]}, {'class': 'A', 'points': [0.0, 0.0]}, {'class': 'B', 'points': [2.0, 2.0]}]
    """
    if order is None:
        return flat_lines(lines)
    taken: dict[Any, int] = {}
    out = []
    for cls in order:
        polys = lines.get(cls, []) if isinstance(cls, str) else []
        k = taken.get(cls, 0)
        if k < len(polys):
            out.append({"class": cls, "points": [v for pt in polys[k] for v in pt]})
            taken[cls] = k + 1
    for cls, polys in lines.items():
        out += [{"class": cls, "points": [v for pt in poly for v in pt]} for poly in polys[taken.get(cls, 0):]]
    return out


def release_entry(item: Mapping[str, Any], lines: Mapping[str, Any]) -> dict[str, Any]:
    """What a release carries of one frame (``FrameRecord.release``): the frame's entry ``item`` as imported,
    every key, but ``lines`` when the stored field lines ``lines`` (pixels, :func:`v3_lines`) give them back exactly
    in their order (:func:`ordered_lines`): then only the class of each line is kept, in order
    (:data:`LINE_ORDER_KEY`), so that an export writes them back as they came on any database.

    >>> release_entry({"imageMetadata": {"width": 2}, "lines": []}, {})
    {'imageMetadata': {'width': 2}, 'v3d_line_order': []}
    """
    entry = dict(item)
    raw = item.get("lines")
    if isinstance(raw, list) and all(isinstance(line, Mapping) for line in raw):
        order = [line.get("class") for line in raw]
        if ordered_lines(lines, order) == raw:
            del entry["lines"]
            entry[LINE_ORDER_KEY] = order
    return entry


def ball_index(bboxes: Any) -> int | None:
    """Index of the first entry of class "Ball" in a frame's ``bboxes`` list (None: no ball entry)."""
    if isinstance(bboxes, list):
        for i, b in enumerate(bboxes):
            if isinstance(b, Mapping) and b.get("class") == BALL_CLASS:
                return i
    return None


def game_release(data: Mapping[str, Any], systems: list[SystemRecord]) -> dict[str, Any]:
    """What a release carries of a game beside its systems (``GameRecord.release``): the labels document's
    top-level keys other than ``actions`` and ``replays`` (``GameMetadata``, every key but those that list the
    frames, :data:`LISTING_KEYS`, which an export writes for what it holds), and under ``replays`` the replay
    entries no action links, as they came (they belong to no system)."""
    out = {k: v for k, v in data.items() if k not in FRAME_SECTIONS}
    if isinstance(out.get("GameMetadata"), Mapping):
        out["GameMetadata"] = {k: v for k, v in out["GameMetadata"].items() if k not in LISTING_KEYS}
    linked = {f.name for s in systems for f in s.frames if f.role is FrameRole.REPLAY}
    replays = data.get("replays")
    unlinked = {k: v for k, v in replays.items() if k not in linked} if isinstance(replays, Mapping) else {}
    if unlinked:
        out["replays"] = unlinked
    return out


def v3_lines(item: Mapping[str, Any], width: int, height: int, file: str | Path, where: str) -> dict[str, Any]:
    """The ``lines`` of a SoccerNet-v3 frame entry as JSON lists of pixel points per class; raises
    :class:`DatasetError` naming ``file`` and the line when one is invalid."""
    lines = item.get("lines", [])
    if not isinstance(lines, list):
        raise DatasetError(file, f"{where}.lines", "expected a list of {class, points}")
    try:
        return lines_to_json_lists(from_soccernet_v3(lines, width, height))
    except AnnotationError as exc:
        raise DatasetError(file, f"{where}.{exc}", "invalid field line") from None


def v3_players(item: Mapping[str, Any], cap: int | None = None
               ) -> tuple[tuple[tuple[str, str | None, tuple[float, float, float, float]], ...], int]:
    """The people boxed in a SoccerNet-v3 frame entry besides the ball: ``(class, ID as text or None, (x1, y1, x2,
    y2) px)`` for every ``bboxes`` entry of another class with four finite coordinates and a box of positive size, in
    order, and the index of ``bboxes`` where the reading stopped. An entry that is not one is left out, never an
    error: the release keeps every entry as it came, and these only help place the cameras the lines cannot
    (``app.services.calibration.players``). With a ``cap``, the reading stops once ``cap`` boxes are read: what
    follows is neither checked nor converted (:func:`beyond_the_cap` counts it), so that a flood of boxes costs its
    parse and no more.

    >>> v3_players({"bboxes": [{"class": "Ball", "ID": None, "points": {"x1": 1, "y1": 1, "x2": 3, "y2": 3}},
    ...     {"class": "Player team left", "ID": 7, "points": {"x1": 10, "y1": 20, "x2": 30, "y2": 80}}]})
    ((('Player team left', '7', (10.0, 20.0, 30.0, 80.0)),), 2)
    """
    boxes = item.get("bboxes")
    if not isinstance(boxes, list):
        return (), 0
    out: list[tuple[str, str | None, tuple[float, float, float, float]]] = []
    isfinite = math.isfinite
    limit = len(boxes) + 1 if cap is None else cap
    # Plain statements, no generator per box: a game has thousands of boxes, read in the import's main process.
    for i, b in enumerate(boxes):
        if len(out) >= limit:
            return tuple(out), i
        if not isinstance(b, dict):  # a parsed JSON object (``Mapping``'s isinstance costs ten times more)
            continue
        cls = b.get("class")
        if not isinstance(cls, str) or cls == BALL_CLASS:
            continue
        pts, ident = b.get("points"), b.get("ID")
        if not isinstance(pts, dict) or not isinstance(ident, (str, int, type(None))) or isinstance(ident, bool):
            continue
        try:
            x1, y1, x2, y2 = float(pts["x1"]), float(pts["y1"]), float(pts["x2"]), float(pts["y2"])
        except (KeyError, TypeError, ValueError):
            continue
        if isfinite(x1) and isfinite(y1) and isfinite(x2) and isfinite(y2) and x2 > x1 and y2 > y1:
            out.append((cls[:200], None if ident is None else str(ident)[:200], (x1, y1, x2, y2)))
    return tuple(out), len(boxes)


def beyond_the_cap(bboxes: list[Any], stop: int) -> tuple[list[Any], int]:
    """A frame's ``bboxes`` list as a release keeps it once :func:`v3_players` stopped at ``stop`` (its cap reached):
    the entries before ``stop`` and the ball's entries after it; and how many entries it leaves out (every entry
    after ``stop`` but the ball's: counted, not checked).

    >>> beyond_the_cap([{"class": "A"}, {"class": "B"}, {"class": "Ball"}, 7], 1)
    ([{'class': 'A'}, {'class': 'Ball'}], 2)
    """
    balls = [b for b in bboxes[stop:] if isinstance(b, dict) and b.get("class") == BALL_CLASS]
    return bboxes[:stop] + balls, len(bboxes) - stop - len(balls)


def _v3_ball(item: Mapping[str, Any], width: int, height: int, file: str | Path, where: str) -> list[float] | None:
    boxes = item.get("bboxes", [])
    if not isinstance(boxes, list):
        raise DatasetError(file, f"{where}.bboxes", "expected a list of boxes")
    i = ball_index(boxes)
    if i is None:
        return None
    pts = boxes[i].get("points")
    if not isinstance(pts, Mapping):
        raise DatasetError(file, f"{where}.bboxes[{i}].points", "expected {x1, y1, x2, y2}")
    try:
        return check_box([pts.get(k) for k in ("x1", "y1", "x2", "y2")], width, height)
    except LabelError as exc:
        raise EntryError(file, f"{where}.bboxes[{i}] (Ball)", str(exc)) from None


class FrameImages:
    """Where a game's frame images are: ``Frames-v3.zip`` (members), a folder, or nowhere; each inside
    the dataset's folder ``root`` (resolved, ``app.datasets.files.dataset_root``): a zip, folder or image
    that resolves outside it (a symbolic link leading out) refuses the game. Each located image is
    checked from its header (PNG or JPEG, at most ``max_pixels`` pixels and ``max_bytes`` bytes,
    ``app.datasets.files.image_header``);
    the zip stays open while the game is read (use as a context manager)."""

    def __init__(self, game_dir: Path, root: Path | None = None, max_pixels: int = MAX_IMAGE_PIXELS,
                 max_bytes: int = MAX_IMAGE_BYTES) -> None:
        self.root = root if root is not None else dataset_root(game_dir)
        self.max_pixels = max_pixels
        self.max_bytes = max_bytes
        self.zip_path: Path | None = None
        self.members: set[str] = set()
        self.folders: list[Path] = []
        self._zf: zipfile.ZipFile | None = None
        self._where = str(game_dir / V3_FRAMES_ZIP)
        zp = game_dir / V3_FRAMES_ZIP
        if zp.is_file() or zp.is_symlink():
            resolved = inside_dataset(self.root, zp, V3_FRAMES_ZIP)
            self._zf = open_zip(resolved)
            self.members = set(safe_names(self._zf, zp))
            self.zip_path = resolved
        for folder in (game_dir / "Frames-v3", game_dir):
            if folder.is_dir() or folder.is_symlink():
                self.folders.append(inside_dataset(self.root, folder, "frames folder"))

    def __enter__(self) -> "FrameImages":
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def close(self) -> None:
        """Close the game's zip."""
        if self._zf is not None:
            self._zf.close()
            self._zf = None

    def locate(self, name: str) -> dict[str, Any]:
        """The image source fields of the frame image ``name`` (zip member or file, relative to the
        dataset's folder, and its checked ``image_type``), ``{}`` when absent.

        Raises:
            DatasetError: the frame's file is a link leading out of the dataset's folder, or it is not a
                PNG or JPEG image within the pixel limit (naming it).
        """
        if self.zip_path is not None and self._zf is not None and name in self.members:
            header = member_image_header(self._zf, name, f"{self._where}!{name}", self.max_pixels,
                                         self.max_bytes)
            return {"image_root": str(self.root), "image_zip": self.zip_path.relative_to(self.root).as_posix(),
                    "image_member": name, "image_type": header.type}
        if "/" not in name and "\\" not in name and ".." not in name:
            for folder in self.folders:
                candidate = folder / name
                if candidate.is_file() or candidate.is_symlink():
                    relative = dataset_relative(self.root, candidate, f"image of frame {name!r}")
                    header = file_image_header(candidate, candidate, self.max_pixels, self.max_bytes)
                    return {"image_root": str(self.root), "image_path": relative, "image_type": header.type}
        return {}


def game_key(game_dir: Path) -> tuple[str, str, str]:
    """``(league, season, match)`` of a game folder ``<league>/<season>/<game>``."""
    parts = game_dir.resolve().parts
    if len(parts) < 4:
        raise DatasetError(game_dir, None, "a game folder must sit at <league>/<season>/<game>")
    return parts[-3], parts[-2], parts[-1]


def find_labels(root: Path, filename: str) -> list[Path]:
    """Every ``filename`` under the folder ``root`` (sorted), or ``[root]`` when it is that file."""
    if not root.exists():
        raise DatasetError(root, None, "no such file or folder")
    if root.is_file():
        if root.name != filename:
            raise DatasetError(root, None, f"expected a folder or a {filename} file")
        return [root]
    found = sorted(root.rglob(filename))
    if not found:
        raise DatasetError(root, None, f"no {filename} found under this folder")
    return found


def _v3_frame(file: Path, section: str, name: str, item: Any, role: FrameRole, images: FrameImages,
              max_players: int | None = None) -> FrameRecord:
    where = f"{section}[{name!r}]"
    item = mapping(item, file, where)
    width, height = image_size_field(item.get("imageMetadata"), file, f"{where}.imageMetadata")
    lines = v3_lines(item, width, height, file, where)
    ball_box = _v3_ball(item, width, height, file, where)
    players, stop = v3_players(item, max_players)
    release, dropped = release_entry(item, lines), 0
    if stop < len(item.get("bboxes") or ()):  # the cap reached: what lies beyond it is counted, not kept
        release["bboxes"], dropped = beyond_the_cap(item["bboxes"], stop)
    return FrameRecord(
        name=name, role=role, width=width, height=height, lines=lines, ball_box=ball_box, release=release,
        players=players, players_dropped=dropped, **images.locate(name),
    )


FrameReader = Callable[[Path, str, str, Any, FrameRole, "FrameImages"], FrameRecord]


def v3_systems(file: Path, data: Any, images: FrameImages, frame_reader: FrameReader = _v3_frame) -> list[SystemRecord]:
    """Systems of a SoccerNet-v3(D) labels document: each action and its ``linked_replays``, each
    frame read by ``frame_reader(file, section, name, item, role, images)``."""
    data = mapping(data, file, "top level")
    actions = mapping(data.get("actions"), file, "actions")
    replays = mapping(data.get("replays", {}), file, "replays")
    systems = []
    for aname, action in actions.items():
        action = mapping(action, file, f"actions[{aname!r}]")
        frames = [frame_reader(file, "actions", aname, action, FrameRole.ACTION, images)]
        linked = action.get("linked_replays", [])
        if not isinstance(linked, list):
            raise DatasetError(file, f"actions[{aname!r}].linked_replays", "expected a list of replay names")
        for rname in linked:
            if not isinstance(rname, str) or rname not in replays:
                raise DatasetError(file, f"actions[{aname!r}].linked_replays",
                                   f"replay {rname!r} is not in 'replays'")
            frames.append(frame_reader(file, "replays", rname, replays[rname], FrameRole.REPLAY, images))
        names = [f.name for f in frames]
        if len(set(names)) != len(names):
            raise DatasetError(file, f"actions[{aname!r}].linked_replays", f"repeated frame names {names}")
        systems.append(SystemRecord(name=aname, kind=SystemKind.SOCCERNET_V3, frames=frames))
    return systems


def read_soccernet_v3(path: str | Path, max_pixels: int = MAX_IMAGE_PIXELS) -> list[GameRecord]:
    """Read and validate a SoccerNet-v3 tree (``<league>/<season>/<game>/Labels-v3.json``).

    ``path`` may be the tree's root, any folder inside it, or one ``Labels-v3.json``. A system is an
    action and its ``linked_replays``; the ball is the box of class "Ball". Images come from
    ``Frames-v3.zip`` beside the labels (members, never extracted) or a folder of frames
    (``Frames-v3/`` or the game folder itself). Every file read resolves inside ``path``'s folder
    (:func:`app.datasets.files.inside_dataset`: a link leading out of it refuses the input).

    Raises:
        DatasetError: naming the file and field (truncated JSON, unknown line class, NaN or
            out-of-image ball box, unsafe zip entry, unknown linked replay, bad image size, ...).
    """
    root = dataset_root(path)
    return [read_soccernet_v3_game(labels, root, max_pixels) for labels in soccernet_v3_labels(path)]


def soccernet_v3_labels(path: str | Path) -> list[Path]:
    """The ``Labels-v3.json`` of every game under ``path`` (as :func:`read_soccernet_v3` reads them,
    sorted), so that a caller can read the games one at a time (:func:`read_soccernet_v3_game`).

    Raises:
        DatasetError: ``path`` does not exist or holds no ``Labels-v3.json``, or one of them resolves
            outside ``path``'s folder (``app.datasets.files.inside_dataset``).
    """
    root = dataset_root(path)
    found = find_labels(Path(path), V3_LABELS)
    for labels in found:
        inside_dataset(root, labels, V3_LABELS)
    return found


def read_soccernet_v3_game(labels: Path, root: Path | None = None, max_pixels: int = MAX_IMAGE_PIXELS,
                           max_players: int | None = None, max_image_bytes: int = MAX_IMAGE_BYTES) -> GameRecord:
    """Read and validate one game's ``Labels-v3.json`` (see :func:`read_soccernet_v3`); ``root`` is the
    imported folder (resolved, :func:`app.datasets.files.dataset_root`; default: the game's folder),
    which every file read must resolve inside; each frame image is a PNG or JPEG of at most ``max_pixels``
    pixels (``V3D_MAX_IMAGE_PIXELS``), read from its header, and of at most ``max_image_bytes`` bytes
    (``V3D_MAX_IMAGE_MB``). A frame keeps at most ``max_players`` player boxes (``V3D_MAX_PLAYERS_PER_FRAME``; None:
    all), the first in the file's order: the rest are counted (``FrameRecord.players_dropped``), not read.

    Raises:
        DatasetError: naming the file and field.
    """
    root = root if root is not None else dataset_root(labels.parent)
    league, season, match = game_key(labels.parent)
    with no_collections():  # the parsed document, every box of a flood, is dropped before a collection sees it
        data = load_json_file(inside_dataset(root, labels, V3_LABELS))
        with FrameImages(labels.parent, root, max_pixels, max_image_bytes) as images:
            systems = v3_systems(labels, data, images, partial(_v3_frame, max_players=max_players))
        game = GameRecord(league, season, match, str(labels.parent.resolve()), systems, game_release(data, systems))
        del data
    return game
