"""What a frame's calibration takes and answers: its settings, the prior it may be given (the game's rig
centre, a dataset's learned camera prior), its result (camera, JaC, residuals per class, flags, refusal) and the
flags' names; with the camera-side vote and the principal point convention every caller shares.

World frame: SoccerNet (metres, centre spot origin, z down); image: continuous pixels, origin top-left.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Literal, Mapping

import numpy as np

from app.geometry.annotations import FieldLines
from app.geometry.calibration.priors import CameraPrior
from app.geometry.calibration.solver import PriorRows
from app.geometry.camera import Camera
from app.geometry.pitch import PITCH_WIDTH_M

#: Flag of a calibration made with its centre fixed by a prior (a position of the game's camera rig).
RIG_FLAG = "rig_assisted"


#: Flag of a calibration fitted to the foot points of the players its view shares with the well-calibrated views of
#: its system (:mod:`.players`), with its lines; ``"rig_assisted"`` too when its centre was fixed at a rig position.
PLAYERS_FLAG = "player_assisted"


#: Flag of a calibration fitted with a learned camera prior (a MAP fit, :mod:`.priors`).
PRIOR_FLAG = "learned_prior"


#: Flag of a calibration whose radial term was fitted under a learned radial prior (:mod:`.priors`).
RADIAL_PRIOR_FLAG = "radial_prior"


#: Largest relative radial distortion at the image corner, ``|k1| (h / f)^2`` with ``h`` the half
#: diagonal, accepted from a fit under the radial prior (the real sets' median is 0.04).
MAX_CORNER_DISTORTION = 0.2


#: Flag of a frame whose field-line labels are probably mirrored (camera-side prior here; the
#: multi-view verdict of ``app.geometry.mirror`` sets the same flag in the service).
MIRROR_FLAG = "probably_mirrored"


#: The flags that say where a camera came from besides its lines, which the review queue filters by (a system with a
#: view so calibrated): a rig position, the players.
SOURCE_FLAGS: tuple[str, ...] = (RIG_FLAG, PLAYERS_FLAG)


Status = Literal["calibrated", "refused"]


@dataclass(frozen=True)
class CalibrationPrior:
    """Prior knowledge about the camera that filmed a frame (all optional).

    Attributes:
        expected_side: +1 when the camera is expected on the y > 0 side of the pitch (broadcast main
            cameras: 1,594 of 1,603 real cameras), -1 for y < 0, ``None`` for no expectation (replay
            cameras can stand anywhere). Used only to flag probably mirrored labels; never to fit.
        centre_m: (3,) known camera centre (world, metres), e.g. from the game's rig; the centre is
            then held fixed and only focal length and rotation are fitted.
        camera_prior: a dataset's learned :class:`~.priors.CameraPrior`: a free fit less sure of its
            centre than the prior's confident fits is refined into a MAP fit (lines and prior) at the
            anchors most consistent with it; the anchors are starts too when no other start fits
            (ignored with ``centre_m``).
    """

    expected_side: int | None = None
    centre_m: tuple[float, float, float] | None = None
    camera_prior: CameraPrior | None = None

    def __post_init__(self) -> None:
        if self.expected_side not in (None, 1, -1):
            raise ValueError(f"CalibrationPrior.expected_side must be +1, -1 or None, got {self.expected_side!r}")
        if self.centre_m is not None:
            c = np.asarray(self.centre_m, dtype=float)
            if c.shape != (3,) or not np.all(np.isfinite(c)):
                raise ValueError("CalibrationPrior.centre_m must be 3 finite numbers (world metres)")
            if c[2] >= 0:
                raise ValueError("CalibrationPrior.centre_m must be above the ground (z < 0, z points down)")


@dataclass(frozen=True)
class CalibrationSettings:
    """Tunable constants of :func:`calibrate_frame` (defaults are the service's).

    Attributes:
        min_constraints: fewest independent scalar constraints the labels must give (7 unknowns:
            focal length, 3 rotation, 3 centre; 4 with a known centre).
        loss_scale_gamma: soft-L1 loss scale as a fraction of the image diagonal.
        accept_gamma: a candidate whose 90th-percentile point distance is below this fraction of the
            diagonal ends the search early.
        refuse_gamma: refuse when a labelled class has a point farther than this fraction of the
            diagonal from its model element. With a known centre (rig prior) the RMS point distance
            must also stay within ``accept_gamma`` of the diagonal.
        k1_min_gain: relative drop of the robust cost that justifies the radial coefficient.
        k1_min_points: fewest labelled points for which the radial coefficient is tried.
        max_k1: largest accepted |k1|.
        max_evaluations: batched residual evaluations allowed per frame over all starts (one per
            Levenberg-Marquardt trial step); bounds the time spent on a frame whose labels fit no
            camera (a typical frame needs 20 to 40); the leave-one-class-out step gets half as many.
        leave_out_max_classes: classes left out in turn, the worst fitted first (all of them when no
            camera was found).
        prior_anchors: with a learned camera prior, MAP fits made (one per anchor, the most
            consistent with the lines first); the lowest MAP cost wins.
        prior_max_d2: an anchor is tried only when its squared Mahalanobis distance to the free fit
            (:func:`~.priors.anchor_order`) is at most this (chi-square, 3 degrees of freedom, 0.999).
        prior_max_evaluations: residual evaluations allowed to the MAP fits of a frame.
    """

    min_constraints: int = 7
    loss_scale_gamma: float = 0.002
    accept_gamma: float = 0.005
    refuse_gamma: float = 0.03
    k1_min_gain: float = 0.3
    k1_min_points: int = 12
    max_k1: float = 0.5
    max_evaluations: int = 140
    leave_out_max_classes: int = 7
    prior_anchors: int = 3
    prior_max_d2: float = 16.27
    prior_max_evaluations: int = 60


#: Why a calibration was refused, as codes (their numbers in :attr:`Refusal.numbers`); the words a person reads are
#: the services' (``app.services.wording.words``: ``WORDS["refusal"]`` and ``refusal_sentence``).
REFUSAL_CODES: tuple[str, ...] = (
    "few_constraints",   # fewer independent line constraints than the camera has unknowns: need, constraints, lines
    "parallel_lines",    # every labelled line parallel on the pitch, and no circle or goal fixes the view
    "collinear_points",  # every labelled point on one image line
    "solver_failed",     # the solver raised: error
    "no_camera_fits",    # every start failed or put the pitch behind the camera
    "residual_too_high", # a class too far from its model element: line, px, limit_px
    "centre_misfit",     # the labels do not fit a camera at the known centre: rms_px, limit_px
    "no_rig_position",   # the game's rig has no position (no well-calibrated frame to estimate it)
)


@dataclass(frozen=True)
class Refusal:
    """Why :func:`calibrate_frame` refused a frame: ``code`` (one of :data:`REFUSAL_CODES`) and the numbers behind
    it (``numbers``: name -> number, or a line class name for ``residual_too_high``; pixels of the frame)."""

    code: str
    numbers: Mapping[str, Any] = field(default_factory=dict)

    def to_json(self) -> dict[str, Any]:
        """``{"code": ..., **numbers}``."""
        return {"code": self.code, **dict(self.numbers)}


@dataclass(frozen=True)
class CalibrationResult:
    """Outcome of :func:`calibrate_frame`.

    Attributes:
        status: ``"calibrated"`` or ``"refused"``.
        camera: the camera (pixels of the frame, SoccerNet world) or ``None`` when refused.
        refusal: why the frame was refused (:class:`Refusal`; ``None`` when calibrated).
        jac: JaC at each gamma of :data:`JAC_GAMMAS` (keys ``"0.005"``, ``"0.01"``, ``"0.02"``), from
            :mod:`app.geometry.jac`; empty when refused or not computed.
        residuals_px: per labelled class, the largest distance (px) of its points to the model
            element under the returned camera (or the best rejected one), so a UI can point at
            the line that disagrees.
        flags: ``"probably_mirrored"`` (camera on the other side than ``prior.expected_side``, beyond
            the far side line: the labels are probably mirrored, :attr:`mirrored_lines` is the fix),
            ``"few_lines"`` (fewer labelled classes than :data:`app.geometry.pitch.MIN_LINE_CLASSES`),
            ``"radial_distortion"`` (``k1`` fitted), ``"ignored_class:<class>"`` (that class disagrees with every camera
            fitting the others; its residual stays in :attr:`residuals_px`), ``"rig_assisted"`` (centre fixed by a
            prior).
        rms_px: root mean square point distance, px.
        elapsed_ms: wall time of the call, milliseconds.
        mirrored_lines: when ``"probably_mirrored"`` is flagged, the mirrored labelling offered as
            the fix (:func:`app.geometry.annotations.mirror_lines`).
        centre_prior: the prior rows of a MAP fit (a centre prior: flag ``"learned_prior"``; the
            radial prior: flag ``"radial_prior"``), for :func:`~.uncertainty.calibration_uncertainty`'s
            posterior covariance; ``None`` otherwise.
    """

    status: Status
    camera: Camera | None
    refusal: Refusal | None
    jac: Mapping[str, float]
    residuals_px: Mapping[str, float]
    flags: tuple[str, ...]
    rms_px: float | None
    elapsed_ms: float
    mirrored_lines: FieldLines | None = field(default=None, repr=False)
    centre_prior: PriorRows | None = field(default=None, repr=False)

    @property
    def calibrated(self) -> bool:
        """True when a camera was returned."""
        return self.status == "calibrated"

    def to_json(self) -> dict[str, Any]:
        """JSON-ready summary (the camera in SoccerNet form)."""
        return {
            "status": self.status,
            "camera": self.camera.to_soccernet() if self.camera is not None else None,
            "refusal": self.refusal.to_json() if self.refusal is not None else None,
            "jac": dict(self.jac),
            "residuals_px": dict(self.residuals_px),
            "flags": list(self.flags),
            "rms_px": self.rms_px,
            "elapsed_ms": self.elapsed_ms,
        }


def side_vote(camera: Camera, expected_side: int | None, margin_m: float = PITCH_WIDTH_M / 2.0) -> int:
    """The side prior on mirrored labels: +1 when the camera stands beyond the far side line from
    ``expected_side`` (labels probably mirrored), -1 beyond the near side line (as labelled), 0
    otherwise or without a side.

    One rule for :func:`calibrate_frame`'s ``probably_mirrored`` flag (a vote of +1) and for
    :func:`app.geometry.mirror.mirror_evidence`, which re-exports it.

    Args:
        camera: the calibrated camera (SoccerNet world, metres).
        expected_side: +1 (camera expected at y > 0), -1, or ``None``.
        margin_m: how far beyond the centre line along y (metres) the camera must stand to vote;
            default the half width, i.e. beyond a side line.

    >>> cam = Camera.from_parameters(focal_px=1000.0, principal_point=(960.0, 540.0), pan_deg=0.0,
    ...                              tilt_deg=80.0, roll_deg=0.0, position_m=[0.0, -50.0, -12.0])
    >>> side_vote(cam, 1), side_vote(cam, -1), side_vote(cam, None)
    (1, -1, 0)
    """
    if expected_side is None:
        return 0
    y = float(camera.C[1]) * expected_side
    return 1 if y < -margin_m else -1 if y > margin_m else 0


def principal_point(width: int, height: int) -> np.ndarray:
    """Principal point v3d's calibration fixes: ``((W - 1) / 2, (H - 1) / 2)`` px (module docstring)."""
    return np.array([(width - 1) / 2.0, (height - 1) / 2.0])
