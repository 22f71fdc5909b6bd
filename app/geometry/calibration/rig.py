"""Game-level camera rig: fixed camera positions estimated from a game's well-calibrated frames, used
as a prior to calibrate frames whose lines alone do not fix a camera.

Broadcast cameras stay where they are during a game (a tripod or a platform); they pan, tilt and
zoom. So once some frames of a game are well calibrated, their centres cluster around the game's
camera positions, and a frame with too few lines can be calibrated with its centre fixed at one of
those positions: 4 unknowns (focal length and rotation) instead of 7. A position counts only when
the labels fit it as tightly as a good calibration; positions are chosen by residual, the main
camera's first for an action frame among equal fits. Results are flagged ``"rig_assisted"``. Pure
functions: the service layer chooses which frames feed the rig and which are retried with it.
"""
from __future__ import annotations

import functools
import math
import time
from dataclasses import dataclass, replace
from typing import Sequence

import numpy as np
from numba import njit

from app.geometry.annotations import FieldLines
from app.geometry.calibration.frame import calibrate_frames_together, frame_jac
from app.geometry.calibration.residuals import JIT
from app.geometry.calibration.result import RIG_FLAG, CalibrationPrior, CalibrationResult, CalibrationSettings, Refusal


@dataclass(frozen=True)
class RigPosition:
    """One fixed camera position of a game.

    Attributes:
        centre_m: (3,) median camera centre of its frames (world, metres, z down).
        frames: number of calibrated frames supporting it.
        spread_m: median distance of those frames' centres to ``centre_m``, metres.
        main_frames: how many of those frames were filmed by the main camera (actions), when the
            caller told (:func:`estimate_rig`'s ``main_camera``).
    """

    centre_m: tuple[float, float, float]
    frames: int
    spread_m: float
    main_frames: int = 0


#: Rigs :func:`estimate_rig` keeps (its last inputs and results; a key is 25 bytes per camera centre).
_RIGS_KEPT = 64


@dataclass(frozen=True)
class CameraRig:
    """The camera positions of one game, most supported first."""

    positions: tuple[RigPosition, ...]

    @property
    def main_index(self) -> int | None:
        """Index of the main camera's position: the one most action frames support (None when no
        position is supported by an action frame)."""
        best = max(range(len(self.positions)), key=lambda i: self.positions[i].main_frames, default=None)
        return best if best is not None and self.positions[best].main_frames > 0 else None


@njit(**JIT)
def _greedy_groups(C: np.ndarray, radius_m: float, min_frames: int) -> np.ndarray:
    """:func:`estimate_rig`'s greedy grouping of the centres ``C`` (N, 3) metres: the group (0, 1, ...
    in the order they are formed) of each centre, -1 for the centres left out. A round seeds a group
    with the remaining centre that has the most remaining neighbours within ``radius_m`` (the first
    such centre on ties), which joins it with them; the rounds end when that count is below
    ``min_frames`` (every later group would be smaller still)."""
    n = C.shape[0]
    near = np.empty((n, n), dtype=np.bool_)
    for i in range(n):
        for j in range(n):
            dx, dy, dz = C[i, 0] - C[j, 0], C[i, 1] - C[j, 1], C[i, 2] - C[j, 2]
            near[i, j] = math.sqrt(dx * dx + dy * dy + dz * dz) <= radius_m
    group = np.full(n, -1)
    left = np.ones(n, dtype=np.bool_)
    g = 0
    while True:
        best, seed = -1, -1
        for i in range(n):
            if left[i]:
                count = 0
                for j in range(n):
                    if left[j] and near[i, j]:
                        count += 1
                if count > best:
                    best, seed = count, i
        if seed < 0 or best < min_frames:
            return group
        for j in range(n):
            if left[j] and near[seed, j]:
                group[j], left[j] = g, False
        g += 1


def estimate_rig(centres: np.ndarray | Sequence[Sequence[float]], *, radius_m: float = 3.0, min_frames: int = 2,
                 main_camera: Sequence[bool] | None = None) -> CameraRig:
    """Group the centres of well-calibrated cameras of one game into fixed positions.

    Greedy clustering: the centre with the most neighbours within ``radius_m`` seeds a position, its
    neighbours join it, and the position's centre is their coordinate-wise median (robust to a
    poorly calibrated frame); repeated on the rest. Positions supported by fewer than
    ``min_frames`` frames are dropped (a single frame is no evidence of a fixed camera).

    Args:
        centres: (N, 3) camera centres of one game, world metres (callers pass only well-calibrated
            frames, e.g. JaC@0.5 % > 0.75 and not rig-assisted themselves); N may be 0.
        radius_m: neighbourhood radius, metres (calibrated centres of one camera scatter by about a
            metre along the viewing direction).
        min_frames: fewest frames per position.
        main_camera: per camera, True when its frame was filmed by the main camera (an action
            frame); counted per position in :attr:`RigPosition.main_frames`.

    Returns:
        :class:`CameraRig` (possibly without positions).

    Raises:
        ValueError: ``radius_m`` not positive, ``min_frames`` < 1, or centres not (N, 3).

    >>> rig = estimate_rig([[0.1 * i, 60.0, -20.0] for i in range(3)])
    >>> rig.positions[0].frames, [round(v, 2) for v in rig.positions[0].centre_m]
    (3, [0.1, 60.0, -20.0])
    """
    if not radius_m > 0:
        raise ValueError(f"radius_m must be positive, got {radius_m!r}")
    if min_frames < 1:
        raise ValueError(f"min_frames must be at least 1, got {min_frames!r}")
    if np.size(centres) and np.shape(centres)[-1] != 3:
        raise ValueError(f"centres must have shape (N, 3), got {np.shape(centres)}")
    C = np.ascontiguousarray(np.asarray(centres, dtype=float).reshape(-1, 3))
    main = np.zeros(len(C), dtype=bool) if main_camera is None else np.asarray(main_camera, dtype=bool)
    if main.shape != (len(C),):
        raise ValueError(f"main_camera must give one flag per camera ({len(C)}), got {main.shape}")
    return _rig_of(C.tobytes(), np.ascontiguousarray(main).tobytes(), float(radius_m), int(min_frames))


@functools.lru_cache(maxsize=_RIGS_KEPT)
def _rig_of(centres: bytes, main_camera: bytes, radius_m: float, min_frames: int) -> CameraRig:
    """:func:`estimate_rig` of the centres (N, 3) float64 and flags (N,) bool given as their bytes, kept for the
    next call with the same ones (the result is immutable): every edit of a SoccerNet game's system estimates the
    game's rig from the same centres until a calibration of the game changes (about 0.4 ms per call on a demo game,
    more on a full one)."""
    C = np.frombuffer(centres, dtype=float).reshape(-1, 3)
    main = np.frombuffer(main_camera, dtype=bool)
    group = _greedy_groups(C, radius_m, min_frames)
    positions: list[RigPosition] = []
    for g in range(int(group.max(initial=-1)) + 1):
        members = np.flatnonzero(group == g)
        centre = np.median(C[members], axis=0)
        spread = float(np.median(np.linalg.norm(C[members] - centre, axis=1)))
        positions.append(RigPosition(centre_m=tuple(float(v) for v in centre),  # type: ignore[arg-type]  # centre is a 3-vector
                                     frames=int(len(members)), spread_m=spread,
                                     main_frames=int(main[members].sum())))
    positions.sort(key=lambda p: -p.frames)
    return CameraRig(positions=tuple(positions))


def calibrate_with_rig(lines: FieldLines, width: int, height: int, rig: CameraRig, *,
                       expected_side: int | None = None, settings: CalibrationSettings | None = None,
                       compute_jac: bool = True, tie_px: float = 1.0, main_camera: bool = False) -> CalibrationResult:
    """Calibrate a frame with its centre fixed at one of the game's rig positions.

    Every position is tried (:func:`~app.geometry.calibration.calibrate_frame` with
    ``CalibrationPrior(centre_m=...)``: focal length and rotation free, centre fixed), and a position
    counts only when the labels fit it as tightly as a good single-frame calibration (RMS within
    ``settings.accept_gamma`` of the diagonal; ``calibrate_frame`` refuses looser fixed-centre fits).
    Among those the smallest RMS residual wins; positions within ``tie_px`` of it (a frame with few
    lines can fit several positions equally) are decided by the frame's role first (``main_camera``:
    the main camera's position, :attr:`CameraRig.main_index`), then by support. The labels' JaC is
    never used to choose. The result carries the ``"rig_assisted"`` flag.

    Args:
        lines: field lines of the frame, pixels.
        width, height: image size, pixels.
        rig: the game's :class:`CameraRig`.
        expected_side: as :class:`CalibrationPrior` (mirror flag only).
        settings, compute_jac: as :func:`calibrate_frame`.
        tie_px: RMS difference (px) under which two positions fit equally well.
        main_camera: the frame was filmed by the main camera (an action frame).

    Returns:
        The chosen :class:`CalibrationResult` (JaC computed for it alone), whose ``elapsed_ms`` is
        the time spent on every position and on that JaC; a refusal (the best-fitting position's, or a rig without
        positions) when no position fits.
    """
    if not rig.positions:
        return CalibrationResult(status="refused", camera=None, jac={}, residuals_px={}, flags=(RIG_FLAG,),
                                 refusal=Refusal("no_rig_position"),
                                 rms_px=None, elapsed_ms=0.0)
    # JaC is the evaluation, never the choice: it is computed once, for the chosen position.
    # Every position is fitted; the fits share the frame's observations (the same results as one
    # calibrate_frame call each).
    t0 = time.perf_counter()
    results = calibrate_frames_together(
        [(lines, width, height, CalibrationPrior(expected_side=expected_side, centre_m=p.centre_m))
         for p in rig.positions], settings=settings, compute_jac=False)
    elapsed = (time.perf_counter() - t0) * 1e3
    fitted = [(i, r) for i, r in enumerate(results) if r.calibrated and r.rms_px is not None]
    if not fitted:
        # The refusal whose labels came closest (its residuals point at the disagreeing line).
        scored = [r for r in results if r.rms_px is not None]
        refusal = min(scored, key=lambda r: r.rms_px) if scored else results[0]  # type: ignore[arg-type,return-value]  # scored keeps only results with an rms
        return replace(refusal, elapsed_ms=elapsed)
    best_rms = min(r.rms_px for _, r in fitted)  # type: ignore[type-var]  # fitted keeps only results with an rms
    ties = [(i, r) for i, r in fitted if r.rms_px <= best_rms + tie_px]  # type: ignore[operator]  # fitted keeps only results with an rms
    main = rig.main_index if main_camera else None
    chosen = min(ties, key=lambda t: (t[0] != main, t[0]))[1]  # role first, then support (sorted)
    if compute_jac and chosen.camera is not None:
        t0 = time.perf_counter()
        chosen = replace(chosen, jac=frame_jac(chosen.camera, lines, width, height))
        elapsed += (time.perf_counter() - t0) * 1e3
    return replace(chosen, elapsed_ms=elapsed)
