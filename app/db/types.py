"""Column types shared by the models: UTC timestamps, JSON, enums stored by value.

Kept apart from the models so that migrations and models agree on one definition of each type.
"""
from __future__ import annotations

import enum
import hashlib
import json
import math
import zlib
from datetime import datetime, timezone
from typing import Any

import orjson
import sqlalchemy as sa
from sqlalchemy.dialects.postgresql import JSONB
from sqlalchemy.engine import Dialect
from sqlalchemy.types import TypeDecorator

#: Bounds of the ``INTEGER`` columns (ids, counts): 32-bit signed on PostgreSQL (SQLite's are 64-bit). A number
#: beyond them compared with a column fails in the database or its driver ("integer out of range",
#: OverflowError): callers refuse it first (the API's path and query parameters, the queue's cursors).
DB_INT_MIN, DB_INT_MAX = -(2**31), 2**31 - 1


class UTCDateTime(TypeDecorator[datetime]):
    """A timezone-aware UTC timestamp on every backend.

    PostgreSQL stores ``timestamp with time zone``; SQLite stores the ISO text without an offset.
    Values bound must be timezone-aware (a naive datetime raises ``ValueError``: its zone is
    unknown); values read are always returned as aware UTC datetimes.
    """

    impl = sa.DateTime(timezone=True)
    cache_ok = True

    def process_bind_param(self, value: datetime | None, dialect: Dialect) -> datetime | None:
        if value is None:
            return None
        if value.tzinfo is None or value.utcoffset() is None:
            raise ValueError(f"naive datetime {value!r}: store timezone-aware UTC times")
        value = value.astimezone(timezone.utc)
        return value.replace(tzinfo=None) if dialect.name == "sqlite" else value

    def process_result_value(self, value: datetime | None, dialect: Dialect) -> datetime | None:
        if value is None:
            return None
        if value.tzinfo is None:
            return value.replace(tzinfo=timezone.utc)
        return value.astimezone(timezone.utc)


#: JSON document column: ``JSONB`` on PostgreSQL, JSON text elsewhere.
JSONDoc = sa.JSON().with_variant(JSONB(), "postgresql")


def json_loads(text: str | bytes) -> Any:
    """Decode a stored JSON document with ``orjson`` (several times faster than ``json``: a SoccerNet-size
    export decodes about 400,000 of them); text ``orjson`` refuses (``NaN`` written by an older
    ``json.dumps``; :func:`json_safe` keeps new rows free of it) falls back to ``json.loads``. The
    SQLite engine's JSON columns decode through it (``app.db.session.make_engine``)."""
    try:
        return orjson.loads(text)
    except orjson.JSONDecodeError:
        return json.loads(text)


def json_dumps(value: Any) -> str:
    """Encode a document for a JSON column with ``orjson`` (several times faster than ``json``, compact: an edit
    writes a few dozen documents), integer keys as strings and numpy numbers as numbers as ``json.dumps`` would;
    NaN and infinities become ``null`` (:func:`json_safe` keeps them out of new rows already; PostgreSQL's JSONB
    has no such numbers either). Both engines' JSON columns encode through it (``app.db.session.make_engine``).

    Raises:
        TypeError: a value JSON cannot hold (orjson's ``JSONEncodeError`` is one).
    """
    return orjson.dumps(value, option=orjson.OPT_NON_STR_KEYS | orjson.OPT_SERIALIZE_NUMPY).decode()


def canonical_json(value: Any) -> bytes:
    """``value`` as JSON in one canonical form (keys sorted, compact, UTF-8): equal documents give equal bytes, so
    that a document can be stored once under the digest of these bytes (:func:`json_digest`)."""
    return orjson.dumps(value, option=orjson.OPT_SORT_KEYS | orjson.OPT_NON_STR_KEYS | orjson.OPT_SERIALIZE_NUMPY)


def json_digest(canonical: bytes) -> str:
    """SHA-256 (64 hex digits) of a document's :func:`canonical_json`: what names it where it is stored once."""
    return hashlib.sha256(canonical).hexdigest()


#: zlib's window bits for a gzip member (16 + 15), and for reading either a gzip member or a zlib stream (32 + 15:
#: the audit's states stored before documents were gzip members are zlib streams).
_GZIP_WBITS, _ANY_HEADER_WBITS = 31, 47


def compressed_json(canonical: bytes) -> bytes:
    """A document's :func:`canonical_json` compressed as one gzip member (RFC 1952: deflate level 6, no file name,
    time stamp 0; field-line polylines of 2,000 points shrink about threefold), as a binary column stores it;
    :func:`decompressed_json` reads it back. A gzip member, not a bare zlib stream, so that stored documents laid one
    after another are a gzip file as they are (a release's ``documents.jsonl.gz``: members concatenate, RFC 1952
    section 2.2) and no export decompresses and compresses them again.

    >>> decompressed_json(compressed_json(canonical_json({"b": [1.5, 2], "a": None})))
    {'a': None, 'b': [1.5, 2]}
    """
    return zlib.compress(canonical, 6, wbits=_GZIP_WBITS)


def decompressed_json(body: bytes) -> Any:
    """The document :func:`compressed_json` stored (a gzip member, or a zlib stream stored before)."""
    return json_loads(zlib.decompress(body, wbits=_ANY_HEADER_WBITS))


def utcnow() -> datetime:
    """The current time, timezone-aware UTC (the default of every timestamp column)."""
    return datetime.now(timezone.utc)


def enum_by_value(enum_cls: type[enum.Enum], name: str) -> sa.Enum:
    """A non-native ``Enum`` column storing each member's **value** (not its name), with a CHECK
    constraint named ``name`` so that both SQLite and PostgreSQL reject unknown strings."""
    values = [m.value for m in enum_cls]
    return sa.Enum(
        enum_cls,
        name=name,
        native_enum=False,
        create_constraint=True,
        length=max(len(v) for v in values),
        values_callable=lambda e: [m.value for m in e],
        validate_strings=True,
    )


def json_safe(value: Any) -> Any:
    """``value`` with numpy scalars and arrays turned into plain Python numbers and lists, so that it
    can be stored in a JSON column; NaN and infinities become ``None`` (JSON has no such numbers and
    PostgreSQL's JSONB rejects them). Raises ``TypeError`` for anything JSON cannot hold."""
    import numpy as np

    kind = type(value)  # the plain types first: an edit passes a few hundred values through here
    if kind is float:
        return value if math.isfinite(value) else None
    if value is None or kind is str or kind is int or kind is bool:
        return value
    if kind is dict:
        return {str(k): json_safe(v) for k, v in value.items()}
    if kind is list:
        return [json_safe(v) for v in value]
    if isinstance(value, dict):
        return {str(k): json_safe(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [json_safe(v) for v in value]
    if isinstance(value, np.ndarray):
        return json_safe(value.tolist())
    if isinstance(value, np.bool_):
        return bool(value)
    if isinstance(value, np.integer):
        return int(value)
    if isinstance(value, np.floating):
        return json_safe(float(value))
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if value is None or isinstance(value, (str, bool, int)):
        return value
    raise TypeError(f"cannot store {type(value).__name__} in a JSON column")
