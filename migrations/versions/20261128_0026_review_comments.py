"""The team's loop: comments pinned on a view (``review_comments``), the hand-off of a system marked needs fix to a
person and back (``review_handoffs``), the review status ``fixed`` (systems sent back by the person they were returned
to), each view's stored distance from the ball the other views agree on (``ball_reprojections.others_distance_px``, the
per-annotator figures' geometry) and an index of the audit log by action and time (those figures' reads).

The status CHECK constraints are rebuilt with the new value: on SQLite in batch mode (copy, drop, rename; foreign keys
are off while migrating, ``migrations/env.py``). Batch mode does not reflect an expression index, so the keyset index
on the systems' names (migration 0013) is dropped before and made again after. ``ADD COLUMN`` for the distance: the
append-only triggers of the audit log are not touched (an index only).

Revision ID: 0026
Revises: 0025
Create Date: 2026-11-28 09:00:00+00:00
"""
from __future__ import annotations

from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op
from sqlalchemy.dialects import postgresql

import app.db.types

revision: str = '0026'
down_revision: str | None = '0025'
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None

_OLD = ('pending', 'accepted', 'rejected', 'needs_fix')
_NEW = (*_OLD, 'fixed')
#: (table, constraint, column) of every review status CHECK constraint.
_CHECKS = (('systems', 'system_review_status', 'review_status'),
           ('review_decisions', 'review_status', 'status'),
           ('review_decisions', 'calibration_review_status', 'calibration_status'))
_NAME_INDEX = 'ix_systems_game_id_name_length_name'


def _statuses(values: tuple[str, ...]) -> None:
    op.drop_index(_NAME_INDEX, table_name='systems')
    for table in ('systems', 'review_decisions'):
        with op.batch_alter_table(table, schema=None) as batch_op:
            for t, name, column in _CHECKS:
                if t == table:
                    batch_op.drop_constraint(name, type_='check')
                    batch_op.create_check_constraint(name, sa.column(column).in_(values))
    op.create_index(_NAME_INDEX, 'systems', ['game_id', sa.text('length(name)'), 'name'], unique=False)


def upgrade() -> None:
    op.create_table(
        'review_handoffs',
        sa.Column('id', sa.Integer(), nullable=False),
        sa.Column('system_id', sa.Integer(), nullable=False),
        sa.Column('returned_to_id', sa.Integer(), nullable=True),
        sa.Column('returned_by', sa.String(length=200), nullable=False),
        sa.Column('note', sa.Text(), nullable=False),
        sa.Column('returned_at', app.db.types.UTCDateTime(timezone=True), nullable=False),
        sa.Column('fixed_at', app.db.types.UTCDateTime(timezone=True), nullable=True),
        sa.Column('closed_at', app.db.types.UTCDateTime(timezone=True), nullable=True),
        sa.ForeignKeyConstraint(['system_id'], ['systems.id'], name=op.f('fk_review_handoffs_system_id_systems'),
                                ondelete='CASCADE'),
        sa.PrimaryKeyConstraint('id', name=op.f('pk_review_handoffs')),
    )
    op.create_index(op.f('ix_review_handoffs_system_id'), 'review_handoffs', ['system_id'], unique=False)
    op.create_index('ix_review_handoffs_returned_to_id_returned_at', 'review_handoffs',
                    ['returned_to_id', 'returned_at'], unique=False)
    op.create_table(
        'review_comments',
        sa.Column('id', sa.Integer(), nullable=False),
        sa.Column('system_id', sa.Integer(), nullable=False),
        sa.Column('frame_id', sa.Integer(), nullable=False),
        sa.Column('point', sa.JSON().with_variant(postgresql.JSONB(astext_type=sa.Text()), 'postgresql'),
                  nullable=True),
        sa.Column('text', sa.Text(), nullable=False),
        sa.Column('author', sa.String(length=200), nullable=False),
        sa.Column('created_at', app.db.types.UTCDateTime(timezone=True), nullable=False),
        sa.Column('resolved', sa.Boolean(), nullable=False),
        sa.Column('resolved_by', sa.String(length=200), nullable=True),
        sa.Column('resolved_at', app.db.types.UTCDateTime(timezone=True), nullable=True),
        sa.ForeignKeyConstraint(['frame_id'], ['frames.id'], name=op.f('fk_review_comments_frame_id_frames'),
                                ondelete='CASCADE'),
        sa.ForeignKeyConstraint(['system_id'], ['systems.id'], name=op.f('fk_review_comments_system_id_systems'),
                                ondelete='CASCADE'),
        sa.PrimaryKeyConstraint('id', name=op.f('pk_review_comments')),
    )
    op.create_index(op.f('ix_review_comments_system_id'), 'review_comments', ['system_id'], unique=False)
    op.add_column('ball_reprojections', sa.Column('others_distance_px', sa.Double(), nullable=True))
    op.create_index('ix_audit_entries_action_at', 'audit_entries', ['action', 'at'], unique=False)
    _statuses(_NEW)


def downgrade() -> None:
    op.execute("UPDATE review_decisions SET status = 'pending' WHERE status = 'fixed'")
    op.execute("UPDATE review_decisions SET calibration_status = 'pending' WHERE calibration_status = 'fixed'")
    op.execute("UPDATE systems SET review_status = 'pending' WHERE review_status = 'fixed'")
    _statuses(_OLD)
    op.drop_index('ix_audit_entries_action_at', table_name='audit_entries')
    op.drop_column('ball_reprojections', 'others_distance_px')
    op.drop_index(op.f('ix_review_comments_system_id'), table_name='review_comments')
    op.drop_table('review_comments')
    op.drop_index('ix_review_handoffs_returned_to_id_returned_at', table_name='review_handoffs')
    op.drop_index(op.f('ix_review_handoffs_system_id'), table_name='review_handoffs')
    op.drop_table('review_handoffs')
