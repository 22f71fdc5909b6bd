"""Small factories of API test data: a synthetic scene with known truth, stored through the ORM and
made consistent by the real recomputation (``app.services.derivation.recompute.recompute_system``).

Cameras look at the pitch from the main stand (y > 0, z < 0 is above the ground); their field lines
are the pitch model projected by the camera itself, so the stored calibrations are exact and the
triangulated ball is the true one.
"""
from __future__ import annotations

import io
import zipfile
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np
from sqlalchemy.orm import Session

from app.core.config import Settings
from app.db.models import (
    BallKind,
    BallLabel,
    Calibration,
    CalibrationSource,
    CalibrationStatus,
    FieldLineAnnotation,
    Frame,
    FrameRole,
    Game,
    System,
    SystemKind,
)
from app.geometry.annotations import lines_to_json_lists
from app.geometry.camera import Camera
from app.geometry.projection import project_pitch_polylines
from app.services.derivation.recompute import recompute_system

WIDTH, HEIGHT = 960, 540
#: The true ball of the default scene: on the grass (z down, radius 0.11 m).
BALL = np.array([6.0, 4.0, -0.11])
#: Camera centres of the default scene (metres): main camera and two replay angles.
CENTRES = ([0.0, 58.0, -16.0], [-32.0, 48.0, -12.0], [36.0, 50.0, -14.0])


def look_at(centre: np.ndarray, target: np.ndarray, focal_px: float = 1200.0) -> Camera:
    """An undistorted ``WIDTH`` x ``HEIGHT`` camera at ``centre`` whose optical axis passes through
    ``target`` (world metres, z down) with no roll."""
    c = np.asarray(centre, float)
    z = np.asarray(target, float) - c
    z /= np.linalg.norm(z)
    x = np.cross([0.0, 0.0, 1.0], z)
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    K = np.array([[focal_px, 0.0, WIDTH / 2], [0.0, focal_px, HEIGHT / 2], [0.0, 0.0, 1.0]])
    return Camera(K=K, R=np.stack([x, y, z]), C=c)


def ball_box(camera: Camera, ball: np.ndarray = BALL, size_px: float = 12.0) -> list[float]:
    """A square box of ``size_px`` around the ball's projection."""
    uv, _ = camera.project(ball[None, :])
    u, v = uv[0]
    h = size_px / 2
    return [float(u - h), float(v - h), float(u + h), float(v + h)]


def png_bytes(width: int = WIDTH, height: int = HEIGHT) -> bytes:
    """A small grey PNG of the given size."""
    ok, buf = cv2.imencode(".png", np.full((height, width), 90, np.uint8))
    assert ok
    return buf.tobytes()


@dataclass
class Scene:
    """Ids of what :func:`make_system` stored, and the cameras it used."""

    game_id: int
    system_id: int
    frame_ids: list[int]
    cameras: list[Camera]


def make_game(session: Session, match: str = "2015-02-21 - 18-00 Chelsea 1 - 1 Burnley") -> Game:
    """A game row."""
    game = Game(league="england_epl", season="2014-2015", match=match, source_path="/nowhere")
    session.add(game)
    session.flush()
    return game


def make_system(session: Session, settings: Settings, game: Game, name: str = "1.png", *,
                centres: tuple = CENTRES, jac: float = 0.9, ball: np.ndarray = BALL,
                labelled: tuple[bool, ...] | None = None, shift_px: tuple[float, ...] | None = None,
                image_dir: Path | None = None) -> Scene:
    """A multi-view system (action then replays) with exact calibrations, field lines and ball boxes,
    recomputed and committed.

    Args:
        jac: JaC@0.5% stored for every view (above ``admit_jac_min`` to admit them).
        labelled: per view, whether it gets a ball box (default: all).
        shift_px: per view, a horizontal shift of the box (label error; default none).
        image_dir: when given, the first view's image is a member of ``image_dir/Frames-v3.zip`` and
            the second view's image a PNG file there; the others have no image.
    """
    system = System(game=game, name=name, kind=SystemKind.SOCCERNET_V3)
    session.add(system)
    cameras = [look_at(np.array(c), ball) for c in centres]
    labelled = labelled or (True,) * len(cameras)
    shift_px = shift_px or (0.0,) * len(cameras)
    stem = name.split(".")[0]
    for i, cam in enumerate(cameras):
        frame_name = name if i == 0 else f"{stem}_{i}.png"
        frame = Frame(system=system, name=frame_name, role=FrameRole.ACTION if i == 0 else FrameRole.REPLAY,
                      position=i, width=WIDTH, height=HEIGHT)
        session.add(frame)
        lines = lines_to_json_lists(project_pitch_polylines(cam, WIDTH, HEIGHT, 2.0, 1.0))
        frame.field_lines = FieldLineAnnotation(lines=lines, original_lines=lines)
        frame.calibration = Calibration(
            source=CalibrationSource.IMPORTED, status=CalibrationStatus.CALIBRATED, camera=cam.to_soccernet(),
            flags=[], residuals_px={}, jac_0005=jac, jac_001=min(1.0, jac + 0.05), jac_002=min(1.0, jac + 0.08),
        )
        if labelled[i]:
            box = ball_box(cam, ball)
            box = [box[0] + shift_px[i], box[1], box[2] + shift_px[i], box[3]]
            frame.ball_label = BallLabel(kind=BallKind.BOX, box=box, original_kind=BallKind.BOX, original_box=box)
        if image_dir is not None and i == 0:
            zip_path = image_dir / "Frames-v3.zip"
            with zipfile.ZipFile(zip_path, "a") as zf:
                zf.writestr(frame_name, png_bytes())
            frame.image_root, frame.image_zip, frame.image_member = str(image_dir.resolve()), zip_path.name, frame_name
        elif image_dir is not None and i == 1:
            path = image_dir / frame_name
            path.write_bytes(png_bytes())
            frame.image_root, frame.image_path = str(image_dir.resolve()), path.name
    session.flush()
    recompute_system(session, system, settings)
    session.commit()
    return Scene(game.id, system.id, [f.id for f in system.frames], cameras)


def zip_listing(data: bytes) -> list[str]:
    """Member names of a zip given as bytes."""
    with zipfile.ZipFile(io.BytesIO(data)) as zf:
        return zf.namelist()
