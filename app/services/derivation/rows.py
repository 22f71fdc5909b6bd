"""Derived rows written in place: a recomputation that leaves a row as it was writes nothing for it (issue 29).

An edit that computes before its write lock (``app.services.curation.writing``) also writes what it changed in
stored rows without the unit of work: :func:`writing_directly` collects, while the recomputation runs, every value
:func:`put_values` changes on a stored row (and takes it as the row's committed value, so the session sees nothing to
flush), and :meth:`DirectWrites.write` sends them under the lock as one ``UPDATE`` per table and set of columns,
executed for all its rows at once (all the tables' in one round trip on PostgreSQL, ``app.db.together``). The unit of
work flushes only the rest (the edited label, new and deleted rows, the audit entry; before the direct writes, which
leave out a row it deleted): a ball edit of a 4-view system changes about 18 stored rows of 7 tables, whose
bookkeeping in the unit of work cost more than their statements. A write that is not sent (the compare under the lock found another
edit's rows) is rolled back with its transaction, which expires every object: nothing collected outlives it.
"""
from __future__ import annotations

import contextlib
import functools
from collections.abc import Iterator, Sequence
from typing import Any, Optional

import sqlalchemy as sa
from sqlalchemy.orm import Session, object_session
from sqlalchemy.orm.attributes import set_committed_value

from app.db.together import Call, send_together

#: ``Session.info`` key of the :class:`DirectWrites` collecting in the session.
_DIRECT = "v3d.rows.direct"


def put_values(row: Any, values: dict[str, Any]) -> Any:
    """Set ``values`` (column attribute -> value) on ``row`` (a NOT NULL column a pending row left unset keeps its
    default); returns the row. An attribute that holds an equal value already is not set (:func:`_set_changed`): a row
    whose values all stay as they were stays out of the next flush altogether. In a session collecting direct writes
    (:func:`writing_directly`), a stored row's changes go to the collector instead of the unit of work."""
    columns = sa.inspect(type(row)).columns
    for key, value in values.items():
        if value is None and not columns[key].nullable:
            continue
        _set_changed(row, key, value)
    return row


def _set_changed(row: Any, key: str, value: Any) -> None:
    """Set ``row.key`` to ``value`` unless it holds an equal value already (``==``: numbers, strings, enums, JSON
    lists and dicts): an unchanged attribute then leaves the row out of the next flush altogether."""
    if key in row.__dict__ and row.__dict__[key] == value:
        return
    session = object_session(row)
    direct: Optional[DirectWrites] = session.info.get(_DIRECT) if session is not None else None
    if direct is None or not direct.note(row, key, value):
        setattr(row, key, value)


def replace_rows(rows: list[Any], row_type: type, values: list[dict[str, Any]]) -> None:
    """Make the ordered collection ``rows`` (a system's pairs or doubts, ordered by id) hold one row per item of
    ``values``, in order, updating the stored rows in place: a row whose values did not change writes nothing, so
    that an edit that leaves a pair or a doubt as it was costs no statement for it; rows beyond ``values`` are
    deleted (the relationship's delete-orphan), missing ones added. Nothing refers to these rows' ids (no foreign
    key, API or page names one), so a doubt kept in another place of the list is the same as a new one."""
    columns = sa.inspect(row_type).columns
    if any(v is None and not columns[k].nullable for item in values for k, v in item.items()):
        rows.clear()  # a pending row left a default unset: only an insert gives it its default
        rows.extend(row_type(**item) for item in values)
        return
    for row, item in zip(rows, values):
        put_values(row, item)
    if len(rows) > len(values):
        del rows[len(values):]
    rows.extend(row_type(**item) for item in values[len(rows):])


class DirectWrites:
    """The changed values of stored rows, collected by :func:`put_values` in one session (:func:`writing_directly`)
    and sent by :meth:`write`: per row, its table, primary key and changed columns (the last value of each)."""

    def __init__(self) -> None:
        self._rows: dict[tuple[Any, tuple[Any, ...]], tuple[Any, dict[str, Any]]] = {}  # (mapper, identity) ->
        # (the row's state, its attribute values)

    def note(self, row: Any, key: str, value: Any) -> bool:
        """Collect ``row.key = value`` and take it as the row's committed value; False (nothing collected) for a row
        that is not stored yet or not mapped to one table: the unit of work writes those."""
        state = sa.inspect(row)
        if not state.persistent or len(state.mapper.tables) != 1:
            return False
        mapper = state.mapper
        _, values = self._rows.setdefault((mapper, state.identity), (state, {}))
        if not values:
            for k, v in _onupdate_values(mapper).items():  # what the unit of work would have set on an UPDATE
                values[k] = v
                set_committed_value(row, k, v)
        values[key] = value
        set_committed_value(row, key, value)
        return True

    def __len__(self) -> int:
        return len(self._rows)

    def write(self, session: Session, after: Sequence[Call] = ()) -> list[Any]:
        """Send every collected row in the session's transaction: one executemany ``UPDATE`` per table and set of
        columns, by primary key (:func:`_update_statement`), in the order of the tables' names (the same for every
        edit), then the calls ``after`` (whose answers are returned), all in one round trip on PostgreSQL
        (``app.db.together.send_together``); then forget them. A row the unit of work has deleted since it was
        collected is left out.

        Raises:
            sqlalchemy.orm.exc.StaleDataError: a row was not found (it was deleted since it was read; the caller has
                compared the rows it read under its lock, so this is a bug, and the transaction is rolled back).
        """
        groups: dict[tuple[Any, tuple[str, ...]], list[dict[str, Any]]] = {}
        for (mapper, ident), (state, values) in self._rows.items():
            if state.was_deleted:
                continue
            keys = tuple(sorted(values))
            params = {f"v_{k}": v for k, v in values.items()}
            params.update({f"pk_{i}": v for i, v in enumerate(ident)})
            groups.setdefault((mapper, keys), []).append(params)
        self._rows = {}
        ordered = sorted(groups.items(), key=lambda g: (g[0][0].local_table.name, g[0][1]))
        calls = [Call(_update_statement(mapper, keys), params) for (mapper, keys), params in ordered]
        answers = send_together(session, [*calls, *after])
        if session.get_bind().dialect.supports_sane_multi_rowcount:
            for ((mapper, _), params), matched in zip(ordered, answers):
                if matched != len(params):
                    raise sa.orm.exc.StaleDataError(
                        f"{mapper.local_table.name}: {len(params)} rows to update, {matched} found")
        return answers[len(calls):]


@contextlib.contextmanager
def writing_directly(session: Session) -> Iterator[DirectWrites]:
    """Collect, for the block, the changes :func:`put_values` makes to stored rows in ``session`` (module docstring);
    the caller sends them with :meth:`DirectWrites.write` in the transaction that commits them, or rolls back."""
    direct = DirectWrites()
    session.info[_DIRECT] = direct
    try:
        yield direct
    finally:
        session.info.pop(_DIRECT, None)


@functools.cache
def _update_statement(mapper: Any, keys: tuple[str, ...]) -> sa.Update:
    """``UPDATE table SET column = :v_key, ... WHERE pk0 = :pk_0 ...`` of the mapper's table (``keys``: attribute
    keys; the primary key's columns in the mapper's order, as ``InstanceState.identity`` gives their values), built
    once per mapper and keys."""
    table = mapper.local_table
    stmt = sa.update(table)
    for i, c in enumerate(mapper.primary_key):
        stmt = stmt.where(c == sa.bindparam(f"pk_{i}", type_=c.type))
    columns = {k: mapper.get_property(k).columns[0] for k in keys}
    return stmt.values({c.key: sa.bindparam(f"v_{k}", type_=c.type) for k, c in columns.items()})


def _onupdate_values(mapper: Any) -> dict[str, Any]:
    """The values of the mapper's columns with an ``onupdate`` default (their attribute keys; a time stamp), as the
    unit of work sets them on an update."""
    return {key: make(None) for key, make in _onupdate_columns(mapper)}


@functools.cache
def _onupdate_columns(mapper: Any) -> tuple[tuple[str, Any], ...]:
    """(attribute key, default's function) of the mapper's columns with a Python ``onupdate`` default."""
    return tuple((mapper.get_property_by_column(c).key, c.onupdate.arg) for c in mapper.local_table.c
                 if c.onupdate is not None and c.onupdate.is_callable)
