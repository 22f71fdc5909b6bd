"""The players' second round (``app.services.calibration.players._chained``): weak views the first round leaves
without any camera, placed by players the anchors see only by their heads, or that a view the players placed at a rig
position, or a view of three admitted line classes, put on the grass. Synthetic cameras of known truth."""
from __future__ import annotations

import numpy as np

from app.core.config import Settings
from app.datasets.records import CalibrationFields
from app.db.models import CalibrationSource, CalibrationStatus
from app.geometry.annotations import lines_to_json_lists
from app.geometry.calibration.grass import HEAD_SIGMA_M, head_grass_points, head_world, players_on_grass_by_heads
from app.geometry.calibration.players import PlayerRefusal
from app.geometry.calibration.result import PLAYERS_FLAG, RIG_FLAG
from app.geometry.calibration.rig import CameraRig, RigPosition
from app.geometry.camera import Camera
from app.services.calibration.players import CHAINED_MIN_PLAYERS, PlacementView, place_in_system
from tests.geometry.synthetic import visible_model_points
from tests.geometry.test_calibration_players import CENTRE, RIG, H, W, camera_at, feet_in, players

SETTINGS = Settings(_env_file=None)
#: A well-lined view (the main camera) and the two weak views, each at a position of the rig.
ANCHOR = camera_at(np.array([0.0, 60.0, -14.0]), (-35.0, 0.0, 0.0), 1800.0)
NEAR = camera_at(CENTRE, (-35.0, 2.0, 0.0), 2600.0)
ZOOMED = camera_at(np.array(RIG[0]), (-35.0, 2.0, 0.0), 3200.0)
BALL = np.array([[-33.0, 3.0, -1.5]])
RIG_OF_GAME = CameraRig(tuple(RigPosition(tuple(c), 5, 0.5) for c in RIG))  # type: ignore[arg-type]  # (3,) each


def _feet_boxes(camera: Camera, pts: dict, rng: np.random.Generator) -> tuple:
    """Boxes whose bottom centres are the players' foot points in ``camera`` (1 px of noise), their tops at the
    image's top edge (no head point read)."""
    return tuple((k[0], k[1], (float(uv[0]) - 12.0, 0.0, float(uv[0]) + 12.0, float(uv[1])))
                 for k, uv in feet_in(camera, pts, 1.0, rng).items())


def _head_boxes(camera: Camera, pts: dict) -> tuple:
    """Boxes the image's bottom edge cuts (no foot point) whose top centres are the players' head points."""
    keys = list(pts)
    uv, ok = camera.project(head_world(np.array([pts[k] for k in keys]), camera.C))
    assert ok.all()
    return tuple((k[0], k[1], (float(p[0]) - 12.0, float(p[1]), float(p[0]) + 12.0, float(H - 1)))
                 for k, p in zip(keys, uv, strict=True))


def _whole_boxes(camera: Camera, pts: dict, rng: np.random.Generator) -> tuple:
    """Whole boxes: the bottom centres the foot points (1 px of noise), the top centres the head points."""
    heads = {(c, i): box[1] for c, i, box in _head_boxes(camera, pts)}
    return tuple((c, i, (x1, heads[(c, i)], x2, y2)) for c, i, (x1, _, x2, y2) in _feet_boxes(camera, pts, rng))


def _view(camera: Camera | None, lines: dict, boxes: tuple) -> PlacementView:
    calibrated = camera is not None
    return PlacementView(
        lines=lines_to_json_lists(lines), width=W, height=H, main=False,
        status=CalibrationStatus.CALIBRATED if calibrated else CalibrationStatus.REFUSED,
        source=CalibrationSource.COMPUTED, camera=camera.to_soccernet() if calibrated else None, flags=(),
        admitted=calibrated, players=boxes, admission=(SETTINGS.admit_jac_gamma, SETTINGS.admit_jac_min))


def _ball_px(got: CalibrationFields | PlayerRefusal, truth: Camera) -> float:
    assert isinstance(got, CalibrationFields), got
    return float(np.linalg.norm(Camera.from_soccernet(got.camera).project(BALL)[0][0] - truth.project(BALL)[0][0]))


def _split(first: int, more: int, seed: int) -> tuple[dict, dict]:
    pts = players(first + more, np.random.default_rng(seed))
    keys = list(pts)
    return {k: pts[k] for k in keys[:first]}, {k: pts[k] for k in keys[first:]}


def test_a_head_point_goes_back_to_where_the_player_stands_with_the_stature_along_the_ray() -> None:
    """``head_grass_points`` inverts ``head_world`` (to a micrometre); the covariance of one view's head point is
    longest along the ground ray, by the stature's spread times the ground distance over the camera's height above the
    head (similar triangles: 0.1 m x 40.01 m / 16.15 m = 0.248 m here), plus the pixel noise and the footprint's."""
    grass = np.array([[-30.0, 4.0], [-40.0, -6.0]])
    uv, _ = NEAR.project(head_world(grass, NEAR.C))
    assert np.allclose(head_grass_points(NEAR, uv), grass, atol=1e-6)
    got = players_on_grass_by_heads([(NEAR, {("Player team left", "0"): uv[0]})])[("Player team left", "0")]
    assert np.allclose(got.point_m, grass[0], atol=1e-6) and got.views == 1
    away = grass[0] - NEAR.C[:2]
    u = away / np.linalg.norm(away)
    stature = HEAD_SIGMA_M * float(np.linalg.norm(away)) / (18.0 - 1.85)
    assert round(stature, 3) == 0.248
    along = float(np.sqrt(u @ np.asarray(got.cov_m2) @ u))
    across = float(np.sqrt(np.array([-u[1], u[0]]) @ np.asarray(got.cov_m2) @ np.array([-u[1], u[0]])))
    assert np.hypot(stature, 0.1) < along < np.hypot(stature, 0.1) + 0.05
    assert 0.1 <= across < 0.11  # across the ray: the footprint's 0.1 m and a little pixel noise


def test_a_view_that_shares_its_players_only_with_a_view_the_players_placed_is_placed_from_it() -> None:
    """The anchor sees 6 players; the near view sees them and 5 more, the zoomed view only the 5 more: the first
    round places the near view (6 shared) and refuses the zoomed one (none shared); the second round puts the 5 on
    the grass through the near view's camera and places the zoomed view at its rig position, within 2 px of the true
    ball. With 3 more players (below ``CHAINED_MIN_PLAYERS``) it stays without a camera; asked for that view alone
    (``only``, as an edit asks), the same camera."""
    assert CHAINED_MIN_PLAYERS == 4
    for more, placed in ((5, True), (3, False)):
        rng = np.random.default_rng(3)
        first, second = _split(6, more, 21)
        views = [_view(ANCHOR, visible_model_points(ANCHOR, W, H, rng, noise_px=0.5), _feet_boxes(ANCHOR, first, rng)),
                 _view(None, {}, _feet_boxes(NEAR, {**first, **second}, rng)),
                 _view(None, {}, _feet_boxes(ZOOMED, second, rng))]
        got = place_in_system(views, RIG_OF_GAME)
        assert _ball_px(got[1], NEAR) < 2.0
        if not placed:
            assert isinstance(got[2], PlayerRefusal) and got[2].code == "few_players"
            continue
        assert _ball_px(got[2], ZOOMED) < 2.0
        assert {PLAYERS_FLAG, RIG_FLAG} <= set(got[2].flags) and got[2].players["players"] == 5
        assert got[2].players["rig"]["index"] == 0
        alone = place_in_system(views, RIG_OF_GAME, only=2)
        assert list(alone) == [2] and alone[2].camera == got[2].camera


def test_players_the_anchor_sees_only_by_their_heads_place_a_view_at_the_second_round() -> None:
    """A high anchor sees 2 of the near view's players by their feet and 6 only by their heads (its bottom edge cuts
    them): the first round refuses the near view (2 players); the second places it by 7 of the 8 (heads and feet of
    whole boxes), 2.5 px from the true ball, its pixel uncertainty 2.7 px@1920. Seen by their feet by no anchor, the
    same 6 place nothing."""
    high = camera_at(np.array([-60.0, 0.0, -25.0]), (-35.0, 0.0, 0.0), 1500.0)
    rng = np.random.default_rng(5)
    first, second = _split(4, 6, 33)
    footed = dict(list(first.items())[:2])
    lines = visible_model_points(high, W, H, rng, noise_px=0.5)
    near = _view(None, {}, _whole_boxes(NEAR, {**footed, **second}, rng))
    got = place_in_system([_view(high, lines, _feet_boxes(high, footed, rng) + _head_boxes(high, second)), near],
                          RIG_OF_GAME)
    assert 2.4 < _ball_px(got[1], NEAR) < 2.6 and got[1].players["players"] == 7
    assert 2.6 < got[1].players["sigma_px"] < 2.8
    unseen = place_in_system([_view(high, lines, _feet_boxes(high, footed, rng)), near], RIG_OF_GAME)
    assert isinstance(unseen[1], PlayerRefusal) and unseen[1].code == "few_players"


def test_a_system_without_an_anchor_is_placed_from_a_view_of_three_admitted_line_classes() -> None:
    """No view of the system has 4 line classes: the first round has no anchor; a view of 3 classes whose lines'
    camera is admitted (the true one here) puts the weak view's 7 players on the grass, which place it within 2 px of
    the true ball (1.5 px). With 2 classes that view tells nothing and the weak view stays without a camera."""
    rng = np.random.default_rng(9)
    pts = players(7, np.random.default_rng(44))
    lines = visible_model_points(ANCHOR, W, H, rng, noise_px=0.5)
    for classes, placed in ((3, True), (2, False)):
        few = dict(list(lines.items())[:classes])
        views = [_view(ANCHOR, few, _feet_boxes(ANCHOR, pts, rng)), _view(None, {}, _whole_boxes(NEAR, pts, rng))]
        got = place_in_system(views, RIG_OF_GAME)
        if placed:
            assert _ball_px(got[1], NEAR) < 2.0 and 0 not in got  # the 3-class view itself is weak, not placed here
            assert got[1].players["players"] == 7 and got[1].players["rig"]["index"] == 1
        else:
            assert got == {}
