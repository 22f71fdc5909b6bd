"""The one declarative registry every model joins (its naming convention, its type map) and the stored JaC
columns.
"""
from __future__ import annotations

from datetime import datetime
from typing import Any

import sqlalchemy as sa
from sqlalchemy.orm import DeclarativeBase

from app.db.types import JSONDoc, UTCDateTime
from app.geometry.jac import JAC_GAMMAS

#: The column of each stored JaC gamma (``app.geometry.jac.JAC_GAMMAS``, fractions of the image diagonal).
JAC_COLUMNS: dict[float, str] = dict(zip(JAC_GAMMAS, ("jac_0005", "jac_001", "jac_002"), strict=True))


#: Constraint names Alembic can rely on (same on SQLite and PostgreSQL).
NAMING_CONVENTION = {
    "ix": "ix_%(column_0_label)s",
    "uq": "uq_%(table_name)s_%(column_0_N_name)s",
    "ck": "ck_%(table_name)s_%(constraint_name)s",
    "fk": "fk_%(table_name)s_%(column_0_name)s_%(referred_table_name)s",
    "pk": "pk_%(table_name)s",
}


class Base(DeclarativeBase):
    """Declarative base: float columns are DOUBLE PRECISION, datetimes UTC, dicts and lists JSON."""

    metadata = sa.MetaData(naming_convention=NAMING_CONVENTION)
    type_annotation_map = {
        float: sa.Double(),
        datetime: UTCDateTime(),
        dict[str, Any]: JSONDoc,
        list[Any]: JSONDoc,
        list[float]: JSONDoc,
        list[str]: JSONDoc,
    }
