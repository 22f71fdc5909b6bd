"""Export of the stored cameras as SoccerNet-calibration JSON files (``v3d export cameras``).

Written under ``out_dir``, for every view of the selected systems (the kinds that take the ``cameras``
export, ``app.services.kinds``: SoccerNet-v3 games and single SoccerNet-calibration frames; accepted
systems unless ``include_all``) whose calibration is admitted:
``<league>/<season>/<match>/camera_<image stem>.json``, the camera as stored, in the SoccerNet-calibration
camera format (method.md section 2: ``pan_degrees``, ``tilt_degrees``, ``roll_degrees``,
``position_meters``, ``x_focal_length``, ``y_focal_length``, ``principal_point``, distortions; SoccerNet
world, metres, z down; pixels of that image). The image stem is the frame's name without its extension
(``12_3.png`` -> ``camera_12_3.json``), as the SoccerNet calibration challenge names its camera files, so
the tree is also what ``v3d evaluate monocular --cameras DIR`` reads.

This is how single-view frames (SoccerNet-calibration, no multi-view system) leave v3d: the SoccerNet-v3D
export holds SoccerNet-v3 systems only. ISSIA cameras leave with the ISSIA-3D export
(``<sequence>/calibration/cam<k>.json``, ``app.services.issia.export``).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path, PurePosixPath

import orjson
import sqlalchemy as sa
from sqlalchemy.orm import Session

from app.core.errors import InvalidInputError
from app.db.models import Calibration, Frame, Game, ReviewDecision, ReviewStatus, System
from app.services.kinds import kinds_exported_by


def camera_file(league: str, season: str, match: str, frame_name: str) -> PurePosixPath:
    """``<league>/<season>/<match>/camera_<image stem>.json``: where a view's camera lies in a cameras tree
    (relative, POSIX separators)."""
    return PurePosixPath(league, season, match, f"camera_{PurePosixPath(frame_name).stem}.json")


@dataclass
class CamerasExport:
    """What :func:`export_cameras` wrote: the camera files, by kind."""

    out_dir: Path
    cameras: int = 0
    by_kind: dict[str, int] = field(default_factory=dict)
    files: list[Path] = field(default_factory=list)


def _safe(value: str, what: str) -> str:
    if not value or value in (".", "..") or "/" in value or "\\" in value or "\0" in value:
        raise InvalidInputError(f"cannot be used as a folder or file name: {value!r}", field=what)
    return value


def export_cameras(session: Session, out_dir: str | Path, include_all: bool = False) -> CamerasExport:
    """Write the cameras tree of the database under ``out_dir`` (module docstring); existing files of the
    same names are overwritten.

    Raises:
        InvalidInputError: a league, season, match or frame name that cannot be a file name (nothing
            written), or two views of one game whose image stems coincide.
    """
    query = (
        sa.select(Game.league, Game.season, Game.match, Frame.name, System.kind, Calibration.camera)
        .select_from(Frame).join(System, System.id == Frame.system_id).join(Game, Game.id == System.game_id)
        .join(Calibration, Calibration.frame_id == Frame.id)
        .outerjoin(ReviewDecision, ReviewDecision.system_id == System.id)
        .where(System.kind.in_(kinds_exported_by("cameras")), Calibration.admitted.is_(True),
               Calibration.camera.is_not(None))
        .order_by(Game.league, Game.season, Game.match, System.id, Frame.position)
    )
    if not include_all:
        query = query.where(ReviewDecision.status == ReviewStatus.ACCEPTED)
    rows = [r for r in session.execute(query) if r.camera is not None]
    seen: set[PurePosixPath] = set()
    for r in rows:  # validate every name before writing anything
        for value, what in ((r.league, "league"), (r.season, "season"), (r.match, "match"), (r.name, "frame")):
            _safe(value, what)
        rel = camera_file(r.league, r.season, r.match, r.name)
        if rel in seen:
            raise InvalidInputError(f"two views would be written as {rel}", field="frame")
        seen.add(rel)
    out = Path(out_dir)
    report = CamerasExport(out)
    for r in rows:
        path = out / camera_file(r.league, r.season, r.match, r.name)
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_bytes(orjson.dumps(r.camera, option=orjson.OPT_INDENT_2))
        report.cameras += 1
        report.by_kind[r.kind.value] = report.by_kind.get(r.kind.value, 0) + 1
        report.files.append(path)
    return report
