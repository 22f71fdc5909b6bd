"""An ISSIA sequence's cameras: for each of the six static cameras, the one the sequence uses and where it came from.

From ``issia_calibration.json`` as in the paper, or calibrated once from the camera's field lines and admitted by
the paper's JaC rule; a refused camera resected from the ball's trajectory of the admitted ones; all of them
refined together from their lines and the ball labels (bundle adjustment), each kept only while its lines still
admit it. The reader (:mod:`app.datasets.issia`) gives the plain records this works on; the import
(:mod:`app.services.issia.sequences`) stores the choice on every view, and a line edit of a view whose camera the
bundle refined runs :func:`bundle_refined_cameras` again.
"""
from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Any, Mapping, Sequence

import numpy as np

from app.core.errors import DatasetError
from app.datasets.issia import FPS, LINES_FILE, IssiaSequence
from app.geometry.annotations import FieldLines
from app.geometry.calibration import calibrate_frame
from app.geometry.calibration.result import Refusal
from app.geometry.camera import Camera
from app.geometry.jac import JAC_GAMMAS, jac_admitted, jac_at_gammas
from app.geometry.pair_error import REFERENCE_WIDTH_PX
from app.geometry.static_bundle import bundle_adjust
from app.geometry.static_cameras import calibrate_with_ball
from app.geometry.trajectory import DEFAULT_FLAG_PX, fit_trajectory
from app.services.wording.words import refusal_sentence


@dataclass(frozen=True)
class CameraChoice:
    """The camera a sequence uses for one id: ``camera`` (``None`` when not usable), where it came
    from (:data:`CAMERA_SOURCES`), JaC at the admission's gamma against its lines when calibrated from them, and
    why it is not used (``None`` when used)."""

    camera: Camera | None
    source: str
    jac: float | None = None
    reason: str | None = None
    #: The refusal's code (``WORDS["refusal"]``: the calibration's or one of :data:`STATIC_CAMERA_REFUSALS`;
    #: ``reason`` is its sentence, ``app.services.wording.words.refusal_sentence``).
    refusal: str | None = None

    @property
    def ball_assisted(self) -> bool:
        """Resected from the ball's trajectory of the other cameras (:func:`_ball_assisted`)."""
        return "ball" in self.source.split("+")

    @property
    def bundle_adjusted(self) -> bool:
        """Refined by the bundle adjustment of the lines and the ball labels (:func:`_bundle_adjusted`)."""
        return "bundle" in self.source.split("+")


#: Why a static camera is not used besides the calibration's own refusals (:data:`~app.geometry.calibration.result.
#: REFUSAL_CODES`): no field lines to calibrate from, JaC@0.5 % not above the admission threshold, or absent from
#: ``issia_calibration.json``; their words and sentences are in ``app.services.wording.words``.
STATIC_CAMERA_REFUSALS = ("no_lines", "below_admission", "not_in_calibration_json")


#: Where a sequence's camera comes from: the calibration JSON; its field lines; resected from the ball's
#: trajectory of the other cameras (``+ball``); refined together with the others from their lines and the
#: ball's labels (``+bundle``).
CAMERA_SOURCES = ("calibration_json", "lines", "lines+ball", "lines+bundle", "lines+ball+bundle")


def sequence_cameras(seq: IssiaSequence, *, from_lines: bool = False, admit_jac_gamma: float, admit_jac_min: float,
                     pair_rules: Mapping[str, Any],
                     ball_assist: bool = True, bundle: bool = True) -> dict[str, CameraChoice]:
    """One camera per id: ``issia_calibration.json`` when present (as in the paper), unless
    ``from_lines`` or it is absent; then each static camera is calibrated once from its field lines
    (:func:`app.geometry.calibration.calibrate_frame`) and admitted when its JaC at ``admit_jac_gamma`` is above
    ``admit_jac_min`` (the paper's admission rule, :func:`app.geometry.jac.jac_admitted`; the callers pass the
    settings' ``admit_jac_gamma`` and ``admit_jac_min``); a refused or not admitted camera has ``camera=None`` and a
    reason. With two or more admitted cameras, the ball's trajectory is fitted with them
    (:func:`app.geometry.trajectory.fit_trajectory`, its per-frame triangulation's ``tau_px``, ``rule``,
    ``min_baseline_m`` and ``min_parallax_deg`` given as ``pair_rules``: ``app.services.issia.trajectory.fit_args``
    of the settings), then:

    * with ``ball_assist``, each refused camera is calibrated again from that trajectory and its own
      labels (source ``"lines+ball"``, :mod:`app.geometry.static_cameras`; admitted by the same JaC rule
      against its lines);
    * with ``bundle``, the cameras are refined together from their lines and the ball labels the
      trajectory keeps (:func:`app.geometry.static_bundle.bundle_adjust`; source ``"+bundle"``); a
      refined camera is kept only when its JaC at ``admit_jac_gamma`` against its own lines is still above
      ``admit_jac_min`` (the lines stay the judge), otherwise the camera before the adjustment stays.

    Raises:
        DatasetError: ``from_lines`` without ``issia_lines.json``.
        ValueError: ``admit_jac_gamma`` is not one of :data:`app.geometry.jac.JAC_GAMMAS` (the calibration's JaC).
    """
    if admit_jac_gamma not in JAC_GAMMAS:
        raise ValueError(f"admit_jac_gamma={admit_jac_gamma!r} is not a gamma the calibration scores; choose one of "
                         f"{list(JAC_GAMMAS)}")

    if seq.cameras and not from_lines:
        missing = Refusal("not_in_calibration_json")
        return {cid: CameraChoice(seq.cameras.get(cid), "calibration_json") if cid in seq.cameras
                else CameraChoice(None, "calibration_json", reason=refusal_sentence(missing), refusal=missing.code)
                for cid in seq.camera_ids}
    if not seq.lines:
        raise DatasetError(seq.root / LINES_FILE, None, "missing: cannot calibrate from lines")
    out = {}
    for cid in seq.camera_ids:
        if cid not in seq.lines:
            out[cid] = CameraChoice(None, "lines", reason=refusal_sentence(Refusal("no_lines")), refusal="no_lines")
            continue
        res = calibrate_frame(seq.lines[cid], *seq.image_size)
        jac = res.jac.get(f"{admit_jac_gamma:g}") if res.jac else None  # calibrate_frame's keys: JAC_GAMMAS
        if res.camera is None:
            assert res.refusal is not None  # calibrate_frame: no camera comes with its refusal
            out[cid] = CameraChoice(None, "lines", None, f"refused: {refusal_sentence(res.refusal)}", res.refusal.code)
        elif not jac_admitted(jac, admit_jac_min):
            below = Refusal("below_admission",
                            {"jac": jac, "gamma_pct": 100 * admit_jac_gamma, "admit_jac_min": admit_jac_min})
            out[cid] = CameraChoice(None, "lines", jac, refusal_sentence(below), below.code)
        else:
            out[cid] = CameraChoice(res.camera, "lines", jac)
    refused = [c for c in seq.camera_ids if out[c].camera is None and c in seq.lines]
    assist = ball_assist and bool(refused)
    if (assist or bundle) and sum(out[c].camera is not None for c in seq.camera_ids) >= 2:
        pts = seq.dense_points()
        fit = fit_trajectory(pts, [out[c].camera for c in seq.camera_ids], [seq.image_size[0]] * len(seq.camera_ids),
                             FPS, **pair_rules)
        if assist:
            out.update(_ball_assisted(seq, out, refused, admit_jac_gamma, admit_jac_min, fit))
        if bundle:
            out.update(_bundle_adjusted(seq, out, fit, admit_jac_gamma, admit_jac_min))
    return out


def _ball_assisted(seq: IssiaSequence, choice: dict[str, CameraChoice], refused: list[str],
                   admit_jac_gamma: float, admit_jac_min: float, fit) -> dict[str, CameraChoice]:
    """Calibrate refused static cameras from ``fit``, the trajectory of the admitted ones
    (:func:`app.geometry.static_cameras.calibrate_with_ball`)."""

    pts = seq.dense_points()
    out = {}
    for cid in refused:
        k = seq.camera_ids.index(cid)
        sel = np.all(np.isfinite(pts[:, k]), axis=1) & np.all(np.isfinite(fit.positions), axis=1)
        cam, jac = calibrate_with_ball(seq.lines[cid], fit.positions[sel], pts[sel, k], *seq.image_size,
                                       admit_jac_gamma=admit_jac_gamma, admit_jac_min=admit_jac_min)
        if cam is not None:
            out[cid] = CameraChoice(cam, "lines+ball", jac)
        elif jac is not None:
            out[cid] = replace(choice[cid], reason=f"{choice[cid].reason}; with the ball's trajectory "
                                                   f"JaC@{100 * admit_jac_gamma:g}% {jac}")
    return out


def _bundle_adjusted(seq: IssiaSequence, choice: dict[str, CameraChoice], fit,
                     admit_jac_gamma: float, admit_jac_min: float) -> dict[str, CameraChoice]:
    """The cameras of ``choice`` refined together from their lines and the ball's labels
    (:func:`bundle_refined_cameras`), each kept when its JaC at ``admit_jac_gamma`` against its own lines stays
    above ``admit_jac_min``."""
    ids = seq.camera_ids
    refined = bundle_refined_cameras([choice[c].camera for c in ids], [seq.lines.get(c) for c in ids],
                                     seq.dense_points(), seq.image_size, fit,
                                     [choice[c].ball_assisted for c in ids], admit_jac_gamma=admit_jac_gamma,
                                     admit_jac_min=admit_jac_min)
    return {cid: CameraChoice(r[0], choice[cid].source + "+bundle", r[1])
            for cid, r in zip(ids, refined, strict=True) if r is not None}


def bundle_refined_cameras(cameras: Sequence[Camera | None], lines: Sequence[FieldLines | None], points: np.ndarray,
                           image_size: tuple[int, int], fit, resected: Sequence[bool],
                           *, admit_jac_gamma: float, admit_jac_min: float) -> list[tuple[Camera, float] | None]:
    """Static cameras refined together from their field lines and the ball's labels
    (:func:`app.geometry.static_bundle.bundle_adjust`): per camera ``(refined camera, its JaC at
    admit_jac_gamma against its own lines)`` when that JaC stays above ``admit_jac_min`` (the lines stay the judge),
    else ``None`` (also for a camera without lines or camera). Used by the import
    (:func:`sequence_cameras`) and by a line edit of a view whose camera it refined.

    Args:
        cameras: K cameras (``None``: not calibrated). lines: K field-line annotations (pixels of
            ``image_size``) or ``None``. points: (F, K, 2) ball labels by frame number, px, NaN where none.
        image_size: (width, height) px of every camera.
        fit: the ball's :class:`~app.geometry.trajectory.TrajectoryFit` with the cameras calibrated from
            their lines: its kept labels are the inliers and its per-frame triangulations (else its
            positions) the starting points.
        resected: per camera, resected from that trajectory since (not in ``fit``): its labels within
            the trajectory's ``flag_px`` of the trajectory's projection are added, as the trajectory
            judges a label.
    """

    cams = list(cameras)
    out: list[tuple[Camera, float] | None] = [None] * len(cams)
    if sum(c is not None for c in cams) < 2:
        return out
    inliers = np.isfinite(fit.residuals_px) & ~fit.outliers
    for k, cam in enumerate(cams):
        if resected[k] and cam is not None:
            uv, front = cam.project(np.nan_to_num(fit.positions))
            err = np.linalg.norm(uv - points[:, k], axis=1) * REFERENCE_WIDTH_PX / image_size[0]
            inliers[:, k] = front & np.all(np.isfinite(fit.positions), axis=1) & (err <= DEFAULT_FLAG_PX)
    start = np.where(np.all(np.isfinite(fit.ball_3d), axis=1)[:, None], fit.ball_3d, fit.positions)
    try:
        res = bundle_adjust(cams, list(lines), points, inliers, start)
    except ValueError:
        return out
    for k in range(len(cams)):
        camera, labelled = res.cameras[k], lines[k]
        if camera is None or labelled is None:
            continue
        jac = float(jac_at_gammas(camera, labelled, *image_size, (admit_jac_gamma,))[admit_jac_gamma])
        if jac_admitted(jac, admit_jac_min):
            out[k] = (camera, jac)
    return out
