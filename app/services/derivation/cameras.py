"""What one recomputation of a system shares with the next, kept once per process (only the pairs
an edit touches are computed again).

An edit changes one view of a system: its label (a ball edit, an exclusion) or its camera (a line edit). The other
views' cameras, their ball rays, and the pairs they form among themselves and with their mirrored cameras are what
the last recomputation of the system computed. Four process-wide caches keep them, each keyed so that nothing is
reused that is not equal to what would be computed:

* :func:`stored_camera`: the :class:`~app.geometry.camera.Camera` of a stored calibration's SoccerNet JSON, one object
  per camera value (keyed by the JSON with its keys sorted; :data:`CAMERAS` kept, least recently used dropped), so
  that its cached matrices (``P``, ``K^-1``) are made once and the pair memo below knows it again;
* :func:`mirrored_camera`: ``app.geometry.mirror.mirror_camera`` of such a camera, once per camera object (the
  mirror evidence's second camera of every view; :data:`CAMERAS` kept, the oldest dropped);
* :data:`PAIR_GEOMETRY`: one :class:`~app.geometry.triangulation.PairGeometryMemo` for every recomputation of the
  process (:data:`PAIRS` pairs and as many rays kept), keyed by the identity of both cameras (one object per value,
  above) and the bytes of both pixels. A pair of two views the edit did not touch is answered from it; a view
  whose label or camera changed makes new keys;
* :data:`PAIR_PLAYERS`: one :class:`PairPlayersMemo` for every recomputation of the process (:data:`PAIRS` pairs
  kept): how far two views' cameras disagree on the players both see
  (``app.geometry.calibration.players.pair_players_disagreement``, what the ball judged by evidence leaves a pair out
  for), keyed by the identity of both cameras and the foot points of both views. A ball edit changes neither, so its
  pairs are answered from it (without it a ball edit's CPU grows by half: ``benchmarks/edit_mechanisms.py``).

The values are the same numbers, bit for bit, as computing them again: the caches only spare the work
(``tests/services/derivation/test_pair_geometry_shared.py``). Bulk recomputations (imports, jobs) keep their
pairs in memos of their own; their cameras go through :func:`stored_camera` too, at the cost of a key each.
"""
from __future__ import annotations

import functools
import threading
from collections import OrderedDict
from typing import Any, Mapping

import numpy as np
import orjson

from app.geometry.calibration.grass import PlayerKey
from app.geometry.calibration.players import pair_players_disagreement
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

#: Foot points of a view by player, as ``app.services.calibration.players.feet_of`` gives them.
Feet = Mapping[PlayerKey, np.ndarray]


class PairPlayersMemo:
    """:func:`~app.geometry.calibration.players.pair_players_disagreement` computed once per pair of cameras and foot
    points (module docstring). Keyed by the identity of both cameras (one object per value, :func:`stored_camera`),
    the bytes of both views' foot points with their players' keys, and both image sizes; the memo holds the cameras,
    so an id is never reused while it lives. Beyond ``max_entries`` the older half is dropped. Safe to share between
    threads: a race computes a pair twice, never answers a wrong one.

    Raises:
        ValueError: ``max_entries`` below 2.
    """

    def __init__(self, max_entries: int) -> None:
        if max_entries < 2:
            raise ValueError(f"PairPlayersMemo: max_entries must be at least 2, got {max_entries}")
        self.max_entries = max_entries
        self._pairs: dict[tuple, tuple[Camera, Camera, float | None]] = {}
        self._lock = threading.Lock()
        self.asked = 0
        self.computed = 0

    def __call__(self, camera_a: Camera, feet_a: Feet, size_a: tuple[int, int],
                 camera_b: Camera, feet_b: Feet, size_b: tuple[int, int]) -> float | None:
        """``pair_players_disagreement`` of the two views (its arguments), computed on the first ask."""
        key = (id(camera_a), _feet_key(feet_a), size_a, id(camera_b), _feet_key(feet_b), size_b)
        self.asked += 1
        hit = self._pairs.get(key)
        if hit is not None and hit[0] is camera_a and hit[1] is camera_b:
            return hit[2]
        self.computed += 1
        got = pair_players_disagreement(camera_a, feet_a, size_a, camera_b, feet_b, size_b)
        with self._lock:
            if len(self._pairs) >= self.max_entries:
                for old in list(self._pairs)[: len(self._pairs) // 2]:
                    self._pairs.pop(old, None)
            self._pairs[key] = (camera_a, camera_b, got)
        return got


def _feet_key(feet: Feet) -> tuple:
    return tuple((k, np.asarray(uv, float).tobytes()) for k, uv in feet.items())


#: How far the cameras of every pair of views disagree on their players, for every recomputation in the process
#: (module docstring).
PAIR_PLAYERS = PairPlayersMemo(max_entries=PAIRS)


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
