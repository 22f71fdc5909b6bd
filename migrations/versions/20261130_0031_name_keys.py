"""Names people read are unique by their key: ``releases.name_key`` and ``users.name_key``, each with a unique index.

The key (``app.core.names.name_key``: NFKC, case folded, trailing dots dropped) tells apart names that people read
as one (``Ana`` / ``ana``, a composed and a decomposed ``é``); the unique index makes the database refuse the second
such name whoever writes it (the model fills the key whenever a name is set). Existing rows keep their names: the
key is computed for each here. When two existing rows' names have one key (made before this rule), both keep their
names and every row after the first, by id, gets the key suffixed with ``#<its id>`` (``ana#7``; once more should
that be some other row's key too): deterministic, and unique as row ids are; a new name reading as either is still
refused (it meets the first row's plain key). ``releases`` is append-only: its trigger is lifted for
this one fill and put back as revision 0027 made it.

The columns are nullable: SQLite adds a NOT NULL column to a filled table only by rebuilding it (and with it the
releases' append-only triggers and the foreign keys pointing at it); every row the models write has a key.

Revision ID: 0031
Revises: 0029
Create Date: 2026-11-30 00:00:00+00:00
"""
from __future__ import annotations

import unicodedata
from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op

revision: str = '0031'
down_revision: str | None = '0029'
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None

_REFUSAL = "releases are append-only"
#: table -> the key column's length
_TABLES = {"releases": 220, "users": 120}


def _key(name: str) -> str:
    """``app.core.names.name_key`` as of this revision (a migration keeps its own copy of the rule it applied)."""
    return unicodedata.normalize("NFKC", unicodedata.normalize("NFKC", name).casefold()).rstrip(".")


def _fill(table: str) -> None:
    rows = sa.table(table, sa.column("id", sa.Integer), sa.column("name", sa.String),
                    sa.column("name_key", sa.String))
    bind = op.get_bind()
    found = bind.execute(sa.select(rows.c.id, rows.c.name).order_by(rows.c.id)).all()
    natural = {_key(name) for _, name in found}
    seen: set[str] = set()
    for ident, name in found:
        key = _key(name)
        if key in seen:
            key = f"{key}#{ident}"
            while key in seen or key in natural:
                key = f"{key}#{ident}"
        seen.add(key)
        bind.execute(sa.update(rows).where(rows.c.id == ident).values(name_key=key))


def upgrade() -> None:
    postgres = op.get_bind().dialect.name == "postgresql"
    for table, length in _TABLES.items():
        op.add_column(table, sa.Column("name_key", sa.String(length=length), nullable=True))
    if postgres:
        op.execute("ALTER TABLE releases DISABLE TRIGGER releases_append_only")
    else:
        op.execute("DROP TRIGGER IF EXISTS releases_no_update")
    for table in _TABLES:
        _fill(table)
    if postgres:
        op.execute("ALTER TABLE releases ENABLE TRIGGER releases_append_only")
    else:
        op.execute(f"CREATE TRIGGER releases_no_update BEFORE UPDATE ON releases "
                   f"BEGIN SELECT RAISE(ABORT, '{_REFUSAL}'); END")
    for table in _TABLES:
        op.create_index(op.f(f"ix_{table}_name_key"), table, ["name_key"], unique=True)


def downgrade() -> None:
    for table in _TABLES:
        op.drop_index(op.f(f"ix_{table}_name_key"), table_name=table)
        if op.get_bind().dialect.name == "postgresql":
            op.drop_column(table, "name_key")
        else:  # SQLite drops a column in place (3.35+) unless it is indexed: the index went first
            op.execute(f"ALTER TABLE {table} DROP COLUMN name_key")
