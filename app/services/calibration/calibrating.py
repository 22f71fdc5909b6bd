"""Calibration of stored frames: the pure ``calibrate_frame`` run on a frame's stored field lines (with the
mirrored labels' refit and the fit's uncertainty), its plain result (:class:`CalibrationFields`) and how it is
stored (:func:`apply_calibration`). Admission is :mod:`.admission`, the process pool of bulk work :mod:`.pool`,
the game rig :mod:`.rigs`, a dataset's learned camera prior :mod:`.priors`.
"""
from __future__ import annotations

import dataclasses
import time
from typing import Any

import numpy as np

from app.datasets.records import CalibrationFields
from app.db import scope
from app.db.models import Calibration, CalibrationSource, CalibrationStatus, Frame, FrameRole
from app.db.types import json_safe, utcnow
from app.geometry.annotations import FieldLines, lines_from_json_lists, mirror_lines
from app.geometry.calibration import (
    CalibrationPrior,
    CameraPrior,
    calibrate_frame,
    calibration_uncertainty,
    lines_used,
)
from app.geometry.calibration.result import MIRROR_FLAG, RIG_FLAG
from app.geometry.calibration.rig import CameraRig, calibrate_with_rig
from app.geometry.calibration.solver import PriorRows
from app.geometry.camera import Camera
from app.geometry.jac import JAC_GAMMAS
from app.geometry.mirror import mirrored_fit_at_rig
from app.services.kinds import kind_of
from app.services.wording.doubt_words import with_sentence
from app.services.wording.words import refusal_sentence


def expected_side(role: FrameRole) -> int | None:
    """Side of the pitch the camera of a frame is expected on: +1 (y > 0) for broadcast main cameras
    (actions and calibration-dataset frames, method.md section 3), None for replays (anywhere).
    Only used to flag probably mirrored labels (calibration's camera-side flag, and the side prior
    of ``app.geometry.mirror.mirror_evidence``)."""
    return None if role is FrameRole.REPLAY else 1


def calibrate_lines(lines_json: dict[str, Any], width: int, height: int, side: int | None = None,
                    rig: CameraRig | CameraPrior | None = None, main_camera: bool = False) -> CalibrationFields:
    """Calibrate one frame from its stored field lines (``{class: [[[x, y], ...], ...]}``, pixels).

    Pure: calls ``app.geometry.calibration.calibrate_frame`` (JaC at :data:`JAC_GAMMAS` included)
    with the prior ``expected_side=side``, or, given a game ``rig``, ``calibrate_with_rig`` (the
    centre fixed at one of the game's camera positions; ``main_camera``: the frame is an action,
    filmed by the main camera, whose position is preferred among equally fitting ones), and converts
    the result. A frame the rig cannot calibrate either is flagged :data:`MIRROR_FLAG` when its
    mirrored labels fit a rig position (``app.geometry.mirror.mirrored_fit_at_rig``; the result stays
    a refusal: labels are never changed silently). Given a dataset's learned ``CameraPrior`` in place
    of a rig (:func:`dataset_prior`), the free fit is made a MAP fit where the lines leave the centre
    open (``CalibrationPrior.camera_prior``). Safe to run in a worker process.
    """
    t0 = time.perf_counter()
    lines = lines_from_json_lists(lines_json)
    if isinstance(rig, CameraPrior):
        fields = _fields_from_result(calibrate_frame(lines, width, height, prior=CalibrationPrior(
            expected_side=side, camera_prior=rig)), lines)
        return dataclasses.replace(fields, elapsed_ms=(time.perf_counter() - t0) * 1e3)
    if rig is not None:
        fields = _fields_from_result(calibrate_with_rig(lines, width, height, rig, expected_side=side,
                                                        main_camera=main_camera), lines)
        if fields.status is CalibrationStatus.REFUSED:
            verdict = mirrored_fit_at_rig(lines, width, height, rig, expected_side=side)
            if verdict is not None:
                fields = dataclasses.replace(fields, flags=[*fields.flags, MIRROR_FLAG],
                                             mirror_evidence=json_safe(with_sentence(verdict.as_dict(), {})))
        return dataclasses.replace(fields, elapsed_ms=(time.perf_counter() - t0) * 1e3)
    prior = CalibrationPrior(expected_side=side) if side is not None else None
    fields = _fields_from_result(calibrate_frame(lines, width, height, prior=prior), lines)
    if fields.status is CalibrationStatus.REFUSED and prior is not None:  # a prior exactly when side is given
        fields = _with_mirrored_refit(fields, lines, width, height, prior)
    return dataclasses.replace(fields, elapsed_ms=(time.perf_counter() - t0) * 1e3)


def _with_mirrored_refit(fields: CalibrationFields, lines: FieldLines, width: int, height: int,
                         prior: CalibrationPrior) -> CalibrationFields:
    """The mirrored re-fit of a main-camera frame its labels cannot calibrate.

    Labels and their mirror fit mirrored cameras equally well (``app.geometry.mirror``), except where a prior
    breaks the symmetry: a main camera is expected on the near side (``expected_side``), so mirrored labels,
    which need the camera on the far side, can be refused outright. When the mirrored labelling
    (``app.geometry.annotations.mirror_lines``) calibrates under the same prior, the refusal is flagged
    :data:`MIRROR_FLAG` with evidence ``refit`` (the camera position and RMS of the mirrored fit, its JaC@0.5 %):
    a mirrored-labels doubt whose fix (mirroring the lines) gives that camera. The labels are not changed here.
    """
    mirrored = calibrate_frame(mirror_lines(lines), width, height, prior=prior)
    if str(getattr(mirrored.status, "value", mirrored.status)) != "calibrated" or mirrored.camera is None:
        return fields
    if MIRROR_FLAG in (mirrored.flags or ()):  # mirrored, it lands beyond the far side as well: no evidence
        return fields
    c = mirrored.camera.C
    evidence: dict[str, Any] = {
                "verdict": MIRROR_FLAG, "margin": None, "camera_y_m": None, "side_vote": 0, "rig_distance_m": None,
                "rig_distance_mirrored_m": None, "rig_vote": 0, "pairs": [],
                "refit": {"position_m": [round(float(x), 2) for x in c],
                          "rms_px": None if mirrored.rms_px is None else round(float(mirrored.rms_px), 2),
                          "jac": None if not mirrored.jac else _opt_float(mirrored.jac.get(f"{JAC_GAMMAS[0]:g}")),
                          "source": "lines"}}
    return dataclasses.replace(fields, flags=[*fields.flags, MIRROR_FLAG],
                               mirror_evidence=json_safe(with_sentence(evidence, {})))


def _fields_from_result(result: Any, lines: FieldLines | None = None) -> CalibrationFields:
    """Plain fields of an ``app.geometry.calibration.CalibrationResult``; given the ``lines`` it was
    fitted to, with the camera's uncertainty (:func:`fit_uncertainty`)."""
    camera = result.camera
    status = CalibrationStatus(str(getattr(result.status, "value", result.status)))
    uncertainty = None
    if lines is not None and camera is not None and status is CalibrationStatus.CALIBRATED:
        uncertainty = fit_uncertainty(camera, lines, tuple(result.flags or ()), getattr(result, "centre_prior", None))
    j0005, j001, j002 = ((_opt_float(result.jac.get(f"{g:g}")) for g in JAC_GAMMAS) if result.jac
                         else (None, None, None))
    return CalibrationFields(
        status=status,
        camera=(json_safe(camera.to_soccernet()) if camera is not None and status is CalibrationStatus.CALIBRATED
                else None),
        jac=(j0005, j001, j002),
        residuals_px=json_safe(dict(result.residuals_px or {})),
        flags=[str(f) for f in (result.flags or ())],
        reason=refusal_sentence(result.refusal),
        refusal=result.refusal.code if result.refusal is not None else None,
        elapsed_ms=float(result.elapsed_ms),
        rms_px=_opt_float(result.rms_px),
        uncertainty=uncertainty,
    )


def fit_uncertainty(camera: Camera, lines: FieldLines, flags: tuple[str, ...],
                    prior: PriorRows | None = None) -> dict[str, Any] | None:
    """JSON of ``app.geometry.calibration.calibration_uncertainty`` for a camera fitted to ``lines``:
    a class the fit ignored (flag ``ignored_class:<class>``) is left out, a rig-assisted fit
    (:data:`RIG_FLAG`) had its centre fixed, a MAP fit with a learned prior (``prior``: its
    ``CalibrationResult.centre_prior``) gets the posterior's std. None when it cannot be computed."""
    try:
        u = calibration_uncertainty(camera, lines_used(lines, flags), fixed_centre=RIG_FLAG in flags, prior=prior)
    except (np.linalg.LinAlgError, ValueError, FloatingPointError):
        return None
    return None if u is None else u.to_json()


def _opt_float(v: Any) -> float | None:
    return None if v is None else float(v)


#: ``(lines_json, width, height, side, rig, main_camera)``: the arguments of :func:`calibrate_lines`
#: (``rig``: a game's rig, or a dataset's learned prior).
CalibrationJob = tuple[dict[str, Any], int, int, "int | None", "CameraRig | CameraPrior | None", bool]


def calibration_job(frame: Frame, rig: CameraRig | CameraPrior | None = None,
                    lines: dict[str, Any] | None = None) -> CalibrationJob:
    """The job that calibrates ``frame`` from its current field lines, or from ``lines`` (JSON lists, px)
    in their place (with the game ``rig``, or a dataset's learned prior, if any).

    Raises:
        ValueError: the frame has no field lines and no ``lines`` are given.
    """
    if lines is None:
        if frame.field_lines is None:
            raise ValueError(f"frame {frame.id} ({frame.name!r}) has no field lines to calibrate from")
        lines = frame.field_lines.lines
    return (lines, frame.width, frame.height, expected_side(frame.role), rig, frame.role is FrameRole.ACTION)


def apply_calibration(frame: Frame, fields: CalibrationFields, source: CalibrationSource) -> Calibration:
    """Write ``fields`` into the frame's calibration row (created if missing), and, for a kind whose games have a
    camera rig, bump its game's version: the calibration may feed the rig, which edits of the game's other systems
    read (``app.db.scope``).

    ``admitted`` is reset to False: it is decided by :func:`recompute_system`.
    """
    if frame.system is not None and kind_of(frame.system).uses_rig:
        scope.game_changed(frame.system.game)
    cal = frame.calibration
    if cal is None:
        cal = Calibration(source=source, status=fields.status)
        frame.calibration = cal
    cal.source = source
    cal.status = fields.status
    cal.camera = fields.camera
    cal.jac_0005, cal.jac_001, cal.jac_002 = fields.jac
    cal.residuals_px = fields.residuals_px
    cal.flags = list(fields.flags)
    cal.reason = fields.reason
    cal.mirror_evidence = fields.mirror_evidence
    cal.uncertainty = fields.uncertainty
    cal.players = fields.players
    cal.admitted = False
    cal.updated_at = utcnow()
    return cal
