"""What is stored of an ISSIA sequence, read back: the trajectory view and the ``ISSIA-3D.csv`` export.

* :func:`sequence_data`: a sequence's stored systems and trajectory points, which the API shapes into
  its trajectory over time (per frame: observed ``ball_3D``, fitted ``ball_3D_smoothed`` and its source,
  flagged cameras).
* :func:`export_issia3d`: one folder per sequence with ``ISSIA-3D.csv``
  (:func:`app.datasets.issia3d.write_issia3d_csv` of :func:`app.datasets.issia3d.issia3d_rows` built
  from the stored labels, cameras and trajectory points) and ``split.json``. The paper's split is by
  camera: cameras 3-6 are the training set and 1-2 the test set (:data:`app.datasets.issia.CAMERA_SET`);
  every row holds all six cameras' columns (``x_camK`` ...), so the split shows in ``split.json``
  (``{"train": [3, 4, 5, 6], "test": [1, 2], "by": "camera"}``): a detector trained on ISSIA-3D reads
  the ``camK`` columns of its split. Beside them ``calibration/cam<k>.json``: each camera's calibration in the
  SoccerNet-calibration camera format (:func:`sequence_calibrations`), so that a user of the CSV can project
  the ``ball_3D`` columns into the views, and the same cameras as ``issia_calibration.json`` (camera id -> camera),
  the file ``v3d import issia`` reads: a sequence's folder of the export is an ISSIA folder that imports again as
  it left (its labels from ``ISSIA-3D.csv``, its cameras from that file). Accepted frames only unless
  ``include_all``.
"""
from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import sqlalchemy as sa
from sqlalchemy.orm import Session

from app.core.errors import NotFoundError, found
from app.datasets.issia import ANNOTATION_SIZE, CALIBRATION_FILE, CAMERA_SET, IssiaSequence
from app.datasets.issia3d import issia3d_rows, write_issia3d_csv
from app.db.models import Calibration, Frame, Game, ReviewStatus, System, SystemKind
from app.geometry.camera import Camera
from app.services.issia.trajectory import load_sequence

CSV_NAME, SPLIT_NAME, CALIBRATION_DIR = "ISSIA-3D.csv", "split.json", "calibration"


def _cam_id(name: str) -> str:
    return name[3:] if name.startswith("cam") else name


def _names(systems: list[System]) -> list[str]:
    pos: dict[str, int] = {}
    for s in systems:
        for f in s.frames:
            pos.setdefault(f.name, f.position)
    return sorted(pos, key=lambda n: (pos[n], n))


@dataclass(frozen=True)
class SequenceData:
    """A stored ISSIA sequence read back for its trajectory view: the game, its systems in frame order
    (frames, review, trajectory point loaded) and its camera views' names in camera order."""

    game: Game
    systems: list[System]
    cameras: list[str]

    @property
    def camera_set(self) -> dict[str, str]:
        """View name -> ``"train"`` or ``"test"`` (the paper's split by camera, :data:`CAMERA_SET`)."""
        return {n: CAMERA_SET.get(_cam_id(n), "unknown") for n in self.cameras}


def sequence_data(session: Session, game_id: int) -> SequenceData:
    """The ISSIA sequence ``game_id`` as stored (for ``GET /api/games/{id}/trajectory``, shaped by
    ``app.api.issia_schemas.TrajectoryOut``). Raises :class:`NotFoundError` for an unknown game or one
    without ISSIA systems."""
    game = found(session.get(Game, game_id), "game", game_id)
    systems = load_sequence(session, game_id)
    if not systems:
        raise NotFoundError("ISSIA sequence of game", game_id)
    return SequenceData(game, systems, _names(systems))


@dataclass
class Issia3DExport:
    """What :func:`export_issia3d` wrote: one CSV per sequence, and how many rows in all."""

    out_dir: Path
    sequences: int = 0
    rows: int = 0
    csv_paths: list[Path] = field(default_factory=list)
    #: ``calibration/cam<k>.json`` files written.
    calibrations: int = 0


def sequence_calibrations(session: Session, game_id: int) -> dict[str, dict[str, Any]]:
    """View name (``cam<k>``) -> the camera of that static ISSIA camera in the SoccerNet-calibration camera
    format as stored (method.md section 2: ``position_meters``, ``rotation_matrix``, ``x_focal_length``, ...,
    SoccerNet world, metres, z down): the admitted calibration of the camera's view at the sequence's first
    frame index that has one (the cameras do not move). Cameras without an admitted calibration are absent."""
    rows = session.execute(
        sa.select(Frame.name, Calibration.camera)
        .join(System, System.id == Frame.system_id).join(Calibration, Calibration.frame_id == Frame.id)
        .where(System.game_id == game_id, System.kind == SystemKind.ISSIA, Calibration.admitted.is_(True),
               Calibration.camera.is_not(None))
        .order_by(System.frame_index, Frame.position))
    out: dict[str, dict[str, Any]] = {}
    for name, camera in rows:
        if camera is not None:
            out.setdefault(name, camera)
    return dict(sorted(out.items()))


def sequence_rows(session: Session, game_id: int, include_all: bool = False) -> list:
    """The ``ISSIA-3D.csv`` rows (:class:`app.datasets.issia3d.Issia3DRow`) of a stored sequence:
    current labels (a reviewer's edits included), the cameras admitted by the last recomputation, the stored
    ``ball_3D``, ``cam_list``, ``ball_3D_smoothed`` and source; ``err``/``opt_d``/``opt_e`` computed from them.
    Accepted frames only unless ``include_all``."""
    systems = load_sequence(session, game_id)
    if not include_all:
        systems = [s for s in systems if s.review is not None and s.review.status is ReviewStatus.ACCEPTED]
    return rows_of(systems)


def rows_of(systems: list[Any]) -> list:
    """The ``ISSIA-3D.csv`` rows of a sequence's systems in frame order (stored ones with their frames, labels,
    calibrations and trajectory points, or a release's stand-ins of them: ``app.services.releases.export``)."""
    systems = [s for s in systems if s.frame_index is not None]
    if not systems:
        return []
    names = _names(systems)
    ids = tuple(_cam_id(n) for n in names)
    col = {n: k for k, n in enumerate(names)}
    indices = [s.frame_index for s in systems if s.frame_index is not None]  # all of them: kept above
    F = max(indices) + 1
    points = np.full((len(systems), len(ids), 2), np.nan)
    ball, smooth = np.full((F, 3), np.nan), np.full((F, 3), np.nan)
    sources: list[str | None] = [None] * F
    cam_lists: list[tuple[int, ...]] = [()] * F
    cameras: dict[str, Camera] = {}
    size = ANNOTATION_SIZE
    for i, (s, f_idx) in enumerate(zip(systems, indices, strict=True)):
        k_of = {f.id: col[f.name] for f in s.frames}
        for f in s.frames:
            size = (f.width, f.height)
            c = f.ball_label.centre if f.ball_label is not None else None
            if c is not None:
                points[i, col[f.name]] = c
            cid = ids[col[f.name]]
            cal = f.calibration
            if cid not in cameras and cal is not None and cal.admitted and cal.camera is not None:
                cameras[cid] = Camera.from_soccernet(cal.camera)
        tp = s.trajectory_point
        if tp is not None:
            if tp.ball3d is not None:
                ball[f_idx] = tp.ball3d
            if tp.ball3d_smoothed is not None:
                smooth[f_idx] = tp.ball3d_smoothed
            sources[f_idx] = tp.source
            cam_lists[f_idx] = tuple(sorted(k_of[i] for i in tp.cam_list if i in k_of))
    seq = IssiaSequence(root=Path("."), camera_ids=ids, image_size=size, cameras={}, lines={},
                        frames=tuple(indices), points=points)
    fit = _StoredFit(ball, smooth, tuple(sources), tuple(cam_lists))
    return issia3d_rows(seq, cameras, fit)


def write_sequence(folder: Path, rows: list, cameras: dict[str, dict[str, Any]], report: Issia3DExport) -> None:
    """One sequence's folder of the export (module docstring): ``ISSIA-3D.csv`` of ``rows``, ``split.json``, and the
    ``cameras`` (view name ``cam<k>`` -> SoccerNet camera) as ``calibration/cam<k>.json`` and
    ``issia_calibration.json``; counts the calibrations in ``report``."""
    folder.mkdir(parents=True, exist_ok=True)
    write_issia3d_csv(folder / CSV_NAME, rows)
    split = {"by": "camera", "train": sorted(int(c) for c, v in CAMERA_SET.items() if v == "train"),
             "test": sorted(int(c) for c, v in CAMERA_SET.items() if v == "test"),
             "columns": "x_camK, y_camK, err_camK, opt_d_camK, opt_e_camK of camera K"}
    (folder / SPLIT_NAME).write_text(json.dumps(split, indent=1) + "\n")
    for name, camera in cameras.items():
        (folder / CALIBRATION_DIR).mkdir(exist_ok=True)
        (folder / CALIBRATION_DIR / f"{name}.json").write_text(json.dumps(camera, indent=1) + "\n")
        report.calibrations += 1
    if cameras:  # what the importer reads (app.datasets.issia.CALIBRATION_FILE): the export imports again
        (folder / CALIBRATION_FILE).write_text(json.dumps(
            {_cam_id(name): camera for name, camera in cameras.items()}, indent=1, sort_keys=True) + "\n")


@dataclass(frozen=True)
class _StoredFit:
    """The stored trajectory in the shape :func:`issia3d_rows` reads (dense by frame index)."""

    ball_3d: np.ndarray
    positions: np.ndarray
    sources: tuple
    cam_lists: tuple


def export_issia3d(session: Session, out_dir: str | Path, include_all: bool = False) -> Issia3DExport:
    """Write ``<out_dir>/<match>/ISSIA-3D.csv``, ``split.json``, ``calibration/cam<k>.json`` and
    ``issia_calibration.json`` for every stored ISSIA
    sequence (module docstring). Accepted frames only unless ``include_all``; a sequence with no exported
    frame gets no folder."""
    out = Path(out_dir)
    report = Issia3DExport(out)
    games = session.scalars(sa.select(Game).where(Game.id.in_(
        sa.select(System.game_id).where(System.kind == SystemKind.ISSIA))).order_by(Game.match)).all()
    for game in games:
        rows = sequence_rows(session, game.id, include_all)
        if not rows:
            continue
        write_sequence(out / game.match, rows, sequence_calibrations(session, game.id), report)
        report.sequences += 1
        report.rows += len(rows)
        report.csv_paths.append(out / game.match / CSV_NAME)
    return report
