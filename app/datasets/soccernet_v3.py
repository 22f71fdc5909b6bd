"""SoccerNet-v3 trees (``<league>/<season>/<game>/Labels-v3.json``, images in ``Frames-v3.zip`` or a
folder) -> validated records (:mod:`app.datasets.records`); no database.

A multi-view system is an action and its ``linked_replays``; the ball is the box of class "Ball";
field lines become pixels. The SoccerNet-v3D reader (:mod:`app.datasets.soccernet_v3d`) reads the same
layout with its own frame reader (:data:`FrameReader`). Images are located, never extracted: a record
holds the zip path and member name or a file path. Every problem raises
:class:`~app.core.errors.DatasetError` naming the file and the field.
"""
from __future__ import annotations

from pathlib import Path
from typing import Any, Callable, Mapping

from app.datasets.files import image_size_field, load_json_file, mapping, open_zip, safe_names
from app.datasets.records import FrameRecord, GameRecord, SystemRecord
from app.db.models import FrameRole, SystemKind
from app.geometry.annotations import AnnotationError, from_soccernet_v3, lines_to_json_lists
from app.datasets.labels import LabelError, check_box
from app.core.errors import DatasetError

V3_LABELS = "Labels-v3.json"
V3_FRAMES_ZIP = "Frames-v3.zip"


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


def _v3_ball(item: Mapping[str, Any], width: int, height: int, file: str | Path, where: str) -> list[float] | None:
    boxes = item.get("bboxes", [])
    if not isinstance(boxes, list):
        raise DatasetError(file, f"{where}.bboxes", "expected a list of boxes")
    for i, b in enumerate(boxes):
        if isinstance(b, Mapping) and b.get("class") == "Ball":
            pts = b.get("points")
            if not isinstance(pts, Mapping):
                raise DatasetError(file, f"{where}.bboxes[{i}].points", "expected {x1, y1, x2, y2}")
            try:
                return check_box([pts.get(k) for k in ("x1", "y1", "x2", "y2")], width, height)
            except LabelError as exc:
                raise DatasetError(file, f"{where}.bboxes[{i}] (Ball)", str(exc)) from None
    return None


class FrameImages:
    """Where a game's frame images are: ``Frames-v3.zip`` (members), a folder, or nowhere."""

    def __init__(self, game_dir: Path) -> None:
        self.zip_path: Path | None = None
        self.members: set[str] = set()
        self.folders: list[Path] = []
        zp = game_dir / V3_FRAMES_ZIP
        if zp.is_file():
            with open_zip(zp) as zf:
                self.members = set(safe_names(zf, zp))
            self.zip_path = zp.resolve()
        for folder in (game_dir / "Frames-v3", game_dir):
            if folder.is_dir():
                self.folders.append(folder.resolve())

    def locate(self, name: str) -> dict[str, str | None]:
        """The image source fields of the frame image ``name`` (zip member or file), ``{}`` when absent."""
        if self.zip_path is not None and name in self.members:
            return {"image_zip": str(self.zip_path), "image_member": name}
        if "/" not in name and "\\" not in name and ".." not in name:
            for folder in self.folders:
                if (folder / name).is_file():
                    return {"image_path": str(folder / name)}
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


def _v3_frame(file: Path, section: str, name: str, item: Any, role: FrameRole, images: FrameImages) -> FrameRecord:
    where = f"{section}[{name!r}]"
    item = mapping(item, file, where)
    width, height = image_size_field(item.get("imageMetadata"), file, f"{where}.imageMetadata")
    return FrameRecord(
        name=name, role=role, width=width, height=height,
        lines=v3_lines(item, width, height, file, where),
        ball_box=_v3_ball(item, width, height, file, where),
        **images.locate(name),
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


def read_soccernet_v3(path: str | Path) -> list[GameRecord]:
    """Read and validate a SoccerNet-v3 tree (``<league>/<season>/<game>/Labels-v3.json``).

    ``path`` may be the tree's root, any folder inside it, or one ``Labels-v3.json``. A system is an
    action and its ``linked_replays``; the ball is the box of class "Ball". Images come from
    ``Frames-v3.zip`` beside the labels (members, never extracted) or a folder of frames
    (``Frames-v3/`` or the game folder itself).

    Raises:
        DatasetError: naming the file and field (truncated JSON, unknown line class, NaN or
            out-of-image ball box, unsafe zip entry, unknown linked replay, bad image size, ...).
    """
    return [read_soccernet_v3_game(labels) for labels in soccernet_v3_labels(path)]


def soccernet_v3_labels(path: str | Path) -> list[Path]:
    """The ``Labels-v3.json`` of every game under ``path`` (as :func:`read_soccernet_v3` reads them,
    sorted), so that a caller can read the games one at a time (:func:`read_soccernet_v3_game`).

    Raises:
        DatasetError: ``path`` does not exist or holds no ``Labels-v3.json``.
    """
    return find_labels(Path(path), V3_LABELS)


def read_soccernet_v3_game(labels: Path) -> GameRecord:
    """Read and validate one game's ``Labels-v3.json`` (see :func:`read_soccernet_v3`).

    Raises:
        DatasetError: naming the file and field.
    """
    league, season, match = game_key(labels.parent)
    systems = v3_systems(labels, load_json_file(labels), FrameImages(labels.parent))
    return GameRecord(league, season, match, str(labels.parent.resolve()), systems)
