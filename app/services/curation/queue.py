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

import functools
import operator
from dataclasses import dataclass
from typing import Any, Callable, Generic, Literal, Optional, TypeVar, get_args

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
    ReviewDecision,
    ReviewStatus,
    System,
    Triangulation,
    User,
)
from app.services.accounts.users import ASSIGNEE_NONE
from app.services.curation.queue_order import (
    DEFAULT_SORT,
    SortKey,
    SystemSort,
    decode_cursor,
    encode_cursor,
    games_then_systems,
    natural_name,
    sort_keys,
)

FrameSort = Literal["error", "-error", "jac", "-jac", "name", "-name"]
Item = TypeVar("Item")


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
class SystemPage(Generic[Item]):
    """One page of the queue: ``items`` are systems with their game, review decision and triangulation
    loaded (:func:`list_systems`), or the plain rows of :data:`SUMMARY_COLUMNS` (:func:`list_system_rows`);
    ``total`` rows match the filters; ``counts`` are per review status over the same filters except
    the status one (the progress of the whole filtered queue). ``next_cursor`` / ``prev_cursor`` page on
    (``after=``) or back (``before=``) in the same order, None when no row lies beyond the page that way."""

    items: list[Item]
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


#: What a queue row shows (``app.api.queue_schemas.SystemSummaryOut``), as the columns of one statement: the system's
#: stored figures, its game's name, its review decision (``review_id`` None: never decided) and its 3D ball. Read as
#: plain rows, not as the four ORM objects of :func:`_queue_from`: building those (their identity map entries, every
#: column of each, the timestamps' time zones) was most of a 50-row page's cost, and it grew with the rows shown.
SUMMARY_COLUMNS = (
    System.id, System.name, System.kind, System.views_total, System.views_calibrated, System.views_admitted,
    System.views_labelled, System.lowest_jac, System.worst_error_px, System.views_flagged, System.views_above_tau,
    System.doubt_counts, System.label_doubts, System.ball_evidence, System.ball_evidence_reasons,
    Game.id.label("game_id"), Game.league, Game.season, Game.match,
    ReviewDecision.id.label("review_id"), ReviewDecision.status.label("review_status"),
    ReviewDecision.comment.label("review_comment"), ReviewDecision.decided_at.label("review_decided_at"),
    ReviewDecision.excluded.label("review_excluded"), ReviewDecision.reset_reason.label("review_reset_reason"),
    ReviewDecision.batch_id.label("review_batch_id"),
    Triangulation.ball3d, Triangulation.sigma_m,
)


@functools.lru_cache(maxsize=1)
def _summary_statement() -> Any:
    """The rows of :data:`SUMMARY_COLUMNS` of the systems whose ids are the expanding parameter ``ids`` (built once:
    its construction cost as much as running it). The joins are those of :func:`_queue_from`'s loaders."""
    return (
        sa.select(*SUMMARY_COLUMNS).join(Game, Game.id == System.game_id)
        .outerjoin(ReviewDecision, ReviewDecision.system_id == System.id)
        .outerjoin(Triangulation, Triangulation.system_id == System.id)
        .where(System.id.in_(sa.bindparam("ids", expanding=True)))
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


def _slice_order(keys: list[SortKey], i: int, reverse: bool) -> list[Any]:
    """The ORDER BY of a slice whose rows are equal on ``keys[:i]`` and beyond the current row on ``keys[i]``: from
    ``keys[i]`` on (the equal ones would change nothing, and SQLite then sorts instead of reading an index whose
    leading expression they are), ``keys[i]`` without its NULLs placement (the slice fixes its NULL-ness), and
    without ``keys[i]`` itself when the slice holds one value of it (a key of ``values``)."""
    head = [] if keys[i].values else [keys[i].clause(reverse, plain=True)]
    return head + [k.clause(reverse) for k in keys[i + 1:]]


def _slices(keys: list[SortKey], current: Optional[tuple[Any, ...]],
            side: Literal["before", "after"]) -> list[tuple[list[Any], list[Any]]]:
    """The rows strictly ``side`` of the row whose sort keys are ``current`` (None: from the start of
    the order for ``"after"``, from its end for ``"before"``) as disjoint slices, nearest first, each
    ``(conditions, order)`` with the order read from ``current`` outwards.

    With a current row: the rows equal on ``keys[:i]`` and beyond on ``keys[i]`` for i from the last key
    down (:meth:`SortKey.beyond`), as in :func:`_neighbour`. Without: the whole order, a first key whose
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
    keys only (the sort's index). A slice is read past ``skip`` rows first; only when that finds nothing is it
    counted, to be skipped whole, and then along its own order as far as ``skip`` (it holds no more): a page by
    offset reads about as many index entries as it skips, however large the slice (the work-to-do slice of the
    default order holds every pending system; counting it whole read all of them for any offset)."""
    keys = sort_keys(sort)
    by_name = sort.lstrip("-") == "name"
    base = sa.select(*(k.expr for k in keys)).select_from(games_then_systems() if by_name else System)
    rows: list[tuple[Any, ...]] = []
    slices = _slices(keys, current, side)
    for n, (where, order) in enumerate(slices):
        stmt = base.where(*conds, *where)
        got = [tuple(r) for r in session.execute(stmt.order_by(*order).limit(limit - len(rows)).offset(skip))]
        if skip and not got:  # the slice holds no more than ``skip`` rows: skipped whole
            if n < len(slices) - 1:
                skip -= int(session.scalar(sa.select(sa.func.count()).select_from(
                    stmt.with_only_columns(System.id).order_by(*order).limit(skip).subquery())) or 0)
            continue
        rows += got
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
                 before: Optional[str] = None) -> SystemPage[System]:
    """One page of the review queue, its systems as ORM objects (game, review decision and triangulation loaded).

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
    ids, page = _page(session, filters, sort, limit, offset, after, before)
    by_id = {s.id: s for s in session.scalars(_queue_from().where(System.id.in_(ids))).unique()} if ids else {}
    return SystemPage(items=[by_id[i] for i in ids if i in by_id], **page)


def list_system_rows(session: Session, filters: SystemFilters = SystemFilters(), sort: SystemSort = DEFAULT_SORT,
                     limit: int = 50, offset: int = 0, after: Optional[str] = None,
                     before: Optional[str] = None) -> SystemPage[sa.RowMapping]:
    """The page of :func:`list_systems` (same rows, order, totals and cursors; same arguments and errors), each
    system as the plain row of :data:`SUMMARY_COLUMNS` that a queue row shows: what the API's queue answers, at a
    fraction of the ORM objects' cost per row."""
    ids, page = _page(session, filters, sort, limit, offset, after, before)
    by_id = {r["id"]: r for r in session.execute(_summary_statement(), {"ids": ids}).mappings()} if ids else {}
    return SystemPage(items=[by_id[i] for i in ids if i in by_id], **page)


def _page(session: Session, filters: SystemFilters, sort: SystemSort, limit: int, offset: int,
          after: Optional[str], before: Optional[str]) -> tuple[list[int], dict[str, Any]]:
    """The ids of a page of the queue in its order (:func:`list_systems`' arguments and errors), and the page's
    ``total``, ``counts``, ``next_cursor`` and ``prev_cursor`` as :class:`SystemPage`'s keywords."""
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
        if start is None:  # from the queue's start: the rows skipped are the ones before, nothing else is
            more_before = bool(rows) and offset > 0
        else:
            more_before = bool(rows) and bool(_walk(session, sort, conds, rows[0], "before", 1))
    counts = _status_counts(session, _system_conditions(filters, with_status=False))
    total = counts[ReviewStatus(filters.status).value] if filters.status is not None else sum(counts.values())
    return [r[-1] for r in rows], {
        "total": int(total), "counts": counts,
        "next_cursor": encode_cursor(sort, rows[-1]) if more_after else None,
        "prev_cursor": encode_cursor(sort, rows[0]) if more_before else None}


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
    key is a column of the system or says its value for one (``SortKey.of_system``), its keys are taken from it
    instead of read (one statement fewer).

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
    system or says its value for one (``SortKey.of_system``: the default order's work-to-do-first key), else None
    (:func:`queue_neighbours` reads them)."""
    getters = _HELD_GETTERS.get(sort)
    return None if getters is None else tuple(get(held) for get in getters)


def _held_getters(sort: SystemSort) -> Optional[tuple[Callable[[System], Any], ...]]:
    """How :func:`_held_keys` takes each key of ``sort`` (:func:`sort_keys`) from a system, None when a key is neither
    a column of the system nor says its value for one."""
    keys = sort_keys(sort)
    if not all(k.of_system is not None or (getattr(k.expr, "class_", None) is System and hasattr(k.expr, "key"))
               for k in keys):
        return None
    return tuple(k.of_system if k.of_system is not None else operator.attrgetter(k.expr.key) for k in keys)


#: :func:`_held_getters` of every sort, made once: the keys' SQL expressions (:func:`sort_keys`) cost more to build
#: than an edit's answer spends on the rest of its neighbours.
_HELD_GETTERS = {sort: _held_getters(sort) for sort in get_args(SystemSort)}


@functools.lru_cache(maxsize=256)
def _neighbour_statements(sort: SystemSort, filters: SystemFilters, nulls: Optional[tuple[bool, ...]]
                          ) -> tuple[Any, Any]:
    """The two statements of :func:`queue_neighbours` for a queue, built once (building them cost about 0.5 ms
    of CPU, most of a neighbour lookup's, on every system page): the system's sort keys (parameter
    ``system_id``) and, for a current row whose keys are NULL where ``nulls`` says (the statement's shape
    depends on it), both neighbours, the current row's non-NULL keys as parameters ``key0``, ``key1``, ...
    (None for ``nulls`` None)."""
    keys = sort_keys(sort)
    base = sa.select(System.id).select_from(games_then_systems()) if sort.lstrip("-") == "name" else \
        sa.select(System.id).join(Game, Game.id == System.game_id)
    keys_stmt = base.with_only_columns(*(k.expr for k in keys)).where(System.id == sa.bindparam("system_id"))
    if nulls is None:
        return keys_stmt, None
    current = tuple(None if null else sa.bindparam(f"key{i}", type_=k.expr.type)
                    for i, (k, null) in enumerate(zip(keys, nulls, strict=False)))
    conds = _system_conditions(filters)
    return keys_stmt, sa.select(_neighbour(base, conds, keys, current, "before"),
                                _neighbour(base, conds, keys, current, "after"))


def _neighbour(base: sa.Select[Any], conds: list[Any], keys: list[SortKey], current: tuple[Any, ...],
               side: Literal["before", "after"]) -> Any:
    """SQL: the id of the nearest row of ``base`` + ``conds`` strictly ``side`` of the row whose sort keys
    are ``current``, or NULL.

    The rows beyond the current one in the order are, nearest first, those equal to it on every key but
    the last and beyond it on the last, then those equal on every key but the last two and beyond on the
    one before, and so on (:meth:`SortKey.beyond`: a key whose NULLs come last adds its NULLs after its
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
        cols = [Game.league, Game.season, Game.match, *natural_name(System.name), Frame.position]
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
