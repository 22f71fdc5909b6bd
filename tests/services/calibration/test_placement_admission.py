"""A camera the players place never takes a view out of the triangulation its own lines let it join: where the
view's lines already give an admitted camera, the players' camera replaces it only when it clears admission too, or
when the players, at a rig position, tell those lines wrong."""
from __future__ import annotations

import dataclasses

import numpy as np

from app.core.config import Settings
from app.datasets.records import CalibrationFields
from app.db.models import CalibrationSource, CalibrationStatus
from app.geometry.calibration.players import PLAYER_REFUSALS, PlayerRefusal
from app.geometry.jac import JAC_GAMMAS
from app.services.calibration.players import _kept, _kept_admitted, _lines_contradicted, view_of_fields
from tests.geometry.test_calibration_players import CENTRE, H, W, as_grass, camera_at, feet_in, players


def _fields(jac_at_admission: float | None, settings: Settings) -> CalibrationFields:
    jac = [0.5, 0.5, 0.5]
    jac[JAC_GAMMAS.index(settings.admit_jac_gamma)] = jac_at_admission  # type: ignore[call-overload]  # a JaC or None
    return CalibrationFields(status=CalibrationStatus.CALIBRATED, camera={"position_meters": [0.0, 60.0, -14.0]},
                             jac=tuple(jac), residuals_px={}, flags=[], reason=None)  # type: ignore[arg-type]  # 3


def test_a_view_its_lines_admit_keeps_their_camera_unless_the_players_camera_is_admitted_too():
    settings = Settings(_env_file=None)
    edge = settings.admit_jac_min
    admitted_by_lines = view_of_fields(_fields(edge + 0.1, settings), {"Side line top": [[[0, 0], [10, 0]]]},
                                       1920, 1080, True, (), settings)
    assert admitted_by_lines.admitted and admitted_by_lines.source is CalibrationSource.COMPUTED
    refused = _kept_admitted(_fields(edge - 0.05, settings), admitted_by_lines)
    assert isinstance(refused, PlayerRefusal) and refused.code == "lines_admitted" and refused.code in PLAYER_REFUSALS
    assert refused.numbers["jac"] == edge - 0.05
    kept = _fields(edge + 0.02, settings)
    assert _kept_admitted(kept, admitted_by_lines) is kept
    # a view its lines do not admit takes the players' camera whatever its JaC (the players are all it has)
    unsure = view_of_fields(_fields(edge - 0.2, settings), {}, 1920, 1080, False, (), settings)
    assert not unsure.admitted
    low = _fields(None, settings)
    assert _kept_admitted(low, unsure) is low


def test_players_at_a_rig_position_overrule_admitted_lines_that_put_them_elsewhere():
    """An admitted camera from a view's few lines that puts the players the view shares with the well-lined views
    far from where those views put them (a wrong solution its lines admit) does not keep the view: the players'
    camera replaces it; the true camera from the same lines keeps it."""
    rng = np.random.default_rng(41)
    settings = Settings(_env_file=None)
    truth = camera_at(CENTRE, (-35.0, 2.0, 0.0), 2600.0)
    pts = players(8, rng)
    grass = as_grass(pts)
    feet = feet_in(truth, pts, 1.0, rng)
    lines = {"Side line top": [[[0, 0], [10, 0]]]}
    wrong = camera_at(CENTRE, (-30.0, 6.0, 0.0), 2600.0)
    for camera, contradicted in ((wrong, True), (truth, False)):
        fields = dataclasses.replace(_fields(settings.admit_jac_min + 0.1, settings), camera=camera.to_soccernet())
        view = view_of_fields(fields, lines, W, H, True, (), settings)
        assert view.admitted
        assert _lines_contradicted(view, feet, grass) is contradicted
        low = _fields(settings.admit_jac_min - 0.05, settings)
        got = _kept(low, view, True, feet, grass)
        assert (got is low) if contradicted else (isinstance(got, PlayerRefusal) and got.code == "lines_admitted")
        assert isinstance(_kept(low, view, False, feet, grass), PlayerRefusal)  # a full pose never overrules lines
        admitted_too = _fields(settings.admit_jac_min + 0.02, settings)
        assert _kept(admitted_too, view, True, feet, grass) is admitted_too
