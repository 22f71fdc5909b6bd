"""Players place the cameras the lines cannot: a camera fitted to the foot points of the players its view shares
with the well-calibrated views of its system, at a position of the game's camera rig where one fits.

SoccerNet-v3 annotates the players of a multi-view system with a class and an ID across its views (one instant
seen by several cameras). A player stands on the grass: the bottom centre of its box (the foot point) back-projected
to the ground plane ``z = 0`` in a calibrated view is where it stands (:func:`grass_point`); fused over the
well-calibrated views that see it (:func:`players_on_grass`, the median, a player whose views disagree by more
than ``max_spread_m`` left out: a wrong ID). A view whose lines give no camera, or an unsure one, is then fitted to
its own foot points of those players (:func:`fit_camera_to_players`, robust least squares, soft-L1 loss): with its
centre at one of the game's rig positions (broadcast cameras stay put during a game) only rotation and focal length
are unknown, which two foot points fix and more over-determine; every position is tried and the best by residual
kept only with a margin over any other position elsewhere; without a position that fits, a full pose (7 unknowns)
when enough players are seen. The top of each whole box (the head point, :func:`~.grass.head_world`: a standing
player's height above where it stands) joins the fit too: players standing close together fix the camera's direction
but leave its zoom loose, which their boxes' heights in the image pin. Whatever field lines the view has join the same
least squares with their own residuals (:func:`app.geometry.calibration.residuals.residuals`). The ball is never an
input. The least squares itself (the rows, each point's whitening, the compiled robust fit) is
:class:`~.player_problem.PlayerProblem`'s; this module chooses the starts, the rig position and what is accepted.

The camera carries its uncertainty from the fit (:func:`~.uncertainty.uncertainty_from_jacobian`: the
Gauss-Newton covariance of the parameters from the Jacobian of every residual, Hartley and Zisserman result 5.11),
the same :class:`~.uncertainty.CalibrationUncertainty` a line fit carries. The fit is refused (:class:`PlayerRefusal`)
when too few players are matched, their foot points lie on one image line, the residuals are large, a second rig
position fits nearly as well, or the propagated pixel uncertainty is large: a wrong camera is worse than none.

World frame: SoccerNet (metres, origin at the centre spot, z down); image: continuous pixels of the view, origin at
the top-left corner, principal point ``((W - 1) / 2, (H - 1) / 2)`` (:func:`~.result.principal_point`).
"""
from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field
from typing import Mapping, Sequence

import cv2
import numpy as np

from app.geometry.annotations import FieldLines, image_diagonal, mirror_lines
from app.geometry.calibration.grass import GrassPlayer, PlayerKey, foot_world, head_world
from app.geometry.calibration.initialisation import camera_from_homography, wahba_rotations
from app.geometry.calibration.pair_players import camera_arrays, pair_figures
from app.geometry.calibration.player_problem import PlayerProblem, projection_sigma_px
from app.geometry.calibration.residuals import CameraParametrisation
from app.geometry.calibration.result import principal_point
from app.geometry.calibration.uncertainty import (
    CalibrationUncertainty,
    line_noise,
    parameter_covariance,
    uncertainty_from_jacobian,
)
from app.geometry.camera import Camera
from app.geometry.pair_error import REFERENCE_WIDTH_PX
from app.geometry.pitch import MIN_LINE_CLASSES, MIRROR_CLASSES


@dataclass(frozen=True)
class PlayerFitSettings:
    """Thresholds of :func:`fit_camera_to_players`; pixels at a 1920-px-wide image (scaled to the view's width).

    Attributes:
        min_players_rig: fewest players matched for a fit at a rig position (4 unknowns; two players fix them).
        min_players_free: fewest players for a full pose (7 unknowns) without a rig position that fits.
        loss_scale: soft-L1 loss scale of a foot point's residual, in its standard deviations (each foot point's
            residual is whitened by what its own box and where the other views put the player allow,
            :func:`players_on_grass`).
        max_rms: largest RMS whitened residual of the inlying foot points of an accepted fit.
        inlier_sigma: a foot point farther than this many standard deviations from its player's projection is an
            outlier.
        min_inlier_share: smallest share of the matched players that must be inliers.
        rig_margin: a rig position is chosen only when every other position more than ``rig_same_m`` away fits
            with a robust cost at least this many times the best's.
        rig_same_m: positions closer than this (m) count as the same place.
        rig_refined: the rig positions whose starts come closest that are refined (the others cannot win).
        max_sigma_px: largest pixel uncertainty (px@1920) accepted of a point where the play is (the players'
            centre on the grass and 3 m up, :func:`projection_sigma_px`), the players' own uncertainty included.
        min_spread_px: the points the fit reads (foot and head points) must spread at least this far (px@1920, the
            smaller singular value of their centred pixels over sqrt(n)) off one image line: players standing in
            a row have their feet on one line, but their heads stand above it.
        line_limit_gamma: every fitted line class within this fraction of the image diagonal of its model
            element (as a line fit's ``refuse_gamma``).
        border_px: a box reaching within this many pixels of the image's bottom edge is cut: no foot point.
    """

    min_players_rig: int = 3
    min_players_free: int = 6
    loss_scale: float = 2.0
    max_rms: float = 2.5
    inlier_sigma: float = 4.0
    min_inlier_share: float = 0.7
    rig_margin: float = 3.0
    rig_refined: int = 3
    rig_same_m: float = 5.0
    max_sigma_px: float = 10.0
    min_spread_px: float = 4.0
    line_limit_gamma: float = 0.03
    border_px: float = 2.0


@dataclass(frozen=True)
class PlayerFit:
    """An accepted camera from players.

    Attributes:
        camera: the camera (pixels of the view, SoccerNet world).
        uncertainty: std of its parameters from the fit (a rig position's centre: position std 0).
        rig_index: the index of the rig position its centre is fixed at (``None``: a full pose).
        players: ``(key, foot pixel (2,), grass point (2,) m)`` of every player the fit used (inliers).
        rms_px: RMS residual of those foot points (px of the view).
        residuals_px: per fitted line class (as labelled), its largest point distance (px of the view).
        line_rms_px: RMS of the line residuals (px), None without lines.
        sigma_px: the largest pixel uncertainty (px@1920) of a point where the players stand, on the grass or 3 m
            up (:func:`projection_sigma_px`).
        lines_mirrored: the view's lines were fitted mirrored (:func:`~app.geometry.annotations.mirror_lines`): as
            labelled they cannot be fitted with the players, mirrored they fit the players' camera at a rig
            position, so the labels are probably mirrored (``residuals_px`` then holds each labelled class's
            distance to its mirror class's model element).
        head_only: the players of ``players`` whose box the image cuts at the feet: the pixel given for them is their
            head point (the top centre of the box), the only point of theirs the fit read.
    """

    camera: Camera
    uncertainty: CalibrationUncertainty
    rig_index: int | None
    players: tuple[tuple[PlayerKey, tuple[float, float], tuple[float, float]], ...]
    rms_px: float
    residuals_px: Mapping[str, float] = field(default_factory=dict)
    line_rms_px: float | None = None
    sigma_px: float = 0.0
    lines_mirrored: bool = False
    head_only: frozenset[PlayerKey] = frozenset()


#: Why :func:`fit_camera_to_players` refused: too few players matched, their foot points on one image line, no
#: fit within the residual limits, two rig positions fitting alike, a camera too unsure; and why the placement
#: (``app.services.calibration.players``) kept a view's lines: they were admitted, or flagged mirrored while the
#: players' camera fits them neither as labelled nor mirrored.
PLAYER_REFUSALS: tuple[str, ...] = ("few_players", "collinear_players", "players_misfit", "rig_ambiguous",
                                    "camera_unsure", "lines_admitted", "mirror_undecided")


@dataclass(frozen=True)
class PlayerRefusal:
    """Why :func:`fit_camera_to_players` gave no camera: ``code`` (one of :data:`PLAYER_REFUSALS`), its numbers."""

    code: str
    numbers: Mapping[str, float] = field(default_factory=dict)


def row_medians(d: np.ndarray) -> np.ndarray:
    """``np.median(d, axis=1)`` of a 2-D array, the same numbers to the bit (the middle value of each sorted row, or
    the mean of the middle two), without its general machinery: a placement takes thousands of these medians of a
    few dozen numbers. A row holding NaN is left to ``np.median``.

    >>> d = np.array([[3.0, 1.0, 2.0, 10.0], [0.5, np.nan, 1.0, 2.0]])
    >>> row_medians(d).tolist(), row_medians(d[:, :3]).tolist()
    ([2.5, nan], [2.0, nan])
    """
    if np.isnan(d).any():
        return np.asarray(np.median(d, axis=1))
    s, k = np.sort(d, axis=1), d.shape[1] // 2
    return s[:, k] if d.shape[1] % 2 else (s[:, k - 1] + s[:, k]) / 2


#: The focal lengths a rig position's starts try, per px of image width.
_START_FOCALS = np.geomspace(0.4, 12.0, 20)


def _rig_starts(problem: PlayerProblem, centre: np.ndarray
                ) -> tuple[float, list[tuple[CameraParametrisation, np.ndarray]]]:
    """Starting rotations and focal lengths at a fixed ``centre``: for a series of focal lengths, the Wahba rotation
    of the foot points' image rays onto their world directions; the two with the smallest median reprojection error
    (px), and that error."""
    alone = problem.head_alone()
    world = np.vstack([foot_world(problem.feet_m[:, :2], centre),
                       head_world(problem.world[problem.head_of[alone], :2], centre)])
    seen = np.vstack([problem.uv, problem.uv_head[alone]])
    world_dirs = world - centre
    world_dirs /= np.linalg.norm(world_dirs, axis=1, keepdims=True)
    focals = _START_FOCALS * problem.width
    # Every focal length at once (the rays, the small SVDs in one compiled call, the projections, the medians).
    cam = np.concatenate([(seen - problem.pp)[None] / focals[:, None, None],
                          np.ones((len(focals), len(seen), 1))], axis=2)
    cam /= np.linalg.norm(cam, axis=2, keepdims=True)
    Rs = wahba_rotations(cam, world_dirs)
    Xc = np.einsum("fij,nj->fni", Rs, world - centre)
    z = Xc[..., 2]
    bad = z <= 1e-6
    uv = focals[:, None, None] * Xc[..., :2] / np.where(bad, 1.0, z)[..., None] + problem.pp
    uv[bad] = 1e6
    errors = row_medians(np.linalg.norm(uv - seen, axis=2))
    order = np.argsort(errors, kind="stable")
    out = []
    for j in order[:2]:
        param = CameraParametrisation(principal_point=problem.pp, R0=Rs[j], fixed_centre=np.asarray(centre, float))
        out.append((param, param.vector(float(focals[j]), centre)))
    return float(errors[order[0]]), out


def _free_start(problem: PlayerProblem) -> tuple[CameraParametrisation, np.ndarray] | None:
    """A full pose from the ground homography of the foot points (Zhang's constraints,
    :func:`~.initialisation.camera_from_homography`), None when it gives none."""
    if len(problem.uv) < 4:
        return None
    H, _ = cv2.findHomography(problem.feet_m[:, :2], problem.uv, 0)
    if H is None or not np.all(np.isfinite(H)):
        return None
    got = camera_from_homography(np.asarray(H, float), problem.pp)
    if got is None:
        return None
    f, R, C = got
    param = CameraParametrisation(principal_point=problem.pp, R0=R)
    return param, param.vector(f, C)


@dataclass
class _Candidate:
    param: CameraParametrisation
    x: np.ndarray
    cost: float
    rig_index: int | None


def _best(problem: PlayerProblem, starts: list[tuple[CameraParametrisation, np.ndarray]], loss: float,
          rig_index: int | None) -> _Candidate | None:
    """The best of the robust fits from ``starts``: each fitted with the foot points whitened at its start, then
    again whitened at its solution (the whitening depends on the camera)."""
    best = None
    for param, x0 in starts:
        try:
            problem.rewhiten(x0, param)
            x, cost = problem.fit(param, x0, loss)
            problem.rewhiten(x, param)
            x, cost = problem.fit(param, x, loss)
        except (ValueError, np.linalg.LinAlgError, FloatingPointError):
            continue
        if not np.all(np.isfinite(x)) or x[0] <= 0:
            continue
        if best is None or cost < best.cost:
            best = _Candidate(param, x, cost, rig_index)
    return best


def _at_rig(problem: PlayerProblem, fits: list[_Candidate], rig_centres: Sequence[Sequence[float]],
            s: PlayerFitSettings) -> _Candidate | PlayerRefusal:
    """The best rig fit (``fits``, lowest cost first, :func:`_rig_fits`) when it passes :func:`_judge` and every
    position elsewhere (beyond ``rig_same_m``) costs at least ``rig_margin`` times as much; else why not."""
    best = fits[0]
    verdict = _judge(problem, best, s)
    if isinstance(verdict, PlayerRefusal):
        return verdict
    centres = {c.rig_index: np.asarray(rig_centres[c.rig_index or 0], dtype=np.float64) for c in fits}
    here = centres[best.rig_index]
    rivals = [c for c in fits[1:] if float(np.linalg.norm(centres[c.rig_index] - here)) > s.rig_same_m]
    if rivals and rivals[0].cost < s.rig_margin * best.cost:
        return PlayerRefusal("rig_ambiguous", {"cost": best.cost, "second_cost": rivals[0].cost})
    return best


def _free_pose(problem: PlayerProblem, fits: list[_Candidate], s: PlayerFitSettings
               ) -> _Candidate | PlayerRefusal | None:
    """A full pose (7 unknowns): the best robust fit from the ground homography's start (:func:`_free_start`) and from
    the two best rig fits with their centre freed (a camera near, not at, a rig position), if it passes
    :func:`_judge` (else why not); None without a start or a fit."""
    free_starts = [start] if (start := _free_start(problem)) is not None else []
    for fitted in fits[:2]:
        f, R, C, _ = fitted.param.split(fitted.x)
        free = CameraParametrisation(principal_point=problem.pp, R0=np.asarray(R))
        free_starts.append((free, free.vector(float(f), np.asarray(C, float))))
    cand = _best(problem, free_starts, s.loss_scale, None) if free_starts else None
    if cand is None:
        return None
    verdict = _judge(problem, cand, s)
    return verdict if isinstance(verdict, PlayerRefusal) else cand


def fit_camera_to_players(feet: Mapping[PlayerKey, np.ndarray], grass: Mapping[PlayerKey, GrassPlayer],
                          lines: FieldLines, width: int, height: int, rig_centres: Sequence[Sequence[float]] = (),
                          settings: PlayerFitSettings | None = None,
                          heads: Mapping[PlayerKey, np.ndarray] | None = None, *,
                          lines_retried: bool = False) -> PlayerFit | PlayerRefusal:
    """Fit a view's camera to its players' foot points (and its field lines), at a rig position where one fits.

    Where the lines and the players cannot be fitted together (``players_misfit``), the lines are tried mirrored
    first (the pitch's 180-degree ambiguity, method.md section 3, is how an annotator's few lines most often go
    wrong): a fit of the players with the mirrored lines at a rig position is returned with ``lines_mirrored``
    set, which keeps the view's labels flagged mirrored and its one-key fix meaningful; else, for a view of 1 to 3
    line classes, the players alone at a rig position (the lines left out, ``residuals_px`` empty).

    Args:
        feet: the view's players: key -> foot pixel (2,) px (:func:`foot_pixel`). Never the ball.
        grass: where the players stand (:func:`players_on_grass`, from the other, well-calibrated views).
        lines: the view's field lines (:data:`~app.geometry.annotations.FieldLines`, px; may be empty): their
            residuals join the fit's.
        width, height: the image size, px.
        rig_centres: the game's camera positions, (3,) metres each (world, z down), most supported first.
        settings: :class:`PlayerFitSettings`; defaults when None.
        heads: the view's players' head points (key -> the box's top centre (2,) px, :func:`~.grass.head_pixel`),
            None for none: each joins the fit as the point :data:`~.grass.HEAD_HEIGHT_M` above its player
            (:func:`~.grass.head_world`), whitened by the height's spread too; a box's height in the image is the
            player's distance, which the foot points of players standing close together leave loose.
        lines_retried: this call is the retry of another's lines (mirrored or left out): it retries nothing.

    Returns:
        :class:`PlayerFit`, or :class:`PlayerRefusal` with its code and numbers.
    """
    s = settings or PlayerFitSettings()
    heads = heads or {}
    footed = [k for k in feet if k in grass]
    # A player whose feet the image's bottom edge cuts is still seen: its head point alone places it.
    keys = footed + [k for k in heads if k in grass and k not in feet]
    if len(keys) < s.min_players_rig:
        return PlayerRefusal("few_players", {"players": len(keys), "need": s.min_players_rig})
    scale = width / REFERENCE_WIDTH_PX
    uv = np.array([np.asarray(feet[k], float) for k in footed]).reshape(-1, 2)
    world = np.array([[grass[k].point_m[0], grass[k].point_m[1], 0.0] for k in keys])
    head_of = np.array([i for i, k in enumerate(keys) if k in heads], dtype=int)
    uv_head = np.array([np.asarray(heads[keys[i]], float) for i in head_of]).reshape(-1, 2)
    seen = np.vstack([uv, uv_head])  # every point the fit reads: the feet and the heads
    spread = float(np.linalg.svd(seen - seen.mean(axis=0), compute_uv=False)[-1]) / math.sqrt(len(seen))
    if spread < s.min_spread_px * scale:
        return PlayerRefusal("collinear_players", {"spread_px": spread, "limit_px": s.min_spread_px * scale})
    problem = PlayerProblem(uv=uv, world=world, lines=dict(lines), pp=principal_point(width, height), width=width,
                            height=height, scale=scale, cov_g=np.array([grass[k].cov_m2 for k in keys], float),
                            uv_head=uv_head, head_of=head_of, foot_of=np.arange(len(footed)))
    fits = _rig_fits(problem, rig_centres, s)
    at_rig = _at_rig(problem, fits, rig_centres, s) if fits else None
    chosen = at_rig if isinstance(at_rig, _Candidate) else None
    refusal = at_rig if isinstance(at_rig, PlayerRefusal) else None
    if chosen is None and len(keys) >= s.min_players_free:
        free = _free_pose(problem, fits, s)
        if isinstance(free, _Candidate):
            chosen, refusal = free, None
        elif free is not None:
            refusal = refusal or free
    if chosen is None:
        refusal = refusal or PlayerRefusal("players_misfit" if fits else "few_players",
                                           {"players": len(keys), "need": s.min_players_free})
        if lines_retried or refusal.code != "players_misfit":
            return refusal
        return _lines_retried(feet, grass, lines, width, height, rig_centres,
                              dataclasses.replace(s, min_players_free=len(keys) + 1), heads) or refusal
    return _accepted(problem, chosen, keys, s)


def _lines_retried(feet: Mapping[PlayerKey, np.ndarray], grass: Mapping[PlayerKey, GrassPlayer], lines: FieldLines,
                   width: int, height: int, rig_centres: Sequence[Sequence[float]], at_rig_only: PlayerFitSettings,
                   heads: Mapping[PlayerKey, np.ndarray]) -> PlayerFit | None:
    """Where a view's lines and its players cannot be fitted together (:func:`fit_camera_to_players`' arguments): the
    lines may be wrong, which the players and the game's rig, two sources the view's labels do not touch, can tell;
    only at a rig position (``at_rig_only``: the retries fit no full pose, it would be dropped). The fit with the lines
    mirrored (the labels are mirrored; ``lines_mirrored``, residuals named as labelled), else, for a view with at most
    3 classes, the players' camera without its lines (a mislabelled class; a view with more classes keeps its refusal:
    its lines alone say whether they are otherwise wrong); None when neither fits."""
    if any(MIRROR_CLASSES[c] != c for c in lines):
        # Mirrored, they fit: the labels are mirrored, and the camera meets them as the mirror fix makes them.
        flipped = fit_camera_to_players(feet, grass, mirror_lines(lines), width, height, rig_centres, at_rig_only,
                                        heads, lines_retried=True)
        if isinstance(flipped, PlayerFit) and flipped.rig_index is not None and flipped.residuals_px:
            return dataclasses.replace(flipped, lines_mirrored=True, residuals_px={
                MIRROR_CLASSES[c]: v for c, v in flipped.residuals_px.items()})
    if 0 < len(lines) < MIN_LINE_CLASSES:
        alone = fit_camera_to_players(feet, grass, {}, width, height, rig_centres, at_rig_only, heads,
                                      lines_retried=True)
        if isinstance(alone, PlayerFit) and alone.rig_index is not None:
            return alone
    return None


#: Where the players tell a view's own lines wrong: the median, over the players it shares with the well-lined views,
#: of each foot point's distance from where those views put the player, in its standard deviations
#: (:func:`players_disagreement`). Chosen on ``soccernet-v3-dev-large`` and ``seed-202``: admitted lines cameras that
#: place the ball right disagree with their players by at most 10.2 sigma; the wrong ones (50-1,400 px@1920 off the
#: ball) by 15-120.
LINES_CONTRADICTED_SIGMA = 15.0


def players_disagreement(camera: Camera, feet: Mapping[PlayerKey, np.ndarray], grass: Mapping[PlayerKey, GrassPlayer],
                         width: int, height: int, min_players: int = 3) -> float | None:
    """How far a view's ``camera`` puts its players from where the well-calibrated views put them: the median, over
    the players with a foot point (``feet``, px) in ``grass`` (:func:`~.grass.players_on_grass`), of the foot point's
    distance from the projection of the player's :func:`~.grass.foot_world` point, in its standard deviations (its
    pixel noise and its grass point's covariance carried into the view, as the fit whitens it); the camera's lens
    distortion is left out. None with fewer than ``min_players`` such players."""
    keys = [k for k in feet if k in grass]
    if len(keys) < min_players:
        return None
    pp = np.array([camera.K[0, 2], camera.K[1, 2]])
    problem = PlayerProblem(uv=np.array([np.asarray(feet[k], float) for k in keys]),
                            world=np.array([[grass[k].point_m[0], grass[k].point_m[1], 0.0] for k in keys]), lines={},
                            pp=pp, width=width, height=height, scale=width / REFERENCE_WIDTH_PX,
                            cov_g=np.array([grass[k].cov_m2 for k in keys], float))
    param = CameraParametrisation(principal_point=pp, R0=np.asarray(camera.R, float), fixed_centre=camera.C)
    x = param.vector(float(camera.K[0, 0]), np.asarray(camera.C, float))
    problem.rewhiten(x, param)
    return float(np.median(problem.pixel_errors(x, param)[1]))


def pair_players_disagreement(camera_a: Camera, feet_a: Mapping[PlayerKey, np.ndarray], size_a: tuple[int, int],
                              camera_b: Camera, feet_b: Mapping[PlayerKey, np.ndarray], size_b: tuple[int, int],
                              min_players: int = 3) -> float | None:
    """How far two views' cameras disagree on the players both see: each view's :func:`players_disagreement` (the
    median foot-point distance, in standard deviations) against where the other view alone puts those players
    (:func:`~.grass.players_on_grass`), the larger of the two. Two right cameras of one instant agree within their
    foot points' noise; a mirrored or misplaced camera, or a replay of another instant, puts the shared players metres
    off (compare with :data:`LINES_CONTRADICTED_SIGMA`).

    Args:
        camera_a, camera_b: the two views' cameras (SoccerNet world, metres, z down).
        feet_a, feet_b: foot pixels (2,) by player (class, ID) of each view (px of its image,
            ``app.services.calibration.players.feet_of``).
        size_a, size_b: each view's image ``(width, height)``, px.
        min_players: players both views must share (with foot points) for a figure.

    Returns:
        The larger median disagreement of the two directions (standard deviations), or None when neither has
        ``min_players`` players to compare (too few to tell a camera wrong; a player the other camera puts off the
        pitch is not compared).
    """
    shared = [k for k in feet_a if k in feet_b]
    if len(shared) < min_players:
        return None
    uv_a = np.array([np.asarray(feet_a[k], float) for k in shared]).reshape(-1, 2)
    uv_b = np.array([np.asarray(feet_b[k], float) for k in shared]).reshape(-1, 2)
    # Both directions in one compiled call (pair_players.py): numpy's per-call cost on a few players was the time.
    figures = pair_figures(*camera_arrays(camera_a), float(size_a[0]), uv_a,
                           *camera_arrays(camera_b), float(size_b[0]), uv_b, min_players)
    worst = None
    for got in figures:
        if got != -1.0:  # -1: too few players to compare in that direction
            worst = float(got) if worst is None else max(worst, float(got))
    return worst


def _rig_fits(problem: PlayerProblem, rig_centres: Sequence[Sequence[float]], s: PlayerFitSettings) -> list[_Candidate]:
    """The view's camera fitted at the game's rig positions (m, world, z down), lowest cost first: every position's
    starts are cheap (a Wahba rotation per focal length); only the closest are refined (the best and its rivals)."""
    ranked = []
    for i, c in enumerate(rig_centres):
        centre = np.asarray(c, float)
        if centre.shape != (3,) or not np.all(np.isfinite(centre)) or centre[2] >= 0:
            continue
        error, starts = _rig_starts(problem, centre)
        ranked.append((error, i, starts))
    ranked.sort(key=lambda t: t[0])
    fits = []
    for k, (_, i, starts) in enumerate(ranked[:s.rig_refined]):
        cand = _best(problem, starts if k == 0 else starts[:1], s.loss_scale, i)
        if cand is not None:
            fits.append(cand)
    fits.sort(key=lambda c: c.cost)
    return fits

def _judge(problem: PlayerProblem, cand: _Candidate, s: PlayerFitSettings) -> PlayerRefusal | None:
    """Refuse a fit whose foot points or lines are far from it."""
    n = len(problem.world)
    problem.rewhiten(cand.x, cand.param)
    _, d = problem.player_errors(cand.x, cand.param)
    inl = d <= s.inlier_sigma
    if inl.sum() < max(s.min_players_rig, math.ceil(s.min_inlier_share * n)):
        return PlayerRefusal("players_misfit", {"inliers": int(inl.sum()), "players": n})
    rms = float(np.sqrt(np.mean(d[inl] ** 2)))
    if rms > s.max_rms:
        return PlayerRefusal("players_misfit", {"rms_sigma": rms, "limit": s.max_rms})
    if problem.obs is not None:
        camera = cand.param.camera(cand.x)
        limit = s.line_limit_gamma * image_diagonal(problem.width, problem.height)
        worst = _class_worst(camera, problem)
        if worst and max(worst.values()) > limit:
            return PlayerRefusal("players_misfit", {"line_px": max(worst.values()), "limit_px": limit})
    return None


def _class_worst(camera: Camera, problem: PlayerProblem) -> dict[str, float]:
    from app.geometry.calibration.starts import class_residuals  # the line fit's own per-class residuals

    assert problem.obs is not None
    per_class, _ = class_residuals(camera, problem.obs)
    return {c: float(v) for c, v in per_class.items()}


def _accepted(problem: PlayerProblem, cand: _Candidate, keys: list[PlayerKey], s: PlayerFitSettings
              ) -> PlayerFit | PlayerRefusal:
    """The fit's camera, its uncertainty from the Jacobian of every residual at the solution, and its checks."""
    n = len(problem.world)
    param, x = cand.param, cand.x
    # Re-centre the rotation vector at the solution (the uncertainty's angles are taken at w = 0).
    f, R, C, _ = param.split(x)
    param = CameraParametrisation(principal_point=problem.pp, R0=np.asarray(R), fixed_centre=param.fixed_centre)
    x = param.vector(float(f), np.asarray(C, float))
    problem.rewhiten(x, param)
    r0 = problem.rows(x, param)
    d_px, d = problem.player_errors(x, param)
    inl = d <= s.inlier_sigma
    n_feet = len(problem.uv)
    n_lines = len(r0) - 2 * n_feet - 2 * len(problem.head_of)  # the rows: feet, lines, heads
    keep = np.concatenate([np.repeat(inl[problem.foot_of], 2), np.ones(n_lines, dtype=bool),
                           np.repeat(inl[problem.head_of], 2)])
    J = problem.jacobian(x, param)[1][keep]
    sigma = line_noise(r0[keep], len(x))
    uncertainty = uncertainty_from_jacobian(param, J, sigma, int(keep.sum()))
    camera = param.camera(x)
    # How far the camera may put a ball where the players are (on the grass and 3 m up), from the full covariance
    # of the fit (the centre's terms included: a full pose trades its centre against its angles).
    cov, undetermined = parameter_covariance(J, sigma)
    if np.any(undetermined):
        return PlayerRefusal("camera_unsure", {"sigma_px": math.inf, "limit_px": s.max_sigma_px})
    here = problem.world[inl].mean(axis=0, keepdims=True)  # where the play is: the players' centre
    probe = np.vstack([here, here + [0.0, 0.0, -3.0]])
    sigma_px = projection_sigma_px(problem, param, x, cov, probe) / problem.scale
    if not sigma_px <= s.max_sigma_px:
        return PlayerRefusal("camera_unsure", {"sigma_px": sigma_px, "limit_px": s.max_sigma_px})
    line_rms = None
    residuals_px: dict[str, float] = {}
    if problem.obs is not None:
        residuals_px = _class_worst(camera, problem)
        lr = r0[2 * n_feet:2 * n_feet + n_lines] * problem.line_sigma
        line_rms = float(np.sqrt(np.mean(lr ** 2))) if len(lr) else None
    pixel = {int(i): problem.uv[k] for k, i in enumerate(problem.foot_of)}
    for k, i in enumerate(problem.head_of):
        pixel.setdefault(int(i), problem.uv_head[k])  # a player seen without its feet: its head point
    footed = {int(i) for i in problem.foot_of}
    used = tuple((keys[i], (float(pixel[i][0]), float(pixel[i][1])),
                  (float(problem.world[i, 0]), float(problem.world[i, 1]))) for i in range(n) if inl[i])
    return PlayerFit(camera=camera, uncertainty=uncertainty, rig_index=cand.rig_index, players=used,
                     rms_px=float(np.sqrt(np.mean(d_px[inl] ** 2))), residuals_px=residuals_px, line_rms_px=line_rms,
                     sigma_px=sigma_px, head_only=frozenset(keys[i] for i in range(n) if inl[i] and i not in footed))
