"""Players place the cameras the lines cannot (``app.geometry.calibration.players``), on stored frames.

After a system's frames are calibrated from their lines (and the game's rig), each view whose lines give no camera
or an unsure one (refused, or fewer than :data:`~app.geometry.pitch.MIN_LINE_CLASSES` line classes) is fitted to the
foot points of the players it shares (class and ID) with the system's well-calibrated views (calibrated, admitted,
four or more line classes), with its centre at a position of the game's rig where one fits, its lines in the same
fit. An accepted fit replaces the view's calibration (flags ``"player_assisted"``, ``"rig_assisted"`` at a rig
position; its uncertainty from the fit, as a line fit's; what it was fitted to in ``Calibration.players``); a
refused one leaves the calibration from lines as it was. The ball label is never read. A camera the players placed
never feeds the game's rig (``rigs``) nor places another view.
"""
from __future__ import annotations

import time
from typing import Any, Iterable, Mapping, Sequence

import numpy as np
import sqlalchemy as sa
from sqlalchemy.orm import Session

from app.core.config import Settings
from app.datasets.records import CalibrationFields
from app.db.models import Calibration, CalibrationSource, CalibrationStatus, Frame, FrameRole, PlayerBox, System
from app.db.types import json_safe
from app.geometry.annotations import lines_from_json_lists
from app.geometry.calibration import frame_jac
from app.geometry.calibration.grass import PlayerKey, foot_pixel, players_on_grass
from app.geometry.calibration.players import PlayerFit, PlayerRefusal, fit_camera_to_players
from app.geometry.calibration.result import PLAYERS_FLAG, RIG_FLAG
from app.geometry.calibration.rig import CameraRig
from app.geometry.camera import Camera
from app.geometry.jac import JAC_GAMMAS
from app.geometry.pitch import MIN_LINE_CLASSES
from app.services.calibration.admission import is_admitted
from app.services.calibration.calibrating import apply_calibration
from app.services.wording.words import player_camera_sentence

#: ``(class, ID or None, (x1, y1, x2, y2) px)``: a player box as the records and the rows give it.
PlayerRow = tuple[str, "str | None", tuple[float, float, float, float]]


def frame_players(frame: Frame) -> list[PlayerRow]:
    """The stored player boxes of ``frame`` (``Frame.players``) as rows."""
    return [(p.cls, p.ident, (p.x1, p.y1, p.x2, p.y2)) for p in frame.players]


def feet_of(rows: Iterable[PlayerRow], width: int, height: int) -> dict[PlayerKey, np.ndarray]:
    """Foot pixels (2,) by player (class, ID) of a ``width`` x ``height`` view; boxes without an ID, boxes cut by the
    image's edges (``foot_pixel``) and a (class, ID) boxed twice in the view are left out."""
    out: dict[PlayerKey, np.ndarray] = {}
    twice: set[PlayerKey] = set()
    for cls, ident, box in rows:
        if ident is None:
            continue
        uv = foot_pixel(box, width, height)
        if uv is None:
            continue
        key = (cls, ident)
        if key in out:
            twice.add(key)
        out[key] = uv
    return {k: v for k, v in out.items() if k not in twice}


def line_classes(frame: Frame) -> int:
    """The classes of field lines labelled in ``frame`` (with at least one polyline)."""
    lines = frame.field_lines.lines if frame.field_lines is not None else {}
    return sum(1 for polys in lines.values() if polys)


def is_weak(frame: Frame) -> bool:
    """Whether the players may place ``frame``'s camera: its lines give none (refused, no calibration) or an unsure
    one (fewer than :data:`MIN_LINE_CLASSES` classes), or the players placed it before (placed again). A camera an
    export brought or a person set (source ``imported``, ``edited``) stays as it is."""
    cal = frame.calibration
    if cal is not None and cal.source is not CalibrationSource.COMPUTED:
        return False
    if cal is None or cal.status is not CalibrationStatus.CALIBRATED or cal.camera is None:
        return True
    return line_classes(frame) < MIN_LINE_CLASSES or PLAYERS_FLAG in (cal.flags or [])


def is_anchor(frame: Frame, settings: Settings) -> bool:
    """Whether ``frame``'s camera tells where its players stand: calibrated from its lines (not by the players),
    admitted, and with at least :data:`MIN_LINE_CLASSES` line classes."""
    cal = frame.calibration
    return (cal is not None and cal.status is CalibrationStatus.CALIBRATED and cal.camera is not None
            and PLAYERS_FLAG not in (cal.flags or []) and line_classes(frame) >= MIN_LINE_CLASSES
            and is_admitted(cal, settings))


def rig_of_calibrations(calibrations: Sequence[Calibration | None], roles_main: Sequence[bool],
                        settings: Settings) -> CameraRig:
    """The game's camera rig (``app.geometry.calibration.rig.estimate_rig``) from its frames' stored calibrations
    in memory, as ``rigs.game_rig`` makes it from the stored rows: admitted, neither rig- nor player-assisted."""
    from app.geometry.calibration.rig import estimate_rig

    rows = [(np.asarray(c.camera["position_meters"], float), main) for c, main in zip(calibrations, roles_main,
                                                                                       strict=True)
            if c is not None and c.status is CalibrationStatus.CALIBRATED and c.camera is not None
            and RIG_FLAG not in (c.flags or []) and PLAYERS_FLAG not in (c.flags or []) and is_admitted(c, settings)]
    return estimate_rig(np.array([c for c, _ in rows]).reshape(-1, 3), main_camera=[m for _, m in rows])


def players_json(fit: PlayerFit, rig: CameraRig) -> dict[str, Any]:
    """What ``Calibration.players`` keeps of an accepted fit: ``feet`` (``class``, ``id``, ``px`` [x, y], ``grass_m``
    [x, y]) of every player used, ``rig`` (``index``, ``centre_m``, ``frames``) or None for a full pose, ``rms_px``,
    ``sigma_px`` (px@1920), ``players`` (their count), ``note`` (its words,
    ``app.services.wording.words.player_camera_sentence``)."""
    rig_part = None
    if fit.rig_index is not None:
        p = rig.positions[fit.rig_index]
        rig_part = {"index": fit.rig_index, "centre_m": [round(float(v), 3) for v in p.centre_m], "frames": p.frames}
    out: dict[str, Any] = {"feet": [{"class": k[0], "id": k[1], "px": [round(uv[0], 2), round(uv[1], 2)],
                     "grass_m": [round(g[0], 3), round(g[1], 3)]} for k, uv, g in fit.players],
           "rig": rig_part, "rms_px": round(fit.rms_px, 3), "sigma_px": round(fit.sigma_px, 3),
           "players": len(fit.players)}
    out["note"] = player_camera_sentence(out)
    return json_safe(out)


def fields_of_fit(fit: PlayerFit, frame: Frame, rig: CameraRig, elapsed_ms: float) -> CalibrationFields:
    """The calibration stored for an accepted fit: the camera, JaC against the view's own lines (None without
    lines), per-class residuals, flags (``few_lines`` as a line fit flags it, ``player_assisted``, ``rig_assisted``
    at a rig position), the fit's uncertainty and :func:`players_json`."""
    lines = lines_from_json_lists(frame.field_lines.lines) if frame.field_lines is not None else {}
    lines = {c: v for c, v in lines.items() if v}
    jac: tuple[float | None, float | None, float | None] = (None, None, None)
    if lines:
        values = frame_jac(fit.camera, lines, frame.width, frame.height)
        jac = tuple(values.get(f"{g:g}") for g in JAC_GAMMAS)  # type: ignore[assignment]  # three gammas
    flags = [*(["few_lines"] if len(lines) < MIN_LINE_CLASSES else []), PLAYERS_FLAG,
             *([RIG_FLAG] if fit.rig_index is not None else [])]
    return CalibrationFields(
        status=CalibrationStatus.CALIBRATED, camera=json_safe(fit.camera.to_soccernet()), jac=jac,
        residuals_px=json_safe(dict(fit.residuals_px)), flags=flags, reason=None, refusal=None,
        elapsed_ms=elapsed_ms, rms_px=fit.rms_px, uncertainty=fit.uncertainty.to_json(),
        players=players_json(fit, rig))


def place_by_players(system: System, settings: Settings, rig: CameraRig,
                     players: Mapping[int, Sequence[PlayerRow]] | None = None
                     ) -> dict[int, CalibrationFields | PlayerRefusal]:
    """Fit each weak view of ``system`` (:func:`is_weak`) to the players it shares with the system's anchors
    (:func:`is_anchor`), with the game's ``rig``. Pure on the loaded rows: writes nothing.

    Args:
        players: per frame (by ``id(frame)``), its player boxes when the caller has them (an import's records);
            otherwise read from ``Frame.players``.

    Returns:
        per weak view's frame id (``id(frame)`` key for a frame not flushed yet: the caller's key), the calibration
        to store or why the players place none.
    """
    frames = list(system.frames)

    def rows(f: Frame) -> Sequence[PlayerRow]:
        if players is not None and id(f) in players:
            return players[id(f)]
        return frame_players(f)

    weak = [f for f in frames if is_weak(f)]
    if not weak:
        return {}
    anchors = [f for f in frames if is_anchor(f, settings)]
    if not anchors:
        return {}
    feet = {id(f): feet_of(rows(f), f.width, f.height) for f in [*weak, *anchors]}
    cameras = {id(f): Camera.from_soccernet(f.calibration.camera) for f in anchors}  # type: ignore[union-attr,arg-type]  # anchors are calibrated
    centres = [p.centre_m for p in rig.positions]
    out: dict[int, CalibrationFields | PlayerRefusal] = {}
    # A weak view is never an anchor (fewer line classes, or placed by the players): where the players stand is the
    # same for every weak view of the system, fused once.
    grass = players_on_grass([(cameras[id(a)], feet[id(a)]) for a in anchors])
    for f in weak:
        t0 = time.perf_counter()
        lines = lines_from_json_lists(f.field_lines.lines) if f.field_lines is not None else {}
        got = fit_camera_to_players(feet[id(f)], grass, {c: v for c, v in lines.items() if v}, f.width, f.height,
                                    centres)
        out[id(f)] = (fields_of_fit(got, f, rig, (time.perf_counter() - t0) * 1e3) if isinstance(got, PlayerFit)
                      else got)
    return out


def apply_player_cameras(system: System, settings: Settings, rig: CameraRig,
                         players: Mapping[int, Sequence[PlayerRow]] | None = None,
                         relined: Any = None) -> int:
    """:func:`place_by_players` stored: each accepted fit becomes the view's calibration (source "computed"); a
    view the players placed before and place no more gets its calibration from lines again (``relined(frame)``:
    the :class:`CalibrationFields` of its lines, given by the caller; left as it is without one). Returns how many
    views the players placed."""
    placed = place_by_players(system, settings, rig, players)
    n = 0
    for f in system.frames:
        got = placed.get(id(f))
        if isinstance(got, CalibrationFields):
            apply_calibration(f, got, CalibrationSource.COMPUTED)
            n += 1
        elif isinstance(got, PlayerRefusal) and f.calibration is not None and PLAYERS_FLAG in (f.calibration.flags
                                                                                               or []):
            if relined is not None:
                apply_calibration(f, relined(f), CalibrationSource.COMPUTED)
    return n



def place_cameras_by_players(systems: Sequence[System], settings: Settings,
                             players: Mapping[int, Sequence[PlayerRow]] | None = None, relined: Any = None) -> int:
    """:func:`apply_player_cameras` for each of ``systems`` of a kind with a game rig (``rigs.uses_rig``), the rig of
    each game made from its frames' calibrations in memory (:func:`rig_of_calibrations`). Returns how many views
    the players placed."""
    from app.services.calibration.rigs import uses_rig

    mine = [s for s in systems if uses_rig(s)]
    games: dict[int, list[System]] = {}
    for s in mine:
        games.setdefault(id(s.game), []).append(s)
    n = 0
    for group in games.values():
        if not any(is_weak(f) for s in group for f in s.frames):
            continue
        frames = [f for s in group[0].game.systems for f in s.frames]
        rig = rig_of_calibrations([f.calibration for f in frames], [f.role is FrameRole.ACTION for f in frames],
                                  settings)
        for s in group:
            n += apply_player_cameras(s, settings, rig, players, relined)
    return n


def store_players(session: Session, frames: list[tuple[Frame, tuple[PlayerRow, ...], bool]]) -> None:
    """Write the player boxes of ``frames`` (new frames, and stored ones whose boxes the file changed: their old rows
    replaced) in one statement each way, after a flush gives the new frames their ids."""
    if not frames:
        return
    session.flush()
    stored = [f.id for f, _, was_stored in frames if was_stored]
    if stored:
        session.execute(sa.delete(PlayerBox).where(PlayerBox.frame_id.in_(stored)))
    rows = [{"frame_id": f.id, "cls": cls, "ident": ident, "x1": b[0], "y1": b[1], "x2": b[2], "y2": b[3]}
            for f, players, _ in frames for cls, ident, b in players]
    if rows:
        session.execute(sa.insert(PlayerBox), rows)
    for f, _, _ in frames:  # written past the ORM: read again when next asked for
        session.expire(f, ["players"])
