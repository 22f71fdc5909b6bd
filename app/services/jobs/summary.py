"""A finished job's result in words: what the jobs panel (and ``v3d jobs list``) says an import, a recompute or an
export gave, computed once when the job ends and stored in its result (``result["summary"]``), so that every page
shows the same sentence and none counts again.

``summary(kind, result)`` answers ``{"words": str, "links": [{"text", "query"}]}``: ``words`` the sentence
("256 systems: 144 with a 3D ball; 87 views without a camera; no images (labels only)"; a predictions import
"1,420 predictions, 44 clipped"), ``links`` the parts of it that name systems the review queue can show, each with
the queue's filters (``query``: the queue page's address parameters, ``static/js/queuestate.js``).
"""
from __future__ import annotations

from typing import Any

#: The queue filter that shows the systems with a view whose calibration was refused (no camera): the info doubt
#: ``calibration_refused`` (``app.geometry.doubts.contract.INFO_KINDS``).
NO_CAMERA_FILTER = {"doubt": "calibration_refused"}


def _n(count: int, one: str, many: str | None = None) -> str:
    """``1,420 predictions`` / ``1 prediction``: a count with its noun, thousands separated."""
    return f"{count:,} {one if count == 1 else (many or one + 's')}"


def _predictions(result: dict[str, Any]) -> dict[str, Any]:
    parts = [_n(int(result.get("stored", 0)), "prediction")]
    if result.get("frames"):
        parts[0] += f" on {_n(int(result['frames']), 'view')} of {_n(int(result.get('systems', 0)), 'system')}"
    if result.get("clipped"):
        parts.append(f"{int(result['clipped']):,} clipped to their image")
    # read from the report when it counts them (a per-frame cap on a detector's boxes)
    dropped = result.get("dropped_over_cap", result.get("dropped"))
    if isinstance(dropped, int) and dropped:
        parts.append(f"{dropped:,} dropped over the cap")
    if result.get("unknown"):
        parts.append(f"{_n(int(result['unknown']), 'row')} naming an image v3d does not hold")
    return {"words": ", ".join(parts), "links": []}


def _dataset(result: dict[str, Any]) -> dict[str, Any]:
    systems, balls = int(result.get("systems", 0)), int(result.get("triangulated", 0))
    refused = int(result.get("refused", 0))
    parts = [f"{balls:,} with a 3D ball"]
    links: list[dict[str, Any]] = []
    if refused:
        no_camera = f"{_n(refused, 'view')} without a camera"
        parts.append(no_camera)
        links.append({"text": no_camera, "query": dict(NO_CAMERA_FILTER)})
    frames, imageless = int(result.get("frames", 0)), int(result.get("frames_without_image", 0))
    if frames and imageless >= frames:
        parts.append("no images (labels only: the views show no picture)")
    elif imageless:
        parts.append(f"{_n(imageless, 'view')} without an image")
    players_dropped = int(result.get("players_dropped", 0))
    if players_dropped:
        parts.append(f"{_n(players_dropped, 'player box', 'player boxes')} beyond the cap a frame not stored")
    skipped = len(result.get("skipped_systems", [])) + len(result.get("skipped_games", []))
    if skipped:
        parts.append(f"{skipped:,} left out (named in the job)")
    return {"words": f"{_n(systems, 'system')}: " + "; ".join(parts), "links": links}


def summary(kind: str, result: dict[str, Any]) -> dict[str, Any]:
    """The words of a finished job's ``result`` (module docstring); ``kind`` the job's kind (``WORK``'s keys).

    >>> summary("import", {"systems": 256, "triangulated": 82, "refused": 87, "frames": 700,
    ...                    "frames_without_image": 700})["words"]
    '256 systems: 82 with a 3D ball; 87 views without a camera; no images (labels only: the views show no picture)'
    >>> summary("import", {"kind": "predictions", "stored": 1420, "clipped": 44})["words"]
    '1,420 predictions, 44 clipped to their image'
    """
    if kind == "import" and result.get("kind") == "predictions":
        return _predictions(result)
    if kind == "import":
        return _dataset(result)
    if kind == "recompute":
        return {"words": f"{_n(int(result.get('systems', 0)), 'system')} recomputed, "
                         f"{int(result.get('triangulated', 0)):,} with a 3D ball", "links": []}
    return {"words": "", "links": []}
