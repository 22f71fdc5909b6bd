"""The review queue and the frame list: filters, the stored sort keys, pages and queue neighbours.

Nothing here writes, and nothing is aggregated per request: the queue reads the per-system figures that
every recomputation stores on ``System`` (``app.services.derivation.recompute.update_summary``; aggregates over the
**admitted** views, the ones the 3D ball is made of, method.md sections 4 and 5): ``lowest_jac``
(JaC@0.5 %), ``worst_error_px`` (the largest reprojection error of the fused ball, px of the view's own
image, SoccerNet-v3D's ``rep_error``), ``views_flagged`` (every view flagged probably mirrored),
``views_above_tau`` (by ``app.geometry.pair_error.error_above_tau``, the rule the system view's
per-view ``error_above_tau`` uses too: queue and system page cannot disagree), and the doubt counts.
Rows come back as ORM objects with what their answer shows loaded; the API's response models
(``app.api.view_schemas``) shape them.

Queue order (``sort``): ``severity`` (the work still to do first: pending systems and those returned as fixed, then
the decided ones; within each the most severe doubt first, the stored ``System.label_severity``, then the largest
reprojection error, then the count of label doubts), ``doubts`` (the stored count of label-accusing doubts, ties by
the largest reprojection error), ``ball_evidence`` (what backs the 3D ball in ``BallEvidence``'s order, vouched first;
ties by the largest reprojection error), ``worst_error``, ``lowest_jac`` or ``name``, descending with a leading ``-``;
systems without the sort value (no 3D ball, no admitted view) always come last, ties break by id (in the sort's
direction, so a descending sort is its index scanned backwards). The default, :data:`DEFAULT_SORT`,
is ``-severity``: the work still to do, worst first, as a review tool's queue puts pending work on top (a decided
system on top would be reopened and decided again). ``name``
orders by game, then system name with numeric names in numeric order (2.png before 10.png). The ``doubt``
filter keeps systems with a doubt of one kind (or any label-accusing one); doubts and their counts are
stored by the recomputation (``app.services.derivation.doubts``), never computed here; so is each ball's tier, which
the ``ball_evidence`` filter reads (``System.ball_evidence``, indexed by review status).

Pages: by ``offset`` (links and scripts that jump to page N) or by cursor (``after`` / ``before``: the
sort key values of a page's last / first row, :func:`encode_cursor`). Either way the page is read as
*slices* of the order (:func:`_slices`), each an index range scanned in the index's own order: the rows
equal to the cursor on every key but the last and beyond it on the last, then those equal on every key
but the last two, ... (the seek of :func:`queue_neighbours`, with a ``LIMIT`` of a page), and, from the
start of the queue, a key whose NULLs come last as its values, then its NULLs. No slice needs ``NULLS
LAST`` on a column that holds NULLs, so no page sorts the queue; a deep ``offset`` skips ids along the
sort's index (covering: the sort keys and the row id) and reads the rows of the page only. The ``severity`` order's
first key (work to do or decided) takes two values: its slices are one per value (an equality, never a range), so that
the keys after it are read in the order of its index (``ix_systems_review_order_severity``) whatever their direction,
and no ORDER BY names a key its slice holds equal (SQLite would sort instead of reading the index).
"""
from __future__ import annotations

import base64
import binascii
import functools
import json
import math
from dataclasses import dataclass
from typing import Any, Literal, Optional

import sqlalchemy as sa
from sqlalchemy.orm import Session, contains_eager, joinedload, selectinload

from app.core.errors import InvalidInputError
from app.db.models import (
    BallEvidence,
    BallReprojection,
    Calibration,
    CalibrationStatus,
    Doubt,
    Frame,
    Game,
    ReviewStatus,
    System,
    Triangulation,
    User,
)
from app.db.models.labels import TO_REVIEW
from app.db.types import DB_INT_MAX, DB_INT_MIN
from app.services.accounts.users import ASSIGNEE_NONE

SystemSort = Literal["severity", "-severity", "doubts", "-doubts", "worst_error",
                      "-worst_error", "lowest_jac", "-lowest_jac", "name", "-name", "ball_evidence", "-ball_evidence"]
FrameSort = Literal["error", "-error", "jac", "-jac", "name", "-name"]
#: The review queue's default order: pending (and fixed, to re-review) systems first, the most severe first.
DEFAULT_SORT: SystemSort = "-severity"


def _to_review_first() -> Any:
    """SQL: 0 for a system of :data:`TO_REVIEW`, 1 for a decided one (the ``severity`` order's first key), written as
    the index ``ix_systems_review_order_severity`` writes it (``REVIEW_ORDER_SQL``: literals, no bound parameter),
    so that both engines read the order from that index."""
    whens: list[tuple[Any, Any]] = [(sa.literal_column(f"'{s.value}'"), sa.literal_column("0")) for s in TO_REVIEW]
    return sa.type_coerce(sa.case(*whens, value=System.review_status, else_=sa.literal_column("1")), sa.Integer)


@dataclass(frozen=True)
class SystemFilters:
    """Filters of the review queue; None means "any". Ranges are inclusive."""

    game_id: Optional[int] = None
    status: Optional[ReviewStatus] = None
    jac_min: Optional[float] = None
    jac_max: Optional[float] = None
    error_min: Optional[float] = None
    error_max: Optional[float] = None
    #: The 3D ball's sigma (metres, ``Triangulation.sigma_m``) at least / at most this: systems with a ball and its
    #: sigma only.
    sigma_min: Optional[float] = None
    sigma_max: Optional[float] = None
    #: Only systems with a doubt of this kind (``app.geometry.doubts``), or ``"any"``: with at least
    #: one label-accusing doubt; ``"none"``: with none.
    doubt: Optional[str] = None
    #: Only systems assigned to the user of this name (``app.services.curation.assignment``), or
    #: :data:`ASSIGNEE_NONE`: the unassigned ones. An unknown name matches nothing, as a known user with none does
    #: (the answer tells no one which names exist).
    assignee: Optional[str] = None
    #: Only systems with a view whose camera carries this flag (one of
    #: ``app.geometry.calibration.result.SOURCE_FLAGS``: placed at a rig position, placed by its players).
    camera: Optional[str] = None
    #: Only systems whose 3D ball is in this tier (the stored ``System.ball_evidence``, ``app.geometry.ball_evidence``).
    ball_evidence: Optional[BallEvidence] = None


@dataclass(frozen=True)
class FrameFilters:
    """Filters of the frame list; None means "any". ``calibration`` is a status or ``"none"`` (no
    calibration row yet). JaC is JaC@0.5 %; error is the view's reprojection error in px."""

    game_id: Optional[int] = None
    system_id: Optional[int] = None
    calibration: Optional[Literal["calibrated", "refused", "none"]] = None
    admitted: Optional[bool] = None
    jac_min: Optional[float] = None
    jac_max: Optional[float] = None
    error_min: Optional[float] = None
    error_max: Optional[float] = None


@dataclass(frozen=True)
class SystemPage:
    """One page of the queue: ``items`` are systems with their game, review decision and triangulation
    loaded; ``total`` rows match the filters; ``counts`` are per review status over the same filters except
    the status one (the progress of the whole filtered queue). ``next_cursor`` / ``prev_cursor`` page on
    (``after=``) or back (``before=``) in the same order, None when no row lies beyond the page that way."""

    items: list[System]
    total: int
    counts: dict[str, int]
    next_cursor: Optional[str] = None
    prev_cursor: Optional[str] = None


@dataclass(frozen=True)
class FramePage:
    """One page of frames (calibration, label, reprojection and review loaded) and how many match."""

    items: list[Frame]
    total: int


def _review_status() -> Any:
    """A system's review status: the copy stored on the system (pending without a decision)."""
    return System.review_status


def _queue_from() -> sa.Select[Any]:
    """The queue's rows: each system with its game, review decision and triangulation (the 3D ball); the
    per-system figures are the stored ``System`` columns (no aggregation here)."""
    return (
        sa.select(System).join(Game, Game.id == System.game_id)
        .options(contains_eager(System.game), joinedload(System.review), joinedload(System.triangulation))
    )


def _range(column: Any, lo: Optional[float], hi: Optional[float]) -> list[sa.ColumnElement[bool]]:
    out = []
    if lo is not None:
        out.append(column >= lo)
    if hi is not None:
        out.append(column <= hi)
    return out


def _system_conditions(filters: SystemFilters, with_status: bool = True) -> list[Any]:
    conds: list[Any] = []
    if filters.game_id is not None:
        conds.append(System.game_id == filters.game_id)
    if with_status and filters.status is not None:
        conds.append(_review_status() == filters.status)
    conds += _range(System.lowest_jac, filters.jac_min, filters.jac_max)
    conds += _range(System.worst_error_px, filters.error_min, filters.error_max)
    if filters.sigma_min is not None or filters.sigma_max is not None:
        conds.append(sa.exists().where(Triangulation.system_id == System.id, Triangulation.ball3d.is_not(None),
                                       *_range(Triangulation.sigma_m, filters.sigma_min, filters.sigma_max)))
    if filters.doubt == "any":
        conds.append(System.label_doubts > 0)
    elif filters.doubt == "none":
        conds.append(System.label_doubts == 0)
    elif filters.doubt is not None:
        conds.append(sa.exists().where(Doubt.system_id == System.id, Doubt.kind == filters.doubt))
    if filters.camera is not None:
        view = sa.orm.aliased(Frame)  # its own name: the queue's statement may join the frames already
        conds.append(sa.exists(sa.select(Calibration.frame_id).join(view, view.id == Calibration.frame_id).where(
            view.system_id == System.id, sa.cast(Calibration.flags, sa.Text).like(f'%"{filters.camera}"%'))))
    if filters.ball_evidence is not None:
        conds.append(System.ball_evidence == filters.ball_evidence)
    if filters.assignee == ASSIGNEE_NONE:
        conds.append(System.assignee_id.is_(None))
    elif filters.assignee is not None:  # the index on assignee_id, the user's id looked up once
        conds.append(System.assignee_id == sa.select(User.id).where(User.name == filters.assignee).scalar_subquery())
    return conds


def matching_system_ids(filters: SystemFilters) -> sa.Select[Any]:
    """SQL: the ids of every system the queue ``filters`` match (all pages, status filter included), in id
    order: what a bulk action on "the result of this filter" acts on (``app.services.curation.assignment``)."""
    return sa.select(System.id).where(*_system_conditions(filters)).order_by(System.id)


def _natural_name(column: Any) -> list[Any]:
    # numeric names ("2.png", "10.png") in numeric order: shorter first, then text
    return [sa.func.length(column, type_=sa.Integer), column]


@dataclass(frozen=True)
class _SortKey:
    """One key of the queue's order: an SQL expression, its direction, and whether NULLs come last
    (the stored aggregates are NULL without a 3D ball or an admitted view)."""

    expr: Any
    desc: bool = False
    nulls_last: bool = False
    #: Every value the key takes, ascending, when they are few and never NULL (the work-to-do-first key: 0, 1):
    #: its rows beyond a value are read as one slice per value (an equality, so that the keys after it are read in
    #: their index's order whatever their direction), not as a range.
    values: tuple[Any, ...] = ()

    def clause(self, reverse: bool = False, plain: bool = False) -> Any:
        """The ORDER BY term; ``plain``: without the NULLs placement (for rows where the key is known
        to be all NULL or all non-NULL, so that the order is the index's own)."""
        desc = self.desc != reverse
        c = self.expr.desc() if desc else self.expr.asc()
        if self.nulls_last and not plain:
            c = c.nulls_first() if reverse else c.nulls_last()
        return c

    def equal(self, value: Any) -> Any:
        return self.expr.is_(None) if value is None else self.expr == value

    def beyond(self, value: Any, side: Literal["before", "after"]) -> list[Any]:
        """SQL: a row's key sorts strictly before (``side="before"``) or after ``value`` (the current
        row's), as conditions each of which an index answers with a range seek, nearest first: after a
        value of a key whose NULLs come last come the values beyond it, then the NULLs."""
        if self.values:
            ahead = self.desc == (side == "before")  # the values beyond are the greater ones
            ordered = self.values if ahead else self.values[::-1]
            if isinstance(value, sa.ColumnElement):  # a parameter of a statement built once: each slice guarded
                return [sa.and_(self.expr == v, value < v if ahead else value > v) for v in ordered]
            return [self.expr == v for v in ordered if (v > value if ahead else v < value)]
        if self.nulls_last and value is None:
            return [self.expr.is_not(None)] if side == "before" else []
        beyond = self.expr > value if self.desc == (side == "before") else self.expr < value
        return [beyond, self.expr.is_(None)] if self.nulls_last and side == "after" else [beyond]


def _sort_keys(sort: SystemSort) -> list[_SortKey]:
    """The queue's order as keys; the system id comes last, in the sort's direction, so that the order
    is strict and a descending sort is an index scanned backwards (no sort of the whole queue)."""
    desc = sort.startswith("-")
    key = sort.lstrip("-")
    tie = _SortKey(System.id, desc)
    if key == "name":
        cols = [Game.league, Game.season, Game.match, *_natural_name(System.name)]
        return [_SortKey(c, desc) for c in cols] + [tie]
    if key == "severity":  # the work to do first in either direction, then severity, the error, the doubts' count
        return [_SortKey(_to_review_first(), values=(0, 1)), _SortKey(System.label_severity, desc),
                _SortKey(System.worst_error_px, desc, True), _SortKey(System.label_doubts, desc), tie]
    if key == "ball_evidence":  # the enum's order, the best backed first (vouched ... none); ties by the error
        rank = sa.type_coerce(sa.case({t.value: i for i, t in enumerate(BallEvidence)}, value=System.ball_evidence,
                                      else_=len(BallEvidence)), sa.Integer)
        return [_SortKey(rank, desc), _SortKey(System.worst_error_px, True, True), tie]
    if key == "doubts":  # ties by the largest reprojection error
        return [_SortKey(System.label_doubts, desc), _SortKey(System.worst_error_px, True, True), tie]
    column = {"worst_error": System.worst_error_px, "lowest_jac": System.lowest_jac}.get(key)
    if column is None:
        raise ValueError(f"unknown sort {sort!r}")
    return [_SortKey(column, desc, True), tie]


def encode_cursor(sort: SystemSort, values: tuple[Any, ...]) -> str:
    """A queue cursor: the sort and a row's sort key values (:func:`_sort_keys`, the system id last),
    as URL-safe base64 of JSON (floats round-trip exactly). Opaque to clients."""
    raw = json.dumps([sort, list(values)], separators=(",", ":")).encode()
    return base64.urlsafe_b64encode(raw).decode().rstrip("=")


def decode_cursor(cursor: str, sort: SystemSort, field: str = "after") -> tuple[Any, ...]:
    """The sort key values of :func:`encode_cursor`'s ``cursor``.

    Raises:
        InvalidInputError (``field``): not a cursor of this queue, or made for another ``sort``; a forged or
            damaged one (a system id that is not a positive integer within the id column, a value its sort key's
            column cannot hold: :func:`_fits`), so that no cursor reaches the database as a query that fails.
    """
    keys = _sort_keys(sort)
    if len(cursor) > _MAX_CURSOR_CHARS:
        raise InvalidInputError(f"not a queue cursor (longer than {_MAX_CURSOR_CHARS} characters)", field=field)
    try:
        raw = base64.urlsafe_b64decode(cursor + "=" * (-len(cursor) % 4))
        made_for, values = json.loads(raw)
    except (binascii.Error, ValueError, TypeError, RecursionError) as exc:
        raise InvalidInputError("not a queue cursor (use next_cursor / prev_cursor of a page)", field=field) from exc
    if made_for != sort:
        shown = made_for if isinstance(made_for, str) and len(made_for) <= 20 else "another sort"
        raise InvalidInputError(f"the cursor was made for sort={shown!r}, not sort={sort!r}", field=field)
    if not isinstance(values, list) or len(values) != len(keys):
        raise InvalidInputError("not a queue cursor (use next_cursor / prev_cursor of a page)", field=field)
    if not isinstance(values[-1], int) or isinstance(values[-1], bool) or not 1 <= values[-1] <= DB_INT_MAX:
        raise InvalidInputError("not a queue cursor (its last value is a system id)", field=field)
    for i, (key, value) in enumerate(zip(keys, values, strict=True)):
        if not _fits(key, value):
            raise InvalidInputError(f"not a queue cursor (its value {i + 1} cannot be a stored "
                                    f"{_kind(key)}: forged or damaged)", field=field)
    return tuple(values)


#: Longest cursor read (characters): a real one holds a few short values (names at most 200 + 200 + 400 + 200).
_MAX_CURSOR_CHARS = 4096


def _kind(key: _SortKey) -> str:
    """What a sort key's column holds: ``integer``, ``number`` or ``text``."""
    if isinstance(key.expr.type, sa.Integer):
        return "integer"
    return "number" if isinstance(key.expr.type, (sa.Float, sa.Numeric)) else "text"


def _fits(key: _SortKey, value: Any) -> bool:
    """Whether a cursor's ``value`` can be a value of ``key``'s column, so that comparing it in SQL cannot fail
    on any database: an integer within the ``INTEGER`` columns' range (``app.db.types.DB_INT_MAX``), a finite
    number, text without a NUL character (PostgreSQL's text cannot hold one); NULL where the key's NULLs sort."""
    if value is None:
        return key.nulls_last
    if isinstance(value, bool):
        return False
    kind = _kind(key)
    if kind == "integer":
        return isinstance(value, int) and DB_INT_MIN <= value <= DB_INT_MAX
    if kind == "number":
        return isinstance(value, (int, float)) and abs(value) < 1e300 and math.isfinite(value)
    return isinstance(value, str) and "\x00" not in value


def _slice_order(keys: list[_SortKey], i: int, reverse: bool) -> list[Any]:
    """The ORDER BY of a slice whose rows are equal on ``keys[:i]`` and beyond the current row on ``keys[i]``: from
    ``keys[i]`` on (the equal ones would change nothing, and SQLite then sorts instead of reading an index whose
    leading expression they are), ``keys[i]`` without its NULLs placement (the slice fixes its NULL-ness), and
    without ``keys[i]`` itself when the slice holds one value of it (a key of ``values``)."""
    head = [] if keys[i].values else [keys[i].clause(reverse, plain=True)]
    return head + [k.clause(reverse) for k in keys[i + 1:]]


def _slices(keys: list[_SortKey], current: Optional[tuple[Any, ...]],
            side: Literal["before", "after"]) -> list[tuple[list[Any], list[Any]]]:
    """The rows strictly ``side`` of the row whose sort keys are ``current`` (None: from the start of
    the order for ``"after"``, from its end for ``"before"``) as disjoint slices, nearest first, each
    ``(conditions, order)`` with the order read from ``current`` outwards.

    With a current row: the rows equal on ``keys[:i]`` and beyond on ``keys[i]`` for i from the last key
    down (:meth:`_SortKey.beyond`), as in :func:`_neighbour`. Without: the whole order, a first key whose
    NULLs come last cut into its values and its NULLs. Every key whose NULL-ness a slice fixes is ordered
    without a NULLs placement, so a slice is its index read in order.
    """
    reverse = side == "before"
    if current is None:
        first = keys[0]
        if first.values:  # one slice per value, in the order's direction
            order = _slice_order(keys, 0, reverse)
            values = first.values[::-1] if first.desc != reverse else first.values
            return [([first.expr == v], order) for v in values]
        if not first.nulls_last:
            return [([], [k.clause(reverse) for k in keys])]
        order = [first.clause(reverse, plain=True)] + [k.clause(reverse) for k in keys[1:]]
        parts = [[first.expr.is_not(None)], [first.expr.is_(None)]]
        return [(p, order) for p in (reversed(parts) if reverse else parts)]
    out = []
    for i in reversed(range(len(keys))):
        order = _slice_order(keys, i, reverse)
        for beyond in keys[i].beyond(current[i], side):
            out.append(([*(k.equal(v) for k, v in zip(keys[:i], current, strict=False)), beyond], order))
    return out


def _walk(session: Session, sort: SystemSort, conds: list[Any], current: Optional[tuple[Any, ...]],
          side: Literal["before", "after"], limit: int, skip: int = 0) -> list[tuple[Any, ...]]:
    """Up to ``limit`` rows' sort key values (system id last), nearest first, strictly ``side`` of
    ``current`` (see :func:`_slices`) under ``conds``, after skipping ``skip`` rows. Reads ids and sort
    keys only (the sort's index); a slice is counted only to be skipped whole."""
    keys = _sort_keys(sort)
    base = sa.select(*(k.expr for k in keys)).select_from(System)
    if sort.lstrip("-") == "name":
        base = base.join(Game, Game.id == System.game_id)
    rows: list[tuple[Any, ...]] = []
    slices = _slices(keys, current, side)
    for n, (where, order) in enumerate(slices):
        stmt = base.where(*conds, *where)
        if skip and n < len(slices) - 1:
            inside = int(session.scalar(sa.select(sa.func.count()).select_from(
                stmt.with_only_columns(System.id).subquery())) or 0)
            if skip >= inside:
                skip -= inside
                continue
        rows += [tuple(r) for r in session.execute(stmt.order_by(*order).limit(limit - len(rows)).offset(skip))]
        skip = 0
        if len(rows) >= limit:
            break
    return rows


def list_games(session: Session) -> list[tuple[Game, int]]:
    """Every game with its number of systems, in (league, season, match) order."""
    n = sa.func.count(System.id)
    stmt = (
        sa.select(Game, n).outerjoin(System, System.game_id == Game.id)
        .group_by(Game.id).order_by(Game.league, Game.season, Game.match, Game.id)
    )
    return [(g, int(c)) for g, c in session.execute(stmt).all()]


def has_games(session: Session) -> bool:
    """True when the database holds at least one game."""
    return session.execute(sa.select(Game.id).limit(1)).first() is not None


def list_systems(session: Session, filters: SystemFilters = SystemFilters(), sort: SystemSort = DEFAULT_SORT,
                 limit: int = 50, offset: int = 0, after: Optional[str] = None,
                 before: Optional[str] = None) -> SystemPage:
    """One page of the review queue.

    Args:
        filters: see :class:`SystemFilters` (JaC as a fraction, errors in px).
        sort: one of :data:`SystemSort` (module docstring).
        limit, offset: the page (``limit >= 1``, ``offset >= 0``); ``offset`` counts from ``after``'s row
            when both are given, and is ignored with ``before``.
        after, before: at most one, a cursor of this ``sort`` (a page's ``next_cursor`` /
            ``prev_cursor``): the ``limit`` rows right after / right before that row. Filters may differ
            from the page that made the cursor (the cursor is a place in the order, not a row).

    Returns:
        :class:`SystemPage` with ``next_cursor`` / ``prev_cursor``.

    Raises:
        ValueError: an unknown ``sort``.
        InvalidInputError: both cursors, or a cursor that is not one of this ``sort`` (``field``: its name).
    """
    if after is not None and before is not None:
        raise InvalidInputError("give after or before, not both", field="before")
    conds = _system_conditions(filters)
    if before is not None:
        rows = _walk(session, sort, conds, decode_cursor(before, sort, "before"), "before", limit + 1)
        more_before = len(rows) > limit
        rows = rows[:limit][::-1]
        more_after = bool(rows) and bool(_walk(session, sort, conds, rows[-1], "after", 1))
    else:
        start = decode_cursor(after, sort, "after") if after is not None else None
        rows = _walk(session, sort, conds, start, "after", limit + 1, skip=offset)
        more_after = len(rows) > limit
        rows = rows[:limit]
        more_before = bool(rows) and bool(_walk(session, sort, conds, rows[0], "before", 1))
    ids = [r[-1] for r in rows]
    by_id = {s.id: s for s in session.scalars(_queue_from().where(System.id.in_(ids))).unique()} if ids else {}
    counts = _status_counts(session, _system_conditions(filters, with_status=False))
    total = counts[ReviewStatus(filters.status).value] if filters.status is not None else sum(counts.values())
    return SystemPage(items=[by_id[i] for i in ids if i in by_id], total=int(total), counts=counts,
                      next_cursor=encode_cursor(sort, rows[-1]) if more_after else None,
                      prev_cursor=encode_cursor(sort, rows[0]) if more_before else None)


def queue_ids(session: Session, filters: SystemFilters = SystemFilters(), sort: SystemSort = DEFAULT_SORT) -> list[int]:
    """Every system id of the queue ``filters`` + ``sort``, in the queue's order, across all its pages (what
    :func:`list_systems` pages through: the same slices of the sort's index, read to the end; ids and sort
    keys only). A review pass freezes this list (``app.services.curation.passes``).

    Raises:
        ValueError: an unknown ``sort``.
    """
    conds = _system_conditions(filters)
    total = int(session.scalar(sa.select(sa.func.count()).select_from(System).where(*conds)) or 0)
    if total == 0:
        return []
    return [int(r[-1]) for r in _walk(session, sort, conds, None, "after", total)]


def _status_counts(session: Session, conds: list[Any]) -> dict[str, int]:
    """Systems per review status under ``conds``: one GROUP BY on the stored status (its index); without
    conditions, the reviewed systems by status (index lookups: as many as have been reviewed) and the
    pending ones as the rest of the table's row count (a count SQLite reads from the table's b-tree
    without visiting its rows), so the unfiltered queue's progress costs what the review has done, not
    the size of the database."""
    status = _review_status()
    counts = {s.value: 0 for s in ReviewStatus}
    if conds:
        rows: list[Any] = list(session.execute(sa.select(status, sa.func.count()).where(*conds).group_by(status)))
    else:
        reviewed = [s.value for s in ReviewStatus if s is not ReviewStatus.PENDING]
        rows = list(session.execute(sa.select(status, sa.func.count()).where(status.in_(reviewed)).group_by(status)))
        everything = session.scalar(sa.select(sa.func.count()).select_from(System)) or 0
        rows.append((ReviewStatus.PENDING.value, everything - sum(int(n) for _, n in rows)))
    for s, n in rows:
        counts[ReviewStatus(s).value] += int(n)
    return counts


def queue_neighbours(session: Session, system_id: int, filters: SystemFilters = SystemFilters(),
                     sort: SystemSort = DEFAULT_SORT, held: Optional[System] = None
                     ) -> tuple[Optional[int], Optional[int]]:
    """``(prev_id, next_id)`` of a system in the queue ``filters`` + ``sort`` (None at either end, or
    for an unknown id). ``held``: the system as its session holds it committed (an edit's answer): when every sort
    key is a column of the system, its keys are taken from it instead of read (one statement fewer).

    The system itself need not match the filters (it may just have been reviewed out of a
    "pending" queue): its neighbours are then those it would have if it did.

    Two statements whatever the size of the queue: the system's sort keys, then both neighbours
    (:func:`_neighbour`), each found by index seeks from the system's place, never by scanning the
    queue up to it.
    """
    current = _held_keys(held, sort) if held is not None and held.id == system_id else None
    if current is None:
        keys_stmt, _ = _neighbour_statements(sort, filters, None)
        row = session.execute(keys_stmt, {"system_id": system_id}).first()
        if row is None:
            return None, None
        current = tuple(row)
    _, stmt = _neighbour_statements(sort, filters, tuple(v is None for v in current))
    prev_id, next_id = session.execute(stmt, {f"key{i}": v for i, v in enumerate(current) if v is not None}).one()
    return prev_id, next_id


def _held_keys(held: System, sort: SystemSort) -> Optional[tuple[Any, ...]]:
    """The sort keys of ``held`` (a system as its session holds it committed) when every key is a column of the
    system, else None (:func:`queue_neighbours` reads them)."""
    keys = _sort_keys(sort)
    if not all(getattr(k.expr, "class_", None) is System and hasattr(k.expr, "key") for k in keys):
        return None
    return tuple(getattr(held, k.expr.key) for k in keys)


@functools.lru_cache(maxsize=256)
def _neighbour_statements(sort: SystemSort, filters: SystemFilters, nulls: Optional[tuple[bool, ...]]
                          ) -> tuple[Any, Any]:
    """The two statements of :func:`queue_neighbours` for a queue, built once (building them cost about 0.5 ms
    of CPU, most of a neighbour lookup's, on every system page): the system's sort keys (parameter
    ``system_id``) and, for a current row whose keys are NULL where ``nulls`` says (the statement's shape
    depends on it), both neighbours, the current row's non-NULL keys as parameters ``key0``, ``key1``, ...
    (None for ``nulls`` None)."""
    keys = _sort_keys(sort)
    base = sa.select(System.id).join(Game, Game.id == System.game_id)
    keys_stmt = base.with_only_columns(*(k.expr for k in keys)).where(System.id == sa.bindparam("system_id"))
    if nulls is None:
        return keys_stmt, None
    current = tuple(None if null else sa.bindparam(f"key{i}", type_=k.expr.type)
                    for i, (k, null) in enumerate(zip(keys, nulls, strict=False)))
    conds = _system_conditions(filters)
    return keys_stmt, sa.select(_neighbour(base, conds, keys, current, "before"),
                                _neighbour(base, conds, keys, current, "after"))


def _neighbour(base: sa.Select[Any], conds: list[Any], keys: list[_SortKey], current: tuple[Any, ...],
               side: Literal["before", "after"]) -> Any:
    """SQL: the id of the nearest row of ``base`` + ``conds`` strictly ``side`` of the row whose sort keys
    are ``current``, or NULL.

    The rows beyond the current one in the order are, nearest first, those equal to it on every key but
    the last and beyond it on the last, then those equal on every key but the last two and beyond on the
    one before, and so on (:meth:`_SortKey.beyond`: a key whose NULLs come last adds its NULLs after its
    values). Each of these sets is one ``LIMIT 1`` subquery with an equality prefix and a range on one
    key, which SQLite answers with a seek on the sort's index; ``coalesce`` takes the first that finds a
    row and evaluates no further one. (One ``OR`` of the sets instead was planned as a scan of the index
    from one end of the queue to the current row: its cost grew with the database, about 0.5 ms a side
    at 12,800 systems.)
    """
    reverse = side == "before"
    nearest_first = [
        base.where(*conds, *(k.equal(v) for k, v in zip(keys[:i], current, strict=False)), beyond)
        .order_by(*_slice_order(keys, i, reverse)).limit(1).scalar_subquery()
        for i in reversed(range(len(keys))) for beyond in keys[i].beyond(current[i], side)
    ]
    return sa.func.coalesce(*nearest_first) if len(nearest_first) > 1 else nearest_first[0]


def list_frames(session: Session, filters: FrameFilters = FrameFilters(), sort: FrameSort = "name",
                limit: int = 50, offset: int = 0) -> FramePage:
    """One page of frames (calibration, label and reprojection loaded).

    ``sort``: ``error`` (the view's reprojection error), ``jac`` (JaC@0.5 %) or ``name`` (game,
    system, position), descending with a leading ``-``; missing values last, ties by id.

    Raises:
        ValueError: an unknown ``sort``.
    """
    conds: list[Any] = []
    if filters.game_id is not None:
        conds.append(System.game_id == filters.game_id)
    if filters.system_id is not None:
        conds.append(Frame.system_id == filters.system_id)
    if filters.calibration == "none":
        conds.append(Calibration.frame_id.is_(None))
    elif filters.calibration is not None:
        conds.append(Calibration.status == CalibrationStatus(filters.calibration))
    if filters.admitted is not None:
        conds.append(sa.func.coalesce(Calibration.admitted, False).is_(filters.admitted))
    conds += _range(Calibration.jac_0005, filters.jac_min, filters.jac_max)
    conds += _range(BallReprojection.error_px, filters.error_min, filters.error_max)
    base = (
        sa.select(Frame).join(System, System.id == Frame.system_id).join(Game, Game.id == System.game_id)
        .outerjoin(Calibration, Calibration.frame_id == Frame.id)
        .outerjoin(BallReprojection, BallReprojection.frame_id == Frame.id)
        .where(*conds)
    )
    desc = sort.startswith("-")
    key = sort.lstrip("-")
    if key == "name":
        cols = [Game.league, Game.season, Game.match, *_natural_name(System.name), Frame.position]
        order = [c.desc() if desc else c.asc() for c in cols]
    elif key in ("error", "jac"):
        col = BallReprojection.error_px if key == "error" else Calibration.jac_0005
        order = [(col.desc() if desc else col.asc()).nulls_last()]
    else:
        raise ValueError(f"unknown sort {sort!r}")
    total = session.scalar(sa.select(sa.func.count()).select_from(base.with_only_columns(Frame.id).subquery()))
    stmt = base.order_by(*order, Frame.id).limit(limit).offset(offset).options(
        selectinload(Frame.calibration), selectinload(Frame.ball_label), selectinload(Frame.reprojection),
        selectinload(Frame.review),
    )
    return FramePage(items=list(session.scalars(stmt)), total=int(total or 0))
