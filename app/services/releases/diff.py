"""What changed between two releases (``GET /api/releases/{a}/diff/{b}``, ``v3d release diff``).

Systems are matched by id. A system in ``b`` only is **added**, in ``a`` only **removed**; one in both whose
document differs (``app.services.releases.content``: a different digest) is **changed**, with how far its 3D ball
moved (``ball3d_moved_m``: Euclidean distance in world metres between the two fused balls, SoccerNet world frame;
null when either has none) and, per view (frame) that differs, what: ``label`` (ball label kind, box or point),
``lines`` (field lines), ``calibration`` (camera, its source, status or admission), ``decision`` (the view's ball
or calibration decision, or its exclusion), ``added`` / ``removed`` (a view the other release's system lacks).
Only changed documents are read: a diff costs reading the two releases' rows plus the documents that differ.
A removed system says why it left (``why``, :func:`why_removed`): ``rejected`` (its decision now), ``no longer
accepted`` (pending, needs fix or fixed now) or ``deleted`` (no such system now).
"""
from __future__ import annotations

import csv
import io
import math
from dataclasses import dataclass
from typing import Any, Optional

import sqlalchemy as sa
from sqlalchemy.orm import Session

from app.datasets.csv_cells import inert_row
from app.db.models import ReviewDecision, ReviewStatus, System
from app.db.types import json_loads
from app.services.releases.content import get_release, read_games, read_systems, release_content
from app.services.releases.document import SystemDocument

#: The view fields each kind of change compares (a view's row in a system document).
VIEW_CHANGES: dict[str, tuple[str, ...]] = {
    "label": ("ball_kind", "ball_box", "ball_point"),
    "lines": ("lines_json",),
    "calibration": ("camera_json", "cal_source", "cal_status", "admitted"),
    "decision": ("view_status", "view_calibration_status", "excluded"),
}
#: The columns of the diff as CSV (:func:`diff_csv`).
DIFF_CSV_COLUMNS = ("change", "system_id", "name", "game", "ball3d_moved_m", "views", "why")
#: Why a system left a release (:func:`why_removed`): the words of each case.
WHY_REMOVED = ("rejected", "no longer accepted", "deleted")


def why_removed(session: Session, system_ids: list[int]) -> dict[int, str]:
    """system id -> why it is in no newer release (:data:`WHY_REMOVED`), from its decision now: ``rejected``,
    ``no longer accepted`` (any other status but accepted: pending, needs fix, fixed; or accepted again since) or
    ``deleted`` (the system is gone)."""
    if not system_ids:
        return {}
    out = dict.fromkeys(system_ids, "deleted")
    rows = session.execute(sa.select(System.id, ReviewDecision.status)
                           .outerjoin(ReviewDecision, ReviewDecision.system_id == System.id)
                           .where(System.id.in_(system_ids)))
    for sid, status in rows:
        out[sid] = "rejected" if status is ReviewStatus.REJECTED else "no longer accepted"
    return out


def _value(text: Any) -> Any:
    """A stored JSON text as its value (so that two spellings of one value compare equal); other values as they
    are."""
    if isinstance(text, str) and text[:1] in "[{\"0123456789-ntf":
        try:
            return json_loads(text)
        except ValueError:
            return text
    return text


def ball_moved_m(a: Optional[str], b: Optional[str]) -> Optional[float]:
    """Distance (m) between two stored 3D balls (JSON text ``[x, y, z]``, world metres); None when either is
    missing.

    >>> ball_moved_m("[0, 0, 0]", "[3.0, 4.0, 0]")
    5.0
    """
    pa, pb = _value(a), _value(b)
    if not isinstance(pa, list) or not isinstance(pb, list) or len(pa) != 3 or len(pb) != 3:
        return None
    return math.dist(pa, pb)


def view_changes(a: SystemDocument, b: SystemDocument) -> list[dict[str, Any]]:
    """Per view (frame, by id) of two documents of one system: ``{"frame_id", "view", "changes"}`` for each view that
    differs (:data:`VIEW_CHANGES`, or ``added`` / ``removed``), in the newer document's order."""
    old = {f.frame_id: f for f in a.frames}
    new = {f.frame_id: f for f in b.frames}
    out = []
    for fid, frame in new.items():
        before = old.get(fid)
        if before is None:
            out.append({"frame_id": fid, "view": frame.name, "changes": ["added"]})
            continue
        kinds = [kind for kind, fields in VIEW_CHANGES.items()
                 if any(_value(getattr(before, f)) != _value(getattr(frame, f)) for f in fields)]
        if kinds:
            out.append({"frame_id": fid, "view": frame.name, "changes": kinds})
    out.extend({"frame_id": fid, "view": f.name, "changes": ["removed"]} for fid, f in old.items() if fid not in new)
    return out


@dataclass(frozen=True)
class ReleaseDiff:
    """A diff (module docstring) as the API answers it."""

    source: dict[str, str]
    target: dict[str, str]
    added: list[dict[str, Any]]
    removed: list[dict[str, Any]]
    changed: list[dict[str, Any]]
    unchanged: int

    def as_dict(self) -> dict[str, Any]:
        """``{"from", "to", "added", "removed", "changed", "unchanged"}`` (``from``/``to``: name and hash)."""
        return {"from": self.source, "to": self.target, "added": self.added, "removed": self.removed,
                "changed": self.changed, "unchanged": self.unchanged}


def diff_releases(session: Session, a: str, b: str) -> ReleaseDiff:
    """What changed from release ``a`` to release ``b`` (module docstring); each list in system id order.

    Raises:
        NotFoundError: either release does not exist.
    """
    ra, rb = get_release(session, a), get_release(session, b)
    ca, cb = release_content(session, ra), release_content(session, rb)
    game_docs = read_games(session, [*ca.games.values(), *cb.games.values()])
    games = {g.game_id: f"{g.league}/{g.season}/{g.match}" for g in game_docs.values()}

    def named(sid: int, entry: tuple[int, str, str]) -> dict[str, Any]:
        return {"system_id": sid, "name": entry[1], "game": games.get(entry[0], "")}

    added = [named(sid, e) for sid, e in sorted(cb.systems.items()) if sid not in ca.systems]
    removed = [named(sid, e) for sid, e in sorted(ca.systems.items()) if sid not in cb.systems]
    why = why_removed(session, [r["system_id"] for r in removed])
    for r in removed:
        r["why"] = why[r["system_id"]]
    differ = [sid for sid in sorted(set(ca.systems) & set(cb.systems)) if ca.systems[sid][2] != cb.systems[sid][2]]
    docs = read_systems(session, [d for sid in differ for d in (ca.systems[sid][2], cb.systems[sid][2])])
    changed = []
    for sid in differ:
        da, db = docs[ca.systems[sid][2]], docs[cb.systems[sid][2]]
        changed.append({**named(sid, cb.systems[sid]), "ball3d_moved_m": ball_moved_m(da.ball3d, db.ball3d),
                        "views": view_changes(da, db)})
    unchanged = len(set(ca.systems) & set(cb.systems)) - len(differ)
    return ReleaseDiff({"name": ra.name, "hash": ra.hash}, {"name": rb.name, "hash": rb.hash},
                       added, removed, changed, unchanged)


def diff_csv(diff: ReleaseDiff) -> str:
    """The diff as CSV (:data:`DIFF_CSV_COLUMNS`): one row per added, removed or changed system; ``views`` lists
    ``<view>: <change>,<change>`` separated by ``; ``, ``ball3d_moved_m`` is empty when unknown and ``why`` says why a
removed system left (empty otherwise). A cell a
    spreadsheet would run as a formula is escaped (``app.datasets.csv_cells``)."""
    out = io.StringIO()
    writer = csv.writer(out, lineterminator="\n")
    writer.writerow(DIFF_CSV_COLUMNS)
    for change, items in (("added", diff.added), ("removed", diff.removed), ("changed", diff.changed)):
        for item in items:
            moved = item.get("ball3d_moved_m")
            views = "; ".join(f"{v['view']}: {','.join(v['changes'])}" for v in item.get("views", []))
            writer.writerow(inert_row([change, str(item["system_id"]), item["name"], item["game"],
                                       "" if moved is None else repr(moved), views, item.get("why", "")]))
    return out.getvalue()
