"""Synthetic field-line labels of a known camera, shared by the geometry and service tests of calibration priors."""
from __future__ import annotations

from typing import Collection, Optional

import numpy as np

from app.geometry.camera import Camera
from app.geometry.pitch import sample_pitch_polylines


def visible_model_points(camera: Camera, width: int, height: int, rng: np.random.Generator, *,
                         classes: Optional[Collection[str]] = None, per_class: int = 10, noise_px: float = 0.0,
                         margin_px: float = 2.0) -> dict[str, list[np.ndarray]]:
    """Labels of the model classes ``camera`` sees: for each class (all, or those in ``classes``) with at least
    ``per_class`` projected model samples more than ``margin_px`` inside the ``width`` x ``height`` image,
    ``per_class`` of them evenly chosen along the class, plus Gaussian noise of ``noise_px`` per axis (pixels).
    Returns ``{class: [(per_class, 2) pixels]}`` in the model's class order; ``rng`` draws once per kept class."""
    out = {}
    for cls, X in sample_pitch_polylines().items():
        if classes is not None and cls not in classes:
            continue
        uv, ok = camera.project(X)
        inside = (ok & (uv[:, 0] > margin_px) & (uv[:, 0] < width - 1 - margin_px)
                  & (uv[:, 1] > margin_px) & (uv[:, 1] < height - 1 - margin_px))
        if inside.sum() < per_class:
            continue
        pts = uv[inside][np.linspace(0, int(inside.sum()) - 1, per_class).astype(int)]
        out[cls] = [pts + rng.normal(0.0, noise_px, pts.shape)]
    return out
