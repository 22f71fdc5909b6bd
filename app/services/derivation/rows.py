"""Derived rows written in place: a recomputation that leaves a row as it was writes nothing for it.

A recomputation sets every derived value again (:func:`put_values`, :func:`replace_rows`); values equal to the stored
ones are not set, so the unit of work flushes only the rows and columns an edit changed (a ball edit of a 4-view
system changes about 18 stored rows of 7 tables, of the several dozen it recomputes), and a pair or doubt list is
updated row by row instead of deleted and inserted again.
"""
from __future__ import annotations

from typing import Any

import sqlalchemy as sa
from sqlalchemy.orm import Mapper


def put_values(row: Any, values: dict[str, Any]) -> Any:
    """Set ``values`` (column attribute -> value) on ``row`` (a NOT NULL column a pending row left unset keeps its
    default); returns the row. An attribute that holds an equal value already (``==``: numbers, strings, enums, JSON
    lists and dicts) is not set: a row whose values all stay as they were stays out of the next flush altogether."""
    columns = None  # the row's columns, looked up for a None only (most values are not: a recomputation sets dozens)
    for key, value in values.items():
        if value is None:
            if columns is None:
                columns = sa.inspect(type(row)).columns
            if not columns[key].nullable:
                continue
        if key in row.__dict__ and row.__dict__[key] == value:
            continue
        setattr(row, key, value)
    return row


def replace_rows(rows: list[Any], row_type: type, values: list[dict[str, Any]]) -> None:
    """Make the ordered collection ``rows`` (a system's pairs or doubts, ordered by id) hold one row per item of
    ``values``, in order, updating the stored rows in place: a row whose values did not change writes nothing, so
    that an edit that leaves a pair or a doubt as it was costs no statement for it; rows beyond ``values`` are
    deleted (the relationship's delete-orphan), missing ones added. Nothing refers to these rows' ids (no foreign
    key, API or page names one), so a doubt kept in another place of the list is the same as a new one."""
    mapper: Mapper[Any] = sa.inspect(row_type)
    columns = mapper.columns
    if any(v is None and not columns[k].nullable for item in values for k, v in item.items()):
        rows.clear()  # a pending row left a default unset: only an insert gives it its default
        rows.extend(row_type(**item) for item in values)
        return
    for row, item in zip(rows, values, strict=False):
        put_values(row, item)
    if len(rows) > len(values):
        del rows[len(values):]
    rows.extend(row_type(**item) for item in values[len(rows):])
