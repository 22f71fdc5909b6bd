"""Large audit states stored once, compressed: ``audit_states`` (``digest``: the SHA-256 of a state's canonical JSON,
``body``: that JSON compressed with zlib) and ``audit_entries.before_digest`` / ``after_digest``, which name a large
state instead of holding it in ``before`` / ``after`` (``app.services.audit.log.stored_state``). A 2,000-point
field-line edit stored its lines twice, whole (about 140 KB an edit); a state after is the next edit's state
before, so a series of edits now adds one compressed state per edit.

The upgrade moves the large states already stored (at least ``LARGE_STATE_BYTES`` of canonical JSON) into the new
table, the downgrade puts every state back into its entry; both lift the append-only triggers of ``audit_entries``
for that rewrite alone (the states read the same before and after it). ``audit_states`` is append-only too. Plain
``CREATE TABLE`` / ``ADD COLUMN`` / ``DROP COLUMN`` (SQLite >= 3.35 and PostgreSQL), no batch copy of the table. A
SQLite file keeps its size until ``VACUUM``.

Revision ID: 0024
Revises: 0023
Create Date: 2026-11-26 14:00:00+00:00
"""
from __future__ import annotations

from collections.abc import Iterator, Sequence
from typing import Any

import sqlalchemy as sa
from alembic import op
from sqlalchemy.dialects import postgresql

from app.db.types import canonical_json, compressed_json, decompressed_json, json_digest

revision: str = '0024'
down_revision: str | None = '0023'
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None

#: The size from which a state is stored once (``app.services.audit.log.LARGE_STATE_BYTES`` when this was written).
LARGE_STATE_BYTES = 1024
_REFUSAL = "audit entries are append-only"
_JSON = sa.JSON().with_variant(postgresql.JSONB(astext_type=sa.Text()), 'postgresql')
_ENTRIES = sa.table('audit_entries', sa.column('id', sa.Integer()), sa.column('before', _JSON),
                    sa.column('after', _JSON), sa.column('before_digest', sa.String(64)),
                    sa.column('after_digest', sa.String(64)))
_STATES = sa.table('audit_states', sa.column('digest', sa.String(64)), sa.column('body', sa.LargeBinary()))
_BATCH = 500


def _postgresql() -> bool:
    return bool(op.get_bind().dialect.name == "postgresql")


def _entry_triggers(on: bool) -> None:
    """The append-only triggers of ``audit_entries`` (migration 0006) off for a rewrite, then on again."""
    if _postgresql():
        op.execute(f"ALTER TABLE audit_entries {'ENABLE' if on else 'DISABLE'} TRIGGER audit_entries_append_only")
        return
    for event in ("UPDATE", "DELETE"):
        if on:
            op.execute(f"CREATE TRIGGER audit_entries_no_{event.lower()} BEFORE {event} ON audit_entries "
                       f"BEGIN SELECT RAISE(ABORT, '{_REFUSAL}'); END")
        else:
            op.execute(f"DROP TRIGGER audit_entries_no_{event.lower()}")


def _state_triggers() -> None:
    if _postgresql():
        op.execute("CREATE TRIGGER audit_states_append_only BEFORE UPDATE OR DELETE ON audit_states "
                   "FOR EACH ROW EXECUTE FUNCTION audit_entries_append_only()")
        return
    for event in ("UPDATE", "DELETE"):
        op.execute(f"CREATE TRIGGER audit_states_no_{event.lower()} BEFORE {event} ON audit_states "
                   f"BEGIN SELECT RAISE(ABORT, '{_REFUSAL}'); END")


def _rows(where: Any) -> Iterator[list[Any]]:
    """The entries matching ``where``, by id, a batch at a time."""
    bind = op.get_bind()
    last = 0
    while True:
        rows = bind.execute(sa.select(_ENTRIES).where(where, _ENTRIES.c.id > last)
                            .order_by(_ENTRIES.c.id).limit(_BATCH)).all()
        if not rows:
            return
        yield rows
        last = rows[-1].id


def upgrade() -> None:
    op.create_table('audit_states',
                    sa.Column('digest', sa.String(length=64), nullable=False),
                    sa.Column('body', sa.LargeBinary(), nullable=False),
                    sa.PrimaryKeyConstraint('digest', name=op.f('pk_audit_states')))
    _state_triggers()
    op.add_column('audit_entries', sa.Column('before_digest', sa.String(length=64), nullable=True))
    op.add_column('audit_entries', sa.Column('after_digest', sa.String(length=64), nullable=True))
    bind = op.get_bind()
    insert = (postgresql.insert if _postgresql() else sa.dialects.sqlite.insert)(_STATES)
    _entry_triggers(on=False)
    for rows in _rows(sa.or_(_ENTRIES.c.before.is_not(None), _ENTRIES.c.after.is_not(None))):
        for row in rows:
            moved: dict[str, Any] = {}
            for side in ("before", "after"):
                state = getattr(row, side)
                canonical = canonical_json(state) if state is not None else b""
                if len(canonical) < LARGE_STATE_BYTES:
                    continue
                digest = json_digest(canonical)
                bind.execute(insert.values(digest=digest, body=compressed_json(canonical))
                             .on_conflict_do_nothing(index_elements=['digest']))
                moved.update({side: None, f"{side}_digest": digest})
            if moved:
                bind.execute(_ENTRIES.update().where(_ENTRIES.c.id == row.id).values(**moved))
    _entry_triggers(on=True)


def downgrade() -> None:
    bind = op.get_bind()
    _entry_triggers(on=False)
    for rows in _rows(sa.or_(_ENTRIES.c.before_digest.is_not(None), _ENTRIES.c.after_digest.is_not(None))):
        for row in rows:
            back = {}
            for side in ("before", "after"):
                digest = getattr(row, f"{side}_digest")
                if digest is not None:
                    body = bind.execute(sa.select(_STATES.c.body).where(_STATES.c.digest == digest)).scalar_one()
                    back[side] = decompressed_json(body)
            bind.execute(_ENTRIES.update().where(_ENTRIES.c.id == row.id).values(**back))
    _entry_triggers(on=True)
    op.drop_column('audit_entries', 'after_digest')
    op.drop_column('audit_entries', 'before_digest')
    op.drop_table('audit_states')  # its triggers go with it
