"""The dry run of a field-line edit: while a person drags a line point, the view's camera,
JaC, worst-line residuals and projected pitch follow the pointer, computed from the lines as they would be
sent on release, with the same calibration the commit runs (:func:`app.services.derivation.recompute.
calibrate_frame_lines`: the rig retry and the learned prior's refit included). Nothing is written: no row, no
audit entry, no recomputation of the system; the release commits as any field-line edit does
(``app.services.curation.editing.replace_field_lines``).

One refinement is left out on purpose: a view whose kind refines its camera beyond the lines on commit (an ISSIA
camera refined with the sequence's ball labels, about a second) is previewed from its lines alone, and the
preview says so (``differs``), so that a person never takes the preview for the stored result.

Like an edit (``app.services.curation.writing``, "Read", then "Compute"), a preview reads everything its calibration
needs first (the frame, its system and game, the game's rig rows), gives its connection back to the pool
(``app.db.session.end_reads``) and only then computes: many previews at once never hold the pool's connections.
"""
from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Any, Mapping, Optional

from sqlalchemy.orm import Session

from app.core.config import Settings
from app.datasets.records import CalibrationFields
from app.db.models import JAC_COLUMNS, Calibration, CalibrationStatus
from app.db.session import end_reads
from app.services.calibration.admission import is_admitted
from app.services.curation.editing import parse_field_lines
from app.services.curation.system_page import pitch_lines
from app.services.curation.writing import get_frame
from app.services.derivation.recompute import calibrate_frame_lines, system_rig_rows
from app.services.kinds import kind_of


@dataclass(frozen=True)
class CalibrationPreview:
    """The calibration an edit of a view's field lines would store, not stored.

    ``fields``: status, camera (SoccerNet JSON, world metres, z down), JaC at each stored gamma, per-class
    residuals (px), flags and refusal reason, as :func:`calibrate_frame_lines` gives them; ``jac``: its JaC keyed as
    a stored calibration's (``Calibration.jac``); ``admitted``: whether
    the system's triangulation would admit it (``is_admitted``: JaC at ``settings.admit_jac_gamma`` above
    ``admit_jac_min``); ``retry``: "rig" or "prior" when that retry made the camera; ``differs``: a sentence when
    the commit computes more than this (``KindPolicy.calibration_refinement``), else None; ``pitch_lines``: the
    pitch model projected by the camera, clipped to the image (``[(class, [[x, y], ...])]`` px, rounded; empty
    when refused); ``elapsed_ms``: the server's wall time of the calibration and projection.
    """

    frame_id: int
    fields: CalibrationFields
    jac: dict[str, Optional[float]]
    admitted: bool
    retry: Optional[str]
    differs: Optional[str]
    pitch_lines: list[tuple[str, list[list[float]]]]
    elapsed_ms: float


def preview_calibration(session: Session, frame_id: int, lines: Mapping[str, Any], *,
                        settings: Settings) -> CalibrationPreview:
    """Calibrate frame ``frame_id`` from ``lines`` (``{class: [[[x, y], ...], ...]}``, pixels of the frame, the
    view's complete lines as a field-line edit would send them) without storing anything.

    Raises:
        NotFoundError: no such frame.
        InvalidInputError: the lines a field-line edit would refuse (field "lines": unknown class, malformed
            polyline, NaN or infinity, a point far outside the image, more than
            ``settings.max_line_points_per_frame`` points), checked before any geometry.
    """
    t0 = time.perf_counter()
    frame = get_frame(session, frame_id)
    parsed = parse_field_lines(lines, frame.width, frame.height, settings.max_line_points_per_frame)
    # everything the calibration reads, read now (its rig retry's rows, its learned prior on the game), then the
    # connection goes back to the pool while it computes
    system = frame.system
    _ = system.game
    rig = system_rig_rows(session, system, settings)
    differs = kind_of(system).calibration_refinement(frame)
    end_reads(session)
    with session.no_autoflush:
        calibrated = calibrate_frame_lines(session, frame, settings, lines=parsed, refine=False, rig=rig)
    fields = calibrated.fields
    # transient: never added to the session
    as_stored = Calibration(status=fields.status, camera=fields.camera, flags=list(fields.flags),
                            **dict(zip(JAC_COLUMNS.values(), fields.jac, strict=True)))
    camera = fields.camera if fields.status is CalibrationStatus.CALIBRATED else None
    drawn = pitch_lines(camera, frame.width, frame.height, keep=False)
    return CalibrationPreview(frame_id=frame.id, fields=fields, jac=as_stored.jac(),
                              admitted=is_admitted(as_stored, settings),
                              retry=calibrated.retry, differs=differs,
                              pitch_lines=drawn, elapsed_ms=(time.perf_counter() - t0) * 1e3)
