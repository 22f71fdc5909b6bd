"""Doubts of a multi-view system: what the service stores of ``app.geometry.doubts``.

:func:`update_doubts` runs at the end of every system recomputation (``app.services.curation.recompute``), so
a system's doubts change in the transaction of the edit that changed them and the queue never
recomputes them: it reads ``System.doubt_counts`` (``{kind: n}``) and ``System.label_doubts`` (how
many accuse a label, the queue's sort key) written here. :func:`doubt_views` is the one adapter from
stored rows to the judge's :class:`~app.geometry.doubts.DoubtView` (the benchmark uses it too);
:func:`doubt_settings` maps the service's settings onto :class:`~app.geometry.doubts.DoubtSettings`.
"""
from __future__ import annotations

import dataclasses
from collections import Counter
from typing import Any

import numpy as np
import sqlalchemy as sa
from sqlalchemy.orm import Session, selectinload

from app.core.config import Settings
from app.db.models import CalibrationStatus, Doubt, Frame, Game, System
from app.db.types import json_safe
from app.geometry.camera import Camera
from app.geometry.doubts import DoubtSettings, DoubtView, judge_system
from app.geometry.calibration.frame import MIRROR_FLAG, RIG_FLAG
from app.services.kinds import kind_of


def doubt_settings(settings: Settings) -> DoubtSettings:
    """The judge's settings: each field ``f`` of :class:`DoubtSettings` from ``settings.doubt_f`` when
    the service has that setting, else from ``settings.f`` (the triangulation's tau, rule, baseline,
    parallax and ball diameter), else the judge's default."""
    values: dict[str, Any] = {}
    for f in dataclasses.fields(DoubtSettings):
        for name in (f"doubt_{f.name}", f.name):
            if name in Settings.model_fields:
                values[f.name] = getattr(settings, name)
                break
    return DoubtSettings(**values)


def is_excluded(frame: Frame) -> bool:
    """True when a reviewer excluded the view from its system's triangulation."""
    return frame.review is not None and bool(frame.review.excluded)


def doubt_view(frame: Frame, camera: Camera | None = None) -> DoubtView:
    """One stored frame as the doubt judge sees it (its camera is rebuilt from the stored JSON unless
    given)."""
    cal = frame.calibration
    calibrated = cal is not None and cal.status is CalibrationStatus.CALIBRATED and cal.camera is not None
    if camera is None and calibrated:
        camera = Camera.from_soccernet(cal.camera)  # type: ignore[union-attr]
    label = frame.ball_label
    box = np.asarray(label.box, float) if label is not None and label.box is not None else None
    point = np.asarray(label.point, float) if label is not None and label.point is not None else None
    lines = frame.field_lines.lines if frame.field_lines is not None else {}
    flags = list(cal.flags or []) if cal is not None else []
    return DoubtView(
        view_id=frame.id, name=frame.name, role=frame.role.value, width=frame.width, height=frame.height,
        camera=camera if calibrated else None, admitted=bool(calibrated and cal.admitted),  # type: ignore[union-attr]
        jac=cal.jac_0005 if cal is not None else None,
        line_classes=sum(1 for polys in lines.values() if polys), box=box, point=point,
        excluded=is_excluded(frame), mirror_flagged=MIRROR_FLAG in flags,
        mirror_evidence=cal.mirror_evidence if cal is not None else None,
        calibration_reason=cal.reason if cal is not None and cal.status is CalibrationStatus.REFUSED else None,
        rig_assisted=RIG_FLAG in flags,
    )


def doubt_views(system: System, cameras: dict[int, Camera] | None = None) -> list[DoubtView]:
    """Every view of ``system`` as a :class:`DoubtView`, in the system's order (``cameras``: frame
    id -> camera already built by the caller, to spare rebuilding it)."""
    cameras = cameras or {}
    return [doubt_view(f, cameras.get(f.id)) for f in system.frames]


def update_doubts(system: System, settings: Settings, cameras: dict[int, Camera] | None = None) -> list[Doubt]:
    """Judge the system (``app.geometry.doubts.judge_system``) and replace its stored doubts and
    counts. Changes the session only; the caller commits (with the edit that caused it)."""
    found = judge_system(doubt_views(system, cameras), doubt_settings(settings))
    found = kind_of(system).judge_doubts(system, found, cameras)
    system.doubts.clear()
    rows = [
        Doubt(frame_id=d.view_id, kind=d.kind, accuses_label=d.accuses_label, message=d.message,
              evidence=json_safe(d.evidence), suggestion=json_safe(d.suggestion) if d.suggestion else None)
        for d in found
    ]
    system.doubts.extend(rows)
    system.doubt_counts = dict(Counter(d.kind for d in found))
    system.label_doubts = sum(1 for d in found if d.accuses_label)
    return rows


def doubt_json(doubt: Doubt, frame_names: dict[int, str]) -> dict[str, Any]:
    """A stored doubt as the API sends it: ``frame`` is the image name (None for the system)."""
    return {
        "kind": doubt.kind, "frame_id": doubt.frame_id,
        "frame": frame_names.get(doubt.frame_id) if doubt.frame_id is not None else None,
        "accuses_label": doubt.accuses_label, "message": doubt.message, "evidence": doubt.evidence,
        "suggestion": doubt.suggestion,
    }


def doubts_report(session: Session, batch: int = 500) -> dict[str, Any]:
    """Every system's stored doubts (the JSON of ``v3d doubts --json``)::

        {"systems": [{"game": {"league", "season", "match"}, "system": <action image name>,
                      "doubts": [{"kind", "frame": <image name> | null, "message", "evidence",
                                  "suggestion", ...}]}]}

    Systems in (league, season, match, name) order, read ``batch`` at a time.
    """
    ids = list(session.scalars(
        sa.select(System.id).join(Game, Game.id == System.game_id)
        .order_by(Game.league, Game.season, Game.match, sa.func.length(System.name), System.name, System.id)
    ))
    out = []
    for start in range(0, len(ids), batch):
        chunk = ids[start:start + batch]
        systems = session.scalars(
            sa.select(System).where(System.id.in_(chunk))
            .options(selectinload(System.game), selectinload(System.frames), selectinload(System.doubts))
        ).all()
        by_id = {s.id: s for s in systems}
        for sid in chunk:
            s = by_id[sid]
            names = {f.id: f.name for f in s.frames}
            out.append({
                "game": {"league": s.game.league, "season": s.game.season, "match": s.game.match},
                "system": s.name,
                "doubts": [doubt_json(d, names) for d in s.doubts],
            })
        session.expunge_all()
    return {"systems": out}
