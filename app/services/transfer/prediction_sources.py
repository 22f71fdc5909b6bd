"""The ball detectors' predictions stored, one summary per source (the Detectors page, ``GET /api/predictions``):
how many predictions and on how many views, the spread of their scores, and when and by whom the source was last
imported.

When and by whom are read from the audit log, where each predictions import records its summary entry
(``app.services.transfer.predictions.import_predictions``: action ``import``, ``after`` holding ``kind:
predictions``, the ``source`` and what it ``stored``): the newest such entry of a source is its import. A source whose
entry is not found (no entry names it) says so (``imported_at`` and ``imported_by`` None: "unknown" on the page).
The rows' own ``created_at`` stands in for the time then.
"""
from __future__ import annotations

from typing import Any, Optional

import numpy as np
import sqlalchemy as sa
from sqlalchemy.orm import Session

from app.db.models import AuditEntry, Frame, Prediction
from app.services.audit.log import actor_words


def _imports(session: Session, sources: set[str]) -> dict[str, AuditEntry]:
    """source -> the newest audit entry of its import (``import`` entries whose ``after`` names it and what it
    stored), for ``sources``."""
    found: dict[str, AuditEntry] = {}
    for entry in session.scalars(sa.select(AuditEntry).where(AuditEntry.action == "import")
                                 .order_by(AuditEntry.id.desc())):
        after = entry.after or {}
        source = after.get("source")
        if after.get("kind") == "predictions" and "stored" in after and source in sources and source not in found:
            found[source] = entry
            if len(found) == len(sources):
                break
    return found


def _spread(scores: list[float]) -> dict[str, Optional[float]]:
    """``{"min", "q1", "median", "q3", "max"}`` of the scores (None each without one)."""
    if not scores:
        return dict.fromkeys(("min", "q1", "median", "q3", "max"))
    q = np.quantile(np.asarray(scores, dtype=float), [0.0, 0.25, 0.5, 0.75, 1.0])
    return dict(zip(("min", "q1", "median", "q3", "max"), (round(float(v), 4) for v in q), strict=True))


def source_summaries(session: Session, admin: bool = False) -> list[dict[str, Any]]:
    """Every stored source, by name: ``source``, ``predictions``, ``frames`` (views they lie on), ``systems``,
    ``scores`` (:func:`_spread`: min, quartiles, max), ``imported_at`` (datetime, UTC; None: unknown),
    ``imported_by`` (the importer in words, ``app.services.audit.log.actor_words``: the OS account of a command-line
    import to admins only; None: unknown)."""
    counts = session.execute(
        sa.select(Prediction.source, sa.func.count(Prediction.id), sa.func.count(sa.distinct(Prediction.frame_id)),
                  sa.func.count(sa.distinct(Frame.system_id)), sa.func.max(Prediction.created_at))
        .join(Frame, Frame.id == Prediction.frame_id)
        .group_by(Prediction.source).order_by(Prediction.source)).all()
    scores: dict[str, list[float]] = {}
    for source, score in session.execute(sa.select(Prediction.source, Prediction.score)):
        scores.setdefault(source, []).append(float(score))
    imports = _imports(session, {c[0] for c in counts})
    out = []
    for source, n, frames, systems, created in counts:
        entry = imports.get(source)
        out.append({"source": source, "predictions": int(n), "frames": int(frames), "systems": int(systems),
                    "scores": _spread(scores.get(source, [])),
                    "imported_at": entry.at if entry is not None else created,
                    "imported_by": actor_words(entry.actor, admin) if entry is not None else None})
    return out
