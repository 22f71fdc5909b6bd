"""The review queue's order: its sorts, their keys (SQL expressions the indexes of ``systems`` read) and the
cursors that name a row's place in one (``app.services.curation.queue`` pages and walks them).

A cursor is opaque to clients: the sort and a row's key values, the system id last, as URL-safe base64 of JSON; a
forged or damaged one is refused in words before it reaches the database (:func:`decode_cursor`).
"""
from __future__ import annotations

import base64
import binascii
import json
import math
from dataclasses import dataclass
from typing import Any, Callable, Literal, Optional

import sqlalchemy as sa
from sqlalchemy.ext.compiler import compiles
from sqlalchemy.sql.selectable import Join

from app.core.errors import InvalidInputError
from app.db.models import BallEvidence, Game, System
from app.db.models.labels import TO_REVIEW
from app.db.types import DB_INT_MAX, DB_INT_MIN

SystemSort = Literal["severity", "-severity", "doubts", "-doubts", "worst_error",
                      "-worst_error", "lowest_jac", "-lowest_jac", "name", "-name", "ball_evidence", "-ball_evidence"]
#: The review queue's default order: pending (and fixed, to re-review) systems first, the most severe first.
DEFAULT_SORT: SystemSort = "-severity"


def to_review_first() -> Any:
    """SQL: 0 for a system of :data:`TO_REVIEW`, 1 for a decided one (the ``severity`` order's first key), written as
    the index ``ix_systems_review_order_severity`` writes it (``REVIEW_ORDER_SQL``: literals, no bound parameter),
    so that both engines read the order from that index."""
    whens: list[tuple[Any, Any]] = [(sa.literal_column(f"'{s.value}'"), sa.literal_column("0")) for s in TO_REVIEW]
    return sa.type_coerce(sa.case(*whens, value=System.review_status, else_=sa.literal_column("1")), sa.Integer)


class _GamesFirst(Join):
    """``games JOIN systems`` (:func:`games_then_systems`), which SQLite is given as ``CROSS JOIN``."""

    inherit_cache = True


@compiles(_GamesFirst, "sqlite")
def _games_first_on_sqlite(element: _GamesFirst, compiler: Any, **kw: Any) -> str:
    """SQLite keeps the left table of a ``CROSS JOIN`` as the outer loop (its documented way to fix a join's order)."""
    side = {**kw, "asfrom": True}
    return (f"{compiler.process(element.left, **side)} CROSS JOIN {compiler.process(element.right, **side)} "
            f"ON {compiler.process(element.onclause, **kw)}")


def games_then_systems() -> Any:
    """The FROM of the ``name`` order (its first keys are the game's): the games, then each game's systems.

    Read in that order, a page by name is the games' unique index (league, season, match) walked in order and, within
    each game, the index of its systems' natural names: no sort, whatever the queue's size. Without statistics of
    the games' table (SQLite's ``PRAGMA optimize`` after an import analyses only the tables its connection asked
    for), SQLite's planner guessed a large games table and read every system to sort them per page (192,000 VM
    instructions for the first page at 12,800 systems against 4,000 for the other orders'); its ``CROSS JOIN``
    keeps the games outside whatever the statistics. PostgreSQL plans the plain join."""
    return _GamesFirst(Game.__table__, System.__table__, Game.id == System.game_id)


def review_first_of(system: System) -> int:
    """:func:`to_review_first` of a ``System`` object: 0 when its ``review_status`` is one of :data:`TO_REVIEW`, else
    1."""
    return 0 if system.review_status in TO_REVIEW else 1


def natural_name(column: Any) -> list[Any]:
    """SQL sort keys of a name with numeric names in numeric order."""
    # numeric names ("2.png", "10.png") in numeric order: shorter first, then text
    return [sa.func.length(column, type_=sa.Integer), column]


@dataclass(frozen=True)
class SortKey:
    """One key of the queue's order: an SQL expression, its direction, and whether NULLs come last
    (the stored aggregates are NULL without a 3D ball or an admitted view)."""

    expr: Any
    desc: bool = False
    nulls_last: bool = False
    #: Every value the key takes, ascending, when they are few and never NULL (the work-to-do-first key: 0, 1):
    #: its rows beyond a value are read as one slice per value (an equality, so that the keys after it are read in
    #: their index's order whatever their direction), not as a range.
    values: tuple[Any, ...] = ()
    #: For a key that is no column of the system: its value for a ``System`` object, the same the expression gives
    #: of the system's stored row (what ``queue.queue_neighbours`` takes from the system an edit holds, not read).
    of_system: Optional[Callable[[Any], Any]] = None

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


def sort_keys(sort: SystemSort) -> list[SortKey]:
    """The queue's order as keys; the system id comes last, in the sort's direction, so that the order
    is strict and a descending sort is an index scanned backwards (no sort of the whole queue)."""
    desc = sort.startswith("-")
    key = sort.lstrip("-")
    tie = SortKey(System.id, desc)
    if key == "name":
        cols = [Game.league, Game.season, Game.match, *natural_name(System.name)]
        return [SortKey(c, desc) for c in cols] + [tie]
    if key == "severity":  # the work to do first in either direction, then severity, the error, the doubts' count
        return [SortKey(to_review_first(), values=(0, 1), of_system=review_first_of),
                SortKey(System.label_severity, desc),
                SortKey(System.worst_error_px, desc, True), SortKey(System.label_doubts, desc), tie]
    if key == "ball_evidence":  # the enum's order, the best backed first (vouched ... none); ties by the error
        rank = sa.type_coerce(sa.case({t.value: i for i, t in enumerate(BallEvidence)}, value=System.ball_evidence,
                                      else_=len(BallEvidence)), sa.Integer)
        return [SortKey(rank, desc), SortKey(System.worst_error_px, True, True), tie]
    if key == "doubts":  # ties by the largest reprojection error
        return [SortKey(System.label_doubts, desc), SortKey(System.worst_error_px, True, True), tie]
    column = {"worst_error": System.worst_error_px, "lowest_jac": System.lowest_jac}.get(key)
    if column is None:
        raise ValueError(f"unknown sort {sort!r}")
    return [SortKey(column, desc, True), tie]


def encode_cursor(sort: SystemSort, values: tuple[Any, ...]) -> str:
    """A queue cursor: the sort and a row's sort key values (:func:`sort_keys`, the system id last),
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
    keys = sort_keys(sort)
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
        if not fits(key, value):
            raise InvalidInputError(f"not a queue cursor (its value {i + 1} cannot be a stored "
                                    f"{_kind(key)}: forged or damaged)", field=field)
    return tuple(values)


#: Longest cursor read (characters): a real one holds a few short values (names at most 200 + 200 + 400 + 200).
_MAX_CURSOR_CHARS = 4096


def _kind(key: SortKey) -> str:
    """What a sort key's column holds: ``integer``, ``number`` or ``text``."""
    if isinstance(key.expr.type, sa.Integer):
        return "integer"
    return "number" if isinstance(key.expr.type, (sa.Float, sa.Numeric)) else "text"


def fits(key: SortKey, value: Any) -> bool:
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
