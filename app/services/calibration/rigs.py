"""Game rigs: broadcast cameras stay put during a game, so a frame of a SoccerNet-v3 game that its lines alone
cannot calibrate, or calibrate only below admission, is retried with its centre at one of the game's camera
positions (:func:`game_rig`, ``app.geometry.calibration.rig``), estimated from the game's admitted frames; the
rig's result is kept only when it fits the labels better (:func:`with_rig_retry`, by residual). Calibration
datasets (frames from many stadiums) never use one.
"""
from __future__ import annotations

import dataclasses
from typing import Any, Collection, Iterable, Sequence, cast

import numpy as np
import sqlalchemy as sa
from sqlalchemy import select
from sqlalchemy.orm import Session

from app.core.config import Settings
from app.datasets.records import CalibrationFields
from app.db.models import Calibration, CalibrationStatus, Frame, FrameRole, System
from app.geometry.calibration.result import MIRROR_FLAG, PLAYERS_FLAG, RIG_FLAG
from app.geometry.calibration.rig import CameraRig, estimate_rig
from app.geometry.jac import JAC_GAMMAS, jac_admitted
from app.services.calibration.admission import admission_gamma, admitted_jac_sql
from app.services.kinds import kind_of


def game_rig(session: Session | None, game_id: int | None, settings: Settings, exclude_frame_ids: Collection[int] = (),
             extra: Iterable[CalibrationFields] = (), extra_roles: Sequence[FrameRole] | None = None,
             stored: Sequence[tuple[int, np.ndarray, bool]] | None = None) -> CameraRig:
    """The camera rig of a game (``app.geometry.calibration.rig.estimate_rig``), from the centres of
    its cameras that are calibrated with JaC@gamma > ``admit_jac_min`` and not rig-assisted themselves.
    Action frames mark the main camera's position (:attr:`RigPosition.main_frames`).

    Args:
        session: reads the stored calibrations; may be None when ``game_id`` is None.
        game_id: the game whose stored calibrations count (None: a game not stored yet).
        exclude_frame_ids: stored frames left out (the ones being recalibrated).
        extra: calibrations not stored yet that count too (an import's fresh results).
        extra_roles: the role of each of ``extra``'s frames (None: unknown, no main camera marked).
        stored: the game's stored rows as :func:`rig_rows` gives them, when the caller has read
            them already (then ``session`` is not queried).
    """
    extra = list(extra)
    roles: Sequence[FrameRole | None] = list(extra_roles) if extra_roles is not None else [None] * len(extra)
    if len(roles) != len(extra):
        raise ValueError(f"extra_roles must give one role per extra calibration ({len(extra)}), got {len(roles)}")
    gamma_index = JAC_GAMMAS.index(admission_gamma(settings))
    rows = [(np.asarray(f.camera["position_meters"], dtype=np.float64),  # type: ignore[index]  # _feeds_rig: a camera
             role is FrameRole.ACTION)
            for f, role in zip(extra, roles, strict=True)  # one role per calibration: checked above
            if _feeds_rig(f.status, f.camera, f.flags, f.jac[gamma_index], settings)]
    if stored is None and game_id is not None and session is not None:
        stored = rig_rows(session, game_id, settings)
    if stored is not None:
        excluded = set(exclude_frame_ids)
        rows += [(c, main) for fid, c, main in stored if fid not in excluded]
    return estimate_rig(np.array([c for c, _ in rows]).reshape(-1, 3), main_camera=[m for _, m in rows])


def rig_centres(session: Session, game_id: int, settings: Settings) -> list[tuple[int, np.ndarray]]:
    """``(frame id, camera centre (3,), metres)`` of the stored calibrations of a game that feed its
    rig (:func:`game_rig`)."""
    return [(fid, c) for fid, c, _ in rig_rows(session, game_id, settings)]


def rig_rows(session: Session, game_id: int, settings: Settings) -> list[tuple[int, np.ndarray, bool]]:
    """``(frame id, camera centre (3,) metres, filmed by the main camera)`` of the calibrations feeding
    the game's rig: calibrated, JaC@gamma > ``admit_jac_min``, not rig-assisted. One query that reads
    only the centre out of each stored camera (the rig needs nothing else), so an edit does not decode
    every calibration of its game; its statement is built once per admission rule (:func:`_rig_statement`)."""
    rows = session.execute(_rig_statement(settings), {"game_id": game_id})
    return [(fid, np.array(centre, dtype=float), role is FrameRole.ACTION) for fid, role, centre in rows]


#: :func:`rig_rows`'s statements by admission rule (``admit_jac_gamma``, ``admit_jac_min``).
_RIG_STATEMENTS: dict[tuple[float, float], sa.Select] = {}


def _rig_statement(settings: Settings) -> sa.Select:
    """:func:`rig_rows`'s statement for the settings' admission rule, taking the game's id as ``game_id``; built once
    per rule (building it and its cache key cost as much as running it). Of the tables' columns, not the mapped
    classes': the same SQL and values, without the ORM's compilation of the statement on every edit that reads it."""
    key = (admission_gamma(settings), settings.admit_jac_min)
    stmt = _RIG_STATEMENTS.get(key)
    if stmt is None:
        cal, frame, system = (cast(sa.Table, m.__table__) for m in (Calibration, Frame, System))
        stmt = _RIG_STATEMENTS[key] = (
            select(cal.c.frame_id, frame.c.role, cal.c.camera["position_meters"])
            .join(frame, frame.c.id == cal.c.frame_id)
            .join(system, system.c.id == frame.c.system_id)
            .where(system.c.game_id == sa.bindparam("game_id"), cal.c.status == CalibrationStatus.CALIBRATED,
                   cal.c.camera.is_not(None), admitted_jac_sql(settings, cal),
                   sa.cast(cal.c.flags, sa.Text).not_like(f'%"{RIG_FLAG}"%'),
                   sa.cast(cal.c.flags, sa.Text).not_like(f'%"{PLAYERS_FLAG}"%')))
    return stmt


def wants_rig_retry(fields: CalibrationFields, settings: Settings) -> bool:
    """True when a frame's calibration from its lines alone is worth retrying with the game's rig:
    refused, or calibrated without clearing admission (JaC@gamma <= ``admit_jac_min``: a free fit of
    few lines can settle metres from the camera's true position, where the rig's known centre fits
    the same labels better; :func:`with_rig_retry` keeps the better fit by residual)."""
    if fields.status is CalibrationStatus.REFUSED:
        return True
    jac = fields.jac[JAC_GAMMAS.index(admission_gamma(settings))]
    return not jac_admitted(jac, settings.admit_jac_min)


def with_rig_retry(first: CalibrationFields, retried: CalibrationFields) -> CalibrationFields:
    """What is stored for a frame retried with the game's rig (:func:`wants_rig_retry`).

    * The rig calibrated it and the first pass refused it: the rig's calibration.
    * Both calibrated it: the one whose camera fits the labels better, by the RMS distance of every
      labelled point to its model element (the same definition for both, ``rms_px``; the first pass
      wins ties and when a residual is missing). The labels' JaC is never used to choose: it is
      what admission evaluates.
    * The rig refused it: the first result; a first refusal carries the rig's mirror flag and
      evidence when the mirrored labels fit a rig position (:func:`calibrate_lines`).
    """
    if retried.status is CalibrationStatus.CALIBRATED:
        if first.status is not CalibrationStatus.CALIBRATED:
            return retried
        if first.rms_px is not None and retried.rms_px is not None and retried.rms_px < first.rms_px:
            return retried
        return first
    if first.status is CalibrationStatus.REFUSED and MIRROR_FLAG in retried.flags:
        flags = first.flags if MIRROR_FLAG in first.flags else [*first.flags, MIRROR_FLAG]
        return dataclasses.replace(first, flags=flags, mirror_evidence=retried.mirror_evidence)
    return first


def _feeds_rig(status: CalibrationStatus, camera: dict[str, Any] | None, flags: Sequence[str] | None,
               jac: float | None, settings: Settings) -> bool:
    return (status is CalibrationStatus.CALIBRATED and camera is not None and RIG_FLAG not in (flags or ())
            and PLAYERS_FLAG not in (flags or ())
            and jac_admitted(jac, settings.admit_jac_min))


def uses_rig(system: System) -> bool:
    """Whether game rigs apply to the system (its kind's ``uses_rig``: SoccerNet-v3 games, whose cameras
    are fixed during a game; never calibration datasets, whose frames come from many stadiums)."""
    return kind_of(system).uses_rig
