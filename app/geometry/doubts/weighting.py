"""What a calibration is worth as evidence: the pixel sigma of a 3D point in a view from the stored calibration
uncertainty, the calibration's weight (a full vote, half a vote, none) and a view's vote weight. The
triangulation's service weighs its pairs by the same :func:`calibration_weight`.
"""
from __future__ import annotations


import math

import numpy as np

from app.geometry.doubts.contract import (DoubtSettings, DoubtView, _centre, _project, _scale)
from app.geometry.doubts.epipolar import (_axis_on_grass, _ray_at_height)


def pixel_sigma(view: DoubtView, point: np.ndarray, s: DoubtSettings) -> float:
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
    uv = _project(view, point)
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
    return float(math.sqrt(sum(t * t for t in terms))) * _scale(view, s)


def calibration_weight(view: DoubtView, s: DoubtSettings) -> tuple[float, float]:
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
    c = _centre(view)
    ref = None if c is None else _ray_at_height(view.camera.C, view.camera.rays(c.reshape(1, 2))[0],
                                                  -s.ball_diameter_m / 2)
    if ref is None:
        ref = _axis_on_grass(view, s)
    if ref is None:  # a camera looking above the horizon: a point 50 m along its axis
        ref = view.camera.C + 50.0 * view.camera.R[2]
    sigma = pixel_sigma(view, ref, s)
    if view.line_classes >= s.min_line_classes:
        return _vote_weight(view, sigma, s), sigma
    sure = bool(view.uncertainty) and sigma <= s.consensus_tau_px and (view.jac or 0.0) >= 0.5
    return (0.5 if sure else 0.0), sigma


def _vote_weight(view: DoubtView, sigma_1920: float, s: DoubtSettings) -> float:
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
    return 0.5 if sure and (view.jac or 0.0) >= 0.5 else 0.0
