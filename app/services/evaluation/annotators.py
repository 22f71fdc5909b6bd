"""Per-annotator figures: how much each person labelled, what came back to them, and the geometry's word on their
labels (``GET /api/stats/annotators``, ``v3d stats annotators``, the statistics page's table).

Everything is read from what is stored, in a few indexed aggregate reads (no system is judged per request):

* ``edits``: the person's label edits in the window (audit entries of ``app.services.curation.handoff.LABEL_ACTIONS``:
  ball, field lines, mirror, exclusion; an undo is recorded under the edit's action and counts as one);
  ``systems_touched``: the systems those edits were on.
* ``systems_decided``: of those systems, the ones accepted or rejected now; ``accepted_first_review``: the ones
  accepted now that were never returned (marked needs fix) to anyone.
* ``needs_fix_received``: the hand-offs of needs-fix systems to the person in the window (``review_handoffs``).
* ``median_edit_to_review_s``: per system touched, from the person's last edit in the window to the next system
  decision (``system.review``) after it, the median in seconds (None without one).
* ``median_label_distance_px``: over the ball labels whose newest edit is theirs (edited in the window), the median
  distance from the ball the system's other views agree on, px of a 1920-wide image, as the recomputation stored it
  (``ball_reprojections.others_distance_px``; None without one); ``accused_share``: the share of those labels a
  label-accusing doubt names (None without a label).

Beside them, each person's figures as a reviewer, from the system decisions they made with a reviewer's role (audit
entries ``system.review``; an undo or a revert is not a decision made, nor is what any role's work writes under the
same action: a ``fixed`` sent back by the person the system was returned to, a decision set back to pending by an
edit of the labels or the camera in the same write, and a batch's acceptance after a sample, ``after.review.batch_id``,
whose undo is an undo too):

* ``decisions``: the system decisions they made in the window; ``accepted``, ``rejected``, ``needs_fix``: of those,
  the ones that set that status (``pending`` back is counted in ``decisions`` only);
* ``re_reviews``: of those, decisions on a system that came back fixed (its status before the decision ``fixed``).

The window is ``since <= at < until`` on the entries' times (UTC; either open). People are the actors of label edits
and of decisions, and the receivers of hand-offs; work run on the machine (``cli:...``) is no one's.
"""
from __future__ import annotations

import bisect
import statistics
from collections import defaultdict
from dataclasses import asdict, dataclass
from datetime import datetime
from typing import Any, Optional

import sqlalchemy as sa
from sqlalchemy.orm import Session, selectinload

from app.db.models import AuditEntry, BallReprojection, Doubt, ReviewHandoff, ReviewStatus, System, User
from app.services.audit.log import MACHINE_ACTOR
from app.services.curation.handoff import LABEL_ACTIONS

#: The figures of one person, in the order of the CSV's columns (one home: the API's model and the CSV read it).
FIELDS = ("name", "edits", "systems_touched", "systems_decided", "needs_fix_received", "accepted_first_review",
          "median_edit_to_review_s", "median_label_distance_px", "accused_share",
          "decisions", "accepted", "rejected", "needs_fix", "re_reviews")


@dataclass
class AnnotatorFigures:
    """One person's figures (module docstring)."""

    name: str
    edits: int = 0
    systems_touched: int = 0
    systems_decided: int = 0
    needs_fix_received: int = 0
    accepted_first_review: int = 0
    median_edit_to_review_s: Optional[float] = None
    median_label_distance_px: Optional[float] = None
    accused_share: Optional[float] = None
    decisions: int = 0
    accepted: int = 0
    rejected: int = 0
    needs_fix: int = 0
    re_reviews: int = 0

    def as_dict(self) -> dict[str, Any]:
        """The figures keyed by :data:`FIELDS`."""
        return asdict(self)


def _window(column: Any, since: Optional[datetime], until: Optional[datetime]) -> list[Any]:
    out = []
    if since is not None:
        out.append(column >= since)
    if until is not None:
        out.append(column < until)
    return out


def _epoch(at: Any, dialect: str) -> Any:
    """SQL: the timestamp ``at`` as seconds (a float; only differences are read): SQLite's stored UTC text through
    ``julianday`` (days), PostgreSQL's ``timestamptz`` through ``extract(epoch ...)``."""
    if dialect == "sqlite":
        return sa.func.julianday(at) * 86400.0
    return sa.extract("epoch", at)


def _person(actor: str) -> bool:
    return not (actor == MACHINE_ACTOR or actor.startswith(f"{MACHINE_ACTOR}:"))


def annotator_figures(session: Session, since: Optional[datetime] = None,
                      until: Optional[datetime] = None) -> list[AnnotatorFigures]:
    """Every person's figures over ``since <= at < until`` (UTC; None: open), by name (module docstring)."""
    people: dict[str, AnnotatorFigures] = {}
    conn = session.connection()  # Core rows: tens of thousands of plain tuples, no ORM row processing

    def of(name: str) -> AnnotatorFigures:
        return people.setdefault(name, AnnotatorFigures(name=name))

    # per person and system touched: the label edits, the last one's time, the system's status now and whether it
    # was ever returned; the system decisions' times. Times cross as epoch seconds (SQL): no timestamp is converted.
    dialect = session.get_bind().dialect.name
    returned = sa.exists().where(ReviewHandoff.system_id == AuditEntry.system_id)
    rows = conn.execute(
        sa.select(AuditEntry.actor, AuditEntry.system_id, sa.func.count(), _epoch(sa.func.max(AuditEntry.at), dialect),
                  sa.type_coerce(System.review_status, sa.String), returned)
        .join(System, System.id == AuditEntry.system_id)
        .where(AuditEntry.action.in_(LABEL_ACTIONS), *_window(AuditEntry.at, since, until))
        .group_by(AuditEntry.actor, AuditEntry.system_id, System.review_status)).all()
    decisions: dict[int, list[float]] = defaultdict(list)
    for system_id, at in conn.execute(
            sa.select(AuditEntry.system_id, _epoch(AuditEntry.at, dialect))
            .where(AuditEntry.action == "system.review", AuditEntry.system_id.is_not(None),
                   *_window(AuditEntry.at, since, None))
            .order_by(AuditEntry.system_id, AuditEntry.at)):
        decisions[system_id].append(float(at))
    waits: dict[str, list[float]] = defaultdict(list)
    for actor, system_id, n, last, status, was_returned in rows:
        if not _person(actor):
            continue
        f = of(actor)
        f.edits += int(n)
        f.systems_touched += 1
        if status in (ReviewStatus.ACCEPTED.value, ReviewStatus.REJECTED.value):
            f.systems_decided += 1
            if status == ReviewStatus.ACCEPTED.value and not was_returned:
                f.accepted_first_review += 1
        times = decisions.get(system_id)
        if times:
            i = bisect.bisect_right(times, float(last))
            if i < len(times):
                waits[actor].append(times[i] - float(last))
    for actor, found in waits.items():
        of(actor).median_edit_to_review_s = float(statistics.median(found))
    for name, n in conn.execute(
            sa.select(User.name, sa.func.count()).select_from(ReviewHandoff)
            .join(User, User.id == ReviewHandoff.returned_to_id)
            .where(*_window(ReviewHandoff.returned_at, since, until)).group_by(User.name)):
        of(name).needs_fix_received = int(n)

    _label_figures(session, since, until, of)
    _review_figures(session, since, until, of)
    return [people[n] for n in sorted(people)]


def _status(state: Any) -> Optional[str]:
    """The review status a ``system.review`` entry's state holds (``{"review": {"status": ...}}``), or None."""
    review = state.get("review") if isinstance(state, dict) else None
    return review.get("status") if isinstance(review, dict) else None


def _batch_acceptance(state: Any) -> bool:
    """Whether a ``system.review`` entry's state is a batch's acceptance after a sample
    (``app.services.curation.batches``: ``{"review": {"batch_id": ...}}``), which no person decided one by one."""
    review = state.get("review") if isinstance(state, dict) else None
    return isinstance(review, dict) and review.get("batch_id") is not None


def _review_figures(session: Session, since: Optional[datetime], until: Optional[datetime], of: Any) -> None:
    """The reviewer figures (module docstring) from the system decisions in the window: the entries' before and after
    states (inline, or their stored rows)."""
    entries = session.scalars(
        sa.select(AuditEntry)
        .where(AuditEntry.action == "system.review", AuditEntry.reverts_id.is_(None),
               *_window(AuditEntry.at, since, until))
        .options(selectinload(AuditEntry.before_state), selectinload(AuditEntry.after_state)))
    counted = {ReviewStatus.ACCEPTED.value: "accepted", ReviewStatus.REJECTED.value: "rejected",
               ReviewStatus.NEEDS_FIX.value: "needs_fix"}
    made = [e for e in entries if _person(e.actor) and _status(e.after) != ReviewStatus.FIXED.value
            and not _batch_acceptance(e.after)]
    edited = _edited_writes(session, {(e.system_id, e.system_version) for e in made
                                      if _status(e.after) == ReviewStatus.PENDING.value})
    for entry in made:
        if (entry.system_id, entry.system_version) in edited and _status(entry.after) == ReviewStatus.PENDING.value:
            continue  # an edit's reset of the decision, not a decision
        f = of(entry.actor)
        f.decisions += 1
        field = counted.get(_status(entry.after) or "")
        if field:
            setattr(f, field, getattr(f, field) + 1)
        if _status(entry.before) == ReviewStatus.FIXED.value:
            f.re_reviews += 1


#: The actions of a write that reviews, and so never sets a decision back to pending on its own behalf.
_REVIEW_ACTIONS = ("system.review", "view.review", "view.calibration_review", "system.assign")


def _edited_writes(session: Session, writes: set[tuple[Optional[int], Optional[int]]]
                   ) -> set[tuple[Optional[int], Optional[int]]]:
    """Of ``writes`` (system id, the version the write gave it: ``AuditEntry.system_version``), those that also
    recorded an edit (an action not of :data:`_REVIEW_ACTIONS`): the writes whose pending decision is a reset."""
    known = [(sid, ver) for sid, ver in writes if sid is not None and ver is not None]
    out: set[tuple[Optional[int], Optional[int]]] = set()
    for start in range(0, len(known), 500):  # a bounded IN list per read
        chunk = known[start:start + 500]
        out.update((sid, ver) for sid, ver in session.execute(
            sa.select(AuditEntry.system_id, AuditEntry.system_version).distinct()
            .where(AuditEntry.system_id.in_({sid for sid, _ in chunk}), AuditEntry.action.not_in(_REVIEW_ACTIONS)))
            if (sid, ver) in set(chunk))
    return out


def _label_figures(session: Session, since: Optional[datetime], until: Optional[datetime], of: Any) -> None:
    """The geometry's figures (``median_label_distance_px``, ``accused_share``) over each frame's newest ball edit."""
    newest = (sa.select(sa.func.max(AuditEntry.id).label("id"))
              .where(AuditEntry.action == "ball.edit", AuditEntry.frame_id.is_not(None),
                     *_window(AuditEntry.at, since, until))
              .group_by(AuditEntry.frame_id).subquery())
    accused = (sa.select(Doubt.frame_id).where(Doubt.accuses_label.is_(True), Doubt.frame_id.is_not(None))
               .distinct().subquery())
    rows = session.connection().execute(
        sa.select(AuditEntry.actor, BallReprojection.others_distance_px, accused.c.frame_id.is_not(None))
        .join(newest, newest.c.id == AuditEntry.id)
        .outerjoin(BallReprojection, BallReprojection.frame_id == AuditEntry.frame_id)
        .outerjoin(accused, accused.c.frame_id == AuditEntry.frame_id))
    distances: dict[str, list[float]] = defaultdict(list)
    labels: dict[str, list[bool]] = defaultdict(list)
    for actor, distance, is_accused in rows:
        if not _person(actor):
            continue
        labels[actor].append(bool(is_accused))
        if distance is not None:
            distances[actor].append(float(distance))
    for actor, flags in labels.items():
        f = of(actor)
        f.accused_share = sum(flags) / len(flags)
        found = distances.get(actor)
        f.median_label_distance_px = float(statistics.median(found)) if found else None
