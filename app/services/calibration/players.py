"""Players place the cameras the lines cannot (``app.geometry.calibration.players``), on stored frames and on an
import's fresh calibrations of a game new to the database (in its pool task, ``first_pass.calibrate_game``).

After a system's frames are calibrated from their lines (and the game's rig), each view whose lines give no camera
or an unsure one (refused, or fewer than :data:`~app.geometry.pitch.MIN_LINE_CLASSES` line classes) is fitted to the
foot points of the players it shares (class and ID) with the system's well-calibrated views (calibrated, admitted,
four or more line classes), with its centre at a position of the game's rig where one fits, its lines in the same
fit. An accepted fit replaces the view's calibration (flags ``"player_assisted"``, ``"rig_assisted"`` at a rig
position; its uncertainty from the fit, as a line fit's; what it was fitted to in ``Calibration.players``); a
refused one leaves the calibration from lines as it was. The ball label is never read. A camera the players placed
never feeds the game's rig (``rigs``) nor places another view.

Mirrored labels: a view's lines that fit the players' camera only mirrored (``PlayerFit.lines_mirrored``) keep the
view flagged :data:`MIRROR_FLAG`, with the players' evidence (:func:`players_mirror_evidence`, which every
recomputation reads again from ``Calibration.players``); the one-key fix (``editing.apply_mirrored_labels``) then
mirrors the labels and places the view by its players again (:func:`place_frame_by_players`), the camera staying
where the players put it. A view its lines flagged mirrored is placed only when the players tell which labelling
is right: its lines fit their camera mirrored, or as labelled; not by the players alone (``mirror_undecided``).
"""
from __future__ import annotations

import time
from typing import Any, Iterable, Mapping, NamedTuple, Sequence, cast

import numpy as np
import sqlalchemy as sa
from sqlalchemy.orm import Session

from app.core.config import Settings
from app.datasets.records import CalibrationFields
from app.db.models import CalibrationSource, CalibrationStatus, Frame, FrameRole, PlayerBox, System
from app.db.types import json_safe
from app.geometry.annotations import lines_from_json_lists
from app.geometry.calibration import frame_jac
from app.geometry.calibration.grass import (
    GrassPlayer,
    PlayerKey,
    foot_pixel,
    head_pixel,
    players_on_grass,
    players_on_grass_by_heads,
)
from app.geometry.calibration.players import (
    LINES_CONTRADICTED_SIGMA,
    PlayerFit,
    PlayerFitSettings,
    PlayerRefusal,
    fit_camera_to_players,
    players_disagreement,
)
from app.geometry.calibration.result import MIRROR_FLAG, PLAYERS_FLAG, RIG_FLAG
from app.geometry.calibration.rig import CameraRig
from app.geometry.camera import Camera
from app.geometry.jac import JAC_GAMMAS, jac_admitted
from app.geometry.pitch import MIN_LINE_CLASSES
from app.services.calibration.admission import admission_args, fields_admitted, is_admitted
from app.services.calibration.calibrating import apply_calibration
from app.services.wording.doubt_words import with_sentence
from app.services.wording.words import player_camera_sentence

#: ``(class, ID or None, (x1, y1, x2, y2) px)``: a player box as the records and the rows give it.
PlayerRow = tuple[str, "str | None", tuple[float, float, float, float]]


#: Where ``app.services.derivation.loading.load_view_players`` keeps a frame's person boxes: a :class:`ViewPlayers` in
#: the ``info`` of the frame's instance state (it lives and goes with the object, as a loaded relationship would); a
#: frame whose boxes are written again drops it (:func:`store_players`).
VIEW_PLAYERS = "v3d.view_players"


class ViewPlayers:
    """One view's person boxes as ``app.services.derivation.loading.load_view_players`` read them: ``rows``
    ``(class, ID, (x1, y1, x2, y2))`` in id order, and ``feet``, its foot points by player (:func:`frame_feet`), made
    on the first ask (None until then)."""

    __slots__ = ("rows", "feet")

    def __init__(self, rows: list[PlayerRow]) -> None:
        self.rows = rows
        self.feet: dict[PlayerKey, np.ndarray] | None = None


def view_players(frame: Frame) -> ViewPlayers | None:
    """The person boxes ``load_view_players`` read for ``frame`` (None: not read so, or ``Frame.players`` loaded
    since, which then holds them)."""
    state = sa.inspect(frame)
    if "players" not in state.unloaded:
        return None
    got: ViewPlayers | None = state.info.get(VIEW_PLAYERS)
    return got


def forget_view_players(frames: Sequence[Frame]) -> None:
    """Drop what ``load_view_players`` kept of ``frames`` (their boxes were written again)."""
    for f in frames:
        sa.inspect(f).info.pop(VIEW_PLAYERS, None)


def frame_players(frame: Frame) -> list[PlayerRow]:
    """The stored player boxes of ``frame`` as rows: as a recomputation's load read them
    (``app.services.derivation.loading.load_view_players``), else ``Frame.players``."""
    kept = view_players(frame)
    if kept is not None:
        return kept.rows
    return [(p.cls, p.ident, (p.x1, p.y1, p.x2, p.y2)) for p in frame.players]


def frame_feet(frame: Frame) -> dict[PlayerKey, np.ndarray]:
    """:func:`feet_of` the stored player boxes of ``frame`` (:func:`frame_players`), made once per frame while the
    session keeps the boxes a recomputation's load read (an edit's ball asks for them more than once)."""
    kept = view_players(frame)
    if kept is None:
        return feet_of(frame_players(frame), frame.width, frame.height)
    if kept.feet is None:
        kept.feet = feet_of(kept.rows, frame.width, frame.height)
    return kept.feet


class PlacementView(NamedTuple):
    """One view as the players' placement reads it: plain values, picklable, so that the placement runs the same
    on stored frames (:func:`view_of_frame`) and in a pool task on an import's fresh results
    (:func:`view_of_fields`, ``first_pass.calibrate_game``).

    Attributes:
        lines: the view's field lines, JSON lists (px), as ``FieldLineAnnotation.lines`` holds them.
        width, height: the image size, px.
        main: filmed by the main camera (an action frame): marks the rig's main position.
        status, source, camera, flags: its calibration's (``status`` None: no calibration).
        admitted: its calibration clears admission (``admission.is_admitted``).
        players: its player boxes.
        admission: the admission rule's gamma and JaC minimum (``admission.admission_args``): a camera the players
            place for a view its lines already admit must clear it too, or the lines' camera stays.
    """

    lines: Mapping[str, Any]
    width: int
    height: int
    main: bool
    status: CalibrationStatus | None
    source: CalibrationSource | None
    camera: Mapping[str, Any] | None
    flags: tuple[str, ...]
    admitted: bool
    players: Sequence[PlayerRow]
    admission: tuple[float, float]


def view_of_frame(frame: Frame, settings: Settings, players: Sequence[PlayerRow] | None = None) -> PlacementView:
    """``frame`` as a :class:`PlacementView`: its stored calibration, and ``players`` (None: ``Frame.players``)."""
    cal = frame.calibration
    return PlacementView(
        lines=frame.field_lines.lines if frame.field_lines is not None else {}, width=frame.width,
        height=frame.height, main=frame.role is FrameRole.ACTION, status=cal.status if cal is not None else None,
        source=cal.source if cal is not None else None, camera=cal.camera if cal is not None else None,
        flags=tuple(cal.flags or ()) if cal is not None else (), admitted=is_admitted(cal, settings),
        players=frame_players(frame) if players is None else players, admission=_admission(settings))


def view_of_fields(fields: CalibrationFields, lines: Mapping[str, Any], width: int, height: int, main: bool,
                   players: Sequence[PlayerRow], settings: Settings) -> PlacementView:
    """A view whose calibration ``fields`` (source "computed") are not stored yet, as a :class:`PlacementView`."""
    return PlacementView(lines=lines, width=width, height=height, main=main, status=fields.status,
                         source=CalibrationSource.COMPUTED, camera=fields.camera, flags=tuple(fields.flags),
                         admitted=fields_admitted(fields, settings), players=players, admission=_admission(settings))


def _admission(settings: Settings) -> tuple[float, float]:
    args = admission_args(settings)
    return args["admit_jac_gamma"], args["admit_jac_min"]


def feet_of(rows: Iterable[PlayerRow], width: int, height: int, point: Any = foot_pixel) -> dict[PlayerKey, np.ndarray]:
    """Foot pixels (2,) by player (class, ID) of a ``width`` x ``height`` view; boxes without an ID, boxes cut by the
    image's edges (``foot_pixel``) and a (class, ID) boxed twice in the view are left out. ``point``: the box's point
    taken (``grass.head_pixel``: the head points, by the same rules)."""
    out: dict[PlayerKey, np.ndarray] = {}
    twice: set[PlayerKey] = set()
    for cls, ident, box in rows:
        if ident is None:
            continue
        uv = point(box, width, height)
        if uv is None:
            continue
        key = (cls, ident)
        if key in out:
            twice.add(key)
        out[key] = uv
    return {k: v for k, v in out.items() if k not in twice}


def line_classes(lines: Mapping[str, Any]) -> int:
    """The classes of field lines labelled in ``lines`` (JSON lists; with at least one polyline)."""
    return sum(1 for polys in lines.values() if polys)


def is_weak(view: PlacementView) -> bool:
    """Whether the players may place ``view``'s camera: its lines give none (refused, no calibration) or an unsure
    one (fewer than :data:`MIN_LINE_CLASSES` classes), or the players placed it before (placed again). A camera an
    export brought or a person set (source ``imported``, ``edited``) stays as it is."""
    if view.status is not None and view.source is not CalibrationSource.COMPUTED:
        return False
    if view.status is not CalibrationStatus.CALIBRATED or view.camera is None:
        return True
    return line_classes(view.lines) < MIN_LINE_CLASSES or PLAYERS_FLAG in view.flags


def is_anchor(view: PlacementView) -> bool:
    """Whether ``view``'s camera tells where its players stand: calibrated from its lines (not by the players),
    admitted, with at least :data:`MIN_LINE_CLASSES` line classes, and not flagged mirrored (a mirrored view's camera
    stands where its mirrored labels put it, and its players on the other side of the pitch)."""
    return (view.status is CalibrationStatus.CALIBRATED and view.camera is not None
            and PLAYERS_FLAG not in view.flags and MIRROR_FLAG not in view.flags
            and line_classes(view.lines) >= MIN_LINE_CLASSES and view.admitted)


def systems_with_mirrored_anchors(systems: Iterable[System], settings: Settings) -> list[System]:
    """The systems of ``systems`` (of a kind with a game rig) with a weak view (:func:`is_weak`) and a view that would
    anchor it (:func:`is_anchor`) but for its mirror flag: their weak views were placed with that view's players
    before its flag was set (an import's placement precedes the recomputation's mirror verdicts), and are placed again
    without them (:func:`place_cameras_by_players`). Reads the systems' stored rows."""
    from app.services.calibration.rigs import uses_rig

    out = []
    for s in systems:
        if not uses_rig(s):
            continue
        views = [view_of_frame(f, settings, ()) for f in s.frames]
        if any(is_weak(v) for v in views) and any(
                MIRROR_FLAG in v.flags and is_anchor(v._replace(flags=tuple(x for x in v.flags if x != MIRROR_FLAG)))
                for v in views):
            out.append(s)
    return out


def rig_of_views(views: Iterable[PlacementView]) -> CameraRig:
    """The game's camera rig (``app.geometry.calibration.rig.estimate_rig``) from the calibrations of every view of
    the game, as ``rigs.game_rig`` makes it from the stored rows: admitted, neither rig- nor player-assisted."""
    from app.geometry.calibration.rig import estimate_rig

    rows = [(np.asarray(v.camera["position_meters"], float), v.main) for v in views
            if v.status is CalibrationStatus.CALIBRATED and v.camera is not None and RIG_FLAG not in v.flags
            and PLAYERS_FLAG not in v.flags and v.admitted]
    return estimate_rig(np.array([c for c, _ in rows]).reshape(-1, 3), main_camera=[m for _, m in rows])


def players_json(fit: PlayerFit, rig: CameraRig) -> dict[str, Any]:
    """What ``Calibration.players`` keeps of an accepted fit: ``feet`` (``class``, ``id``, ``px`` [x, y], ``grass_m``
    [x, y], ``point``: ``foot``, or ``head`` for a player whose feet the image cuts, fitted by its head point at ``px``)
    of every player used, ``rig`` (``index``, ``centre_m``, ``frames``) or None for a full pose, ``rms_px``,
    ``sigma_px`` (px@1920), ``players`` (their count), ``note`` (its words,
    ``app.services.wording.words.player_camera_sentence``)."""
    rig_part = None
    if fit.rig_index is not None:
        p = rig.positions[fit.rig_index]
        rig_part = {"index": fit.rig_index, "centre_m": [round(float(v), 3) for v in p.centre_m], "frames": p.frames}
    out: dict[str, Any] = {"feet": [{"class": k[0], "id": k[1], "px": [round(uv[0], 2), round(uv[1], 2)],
                     "grass_m": [round(g[0], 3), round(g[1], 3)], "point": "head" if k in fit.head_only else "foot"}
                    for k, uv, g in fit.players],
           "rig": rig_part, "rms_px": round(fit.rms_px, 3), "sigma_px": round(fit.sigma_px, 3),
           "players": len(fit.players)}
    if fit.lines_mirrored:
        out["lines_mirrored"] = {"line_px": round(max(fit.residuals_px.values()), 2)}
    out["note"] = player_camera_sentence(out)
    return json_safe(out)


def players_mirror_evidence(players: Mapping[str, Any] | None, camera: Mapping[str, Any] | None
                            ) -> dict[str, Any] | None:
    """The mirror evidence (``Calibration.mirror_evidence``, with its sentence) of a camera the players placed whose
    view's lines fit it only mirrored (``players``: its ``Calibration.players``, :func:`players_json`; ``camera``: its
    SoccerNet JSON), or None when they fit it as labelled. The verdict is mirrored; the players' camera, which the
    labels' naming does not move, is given as ``refit`` (source ``players``): the mirror fix leaves it where it is
    and the labels, mirrored, meet it."""
    got = (players or {}).get("lines_mirrored")
    if not got or camera is None:
        return None
    c = [round(float(x), 2) for x in camera["position_meters"]]
    rig = (players or {}).get("rig") or {}
    evidence: dict[str, Any] = {
        "verdict": MIRROR_FLAG, "margin": None, "camera_y_m": c[1], "mirrored_camera_y_m": -c[1], "side_vote": 0,
        "rig_distance_m": None, "rig_distance_mirrored_m": None, "rig_vote": 0, "pairs": [],
        "refit": {"source": "players", "position_m": c, "players": (players or {}).get("players"),
                  "line_px": got.get("line_px"), "rig_centre_m": rig.get("centre_m")}}
    return json_safe(with_sentence(evidence, {}))


def fields_of_fit(fit: PlayerFit, view: PlacementView, rig: CameraRig, elapsed_ms: float) -> CalibrationFields:
    """The calibration stored for an accepted fit: the camera, JaC against the view's own lines (None without
    lines; the same for the lines and their mirror), per-class residuals, flags (``few_lines`` as a line fit flags
    it, ``player_assisted``, ``rig_assisted`` at a rig position, :data:`MIRROR_FLAG` when its lines fit it only
    mirrored, with :func:`players_mirror_evidence`), the fit's uncertainty and :func:`players_json`."""
    lines = {c: v for c, v in lines_from_json_lists(dict(view.lines)).items() if v}
    jac: tuple[float | None, float | None, float | None] = (None, None, None)
    if lines:
        values = frame_jac(fit.camera, lines, view.width, view.height)
        jac = tuple(values.get(f"{g:g}") for g in JAC_GAMMAS)  # type: ignore[assignment]  # three gammas
    flags = [*(["few_lines"] if len(lines) < MIN_LINE_CLASSES else []), PLAYERS_FLAG,
             *([RIG_FLAG] if fit.rig_index is not None else []), *([MIRROR_FLAG] if fit.lines_mirrored else [])]
    camera = json_safe(fit.camera.to_soccernet())
    players = players_json(fit, rig)
    return CalibrationFields(
        status=CalibrationStatus.CALIBRATED, camera=camera, jac=jac,
        residuals_px=json_safe(dict(fit.residuals_px)), flags=flags, reason=None, refusal=None,
        elapsed_ms=elapsed_ms, rms_px=fit.rms_px, uncertainty=fit.uncertainty.to_json(),
        mirror_evidence=players_mirror_evidence(players, camera), players=players)


def place_in_system(views: Sequence[PlacementView], rig: CameraRig, only: int | None = None
                    ) -> dict[int, CalibrationFields | PlayerRefusal]:
    """Fit each weak view of a system (:func:`is_weak`; ``only``: that view's index alone) to the players it shares
    with the system's anchors (:func:`is_anchor`), with the game's ``rig``; then each weak view left without any
    camera (:func:`_cameraless`) again, with the players the system's surer views place too (:func:`_chained`).
    Pure on plain values: the one placement, for stored frames and for an import's pool task alike.

    Returns:
        per weak view's index in ``views``, the calibration to store or why the players place none.
    """
    weak = [i for i, v in enumerate(views) if is_weak(v)]
    mine = [i for i in weak if only in (None, i)]
    if not mine:
        return {}
    anchors = [i for i, v in enumerate(views) if is_anchor(v)]
    feet = {i: feet_of(views[i].players, views[i].width, views[i].height) for i in range(len(views))}
    cameras = {i: Camera.from_soccernet(dict(views[i].camera or {})) for i in anchors}
    # A weak view is never an anchor (fewer line classes, or placed by the players): where the players stand is the
    # same for every weak view of the system, fused once.
    grass = players_on_grass([(cameras[a], feet[a]) for a in anchors])
    out = {i: _placed_one(views[i], rig, feet[i], grass) for i in mine} if anchors else {}
    left = [i for i in mine if not isinstance(out.get(i), CalibrationFields) and _cameraless(views[i])]
    if left:
        # The second round reads every weak view's first-round camera, also where only one view is placed.
        first = {**out, **{i: _placed_one(views[i], rig, feet[i], grass) for i in weak if i not in out and anchors}}
        out.update(_chained(views, rig, first, left, cameras, feet))
    return out


def _placed_one(view: PlacementView, rig: CameraRig, feet: Mapping[PlayerKey, np.ndarray],
                grass: Mapping[PlayerKey, GrassPlayer], settings: PlayerFitSettings | None = None,
                at_rig_only: bool = False) -> CalibrationFields | PlayerRefusal:
    """One weak ``view`` fitted to its players' ``feet`` (and head points) on ``grass``, with its lines, at the
    game's ``rig`` (``settings``: the fit's thresholds; ``at_rig_only``: a full pose is refused, ``players_misfit``):
    the calibration to store, or why not (:func:`_kept`)."""
    t0 = time.perf_counter()
    lines = lines_from_json_lists(dict(view.lines))
    got = fit_camera_to_players(feet, grass, {c: x for c, x in lines.items() if x}, view.width, view.height,
                                [p.centre_m for p in rig.positions], settings,
                                heads=feet_of(view.players, view.width, view.height, head_pixel))
    if not isinstance(got, PlayerFit):
        return got
    if at_rig_only and got.rig_index is None:
        return PlayerRefusal("players_misfit", {"players": len(got.players)})
    if MIRROR_FLAG in view.flags and PLAYERS_FLAG not in view.flags and not got.residuals_px:
        # Its lines flagged mirrored fit the players' camera neither as labelled nor mirrored: placed, the view
        # would lose the flag its lines earned, and the players cannot tell the reviewer which labelling is right.
        return PlayerRefusal("mirror_undecided", {"players": len(got.players)})
    return _kept(fields_of_fit(got, view, rig, (time.perf_counter() - t0) * 1e3), view, got.rig_index is not None,
                 feet, grass)


def _cameraless(view: PlacementView) -> bool:
    """Whether ``view`` has no camera but what the players give: no calibration from its lines (refused, none), or
    one the players placed before."""
    return view.status is not CalibrationStatus.CALIBRATED or view.camera is None or PLAYERS_FLAG in view.flags


#: The fewest players that place a view at the second round (:func:`_chained`), whose players may stand where views
#: less sure than the anchors put them. Chosen on the study sets (the four detector sets made with seed 73 and the
#: shared dev-large and seed-204): with 2 or 3, 2 of 28 views placed more than 20 px@1920 off the ball (one 52 px,
#: 3 players), with 4 one of 21 (22.5 px).
CHAINED_MIN_PLAYERS = 4


def _helpers(views: Sequence[PlacementView], first: Mapping[int, CalibrationFields | PlayerRefusal],
             cameras: Mapping[int, Camera]) -> dict[int, Camera]:
    """The views of a system whose cameras, besides the anchors' (``cameras``), tell where more players stand: a
    view the players placed at a rig position in the first round (``first``; not flagged mirrored), and a view of
    :data:`MIN_LINE_CLASSES` - 1 classes whose lines' camera is admitted (as :func:`is_anchor` asks otherwise) and
    that the first round left as it was."""
    out: dict[int, Camera] = {}
    for i, v in enumerate(views):
        got = first.get(i)
        if i in cameras:
            continue
        if isinstance(got, CalibrationFields):
            if RIG_FLAG in got.flags and MIRROR_FLAG not in got.flags and got.camera is not None:
                out[i] = Camera.from_soccernet(dict(got.camera))
        elif (line_classes(v.lines) == MIN_LINE_CLASSES - 1 and v.status is CalibrationStatus.CALIBRATED
              and v.camera is not None and v.admitted and PLAYERS_FLAG not in v.flags and MIRROR_FLAG not in v.flags):
            out[i] = Camera.from_soccernet(dict(v.camera or {}))
    return out


def _chained(views: Sequence[PlacementView], rig: CameraRig, first: Mapping[int, CalibrationFields | PlayerRefusal],
             left: Sequence[int], cameras: Mapping[int, Camera], feet: Mapping[int, Mapping[PlayerKey, np.ndarray]]
             ) -> dict[int, CalibrationFields | PlayerRefusal]:
    """The second round: each weak view of ``left`` (no camera after the first round, :func:`_cameraless`) fitted
    again at a rig position only, with at least :data:`CHAINED_MIN_PLAYERS` players, to more players than the
    anchors' feet place: those the anchors (``cameras``) see only by their heads
    (``grass.players_on_grass_by_heads``), then those the helper views (:func:`_helpers`) see by their feet where
    neither placed them. A view without a camera can take no part in the ball's votes; the stricter fit keeps a
    wrong camera rarer than a missing one. Returns the accepted fits (calibrations to store) by index."""
    helpers = _helpers(views, first, cameras)
    grass = dict(players_on_grass([(cameras[a], feet[a]) for a in cameras]))
    heads = [(cameras[a], {k: uv for k, uv in feet_of(views[a].players, views[a].width, views[a].height,
                                                        head_pixel).items() if k not in feet[a]}) for a in cameras]
    for source in (players_on_grass_by_heads(heads), players_on_grass([(helpers[h], feet[h]) for h in helpers])):
        for k, g in source.items():
            grass.setdefault(k, g)
    s = PlayerFitSettings(min_players_rig=CHAINED_MIN_PLAYERS)
    out: dict[int, CalibrationFields | PlayerRefusal] = {}
    for i in left:
        got = _placed_one(views[i], rig, feet[i], grass, s, at_rig_only=True)
        if isinstance(got, CalibrationFields):
            out[i] = got
    return out


def _kept(fields: CalibrationFields, view: PlacementView, at_rig: bool, feet: Mapping[PlayerKey, np.ndarray],
          grass: Mapping[PlayerKey, GrassPlayer]) -> CalibrationFields | PlayerRefusal:
    """``fields`` of a player fit as :func:`_kept_admitted` keeps or refuses them, except that a fit at a rig position
    (``at_rig``) replaces an admitted camera from the view's lines that the players tell wrong
    (:func:`_lines_contradicted`): then the view leaves the triangulation with a right camera rather than join it
    with a wrong one. The players' disagreement is measured only when the admission rule refuses."""
    kept = _kept_admitted(fields, view)
    if isinstance(kept, PlayerRefusal) and at_rig and _lines_contradicted(view, feet, grass):
        return fields
    return kept


def _lines_contradicted(view: PlacementView, feet: Mapping[PlayerKey, np.ndarray],
                        grass: Mapping[PlayerKey, GrassPlayer]) -> bool:
    """Whether ``view``'s admitted camera from its own lines puts the players it shares with the well-lined views
    farther from where those views put them than :data:`LINES_CONTRADICTED_SIGMA` (median, in their standard
    deviations, ``players.players_disagreement``): its few lines are wrong, whatever their JaC."""
    if not view.admitted or view.camera is None:
        return False
    got = players_disagreement(Camera.from_soccernet(dict(view.camera)), feet, grass, view.width, view.height)
    return got is not None and got > LINES_CONTRADICTED_SIGMA


def _kept_admitted(fields: CalibrationFields, view: PlacementView) -> CalibrationFields | PlayerRefusal:
    """``fields`` of a player fit, or a refusal (``lines_admitted``) where the view's lines already give a camera that
    clears admission and the fit's camera does not: a placement never takes a view out of the triangulation its
    lines let it join (the players' fit also weighs head points and foot points the lines do not see), unless the
    players tell those lines wrong (:func:`_kept`)."""
    gamma, minimum = view.admission
    if view.admitted and not jac_admitted(fields.jac[JAC_GAMMAS.index(gamma)], minimum):
        return PlayerRefusal("lines_admitted", {"jac": fields.jac[JAC_GAMMAS.index(gamma)] or 0.0,
                                                "admit_jac_min": minimum})
    return fields


def place_in_game(game: Sequence[Sequence[PlacementView]], placed: Sequence[bool] | None = None
                  ) -> list[dict[int, CalibrationFields | PlayerRefusal]]:
    """:func:`place_in_system` for each system of a game (its views, every system of the game), the rig made from
    every view of the game (:func:`rig_of_views`) when a system to place has a weak view. ``placed``: per system,
    whether to place it (None: all). Pure. Returns per system what :func:`place_in_system` gives ({} unplaced)."""
    mine = [placed is None or placed[k] for k in range(len(game))]
    if not any(m and any(is_weak(v) for v in views) for m, views in zip(mine, game, strict=True)):
        return [{} for _ in game]
    rig = rig_of_views([v for views in game for v in views])
    return [place_in_system(views, rig) if m else {} for m, views in zip(mine, game, strict=True)]


def place_by_players(system: System, settings: Settings, rig: CameraRig,
                     players: Mapping[int, Sequence[PlayerRow]] | None = None
                     ) -> dict[int, CalibrationFields | PlayerRefusal]:
    """:func:`place_in_system` on a system's loaded rows. Writes nothing.

    Args:
        players: per frame (by ``id(frame)``), its player boxes when the caller has them (an import's records);
            otherwise read from ``Frame.players``.

    Returns:
        per weak view's ``id(frame)``, the calibration to store or why the players place none.
    """
    frames = list(system.frames)
    got = place_in_system([view_of_frame(f, settings, (players or {}).get(id(f))) for f in frames], rig)
    return {id(frames[i]): v for i, v in got.items()}


def place_frame_by_players(session: Session, frame: Frame, settings: Settings,
                           rig: Sequence[tuple[int, np.ndarray, bool]] | None = None) -> bool:
    """Place one stored ``frame`` by its players (:func:`place_in_system` on its system's stored views, the game's
    rig from its stored calibrations, ``rigs.game_rig``; ``rig``: the game's rig rows when the caller has read them)
    and store the camera when they place it: what the import would do with its calibration as it is now (an edit
    recalibrated it from its lines). Returns whether the players placed it; writes nothing otherwise."""
    from app.services.calibration.rigs import game_rig, uses_rig

    system = frame.system
    if not uses_rig(system) or system.game_id is None:
        return False
    frames = list(system.frames)
    me = next(i for i, f in enumerate(frames) if f is frame)
    views = [view_of_frame(f, settings) for f in frames]
    if not is_weak(views[me]):
        return False
    got = place_in_system(views, game_rig(session, system.game_id, settings, stored=rig), only=me).get(me)
    if not isinstance(got, CalibrationFields):
        return False
    apply_calibration(frame, got, CalibrationSource.COMPUTED)
    return True


def apply_placed(frames: Sequence[Frame], placed: Mapping[int, CalibrationFields | PlayerRefusal],
                 relined: Any = None) -> int:
    """Store what the players placed (by index in ``frames``): each accepted fit becomes the view's calibration
    (source "computed"); a view the players placed before and place no more gets its calibration from lines again
    (``relined(frame)``: the :class:`CalibrationFields` of its lines, given by the caller; left as it is without
    one). Returns how many views the players placed."""
    n = 0
    for i, f in enumerate(frames):
        got = placed.get(i)
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
    """:func:`place_in_game` on ``systems`` of a kind with a game rig (``rigs.uses_rig``), the rig of each game made
    from its frames' calibrations in memory, stored (:func:`apply_placed`). Returns how many views the players
    placed."""
    from app.services.calibration.rigs import uses_rig

    games: dict[int, list[System]] = {}
    for s in systems:
        if uses_rig(s):
            games.setdefault(id(s.game), []).append(s)
    n = 0
    for group in games.values():
        if not any(is_weak(view_of_frame(f, settings, ())) for s in group for f in s.frames):
            continue
        everyone = list(group[0].game.systems)
        wanted = {id(s) for s in group}
        # The players of the views the fits read (weak views and anchors of the systems placed), no other's:
        # a stored frame's boxes are one query each.
        views = [[view_of_frame(f, settings, ()) for f in s.frames] for s in everyone]
        for s, row in zip(everyone, views, strict=True):
            for k, (f, v) in enumerate(zip(s.frames, row, strict=True)):
                if id(s) in wanted and (is_weak(v) or is_anchor(v)):
                    got = (players or {}).get(id(f))
                    row[k] = v._replace(players=frame_players(f) if got is None else got)
        placed = place_in_game(views, [id(s) in wanted for s in everyone])
        for s, fits in zip(everyone, placed, strict=True):
            n += apply_placed(list(s.frames), fits, relined)
    return n


def store_players(session: Session, frames: list[tuple[Frame, tuple[PlayerRow, ...], bool]]) -> None:
    """Write the player boxes of ``frames`` (new frames, and stored ones whose boxes the file changed: their old rows
    replaced) in one statement each way, after a flush gives the new frames their ids. The rows go through the
    connection (a Core ``INSERT`` of the table), not the ORM's bulk insert: the same rows in the same order, at half
    its CPU (an import writes a dozen boxes a frame)."""
    if not frames:
        return
    session.flush()
    stored = [f.id for f, _, was_stored in frames if was_stored]
    if stored:
        session.execute(sa.delete(PlayerBox).where(PlayerBox.frame_id.in_(stored)))
    rows = [{"frame_id": frame_id, "cls": cls, "ident": ident, "x1": b[0], "y1": b[1], "x2": b[2], "y2": b[3]}
            for frame_id, players in [(f.id, players) for f, players, _ in frames] for cls, ident, b in players]
    if rows:
        session.connection().execute(sa.insert(cast(sa.Table, PlayerBox.__table__)), rows)
    for f, _, _ in frames:  # written past the ORM: read again when next asked for
        session.expire(f, ["players"])
    forget_view_players([f for f, _, _ in frames])
