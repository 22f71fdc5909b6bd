"""What one recomputation of a system shares with the next, kept once per process (only the pairs
an edit touches are computed again).

An edit changes one view of a system: its label (a ball edit, an exclusion) or its camera (a line edit). The other
views' cameras, their ball rays, and the pairs they form among themselves and with their mirrored cameras are what
the last recomputation of the system computed. Three process-wide caches keep them, each keyed so that nothing is
reused that is not equal to what would be computed:

* :func:`stored_camera`: the :class:`~app.geometry.camera.Camera` of a stored calibration's SoccerNet JSON, one object
  per camera value (keyed by the JSON with its keys sorted; :data:`CAMERAS` kept, least recently used dropped), so
  that its cached matrices (``P``, ``K^-1``) are made once and the pair memo below knows it again;
* :func:`mirrored_camera`: ``app.geometry.mirror.mirror_camera`` of such a camera, once per camera object (the
  mirror evidence's second camera of every view; :data:`CAMERAS` kept, the oldest dropped);
* :data:`PAIR_GEOMETRY`: one :class:`~app.geometry.triangulation.PairGeometryMemo` for every recomputation of the
  process (:data:`PAIRS` pairs and as many rays kept), keyed by the identity of both cameras (one object per value,
  above) and the bytes of both pixels. A pair of two views the edit did not touch is answered from it; a view
  whose label or camera changed makes new keys.

The values are the same numbers, bit for bit, as computing them again: the caches only spare the work
(``tests/services/derivation/test_pair_geometry_shared.py``). Bulk recomputations (imports, jobs) keep their
pairs in memos of their own; their cameras go through :func:`stored_camera` too, at the cost of a key each.
"""
from __future__ import annotations

import functools
import threading
from collections import OrderedDict
from typing import Any, Mapping

import orjson

from app.geometry.camera import Camera
from app.geometry.mirror import mirror_camera
from app.geometry.triangulation import PairGeometryMemo

#: Stored cameras kept (:func:`stored_camera`, and as many mirrored ones): the views of the last couple of hundred
#: systems edited or read, about 6 MB.
CAMERAS = 1024
#: Pairs (and rays) kept by :data:`PAIR_GEOMETRY`: the pairs of the last hundred or more systems edited (a 4-view
#: system asks 12 to 14, as calibrated and mirrored), about 4 MB. Bulk recomputations (imports, jobs) use memos of
#: their own (``recompute.recompute_systems``): they would only push the edited systems' pairs out.
PAIRS = 2048

#: The pair geometry of every recomputation in the process (module docstring).
PAIR_GEOMETRY = PairGeometryMemo(max_entries=PAIRS)


def stored_camera(camera_json: Mapping[str, Any]) -> Camera:
    """The camera of a stored calibration's SoccerNet JSON (``Camera.from_soccernet``: world metres, SoccerNet frame,
    z down), the same object for an equal JSON while it is kept (module docstring).

    Raises:
        ValueError: a malformed camera JSON (``Camera.from_soccernet``'s message).
    """
    return _camera(orjson.dumps(camera_json, option=orjson.OPT_SORT_KEYS | orjson.OPT_NON_STR_KEYS))


@functools.lru_cache(maxsize=CAMERAS)
def _camera(key: bytes) -> Camera:
    return Camera.from_soccernet(orjson.loads(key))


_MIRRORED: "OrderedDict[int, tuple[Camera, Camera]]" = OrderedDict()
_MIRRORED_LOCK = threading.Lock()


def mirrored_camera(camera: Camera) -> Camera:
    """``app.geometry.mirror.mirror_camera(camera)`` (``C' = M C``, ``R' = R M``), made once per camera object while
    it is kept (:data:`CAMERAS` at most, the oldest dropped): the mirror evidence's second camera of a view, known
    again by the shared pair memo."""
    hit = _MIRRORED.get(id(camera))
    if hit is not None and hit[0] is camera:
        return hit[1]
    mirrored = mirror_camera(camera)
    with _MIRRORED_LOCK:
        _MIRRORED[id(camera)] = (camera, mirrored)  # holds the camera: its id is not reused while kept
        while len(_MIRRORED) > CAMERAS:
            _MIRRORED.popitem(last=False)
    return mirrored
