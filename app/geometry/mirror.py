"""Mirrored field-line labels: the mirrored camera and the evidence that a view's labels are mirrored.

The pitch is symmetric under the 180-degree rotation about the vertical axis through the centre
spot, ``M = diag(-1, -1, 1)`` (method.md section 3; :data:`app.geometry.pitch.MIRROR_CLASSES` is the
same rotation as a relabelling). Labels relabelled by it fit the camera ``C' = M C``, ``R' = R M``
exactly as well as the true labels fit the true camera ``(C, R)``, because ``R' (M X - C') = R (X - C)``:
the mirrored camera sees the rotated pitch exactly as the true camera sees the pitch. Residuals
and JaC therefore cannot tell mirrored labels; priors can (method.md section 3):

* **side** (:attr:`MirrorView.expected_side`): broadcast main cameras stand on the y > 0 side
  (1,594 of 1,603 real cameras in ``data/real``). A camera beyond the far side line votes
  "mirrored"; one beyond the near side line votes "as labelled"; in between, no vote.
* **rig** (``rig_positions``): a game's cameras stay where they are. A camera within
  ``rig_near_m`` of a known camera position of the game while its mirror image is more than
  ``rig_far_m`` from every position votes "as labelled"; the reverse votes "mirrored"; no vote
  otherwise (symmetric positions, such as cameras behind both goals, say nothing). The "mirrored"
  vote weighs less: a replay camera seen once, whose mirror image happens to be a known position,
  is common, so that vote alone never flags a view; it decides only where the rays leave a tie.
* **rays** (the other views of the system): a view's ball ray must meet the other views' rays.
  For a pair of views, the pair error ``e_ij`` (:func:`app.geometry.triangulation.triangulate_pair`,
  the triangulation's rule and tau) is computed with both cameras as calibrated ("same": both or
  neither mirrored, since mirroring both rotates the whole scene rigidly and leaves every error
  unchanged) and with one camera mirrored ("different"). The pair says *same* when only the first
  meets (``e < tau`` at a plausible ball position), *different* when only the second does, and
  nothing when both meet (a ball near the centre spot, which its mirror image nearly is, or a ball
  within ``min_axis_distance_m`` of the vertical axis there) or neither (a wrong ball label, a
  desynchronised replay, a poor calibration).

Rule (a small Bayesian vote; weights are log-odds, documented in :class:`MirrorSettings`): every
hypothesis ``h`` in {as labelled, mirrored}^n over the n views scores

    score(h) = sum_v h_v (side_v + rig_v - prior) + sum_pairs pair_weight * (+1 if h agrees with the
               pair's same/different, -1 if not),

where ``side_v``/``rig_v`` are +weight for a "mirrored" vote, -weight for an "as labelled" vote and
``prior`` is the log-odds against a view being mirrored (mirrors are rare). A view is flagged when its
max-marginal margin, the best score with it mirrored minus the best with it as labelled, is at
least ``decision_margin``; it is "as labelled" when the evidence alone (the margin without the
prior) favours the labels by that much, and "undecided" otherwise. Consequences, each a guard
against false flags:

* a single view reduces to the side prior (exactly ``calibrate_frame``'s camera-side flag) and the
  rig prior;
* ray agreement fixes only which views go together, never which group is mirrored (mirroring every
  view changes no error): with two views that disagree, mirroring either is equally good, so only
  the side or the rig prior can decide (an action camera beyond the near side line is presumed right)
  and otherwise nothing is flagged; with more views the smaller group is the mirrored one unless
  the priors say otherwise;
* other views that are themselves doubtful are not trusted blindly: all hypotheses are scored
  jointly, so a view is judged against the most probable state of the others.

Verdicts are numbers and codes; the sentence a person reads is composed above the geometry
(``app.services.wording.doubt_words.mirror_sentence``).

A frame that calibration refuses has no camera, hence no ray: :func:`mirrored_fit_at_rig` gives it
the rig and side priors by calibrating its mirrored labels at the game's camera positions.

World frame: SoccerNet (metres, origin at the centre spot, z down). Pixels: continuous, origin at the
top-left corner of each view's own image.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from itertools import combinations, product
from typing import Callable, Hashable, Sequence

import numpy as np

from app.geometry.annotations import FieldLines, image_diagonal, mirror_lines
from app.geometry.calibration.result import MIRROR_FLAG, CalibrationSettings, side_vote
from app.geometry.calibration.rig import CameraRig, calibrate_with_rig
from app.geometry.camera import Camera, as_points
from app.geometry.pitch import PITCH_WIDTH_M, within_play_volume
from app.geometry.triangulation import BallObservation, PairGeometry, pair_geometry, triangulate_pair

#: The 180-degree rotation of the world about the vertical axis through the centre spot.
MIRROR_ROTATION = np.diag([-1.0, -1.0, 1.0])
MIRROR_ROTATION.setflags(write=False)

#: Verdicts of :class:`MirrorVerdict` (a mirrored verdict is the calibration's flag of the same name).
VERDICT_MIRRORED = MIRROR_FLAG
VERDICT_AS_LABELLED = "as_labelled"
VERDICT_UNDECIDED = "undecided"

#: Pair relations (see the module docstring).
SAME, DIFFERENT, AMBIGUOUS, NO_AGREEMENT = "same", "different", "ambiguous", "no_agreement"


def mirror_camera(camera: Camera) -> Camera:
    """The camera that the mirrored labels of ``camera``'s view calibrate to: ``C' = M C``, ``R' = R M``.

    Intrinsics and distortion are unchanged. Where ``camera`` projects the world point X, the mirrored
    camera projects ``M X`` to the same pixel; the map is an involution (mirroring twice gives back
    the camera).

    Args:
        camera: a calibrated camera (SoccerNet world, metres, z down).

    Returns:
        The mirrored :class:`~app.geometry.camera.Camera`.

    >>> cam = Camera.from_parameters(focal_px=1000.0, principal_point=(960.0, 540.0), pan_deg=0.0,
    ...                              tilt_deg=80.0, roll_deg=0.0, position_m=[5.0, 50.0, -12.0])
    >>> mirror_camera(cam).C.tolist()
    [-5.0, -50.0, -12.0]
    """
    return Camera(K=camera.K, R=camera.R @ MIRROR_ROTATION, C=MIRROR_ROTATION @ camera.C, radial=camera.radial,
                  tangential=camera.tangential, thin_prism=camera.thin_prism)


@dataclass(frozen=True)
class MirrorSettings:
    """The mirror evidence's own constants (its priors and weights, fitted here; the triangulation's tau and rule
    are the caller's, from the settings: :func:`mirror_evidence`'s ``tau_px`` and ``rule``).

    Attributes:
        side_line_margin_m: a camera votes with the side prior when ``|C_y|`` exceeds this (metres;
            default the half width, 34 m: beyond a side line, as ``calibrate_frame``'s flag).
        rig_near_m: a centre this close to a rig position (metres) stands there: calibrated centres
            of one camera scatter by about a metre along the viewing direction, more for replays
            with few lines.
        rig_far_m: a centre farther than this from every rig position (metres) stands at none.
        min_axis_distance_m: a ball closer than this to the vertical axis through the centre spot
            (metres, horizontal) is nearly its own mirror image: its rays say nothing.
        prior: log-odds against a view being mirrored (mirrored labels hit about 5 % of views; ln 19).
        side_weight: log-likelihood ratio of the side vote, ln(1594 / 9) from the real cameras.
        rig_weight_as_labelled: log-likelihood ratio of the rig's "as labelled" vote (the camera
            stands at a known position of the game: about as telling as the side of a main camera,
            kept below it).
        rig_weight_mirrored: log-likelihood ratio of the rig's "mirrored" vote (only the mirror image
            stands at a known position; a camera seen once is common, so this stays below
            ``prior + decision_margin`` and never flags alone).
        pair_weight: log-likelihood ratio of one pair's same/different (a chance meeting of two
            unrelated rays within tau at a plausible place is rare: about 1 in 100).
        decision_margin: flag when the max-marginal margin reaches this (log-odds; 1 is about 3:1).
        max_views: views linked by rays judged jointly at most (2**n hypotheses); beyond, every
            view is judged by its priors only (systems have 2 to 4 views).
    """

    side_line_margin_m: float = PITCH_WIDTH_M / 2.0
    rig_near_m: float = 5.0
    rig_far_m: float = 15.0
    min_axis_distance_m: float = 1.0
    prior: float = float(np.log(19.0))
    side_weight: float = float(np.log(1594.0 / 9.0))
    rig_weight_as_labelled: float = 4.0
    rig_weight_mirrored: float = 2.0
    pair_weight: float = float(np.log(100.0))
    decision_margin: float = 1.0
    max_views: int = 12


@dataclass(frozen=True)
class MirrorView:
    """One calibrated view of a system, as the mirror evidence needs it.

    Attributes:
        view_id: any hashable id (frame id); unique within a call.
        camera: the view's calibrated camera.
        ball_px: (2,) labelled ball centre, pixels of this image, or ``None`` (no ray evidence).
        image_width: image width, pixels (for the scaled pair-error rules).
        expected_side: +1 (main camera, y > 0), -1, or ``None`` (replays: anywhere).
        rays: whether the view's ray joins the pair evidence (a caller may leave out views whose
            camera it distrusts; a rough camera gives no agreement within tau, hence no evidence).
        name: how sentences name the view (image name); the id when None.
        mirrored: ``mirror_camera(camera)`` when the caller keeps it (one object per camera, so that a pair memo
            shared across recomputations finds its mirrored pairs again); made here when None.
    """

    view_id: Hashable
    camera: Camera
    ball_px: np.ndarray | None = None
    image_width: float = 1920.0
    expected_side: int | None = None
    rays: bool = True
    name: str | None = None
    mirrored: Camera | None = None

    def __post_init__(self) -> None:
        if self.expected_side not in (None, 1, -1):
            raise ValueError(f"MirrorView.expected_side must be +1, -1 or None, got {self.expected_side!r}")
        if self.ball_px is not None:
            p = np.array(self.ball_px, dtype=float).reshape(-1)
            if p.shape != (2,) or not np.all(np.isfinite(p)):
                raise ValueError(f"MirrorView.ball_px must be 2 finite numbers, got {self.ball_px!r}")
            p.setflags(write=False)
            object.__setattr__(self, "ball_px", p)


@dataclass(frozen=True)
class PairEvidence:
    """How one other view's ray meets this view's ray (errors in the rule's px, None when undefined).

    Attributes:
        other: the other view's id.
        error_as_labelled_px: ``e_ij`` with both cameras as calibrated.
        error_mirrored_px: ``e_ij`` with this view's camera mirrored.
        relation: :data:`SAME`, :data:`DIFFERENT`, :data:`AMBIGUOUS` or :data:`NO_AGREEMENT`.
        ball_axis_distance_m: horizontal distance of the agreeing ball to the centre spot's vertical
            axis (None without agreement).
    """

    other: Hashable
    error_as_labelled_px: float | None
    error_mirrored_px: float | None
    relation: str
    ball_axis_distance_m: float | None

    def as_dict(self) -> dict:
        return {"other": self.other, "error_as_labelled_px": self.error_as_labelled_px,
                "error_mirrored_px": self.error_mirrored_px, "relation": self.relation,
                "ball_axis_distance_m": self.ball_axis_distance_m}


@dataclass(frozen=True)
class MirrorVerdict:
    """The mirror evidence of one view.

    Attributes:
        view_id: the view.
        verdict: :data:`VERDICT_MIRRORED` (flag it), :data:`VERDICT_AS_LABELLED` (the evidence says
            the labels are right) or :data:`VERDICT_UNDECIDED` (too little evidence either way; not
            flagged, mirrors being rare).
        margin: best score with the view mirrored minus best with it as labelled (log-odds).
        camera_y_m: y of the calibrated centre, metres; ``mirrored_camera_y_m`` is ``-camera_y_m``.
        side_vote: +1 "mirrored", -1 "as labelled", 0 none (see the module docstring).
        rig_distance_m: distance of C to the nearest rig position (None without a rig).
        rig_distance_mirrored_m: distance of ``M C`` to the nearest rig position.
        rig_vote: +1, -1 or 0 as ``side_vote``.
        pairs: one :class:`PairEvidence` per other view with a ray.
        refit: for the verdict of :func:`mirrored_fit_at_rig`, the numbers of the mirrored labels' fit
            (``position_m``: the rig position they fit, ``rms_px``); None otherwise.

    The sentence a person reads is composed from these numbers above the geometry
    (``app.services.wording.doubt_words.mirror_sentence``).
    """

    view_id: Hashable
    verdict: str
    margin: float
    camera_y_m: float
    side_vote: int
    rig_distance_m: float | None
    rig_distance_mirrored_m: float | None
    rig_vote: int
    pairs: tuple[PairEvidence, ...] = field(default=())
    refit: dict | None = None

    @property
    def flagged(self) -> bool:
        """True when the labels are probably mirrored."""
        return self.verdict == VERDICT_MIRRORED

    def as_dict(self) -> dict:
        """JSON-ready form (the ``mirror_evidence`` of the system view)."""
        return {"verdict": self.verdict, "margin": round(self.margin, 3), "camera_y_m": self.camera_y_m,
                "mirrored_camera_y_m": -self.camera_y_m, "side_vote": self.side_vote,
                "rig_distance_m": self.rig_distance_m, "rig_distance_mirrored_m": self.rig_distance_mirrored_m,
                "rig_vote": self.rig_vote, "pairs": [p.as_dict() for p in self.pairs],
                **({"refit": self.refit} if self.refit is not None else {})}


def rig_distances(camera: Camera, rig_positions: np.ndarray | None) -> tuple[float | None, float | None]:
    """Distances (metres) of C and of ``M C`` to the nearest of ``rig_positions`` (K, 3) (world
    metres); Nones without positions.

    Raises:
        ValueError: ``rig_positions`` not (K, 3) (a single (3,) position is K = 1).
    """
    P = _rig_array(rig_positions)
    if P is None:
        return None, None
    c = np.asarray(camera.C, dtype=float)
    return (float(np.min(np.linalg.norm(P - c, axis=1))),
            float(np.min(np.linalg.norm(P - MIRROR_ROTATION @ c, axis=1))))


def _rig_array(rig_positions: np.ndarray | None) -> np.ndarray | None:
    """``rig_positions`` as a (K, 3) array, None when there is none; ValueError for another shape."""
    if rig_positions is None or np.size(rig_positions) == 0:
        return None
    return as_points(rig_positions, 3, "rig_positions")


def _rig_vote(d: float | None, d_mirror: float | None, s: MirrorSettings) -> int:
    if d is None or d_mirror is None:
        return 0
    if d_mirror <= s.rig_near_m and d > s.rig_far_m:
        return 1
    if d <= s.rig_near_m and d_mirror > s.rig_far_m:
        return -1
    return 0


def _plausible(point: np.ndarray, s: MirrorSettings) -> bool:
    return bool(within_play_volume(point)[0])


def _meet(a: BallObservation, b: BallObservation, s: MirrorSettings, tau_px: float, rule: str,
          geometry: Callable[[BallObservation, BallObservation], PairGeometry] = pair_geometry
          ) -> tuple[float | None, np.ndarray | None]:
    """Pair error (rule px) and point when the two rays meet within tau at a plausible place.

    A pixel that a camera's distortion cannot undistort (a strongly distorted, poorly calibrated
    camera far outside its valid field) gives no evidence: ``(None, None)``.
    """
    try:
        with np.errstate(all="ignore"):
            pr = triangulate_pair(a, b, tau_px=tau_px, rule=rule, min_baseline_m=0.0, min_parallax_deg=0.0,
                                  geometry=geometry)
    except (np.linalg.LinAlgError, ValueError):
        return None, None
    if pr.error is not None and not np.isfinite(pr.error):
        return None, None
    if pr.error is None or pr.point is None:
        return pr.error, None
    return pr.error, (pr.point if pr.error < tau_px and _plausible(pr.point, s) else None)


def pair_relation(a: MirrorView, b: MirrorView, settings: MirrorSettings = MirrorSettings(),
                  geometry: Callable[[BallObservation, BallObservation], PairGeometry] = pair_geometry, *,
                  tau_px: float, rule: str, mirrored: Camera | None = None) -> PairEvidence:
    """Relation of two views' rays: as calibrated and with ``a``'s camera mirrored (module docstring).

    Both views need ``ball_px``. The evidence is stated from ``a``'s side (``other`` is ``b``). ``geometry``: where
    the pairs' raw geometry comes from (``app.geometry.triangulation.PairGeometryMemo`` shares it with the
    triangulation and the doubts of one recomputation). ``tau_px``, ``rule``: the triangulation's (px at 1920 width,
    :data:`app.geometry.pair_error.PAIR_ERROR_RULES`), the settings'. ``mirrored``: ``mirror_camera(a.camera)`` when
    the caller made it already (one per view, so that a memo computes the mirrored ray once for all its pairs).
    """
    if a.ball_px is None or b.ball_px is None:
        raise ValueError("pair_relation needs a ball label in both views")
    ob = BallObservation(b.view_id, b.camera, b.ball_px, b.image_width)
    e_same, p_same = _meet(BallObservation(a.view_id, a.camera, a.ball_px, a.image_width), ob, settings, tau_px, rule,
                           geometry)
    mirrored = mirror_camera(a.camera) if mirrored is None else mirrored
    e_diff, p_diff = _meet(BallObservation(a.view_id, mirrored, a.ball_px, a.image_width), ob, settings,
                           tau_px, rule, geometry)
    axis = [float(np.hypot(p[0], p[1])) for p in (p_same, p_diff) if p is not None]
    if p_same is not None and p_diff is not None:
        relation = AMBIGUOUS
    elif p_same is None and p_diff is None:
        relation = NO_AGREEMENT
    elif axis[0] < settings.min_axis_distance_m:
        relation = AMBIGUOUS
    else:
        relation = SAME if p_same is not None else DIFFERENT
    return PairEvidence(b.view_id, e_same, e_diff, relation, min(axis) if axis else None)


def mirror_evidence(views: Sequence[MirrorView], rig_positions: np.ndarray | None = None,
                    settings: MirrorSettings = MirrorSettings(),
                    geometry: Callable[[BallObservation, BallObservation], PairGeometry] = pair_geometry, *,
                    tau_px: float, rule: str) -> dict[Hashable, MirrorVerdict]:
    """Judge, for every calibrated view of one multi-view system, whether its labels are mirrored.

    Args:
        views: the system's calibrated views (ids unique). Views with ``ball_px`` and ``rays`` give
            ray evidence; every view gets the side and rig priors.
        rig_positions: (K, 3) camera positions of the game (world metres), best estimated without
            this system's own frames; None or empty: no rig prior.
        settings: :class:`MirrorSettings`.
        geometry: the pairs' raw geometry (:func:`pair_relation`).
        tau_px, rule: the triangulation's pair threshold (px at 1920 width) and error rule
            (:data:`app.geometry.pair_error.PAIR_ERROR_RULES`), the settings' (the service passes its own).

    Returns:
        view id -> :class:`MirrorVerdict`, by the rule of the module docstring.

    Raises:
        ValueError: duplicate view ids; ``rig_positions`` not (K, 3).
    """
    vs = list(views)
    ids = [v.view_id for v in vs]
    if len(set(ids)) != len(ids):
        raise ValueError(f"views: ids must be unique, got {ids!r}")
    n = len(vs)
    rig = _rig_array(rig_positions)
    sides = [side_vote(v.camera, v.expected_side, settings.side_line_margin_m) for v in vs]
    dists = [rig_distances(v.camera, rig) for v in vs]
    rigs = [_rig_vote(d, dm, settings) for d, dm in dists]
    rig_w = {1: settings.rig_weight_mirrored, -1: settings.rig_weight_as_labelled, 0: 0.0}
    unary = np.array([settings.side_weight * sv + rig_w[rv] * rv - settings.prior
                      for sv, rv in zip(sides, rigs, strict=True)])

    pair_ev: dict[int, list[PairEvidence]] = {i: [] for i in range(n)}
    constraints: list[tuple[int, int, int]] = []  # (i, j, +1 same / -1 different)
    rayed = [i for i, v in enumerate(vs) if v.rays and v.ball_px is not None]
    mirrored = {i: vs[i].mirrored if vs[i].mirrored is not None else mirror_camera(vs[i].camera) for i in rayed}
    for i, j in combinations(rayed, 2):
        ev_i = pair_relation(vs[i], vs[j], settings, geometry, tau_px=tau_px, rule=rule, mirrored=mirrored[i])
        pair_ev[i].append(ev_i)
        # Seen from j: mirroring j instead of i gives the same errors (M applied to both is rigid).
        ev_j = PairEvidence(vs[i].view_id, ev_i.error_as_labelled_px, ev_i.error_mirrored_px, ev_i.relation,
                            ev_i.ball_axis_distance_m)
        pair_ev[j].append(ev_j)
        if ev_i.relation in (SAME, DIFFERENT):
            constraints.append((i, j, 1 if ev_i.relation == SAME else -1))

    margins = _max_marginals(n, unary, constraints, settings)
    verdicts = [VERDICT_MIRRORED if m >= settings.decision_margin
                else VERDICT_AS_LABELLED if m + settings.prior <= -settings.decision_margin
                else VERDICT_UNDECIDED for m in margins]
    out: dict[Hashable, MirrorVerdict] = {}
    for i, v in enumerate(vs):
        out[v.view_id] = MirrorVerdict(
            view_id=v.view_id, verdict=verdicts[i], margin=float(margins[i]), camera_y_m=float(v.camera.C[1]),
            side_vote=sides[i], rig_distance_m=dists[i][0], rig_distance_mirrored_m=dists[i][1], rig_vote=rigs[i],
            pairs=tuple(pair_ev[i]))
    return out


def _max_marginals(n: int, unary: np.ndarray, constraints: list[tuple[int, int, int]],
                   s: MirrorSettings) -> np.ndarray:
    """Per view: best score with it mirrored minus best score with it as labelled."""
    if n == 0:
        return np.zeros(0)
    idx = sorted({i for c in constraints for i in c[:2]})  # views the rays link; the others keep their priors
    if not idx or len(idx) > s.max_views:
        return unary.copy()
    margins = unary.copy()
    pos = {v: k for k, v in enumerate(idx)}
    H = np.array(list(product((0, 1), repeat=len(idx))), dtype=float)  # (2**k, k)
    score = H @ unary[idx]
    for i, j, sign in constraints:
        same = H[:, pos[i]] == H[:, pos[j]]
        score += s.pair_weight * np.where(same == (sign > 0), 1.0, -1.0)
    for i in idx:
        on = H[:, pos[i]] == 1
        margins[i] = float(score[on].max() - score[~on].max())
    return margins


def mirrored_fit_at_rig(lines: FieldLines, width: int, height: int, rig: CameraRig, *,
                        expected_side: int | None = None, settings: MirrorSettings = MirrorSettings(),
                        calibration_settings: CalibrationSettings | None = None) -> MirrorVerdict | None:
    """The rig prior for a view its labels cannot calibrate, even with the game's rig.

    A frame with few lines is calibrated with its centre fixed at one of the game's camera positions
    (:func:`app.geometry.calibration.rig.calibrate_with_rig`). Mirrored labels need the camera at the
    mirror image ``M P`` of the true position ``P``, where no camera of the game stands, so they are
    refused at every position; their mirror image (:func:`app.geometry.annotations.mirror_lines`)
    fits at ``P``. Call this for a frame refused with the rig: it calibrates the mirrored labels with
    the rig. When they fit a position ``P`` tightly (RMS within the calibration's ``accept_gamma`` of
    the diagonal), two explanations remain: the labels are mirrored and the camera stands at the
    known position ``P``, or the labels are right and the camera stands at ``M P``, where no camera
    of the game was seen. The first gets the rig's "mirrored" weight, the side prior judges ``M P``
    (a main camera beyond the far side line: mirrored), and the rule of the module docstring
    decides: a main camera is flagged, a replay (no side prior) is not on this alone.

    Args:
        lines: the frame's labels, pixels; width, height: image size, pixels.
        rig: the game's camera positions (best estimated without this frame).
        expected_side: as :class:`MirrorView`.
        settings, calibration_settings: thresholds of this module and of calibration.

    Returns:
        A :data:`VERDICT_MIRRORED` verdict (``view_id`` None) or None.
    """
    if not rig.positions:
        return None
    cal_settings = calibration_settings or CalibrationSettings()
    result = calibrate_with_rig(mirror_lines(lines), width, height, rig, settings=cal_settings, compute_jac=False)
    if not result.calibrated or result.camera is None or result.rms_px is None:
        return None
    if result.rms_px > cal_settings.accept_gamma * image_diagonal(width, height):
        return None
    as_labelled = mirror_camera(result.camera)  # the camera the labels as given describe, at M P
    side = side_vote(as_labelled, expected_side, settings.side_line_margin_m)
    margin = settings.rig_weight_mirrored + settings.side_weight * side - settings.prior
    if margin < settings.decision_margin:
        return None
    d, d_mirror = rig_distances(as_labelled, np.array([p.centre_m for p in rig.positions]))
    c = result.camera.C
    return MirrorVerdict(view_id=None, verdict=VERDICT_MIRRORED, margin=float(margin),
                         camera_y_m=float(as_labelled.C[1]), side_vote=side, rig_distance_m=d,
                         rig_distance_mirrored_m=d_mirror, rig_vote=1,
                         refit={"position_m": [round(float(x), 2) for x in c],
                                "rms_px": round(float(result.rms_px), 2)})
