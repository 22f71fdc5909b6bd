"""Derived rows written in place: a recomputation that leaves a row as it was writes nothing for it (issue 29)."""
from __future__ import annotations

from typing import Any

import sqlalchemy as sa


def put_values(row: Any, values: dict[str, Any]) -> Any:
    """Set ``values`` (column attribute -> value) on ``row`` (a NOT NULL column a pending row left unset keeps its
    default); returns the row. An attribute that holds an equal value already is not set (:func:`_set_changed`): a row
    whose values all stay as they were stays out of the next flush altogether."""
    columns = sa.inspect(type(row)).columns
    for key, value in values.items():
        if value is None and not columns[key].nullable:
            continue
        _set_changed(row, key, value)
    return row


def _set_changed(row: Any, key: str, value: Any) -> None:
    """Set ``row.key`` to ``value`` unless it holds an equal value already (``==``: numbers, strings, enums, JSON
    lists and dicts): an unchanged attribute then leaves the row out of the next flush altogether."""
    if key not in row.__dict__ or row.__dict__[key] != value:
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
