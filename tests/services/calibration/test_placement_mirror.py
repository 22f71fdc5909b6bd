"""A view whose labels are mirrored is placed by its players and stays flagged mirrored, with the players' evidence
and the one-key fix; the players tell a flag its lines earned wrongly, and leave a view flagged when they cannot
tell. Synthetic cameras of known truth (``tests.geometry.test_calibration_players``)."""
from __future__ import annotations

import numpy as np

from app.core.config import Settings
from app.datasets.records import CalibrationFields
from app.db.models import CalibrationSource, CalibrationStatus
from app.geometry.annotations import lines_to_json_lists, mirror_lines
from app.geometry.calibration.players import PLAYER_REFUSALS, PlayerRefusal
from app.geometry.calibration.result import MIRROR_FLAG, PLAYERS_FLAG, RIG_FLAG
from app.geometry.calibration.rig import CameraRig, RigPosition
from app.geometry.camera import Camera
from app.geometry.doubts.contract import DoubtView
from app.geometry.doubts.judge import _mirror_fix_check
from app.geometry.mirror import mirror_camera
from app.services.calibration.players import PlacementView, place_in_system, players_mirror_evidence
from app.services.derivation.doubts import doubt_settings
from tests.geometry.synthetic import visible_model_points
from tests.geometry.test_calibration_players import CENTRE, RIG, H, W, camera_at, feet_in, players

SETTINGS = Settings(_env_file=None)
ANCHORS = [camera_at(np.array([0.0, 60.0, -14.0]), (-35.0, 0.0, 0.0), 1800.0),
           camera_at(np.array([-20.0, 45.0, -10.0]), (-35.0, 0.0, 0.0), 2400.0)]
TRUTH = camera_at(CENTRE, (-35.0, 2.0, 0.0), 2600.0)
BALL = np.array([[-33.0, 3.0, -1.5]])


def _boxes(camera: Camera, pts: dict, rng: np.random.Generator) -> tuple:
    """Player boxes whose bottom centres are the players' foot points in ``camera`` (1 px of noise); their tops at
    the image's top edge, so no head point is read."""
    feet = feet_in(camera, pts, 1.0, rng)
    return tuple((k[0], k[1], (float(uv[0]) - 12.0, 0.0, float(uv[0]) + 12.0, float(uv[1]))) for k, uv in feet.items())


def _view(camera: Camera | None, lines: dict, boxes: tuple, flags: tuple[str, ...] = ()) -> PlacementView:
    calibrated = camera is not None
    return PlacementView(
        lines=lines_to_json_lists(lines), width=W, height=H, main=False,
        status=CalibrationStatus.CALIBRATED if calibrated else CalibrationStatus.REFUSED,
        source=CalibrationSource.COMPUTED, camera=camera.to_soccernet() if camera is not None else None, flags=flags,
        admitted=calibrated, players=boxes, admission=(SETTINGS.admit_jac_gamma, SETTINGS.admit_jac_min))


def _system(weak_lines: dict, flags: tuple[str, ...], seed: int) -> dict:
    rng = np.random.default_rng(seed)
    pts = players(8, rng)
    views = [_view(a, visible_model_points(a, W, H, rng, noise_px=0.5), _boxes(a, pts, rng)) for a in ANCHORS]
    views.append(_view(None, weak_lines, _boxes(TRUTH, pts, rng), flags))
    rig = CameraRig(tuple(RigPosition(tuple(c), 5, 0.5) for c in RIG))  # type: ignore[arg-type]  # (3,) each
    return place_in_system(views, rig)


def _ball_px(camera_json: dict) -> float:
    return float(np.linalg.norm(Camera.from_soccernet(camera_json).project(BALL)[0][0] - TRUTH.project(BALL)[0][0]))


def _lines(seed: int) -> dict:
    return visible_model_points(TRUTH, W, H, np.random.default_rng(seed),
                                classes=("Big rect. left main", "Small rect. left main"), noise_px=1.0)


def test_a_view_whose_lines_are_mirrored_is_placed_by_its_players_and_stays_flagged_with_their_evidence() -> None:
    """Flagged mirrored by its lines (refused as labelled) or not flagged at all, a view whose 2 classes are labelled
    left for right gets the true camera from its players, with its lines fitted mirrored: it keeps (or gets) the
    mirror flag, the evidence names the players' camera, and the doubts' fix is offered without moving it."""
    for flags in ((MIRROR_FLAG, "few_lines"), ("few_lines",)):
        got = _system(mirror_lines(_lines(5)), flags, 7)[2]
        assert isinstance(got, CalibrationFields), got
        assert {MIRROR_FLAG, PLAYERS_FLAG, RIG_FLAG} <= set(got.flags)
        assert _ball_px(got.camera) < 3.0  # the true camera, not its mirror image
        assert got.players is not None and got.players["lines_mirrored"]["line_px"] < 5.0
        evidence = got.mirror_evidence
        assert evidence == players_mirror_evidence(got.players, got.camera)  # what each recomputation derives again
        assert evidence["verdict"] == MIRROR_FLAG and evidence["refit"]["source"] == "players"
        assert evidence["sentence"].startswith("Labels probably mirrored: the camera its")
        camera = Camera.from_soccernet(got.camera)
        view = DoubtView(view_id=1, name="3.png", role="replay", width=W, height=H, camera=camera, admitted=False,
                         jac=None, line_classes=2, box=None, point=None, mirror_flagged=True,
                         mirror_evidence=evidence, player_assisted=True)
        offered, why, _ = _mirror_fix_check(view, evidence, None, doubt_settings(SETTINGS))
        assert offered and why == ""


def test_the_players_tell_a_wrong_mirror_flag_and_leave_a_flag_they_cannot_judge() -> None:
    """A view flagged mirrored whose lines are labelled right gets the players' camera with its lines as labelled
    (the flag is its camera's verdict's again); one whose lines are wrong otherwise (fitting the players' camera
    neither as labelled nor mirrored) is not placed (``mirror_undecided``): it keeps its lines' calibration and flag."""
    right = _system(_lines(5), (MIRROR_FLAG, "few_lines"), 7)[2]
    assert isinstance(right, CalibrationFields), right
    assert MIRROR_FLAG not in right.flags and PLAYERS_FLAG in right.flags and right.mirror_evidence is None
    assert "lines_mirrored" not in (right.players or {}) and _ball_px(right.camera) < 3.0
    lines = _lines(5)
    wrong = {"Big rect. left main": lines["Small rect. left main"],
             "Small rect. left main": lines["Big rect. left main"]}
    got = _system(wrong, (MIRROR_FLAG, "few_lines"), 7)[2]
    assert isinstance(got, PlayerRefusal) and got.code == "mirror_undecided" and got.code in PLAYER_REFUSALS
    unflagged = _system(wrong, ("few_lines",), 7)[2]  # without the flag the players alone place it, as before
    assert isinstance(unflagged, CalibrationFields) and MIRROR_FLAG not in unflagged.flags


def test_an_anchor_flagged_mirrored_places_no_player() -> None:
    """A well-lined view whose labels are mirrored calibrates to the mirror image of its camera, which puts its
    players on the other side of the pitch: left as an anchor, it contradicts the true anchor about every player the
    weak view shares (none is kept: too few players); flagged mirrored, it is no anchor, and the weak view gets the true
    camera from the other anchor's players."""
    rng = np.random.default_rng(11)
    pts = players(8, rng)
    true_anchor, slipped = ANCHORS
    views = [_view(true_anchor, visible_model_points(true_anchor, W, H, rng, noise_px=0.5),
                   _boxes(true_anchor, pts, rng)),
             _view(mirror_camera(slipped), mirror_lines(visible_model_points(slipped, W, H, rng, noise_px=0.5)),
                   _boxes(slipped, pts, rng)),
             _view(None, _lines(5), _boxes(TRUTH, pts, rng), ("few_lines",))]
    rig = CameraRig(tuple(RigPosition(tuple(c), 5, 0.5) for c in RIG))  # type: ignore[arg-type]  # (3,) each
    unflagged = place_in_system(views, rig)[2]
    assert isinstance(unflagged, PlayerRefusal) and unflagged.code == "few_players"
    views[1] = views[1]._replace(flags=(MIRROR_FLAG,))
    got = place_in_system(views, rig)[2]
    assert isinstance(got, CalibrationFields) and _ball_px(got.camera) < 3.0
