"""What the system page shows, read in a few queries: a system with every relation its views draw, one
frame the same way, its neighbours in the queue, and the pitch model projected into a view.

Read only. The API's response models (``app.api.view_schemas``) shape these ORM objects into the system
view of ``docs/api.md``; the one computation left to the read path, the projected pitch, depends
only on the calibration and is computed once per camera and image size (:func:`pitch_lines`).
"""
from __future__ import annotations

import functools
import hashlib
import json
from dataclasses import dataclass, field
from typing import Any, Optional

import numpy as np
import orjson
import sqlalchemy as sa
from sqlalchemy.orm import Session, joinedload

from app.core.errors import found
from app.db.models import Frame, ReviewBatch, System
from app.db.scope import FRAME_ROWS
from app.db.session import reads_on_their_own
from app.geometry.camera import Camera
from app.geometry.projection import project_pitch_polylines
from app.services.curation.assignment import Assignment, assignment_of
from app.services.curation.presence import Presence, open_on
from app.services.curation.queue import DEFAULT_SORT, SystemFilters, SystemSort, queue_neighbours
from app.services.derivation.loading import load_systems

#: Pitch sampling for drawing (metres between samples on lines and on circles): about 1,500 points
#: per view, smooth at 1920 px, a tenth of the JaC sampling.
_DRAW_DIST_M = 0.5
_DRAW_DIST_CIRCLES_M = 0.25
#: Pixel coordinates sent to the UI are rounded to this many decimals.
PX_DECIMALS = 2
#: Projected pitches kept (:func:`_projected_pitch`): one per view of about the last 400 systems read.
_PITCH_CACHE_SIZE = 1024


@dataclass(frozen=True)
class SystemPageData:
    """A system loaded for its page (game, review, triangulation and pairs, frames with field lines,
    calibration, ball label, reprojection, optimised box and review, doubts), its queue neighbours, its
    assignment and who has it open now (``app.services.curation.presence``, everyone's live claims), and, when its
    acceptance is a batch's (``ReviewDecision.batch_id``), that batch (``app.services.curation.batches``)."""

    system: System
    prev_id: Optional[int]
    next_id: Optional[int]
    assignment: Optional[Assignment] = None
    open_by: list[Presence] = field(default_factory=list)
    batch: Optional[ReviewBatch] = None


def round_px(values: Any) -> Any:
    """Pixel coordinates (nested lists or arrays) rounded to :data:`PX_DECIMALS` for JSON, as lists.

    >>> round_px([[1.23456, 2.0], [3.0, 4.98765]])
    [[1.23, 2.0], [3.0, 4.99]]
    """
    return np.round(np.asarray(values, dtype=float), PX_DECIMALS).tolist()


def pitch_lines(camera_json: Optional[dict[str, Any]], width: int, height: int, *,
                keep: bool = True) -> list[tuple[str, list[list[float]]]]:
    """The pitch model projected by a stored camera (SoccerNet JSON, world metres, z down) and clipped to
    its ``width`` x ``height`` image: ``[(class, [[x, y], ...] px rounded)]``, one item per in-image run of
    two points or more; empty without a camera. It depends only on the calibration, so it is computed once
    per camera and image size and kept (:func:`_projected_pitch`, an LRU cache keyed by the camera JSON),
    not on every request; the lists are made from the kept array per request. ``keep=False`` projects without
    the cache (a camera seen once, as a drag's preview: it would push the stored views' pitches out)."""
    if not camera_json:
        return []
    project = _projected_pitch if keep else _projected_pitch.__wrapped__
    classes, points, bounds = project(json.dumps(camera_json, sort_keys=True), int(width), int(height))
    xy = points.tolist()
    return [(cls, xy[s:e]) for cls, s, e in zip(classes, bounds, bounds[1:], strict=False)]  # bounds has one more


def pitch_lines_key(camera_json: Optional[dict[str, Any]], width: int, height: int) -> Optional[str]:
    """The version of a view's projected pitch (:func:`pitch_lines`): 16 hex digits of the SHA-256 of its
    camera (SoccerNet JSON, keys sorted) and image size, None without a camera. Equal keys mean equal lines,
    so a client keeps the lines of a key for as long as it likes (``GET /api/frames/{id}/pitch-lines``).

    >>> pitch_lines_key(None, 1920, 1080) is None, len(pitch_lines_key({"a": 1}, 1920, 1080))
    (True, 16)
    """
    if not camera_json:
        return None
    return _pitch_lines_key(orjson.dumps(camera_json, option=orjson.OPT_SORT_KEYS | orjson.OPT_NON_STR_KEYS),
                            int(width), int(height))


@functools.lru_cache(maxsize=_PITCH_CACHE_SIZE)
def _pitch_lines_key(camera: bytes, width: int, height: int) -> str:
    """:func:`pitch_lines_key` of a camera given as its JSON with sorted keys (orjson's, a cheap cache key); the key
    itself hashes ``json.dumps`` of the camera, as it always has (the URLs clients keep stay valid). Computed once
    per camera and image size (every view of every system page and edit answer names it)."""
    text = f"{json.dumps(orjson.loads(camera), sort_keys=True)}|{width}x{height}"
    return hashlib.sha256(text.encode()).hexdigest()[:16]


@functools.lru_cache(maxsize=_PITCH_CACHE_SIZE)
def _projected_pitch(camera_key: str, width: int, height: int) -> tuple[tuple[str, ...], np.ndarray, tuple[int, ...]]:
    """``(classes, points, bounds)`` of :func:`pitch_lines`: run ``k`` of class ``classes[k]`` is
    ``points[bounds[k]:bounds[k + 1]]`` ((N, 2) px, rounded to :data:`PX_DECIMALS`). A view takes 6 kB on
    average, 25 kB at most (nested lists of floats took about 8 times as much), so the cache holds at most
    25 MB. A miss costs about 0.5 ms of CPU, a hit the lists' 0.04 ms."""
    camera = Camera.from_soccernet(json.loads(camera_key))
    runs = project_pitch_polylines(camera, width, height, _DRAW_DIST_M, _DRAW_DIST_CIRCLES_M, mode="clip")
    kept = [(cls, run) for cls, polys in runs.items() for run in polys if len(run) >= 2]
    if not kept:
        return (), np.zeros((0, 2)), (0,)
    points = np.round(np.concatenate([run for _, run in kept], axis=0).astype(float), PX_DECIMALS)
    points.setflags(write=False)
    return tuple(cls for cls, _ in kept), points, tuple(np.cumsum([0, *(len(run) for _, run in kept)]).tolist())


def _frame_loads(load: Any) -> list[Any]:
    """The frame's one-to-one rows the view draws (``scope.FRAME_ROWS``), joined to their parent."""
    return [load(r) for r in FRAME_ROWS]


def load_system(session: Session, system_id: int) -> System:
    """The system with every relation its page draws loaded: its game and review joined to it, its views with their
    one-to-one rows, its pairs and doubts (``app.services.derivation.loading.load_systems``: four queries whatever
    the number of views), or the system as the session holds it so loaded already (an edit's answer).

    Raises:
        NotFoundError: no system has this id.
    """
    loaded = _loaded_system(session, system_id)
    if loaded is not None:
        return loaded
    loaded_now = load_systems(session, [system_id], _PAGE_SYSTEM_ROWS, predictions=None, players=False)
    return found(loaded_now.get(system_id), "system", system_id)


#: The system's one-to-one rows its page draws besides its triangulation (``loading.load_systems``).
_PAGE_SYSTEM_ROWS = (System.game, System.review)


#: What :func:`load_system` loads, per object: the system's lists and each view's one-to-one rows (its game and
#: review, one row each, are read by a lazy load where the session does not hold them).
_SYSTEM_PAGE_RELATIONS = ("triangulation", "frames", "doubts")
_FRAME_PAGE_RELATIONS = frozenset(r.key for r in FRAME_ROWS)


def _loaded_system(session: Session, system_id: int) -> Optional[System]:
    """The system as the session holds it already with everything its page draws loaded and nothing expired (an
    edit's answer: the edit loaded and recomputed it and committed it, ``expire_on_commit`` off), else None. Spares
    the answer of every edit a second round of queries for rows it has just written."""
    system = session.identity_map.get(session.identity_key(System, system_id))
    if system is None:
        return None
    state = sa.inspect(system)
    if state.expired or state.unloaded & set(_SYSTEM_PAGE_RELATIONS) or state.modified:
        return None
    tri = system.triangulation
    if tri is not None and (sa.inspect(tri).unloaded & {"pairs"} or sa.inspect(tri).expired):
        return None
    for frame in system.frames:
        fs = sa.inspect(frame)
        if fs.expired or fs.unloaded & _FRAME_PAGE_RELATIONS:
            return None
    return system


def load_frame(session: Session, frame_id: int) -> Frame:
    """One frame with what its view draws loaded (and its system's triangulation, for the reprojection
    error's rule and tau).

    Raises:
        NotFoundError: no frame has this id.
    """
    stmt = sa.select(Frame).where(Frame.id == frame_id).options(
        joinedload(Frame.system).joinedload(System.triangulation), *_frame_loads(joinedload))
    return found(session.scalars(stmt).unique().first(), "frame", frame_id)


def system_page(session: Session, system_id: int, filters: SystemFilters = SystemFilters(),
                sort: SystemSort = DEFAULT_SORT) -> SystemPageData:
    """The system for its page (:func:`load_system`: the system as an edit just committed it when the session holds
    it so), its neighbours in the queue ``filters`` + ``sort`` (by default the whole queue in its default order;
    ``app.services.curation.queue.queue_neighbours``), its assignment (from the loaded system:
    ``assignment.assignment_of``) and its live presence claims (one indexed read). After an edit the reads left run
    without a transaction of their own on PostgreSQL (``app.db.session.reads_on_their_own``).

    Raises:
        NotFoundError: no system has this id.
    """
    held = _loaded_system(session, system_id)
    if held is not None:  # an edit's answer: what is left to read needs no common snapshot
        reads_on_their_own(session)
    system = held if held is not None else load_system(session, system_id)
    prev_id, next_id = queue_neighbours(session, system_id, filters, sort, held=held)
    batch_id = system.review.batch_id if system.review is not None else None
    return SystemPageData(system, prev_id, next_id, assignment_of(session, system),
                          open_on(session, [system_id]).get(system_id, []),
                          session.get(ReviewBatch, batch_id) if batch_id is not None else None)
