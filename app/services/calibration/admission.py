"""Admission (method.md section 4): a stored frame joins the triangulation when it is calibrated with JaC at
``settings.admit_jac_gamma`` strictly above ``settings.admit_jac_min``. One predicate on a stored calibration
(:func:`is_admitted`, from the pure rule ``app.geometry.jac.jac_admitted``) and one SQL expression of the
same rule (:func:`admitted_jac_sql`) for the queries that select admitted calibrations; the rule's two numbers as
the geometry takes them (:func:`admission_args`) for what judges a camera before it is stored (ISSIA's cameras).
"""
from __future__ import annotations

from typing import Any

import sqlalchemy as sa

from app.core.config import Settings
from app.datasets.records import CalibrationFields
from app.db.models import JAC_COLUMNS, Calibration, CalibrationStatus
from app.geometry.jac import JAC_GAMMAS, jac_admitted

#: Calibration flag of a camera given by its dataset with no field lines to compute JaC on (an ISSIA
#: ``issia_calibration.json`` camera without ``issia_lines.json``): admitted as given.
GIVEN_CAMERA_FLAG = "given_camera"


def admission_jac(calibration: Calibration, settings: Settings) -> float | None:
    """The calibration's JaC at ``settings.admit_jac_gamma``.

    Raises:
        ValueError: the gamma is not one of the stored :data:`JAC_GAMMAS`.
    """
    return getattr(calibration, JAC_COLUMNS[admission_gamma(settings)])


def is_admitted(calibration: Calibration | None, settings: Settings) -> bool:
    """True when the frame joins triangulation: calibrated with JaC@gamma > ``admit_jac_min``."""
    if calibration is None:
        return False
    return _admitted(calibration.status, calibration.camera, calibration.flags, admission_jac(calibration, settings),
                     settings)


def fields_admitted(fields: CalibrationFields, settings: Settings) -> bool:
    """:func:`is_admitted` of a calibration not stored yet (what ``apply_calibration`` would store of ``fields``)."""
    jac = fields.jac[JAC_GAMMAS.index(admission_gamma(settings))]
    return _admitted(fields.status, fields.camera, fields.flags, jac, settings)


def _admitted(status: CalibrationStatus, camera: Any, flags: Any, jac: float | None, settings: Settings) -> bool:
    if status is not CalibrationStatus.CALIBRATED or camera is None:
        return False
    if GIVEN_CAMERA_FLAG in (flags or []):
        return True  # a static camera given by its dataset (ISSIA) without field lines to judge it
    return jac_admitted(jac, settings.admit_jac_min)


def admitted_jac_sql(settings: Settings, table: sa.Table | None = None) -> Any:
    """The admission rule of :func:`app.geometry.jac.jac_admitted` as one SQL expression on ``calibrations``:
    the JaC column of ``settings.admit_jac_gamma`` strictly above ``settings.admit_jac_min`` (NULL, no JaC,
    is never admitted: SQL's comparison with NULL is not true). Status, camera and flags are the caller's
    other conditions, as in :func:`is_admitted`. ``table``: the ``calibrations`` table, for a statement of the
    table's columns (None: the mapped class's attribute).

    Raises:
        ValueError: the gamma is not one of the stored :data:`JAC_GAMMAS`.
    """
    name = JAC_COLUMNS[admission_gamma(settings)]
    return (getattr(Calibration, name) if table is None else table.c[name]) > settings.admit_jac_min


def admission_args(settings: Settings) -> dict[str, Any]:
    """The admission's ``admit_jac_gamma`` (checked: :func:`admission_gamma`) and ``admit_jac_min`` of ``settings``, as
    the keyword arguments of the geometry and services that judge a camera by the rule before it is stored
    (``app.geometry.static_cameras.calibrate_with_ball``, ``app.services.issia.cameras.sequence_cameras``).

    Raises:
        ValueError: the gamma is not one of the stored :data:`JAC_GAMMAS`.
    """
    return {"admit_jac_gamma": admission_gamma(settings), "admit_jac_min": settings.admit_jac_min}


def admission_gamma(settings: Settings) -> float:
    """``settings.admit_jac_gamma``, checked against the stored gammas (ValueError naming them otherwise)."""
    if settings.admit_jac_gamma not in JAC_COLUMNS:
        raise ValueError(f"settings.admit_jac_gamma={settings.admit_jac_gamma!r} is not a stored JaC gamma; "
                         f"choose one of {list(JAC_GAMMAS)}")
    return settings.admit_jac_gamma
