"""What a calibration is worth as evidence of a ball: the pixel sigma of a 3D point in a view from the stored
calibration uncertainty, and the calibration's weight (a full vote, half a vote, none). The doubt judge weighs
its votes with it and the triangulation's service its views (``app.geometry.triangulation.triangulate_ball``
``view_weights``), so that the triangulation trusts the views the judge trusts without importing the doubts.

It reads a view and its thresholds through two small protocols (:class:`WeighedView`, :class:`Weighing`;
``app.geometry.doubts.DoubtView`` and ``DoubtSettings`` are both), with the few view facts the doubts share: a
label's centre, a point's pixel, the units of the pair-error rule, where a ray meets the grass.

World frame: SoccerNet (metres, origin at the centre spot, z down); pixels of each view's own image.
"""
from __future__ import annotations

import math
from typing import Any, Protocol

import numpy as np

from app.geometry.camera import Camera
from app.geometry.pair_error import REFERENCE_WIDTH_PX


class WeighedView(Protocol):
    """What the weighting reads of a view (``app.geometry.doubts.DoubtView`` documents each)."""

    @property
    def camera(self) -> Camera | None: ...
    @property
    def width(self) -> int: ...
    @property
    def box(self) -> np.ndarray | None: ...
    @property
    def point(self) -> np.ndarray | None: ...
    @property
    def uncertainty(self) -> dict[str, Any] | None: ...
    @property
    def line_classes(self) -> int: ...
    @property
    def admitted(self) -> bool: ...
    @property
    def jac(self) -> float | None: ...


class Weighing(Protocol):
    """The thresholds the weighting reads (``app.geometry.doubts.DoubtSettings`` documents each, built from
    ``Settings``: the pair-error rule, phi, ``doubt_consensus_tau_px``, ``doubt_min_line_classes``)."""

    @property
    def pair_error_rule(self) -> str: ...
    @property
    def ball_diameter_m(self) -> float: ...
    @property
    def consensus_tau_px(self) -> float: ...
    @property
    def min_line_classes(self) -> int: ...


def rule_scale(view: WeighedView, s: Weighing) -> float:
    """Factor from the view's pixels to the units of the settings (1920-px width, or raw px for ``max_px``)."""
    return 1.0 if s.pair_error_rule == "max_px" else REFERENCE_WIDTH_PX / view.width


def label_centre(view: WeighedView) -> np.ndarray | None:
    """The view's ball label as a pixel (2,): its box's centre, else its point, else None."""
    if view.box is not None:
        b = np.asarray(view.box, float)
        return np.array([(b[0] + b[2]) / 2, (b[1] + b[3]) / 2])
    return None if view.point is None else np.asarray(view.point, float).reshape(2)


def camera_of(view: WeighedView) -> Camera:
    """The view's camera, where only calibrated views are judged (the callers keep those)."""
    assert view.camera is not None, "a judged view has a camera"
    return view.camera


def centre_of(view: WeighedView) -> np.ndarray:
    """:func:`label_centre` where only labelled views are judged (the callers keep those)."""
    centre = label_centre(view)
    assert centre is not None, "a judged view has a ball label"
    return centre


def project_point(view: WeighedView, point: np.ndarray) -> np.ndarray | None:
    """The pixel (2,) of world ``point`` (3,) in the view, None behind its camera."""
    uv, ok = camera_of(view).project(np.asarray(point, float).reshape(1, 3))
    return uv[0] if ok[0] else None


def ray_at_height(origin: np.ndarray, direction: np.ndarray, z: float) -> np.ndarray | None:
    """Where the ray ``origin + t direction`` (t > 0) meets the plane of height ``z`` (world metres, z down),
    None when it never does ahead of its origin."""
    if abs(direction[2]) < 1e-9:
        return None
    t = (z - origin[2]) / direction[2]
    return None if t <= 0 else origin + t * direction


def axis_on_grass(view: WeighedView, s: Weighing) -> np.ndarray | None:
    """Where the view's optical axis meets the plane of ball centres on the grass, or None."""
    camera = camera_of(view)
    d = camera.R[2]  # optical axis in the world frame
    return ray_at_height(camera.C, d, -s.ball_diameter_m / 2)


def pixel_sigma(view: WeighedView, point: np.ndarray, s: Weighing) -> float:
    """How far (px at 1920 width) the view's calibration may put ``point``'s projection: the first-order
    propagation of its stored uncertainty (``calibrations.uncertainty``,
    :class:`app.geometry.calibration.uncertainty.CalibrationUncertainty`) to the pixel of ``point``, with
    the rotation and focal terms independent: ``sqrt((f s_pan)^2 + (f s_tilt)^2 + (r s_roll)^2 + (r s_f / f)^2)``
    (angles in radians, ``r`` the pixel's distance to the principal point). The centre's terms are left
    out: the fit trades the centre along the viewing direction against the focal length, which moves
    the ball's pixel little (with them the figure overstates the error of the synthetic sets' views
    about 25 times at the median; without them about 5 times, and it still ranks the views whose
    calibration failed: of the admitted views above ``consensus_tau_px`` 11 % project the true ball more
    than that far off, of those below it 0.3 %). 0 without a stored uncertainty; ``inf`` for a parameter the
    lines leave undetermined.
    """
    u = view.uncertainty
    if not u or view.camera is None:
        return 0.0
    uv = project_point(view, point)
    if uv is None:
        return math.inf
    f = float(view.camera.K[0, 0])
    r = float(np.linalg.norm(uv - view.camera.K[:2, 2]))
    def num(key: str) -> float:
        v = u.get(key)
        return math.inf if v is None else float(v)
    terms = (f * math.radians(num("pan_deg")), f * math.radians(num("tilt_deg")), r * math.radians(num("roll_deg")),
             r * num("focal_px") / f)
    if any(math.isinf(t) or math.isnan(t) for t in terms):
        return math.inf
    return float(math.sqrt(sum(t * t for t in terms))) * rule_scale(view, s)


#: Least share of its own field lines (JaC@0.5 %) a camera below admission must fit for its uncertainty to speak for
#: it: below, its fit failed whatever sigma it states (a camera that fits none, JaC 0, is no camera of the view).
MIN_OWN_LINES_JAC = 0.5


def fits_own_lines(jac: float | None) -> bool:
    """Whether a camera below admission (JaC@0.5 % ``jac``, a fraction, at most ``admit_jac_min``; None without one)
    still fits most of its own field lines (:data:`MIN_OWN_LINES_JAC`): its stated uncertainty then speaks for it, in
    the doubts' votes (:func:`calibration_weight`) and in the ball judged by evidence
    (``app.services.derivation.ball.takes_part``). SoccerNet's JaC: the share of the annotated line points
    within gamma of the camera's projected lines (``app.geometry.jac``)."""
    return (jac or 0.0) >= MIN_OWN_LINES_JAC


def calibration_weight(view: WeighedView, s: Weighing) -> tuple[float, float]:
    """What the view's calibration is worth as evidence of a ball, and its pixel sigma: ``(weight, sigma)``.

    ``sigma`` (px at 1920 width) is :func:`pixel_sigma` where the view's ball label's ray meets the grass
    (the pixel sigma hardly depends on the point's depth), else where its optical axis does, else 50 m
    along the axis. ``weight``: for a view with at least ``min_line_classes`` line classes the vote of
    :func:`_vote_weight` (1 admitted and sure, 0.5 unsure or below admission but sure, else 0); for a view
    with fewer classes (its camera is not fixed by its own lines: with the game's rig two or three classes
    fit exactly yet may turn the ball ray by degrees) half a vote when its stored uncertainty is sure (sigma
    within ``consensus_tau_px``) and it fits at least half of its lines (JaC@0.5 % >= 0.5), else 0.
    The doubt judge weighs its votes with it; the triangulation (``app.geometry.triangulation.triangulate_ball``
    ``view_weights``) lets no pair without a full vote make a ball, and no weaker pair move one that
    full votes make. A view without a camera: ``(0.0, inf)``."""
    if view.camera is None:
        return 0.0, math.inf
    c = label_centre(view)
    ref = None if c is None else ray_at_height(view.camera.C, view.camera.rays(c.reshape(1, 2))[0],
                                                 -s.ball_diameter_m / 2)
    if ref is None:
        ref = axis_on_grass(view, s)
    if ref is None:  # a camera looking above the horizon: a point 50 m along its axis
        ref = view.camera.C + 50.0 * view.camera.R[2]
    sigma = pixel_sigma(view, ref, s)
    if view.line_classes >= s.min_line_classes:
        return _vote_weight(view, sigma, s), sigma
    sure = bool(view.uncertainty) and sigma <= s.consensus_tau_px and fits_own_lines(view.jac)
    return (0.5 if sure else 0.0), sigma


def _vote_weight(view: WeighedView, sigma_1920: float, s: Weighing) -> float:
    """What the view's calibration is worth in the consensus: 1 for an admitted view whose pixel sigma
    (:func:`pixel_sigma`) is within ``consensus_tau_px``; half a vote for an admitted view above it or
    for a view below admission within it (each projects the true ball more than tau off about one time in
    ten on the synthetic sets, against 0.3 % for full votes), the latter only when it fits at least half of
    its own lines (JaC@0.5 % >= 0.5); 0 otherwise."""
    sure = sigma_1920 <= s.consensus_tau_px
    if view.admitted:
        return 1.0 if sure else 0.5
    # below admission: its uncertainty speaks for it only if the camera fits most of its own lines
    # (JaC@0.5 % of at least a half; a camera that fits none, JaC 0, is a failed fit whatever its sigma)
    return 0.5 if sure and fits_own_lines(view.jac) else 0.0
