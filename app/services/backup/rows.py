"""A table's values written engine-neutrally (Django's ``dumpdata`` idea): each column gets a kind from its type as
the database reports it (reflection, so an archive of any schema revision reads and writes without v3d's models), and
each value is written as JSON by its kind, then read back into whichever engine restores it.

| kind | column types | written as |
|---|---|---|
| ``datetime`` | ``DATETIME`` (SQLite, naive UTC text), ``timestamp with time zone`` | ISO 8601 in UTC, ``+00:00`` |
| ``bytes`` | ``BLOB``, ``bytea`` | base64 |
| ``json`` | ``JSON`` (SQLite's text), ``JSONB`` | the document's JSON text (SQL NULL null, JSON's null ``"null"``) |
| ``bool``, ``int``, ``float``, ``text`` | the rest | themselves |

Every timestamp v3d stores is UTC (``app.db.types.UTCDateTime``), so a naive one read from SQLite is UTC.
"""
from __future__ import annotations

import base64
from datetime import date, datetime, timezone
from typing import Any, Callable

import orjson
import sqlalchemy as sa
from sqlalchemy.dialects.postgresql import JSONB

#: Each kind with the reflected column types it takes, the first that matches winning (a ``DATETIME`` is no
#: ``DATE``); a column of any other type is ``text``.
_TYPE_KINDS: tuple[tuple[tuple[type[sa.types.TypeEngine[Any]], ...], str], ...] = (
    ((sa.DateTime,), "datetime"), ((sa.Date,), "date"), ((sa.LargeBinary,), "bytes"), ((sa.JSON,), "json"),
    ((sa.Boolean,), "bool"), ((sa.Integer,), "int"), ((sa.Float, sa.Numeric), "float"))
KINDS = (*(kind for _, kind in _TYPE_KINDS), "text")


def column_kind(type_: sa.types.TypeEngine[Any]) -> str:
    """The neutral kind (:data:`KINDS`) of a reflected column type."""
    return next((kind for types, kind in _TYPE_KINDS if isinstance(type_, types)), "text")


def read_column(column: sa.Column[Any], kind: str, dialect: str) -> Any:
    """What a snapshot on ``dialect`` selects for ``column`` of ``kind``: a JSON document as its text (so that SQL
    NULL and JSON's null stay apart: PostgreSQL casts ``jsonb`` to text, SQLite's is text already), everything else as
    the column."""
    if kind == "json":
        return sa.cast(column, sa.Text) if dialect == "postgresql" else sa.type_coerce(column, sa.Text)
    return column


def encoder(kind: str) -> Callable[[Any], Any]:
    """``value -> JSON-able`` for a value of ``kind`` as :func:`read_column` selects it (None stays None)."""
    return _ENCODERS.get(kind, _same)


def _same(value: Any) -> Any:
    return value


def _datetime(value: Any) -> Any:
    if value is None:
        return None
    if isinstance(value, str):  # a driver that answers text
        value = datetime.fromisoformat(value)
    if value.tzinfo is None:
        value = value.replace(tzinfo=timezone.utc)
    return value.astimezone(timezone.utc).isoformat()


def _float(value: Any) -> Any:
    return None if value is None else float(value)


_ENCODERS: dict[str, Callable[[Any], Any]] = {
    "datetime": _datetime,
    "date": lambda v: None if v is None else (v.isoformat() if isinstance(v, date) else str(v)),
    "bytes": lambda v: None if v is None else base64.b64encode(bytes(v)).decode("ascii"),
    "float": _float,
    "bool": lambda v: None if v is None else bool(v),
}


def write_type(kind: str, dialect: str) -> sa.types.TypeEngine[Any]:
    """The type a restore binds a value of ``kind`` with on ``dialect`` (``sqlite`` or ``postgresql``)."""
    if kind == "json":
        return JSONB(none_as_null=True) if dialect == "postgresql" else sa.JSON(none_as_null=True)
    types: dict[str, sa.types.TypeEngine[Any]] = {
        "datetime": sa.DateTime(timezone=True), "date": sa.Date(), "bytes": sa.LargeBinary(), "bool": sa.Boolean(),
        "int": sa.BigInteger(), "float": sa.Double()}
    return types.get(kind, sa.Text())


def decoder(kind: str, dialect: str) -> Callable[[Any], Any]:
    """``archived value -> value to bind`` with :func:`write_type` of ``kind`` on ``dialect``."""
    if kind == "datetime":
        naive = dialect == "sqlite"  # SQLite keeps UTC text without an offset (app.db.types.UTCDateTime)

        def _dt(v: Any) -> Any:
            if v is None:
                return None
            value = datetime.fromisoformat(v).astimezone(timezone.utc)
            return value.replace(tzinfo=None) if naive else value
        return _dt
    if kind == "date":
        return lambda v: None if v is None else date.fromisoformat(v)
    if kind == "bytes":
        return lambda v: None if v is None else base64.b64decode(v)
    if kind == "json":
        def _json(v: Any) -> Any:
            if v is None:
                return None
            doc = orjson.loads(v)
            return sa.JSON.NULL if doc is None else doc
        return _json
    return _same
