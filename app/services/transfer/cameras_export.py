"""Export of the stored cameras as SoccerNet's official calibration evaluator reads them (``v3d export cameras``,
``GET /api/exports/cameras``).

SoccerNet's evaluator (the ``SoccerNet`` package, ``SoccerNet.Evaluation.CameraCalibration.evaluate(gt_zip,
prediction_zip, threshold, width, height)``; repository SoccerNet/sn-calibration, ``evaluate_camera.py``) takes
one image size, a ground-truth zip whose members are ``<split>/<name>.json`` (field lines, SoccerNet-calibration
format: ``{class: [{"x", "y"}, ...]}`` normalised, ``x (W - 1)`` pixels) and a predictions zip beside it whose
members are ``camera_<name>.json`` (SoccerNet-calibration camera, pixels of that size). The export writes one such
pair per image size, under ``out_dir``::

    cameras.json                      the index (below)
    <W>x<H>/ground_truth.zip          <split>/<name>.json: the view's current field lines (every exported view)
    <W>x<H>/predictions.zip           camera_<name>.json: the view's stored camera (views whose calibration is admitted)

so that ``evaluate("<W>x<H>/ground_truth.zip", "<W>x<H>/predictions.zip", 5, W, H)`` scores v3d's cameras
against v3d's lines as written (its JaC at a threshold equals v3d's, ``app.geometry.jac``; a view without an
admitted camera lowers its completeness). ``<name>`` is the kind's ``view_stem`` (``app.services.kinds``:
``<game slug>-<hash>_<frame stem>``), unique across games and sizes; ``<split>`` the kind's split (train /
test, as the other exports). The views: every view with field lines of the selected systems (the kinds that
take the ``cameras`` export: SoccerNet-v3 games and single SoccerNet-calibration frames; accepted systems
unless ``include_all``). Class points of several polylines of one class are pooled into one list (the
evaluator holds one point list per class and scores every point).

``cameras.json`` maps each name back to v3d: ``{"format": "v3d-cameras/2", "sets": [{"size": "960x540",
"width", "height", "ground_truth", "predictions", "views": [{"name", "split", "kind", "game":
"<league>/<season>/<match>", "frame", "camera": bool, "jac": {"0.005": .., "0.01": .., "0.02": ..}}]}]}``
(paths relative to the export: nothing in it names a server folder). ``v3d evaluate monocular --cameras DIR``
reads this layout (:func:`read_cameras`).

ISSIA cameras leave with the ISSIA-3D export (``<sequence>/calibration/cam<k>.json``, ``app.services.issia.export``).
"""
from __future__ import annotations

import zipfile
from collections.abc import Iterable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import orjson
from sqlalchemy.orm import Session, selectinload

from app.core.errors import DatasetError, InvalidInputError
from app.datasets.files import dataset_root, inside_dataset, load_json_bytes
from app.db.models import JAC_COLUMNS, Frame, System
from app.geometry.annotations import lines_from_json_lists
from app.services.kinds import kind_of
from app.services.transfer.exporting import exported_systems

#: The index file of a cameras export.
INDEX = "cameras.json"
FORMAT = "v3d-cameras/2"
GROUND_TRUTH = "ground_truth.zip"
PREDICTIONS = "predictions.zip"
#: Largest camera file :func:`read_cameras` reads from a predictions zip (bytes): a camera is a few hundred bytes.
MAX_CAMERA_BYTES = 1 << 20


@dataclass(frozen=True)
class CameraView:
    """One view of a cameras export.

    Attributes:
        name: file stem, unique in the export (``<split>/<name>.json``, ``camera_<name>.json``).
        split: "train" or "test".
        game: ``league/season/match``.
        frame: the frame's name in its game (``12_3.png``).
        kind: the system kind's value.
        width, height: image size, pixels (the set it joins).
        camera: the SoccerNet-calibration camera (pixels of that image), None without an admitted one.
        lines: the field lines in SoccerNet-calibration form (class -> normalised points), None to write no
            ground truth for the view.
        jac: v3d's stored JaC by gamma (``"0.005"``...), as the index reports it.
    """

    name: str
    split: str
    game: str
    frame: str
    kind: str
    width: int
    height: int
    camera: dict[str, Any] | None
    lines: dict[str, list[dict[str, float]]] | None
    jac: dict[str, float | None] = field(default_factory=dict)


@dataclass
class CamerasExport:
    """What :func:`export_cameras` wrote: the camera files by kind, the views of each image size."""

    out_dir: Path
    cameras: int = 0
    by_kind: dict[str, int] = field(default_factory=dict)
    sizes: dict[str, int] = field(default_factory=dict)
    ground_truth: int = 0

    def as_dict(self) -> dict[str, Any]:
        """The counts (no path: what a job stores)."""
        return {"cameras": self.cameras, "by_kind": dict(self.by_kind), "sizes": dict(self.sizes),
                "ground_truth": self.ground_truth}


def pooled_lines(stored: dict[str, Any], width: int, height: int) -> dict[str, list[dict[str, float]]]:
    """Stored field lines (``{class: [[[x, y], ...], ...]}`` px) as one SoccerNet-calibration point list per
    class, normalised as the evaluator's ``scale_points`` inverts (``x / (W - 1)``, ``y / (H - 1)``).

    >>> pooled_lines({"Middle line": [[[480.0, 0.0]], [[480.0, 540.0]]]}, 961, 541)
    {'Middle line': [{'x': 0.5, 'y': 0.0}, {'x': 0.5, 'y': 1.0}]}
    """
    scale = np.array([width - 1.0, height - 1.0])
    out: dict[str, list[dict[str, float]]] = {}
    for cls, polys in lines_from_json_lists(stored).items():
        pts = [p for poly in polys for p in (np.asarray(poly, float) / scale)]
        if pts:
            out[cls] = [{"x": float(x), "y": float(y)} for x, y in pts]
    return out


def _zip(path: Path, members: Iterable[tuple[str, Any]]) -> None:
    """A zip of JSON members and no folder entries (the evaluator splits every member name on ``/``)."""
    part = path.with_name(path.name + ".part")
    with zipfile.ZipFile(part, "w", zipfile.ZIP_DEFLATED) as zf:
        for name, doc in members:
            zf.writestr(zipfile.ZipInfo(name, date_time=(2020, 1, 1, 0, 0, 0)), orjson.dumps(doc),
                        compress_type=zipfile.ZIP_DEFLATED)
    part.replace(path)


def write_camera_sets(out_dir: str | Path, views: Iterable[CameraView]) -> CamerasExport:
    """Write ``views`` in the layout of the module docstring under ``out_dir`` (created; the export's own files
    are replaced, others left).

    Raises:
        InvalidInputError: two views of one name, or a name that cannot be a file name (nothing written).
    """
    out = Path(out_dir)
    by_size: dict[tuple[int, int], list[CameraView]] = {}
    seen: set[str] = set()
    for v in views:
        if not v.name or v.name in (".", "..") or any(c in v.name for c in "/\\\0"):
            raise InvalidInputError(f"cannot be used as a file name: {v.name!r}", field="frame")
        if v.name in seen:
            raise InvalidInputError(f"two views would be written as {v.name!r} ({v.game}/{v.frame})", field="frame")
        seen.add(v.name)
        by_size.setdefault((int(v.width), int(v.height)), []).append(v)
    report = CamerasExport(out)
    sets = []
    for (w, h), group in sorted(by_size.items()):
        size = f"{w}x{h}"
        folder = out / size
        folder.mkdir(parents=True, exist_ok=True)
        _zip(folder / GROUND_TRUTH, ((f"{v.split}/{v.name}.json", v.lines) for v in group if v.lines is not None))
        _zip(folder / PREDICTIONS, ((f"camera_{v.name}.json", v.camera) for v in group if v.camera is not None))
        for v in group:
            if v.camera is not None:
                report.cameras += 1
                report.by_kind[v.kind] = report.by_kind.get(v.kind, 0) + 1
        report.ground_truth += sum(v.lines is not None for v in group)
        report.sizes[size] = len(group)
        sets.append({"size": size, "width": w, "height": h, "ground_truth": f"{size}/{GROUND_TRUTH}",
                     "predictions": f"{size}/{PREDICTIONS}",
                     "views": [{"name": v.name, "split": v.split, "kind": v.kind, "game": v.game, "frame": v.frame,
                                "camera": v.camera is not None, "jac": v.jac} for v in group]})
    out.mkdir(parents=True, exist_ok=True)
    (out / INDEX).write_bytes(orjson.dumps({"format": FORMAT, "sets": sets}, option=orjson.OPT_INDENT_2))
    return report


def camera_views(session: Session, include_all: bool = False) -> list[CameraView]:
    """The views :func:`export_cameras` writes (module docstring), in game, system and view order."""
    query = exported_systems("cameras", include_all, selectinload(System.frames).options(
        selectinload(Frame.calibration), selectinload(Frame.field_lines)))
    out = []
    for system in session.scalars(query):
        kind = kind_of(system)
        for f in system.frames:
            cal = f.calibration
            camera = cal.camera if cal is not None and cal.admitted and cal.camera is not None else None
            stored = f.field_lines.lines if f.field_lines is not None else None
            if camera is None and not stored:
                continue
            jac = {str(g): getattr(cal, col) if cal is not None else None for g, col in JAC_COLUMNS.items()}
            out.append(CameraView(kind.view_stem(system.game, f), kind.split(system, f), system.game.path, f.name,
                                  system.kind.value, f.width, f.height, camera,
                                  pooled_lines(stored, f.width, f.height) if stored else None, jac))
    return out


def export_cameras(session: Session, out_dir: str | Path, include_all: bool = False) -> CamerasExport:
    """Write the cameras export of the database under ``out_dir`` (module docstring).

    Raises:
        InvalidInputError: two views whose names coincide (nothing written).
    """
    return write_camera_sets(out_dir, camera_views(session, include_all))


def read_cameras(root: Path) -> dict[tuple[str, str], dict[str, Any]]:
    """``(league/season/match, frame name)`` -> SoccerNet camera dict of a cameras export at ``root`` (the
    layout of the module docstring; ``root`` trusted as a folder the caller checked, its contents not: the
    zips are read member by member, by name, at most :data:`MAX_CAMERA_BYTES` each, nothing extracted).

    Raises:
        DatasetError: no readable ``cameras.json``, a set whose zip is missing, leads out of ``root`` or is not
            a zip, a camera file too large or not JSON (naming the file).
    """
    top = dataset_root(root)
    index_path = inside_dataset(top, root / INDEX, "cameras")
    if not index_path.is_file():
        raise DatasetError(index_path, None, f"no {INDEX}: not a cameras export (v3d export cameras)")
    index = load_json_bytes(index_path.read_bytes(), str(index_path))
    if not isinstance(index, dict) or not isinstance(index.get("sets"), list):
        raise DatasetError(index_path, "sets", "expected {\"sets\": [...]}")
    out: dict[tuple[str, str], dict[str, Any]] = {}
    for i, s in enumerate(index["sets"]):
        try:
            views = [(str(v["name"]), str(v["game"]), str(v["frame"])) for v in s["views"] if v.get("camera")]
            zpath = inside_dataset(top, root / str(s["predictions"]), f"sets[{i}].predictions")
        except (TypeError, KeyError, AttributeError) as exc:
            raise DatasetError(index_path, f"sets[{i}]", f"expected predictions and views: {exc}") from exc
        try:
            with zipfile.ZipFile(zpath) as zf:
                for name, game, frame in views:
                    member = f"camera_{name}.json"
                    try:
                        info = zf.getinfo(member)
                    except KeyError:
                        continue
                    if info.file_size > MAX_CAMERA_BYTES:
                        raise DatasetError(zpath, member, f"larger than {MAX_CAMERA_BYTES} bytes")
                    out[(game, frame)] = load_json_bytes(zf.read(info), f"{zpath}:{member}")
        except (OSError, zipfile.BadZipFile) as exc:
            raise DatasetError(zpath, None, f"not a readable zip: {exc}") from exc
    return out
