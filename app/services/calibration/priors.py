"""A dataset's learned camera prior in the service: learned from an import's first calibrations when its
systems have no rig (:func:`dataset_prior`), stored with the game, and the retry of a frame with it
(:func:`wants_prior_retry`, :func:`with_prior_refit`).
"""
from __future__ import annotations

from typing import Sequence

import numpy as np

from app.datasets.records import CalibrationFields
from app.db.models import CalibrationStatus, System
from app.geometry.annotations import FieldLines
from app.geometry.calibration import (
    CameraPrior,
    learn_camera_prior,
    lines_used,
    radial_corner,
)
from app.geometry.calibration.priors import confident_mask
from app.geometry.calibration.result import MIRROR_FLAG, RIG_FLAG
from app.geometry.camera import Camera
from app.services.calibration.rigs import uses_rig

#: Fewest calibrated frames of an import's systems without a rig from which a dataset prior is learned
#: (half of them confident: a handful of anchors at least).
MIN_PRIOR_FRAMES = 40


def dataset_prior(results: Sequence[CalibrationFields],
                  lines: Sequence[tuple[FieldLines, int, int]] | None = None) -> CameraPrior | None:
    """The learned camera prior of a dataset (``app.geometry.calibration.learn_camera_prior``) from
    its frames' calibrations from their lines alone: the calibrated ones, not rig-assisted, with an
    uncertainty (camera and position std read from the fields). With ``lines`` (per result: its
    frame's field lines, width and height, px) the prior learns the radial term too, from the
    confident fits refitted with ``k1`` free (``radial_corner``; classes a fit ignored left out). None
    below :data:`MIN_PRIOR_FRAMES` such frames or when no anchor is found."""
    cams, stds, used = [], [], []
    for i, r in enumerate(results):
        if (r.status is not CalibrationStatus.CALIBRATED or r.camera is None or r.uncertainty is None
                or RIG_FLAG in r.flags):
            continue
        p = r.uncertainty["position_m"]
        cams.append(Camera.from_soccernet(r.camera))
        stds.append(float(np.sqrt(sum(float("inf") if p[k] is None else float(p[k]) ** 2 for k in "xyz"))))
        used.append(i)
    if len(cams) < MIN_PRIOR_FRAMES:
        return None
    radial = None
    if lines is not None:
        confident, _ = confident_mask(stds)
        radial = []
        for cam, sure, i in zip(cams, confident, used, strict=True):
            if not sure:
                radial.append(float("nan"))  # not among the confident fits the prior learns from
                continue
            field_lines, width, height = lines[i]
            radial.append(radial_corner(cam, lines_used(field_lines, results[i].flags), width, height))
    prior = learn_camera_prior(cams, stds, radial_corner=radial)
    return prior if prior.anchors_m else None


def stored_camera_prior(system: System) -> CameraPrior | None:
    """The learned camera prior stored on ``system``'s game (``games.camera_prior``: its calibration
    dataset's import learned it), or None: no game, a kind that uses rigs (:func:`uses_rig`: a game's
    cameras are its rig), nothing stored, or a stored value that is not a prior (then it is ignored)."""
    if uses_rig(system):  # asked first: a rig system's game is not read (a query per line edit)
        return None
    game = system.game
    if game is None or game.camera_prior is None:
        return None
    try:
        return CameraPrior.from_json(game.camera_prior)
    except ValueError:
        return None


def with_prior_refit(first: CalibrationFields, refit: CalibrationFields) -> CalibrationFields:
    """The calibration kept after a :func:`wants_prior_retry` refit: the refit when it calibrates (the MAP
    fit is the better estimate where the lines leave the centre open), the first fit otherwise."""
    return refit if refit.status is CalibrationStatus.CALIBRATED else first


def wants_prior_retry(fields: CalibrationFields, prior: CameraPrior) -> bool:
    """True when a frame's calibration from its lines alone is worth refitting with the dataset's
    learned ``prior``: refused, or calibrated while the prior has a radial term (every fit takes
    it: the lines of one frame rarely fix the lens), or calibrated with a camera-position std above the
    prior's confident ones' (``CameraPrior.confident_std_m``: the lines leave the centre open). Without
    a radial term, frames whose lines fix the camera as well as the confident ones are never refitted
    (their calibration stays as it is); refusals flagged :data:`MIRROR_FLAG` never are (the prior's
    anchors, on the labelled side, would fit mirrored labels with a wrong camera), nor rig-assisted
    fits."""
    if fields.status is CalibrationStatus.REFUSED:
        return MIRROR_FLAG not in fields.flags  # mirrored labels: a prior on this side would hide it
    if fields.uncertainty is None or RIG_FLAG in fields.flags:
        return False
    if prior.has_radial:
        return True
    p = fields.uncertainty["position_m"]
    if any(p[k] is None for k in "xyz"):
        return True
    return float(np.sqrt(sum(float(p[k]) ** 2 for k in "xyz"))) > prior.confident_std_m
