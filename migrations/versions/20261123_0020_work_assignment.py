"""Work assignment and presence (issue 28, item 10).

``systems`` gains ``assignee_id`` (a user's id, nullable, indexed, no foreign key), ``assigned_at``
(UTC) and ``assigned_by`` (the assigning actor's name): who should review the system. Existing systems are
unassigned.

``system_presence`` (new): one soft claim per (system, user) that has the system open in a page, with
``since`` and ``expires_at`` (indexed): a claim past ``expires_at`` is absent (``app.services.curation.presence``).

The columns are added and dropped with ``ALTER TABLE`` on SQLite too, never by rebuilding ``systems``: a batch
rebuild would lose the expression index ``ix_systems_game_id_name_length_name``, which SQLite's reflection skips.
That is why ``assignee_id`` is a plain indexed id (as the audit log's ids) without a foreign key: SQLite can
neither add one to an existing table nor drop a column that has one without a rebuild.

Revision ID: 0020
Revises: 0019
Create Date: 2026-11-23 21:30:00+00:00
"""
from __future__ import annotations

from typing import Sequence, Union

import sqlalchemy as sa
from alembic import op

import app.db.types

revision: str = '0020'
down_revision: Union[str, None] = '0019'
branch_labels: Union[str, Sequence[str], None] = None
depends_on: Union[str, Sequence[str], None] = None


def upgrade() -> None:
    with op.batch_alter_table('systems', schema=None, recreate='never') as batch_op:
        batch_op.add_column(sa.Column('assignee_id', sa.Integer(), nullable=True))
        batch_op.add_column(sa.Column('assigned_at', app.db.types.UTCDateTime(timezone=True), nullable=True))
        batch_op.add_column(sa.Column('assigned_by', sa.String(length=200), nullable=True))
        batch_op.create_index('ix_systems_assignee_id', ['assignee_id'], unique=False)
    op.create_table(
        'system_presence',
        sa.Column('system_id', sa.Integer(), nullable=False),
        sa.Column('user_id', sa.Integer(), nullable=False),
        sa.Column('since', app.db.types.UTCDateTime(timezone=True), nullable=False),
        sa.Column('expires_at', app.db.types.UTCDateTime(timezone=True), nullable=False),
        sa.ForeignKeyConstraint(['system_id'], ['systems.id'], name=op.f('fk_system_presence_system_id_systems'),
                                ondelete='CASCADE'),
        sa.ForeignKeyConstraint(['user_id'], ['users.id'], name=op.f('fk_system_presence_user_id_users'),
                                ondelete='CASCADE'),
        sa.PrimaryKeyConstraint('system_id', 'user_id', name=op.f('pk_system_presence')),
    )
    op.create_index('ix_system_presence_expires_at', 'system_presence', ['expires_at'], unique=False)


def downgrade() -> None:
    op.drop_index('ix_system_presence_expires_at', table_name='system_presence')
    op.drop_table('system_presence')
    # ALTER TABLE ... DROP COLUMN (SQLite >= 3.35), never a copy of the table (module docstring)
    with op.batch_alter_table('systems', schema=None, recreate='never') as batch_op:
        batch_op.drop_index('ix_systems_assignee_id')
        batch_op.drop_column('assigned_by')
        batch_op.drop_column('assigned_at')
        batch_op.drop_column('assignee_id')
