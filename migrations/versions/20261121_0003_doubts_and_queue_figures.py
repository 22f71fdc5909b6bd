"""Doubts of a system (label problems the geometry sees, with fixes), the per-view exclusion decision,
and the review queue's per-system figures and review status stored on the write path (app/db/models/: derived.py's
Doubt, review.py's ReviewDecision.excluded, labels.py's System.doubt_counts ... derived_version). Existing systems get
derived_version 0: the service recomputes them before serving (app.services.derivation.recompute.refresh_stale_systems).

Revision ID: 0003
Revises: 0002
Create Date: 2026-11-21 22:45:13.640548+00:00
"""
from __future__ import annotations

from typing import Sequence, Union

import sqlalchemy as sa
from alembic import op
from sqlalchemy.dialects import postgresql

revision: str = '0003'
down_revision: Union[str, None] = '0002'
branch_labels: Union[str, Sequence[str], None] = None
depends_on: Union[str, Sequence[str], None] = None


def upgrade() -> None:
    op.create_table('doubts',
    sa.Column('id', sa.Integer(), nullable=False),
    sa.Column('system_id', sa.Integer(), nullable=False),
    sa.Column('frame_id', sa.Integer(), nullable=True),
    sa.Column('kind', sa.String(length=40), nullable=False),
    sa.Column('accuses_label', sa.Boolean(), nullable=False),
    sa.Column('message', sa.Text(), nullable=False),
    sa.Column('evidence', sa.JSON().with_variant(postgresql.JSONB(astext_type=sa.Text()), 'postgresql'),
              nullable=False),
    sa.Column('suggestion', sa.JSON().with_variant(postgresql.JSONB(astext_type=sa.Text()), 'postgresql'),
              nullable=True),
    sa.ForeignKeyConstraint(['frame_id'], ['frames.id'], name=op.f('fk_doubts_frame_id_frames'), ondelete='CASCADE'),
    sa.ForeignKeyConstraint(['system_id'], ['systems.id'], name=op.f('fk_doubts_system_id_systems'),
                            ondelete='CASCADE'),
    sa.PrimaryKeyConstraint('id', name=op.f('pk_doubts'))
    )
    with op.batch_alter_table('doubts', schema=None) as batch_op:
        batch_op.create_index('ix_doubts_kind_system_id', ['kind', 'system_id'], unique=False)
        batch_op.create_index(batch_op.f('ix_doubts_system_id'), ['system_id'], unique=False)

    with op.batch_alter_table('review_decisions', schema=None) as batch_op:
        batch_op.add_column(sa.Column('excluded', sa.Boolean(), nullable=False, server_default=sa.false()))

    with op.batch_alter_table('systems', schema=None) as batch_op:
        batch_op.add_column(sa.Column('doubt_counts',
                                      sa.JSON().with_variant(postgresql.JSONB(astext_type=sa.Text()), 'postgresql'),
                                      nullable=False, server_default='{}'))
        batch_op.add_column(sa.Column('label_doubts', sa.Integer(), nullable=False, server_default='0'))
        batch_op.add_column(sa.Column('views_total', sa.Integer(), nullable=False, server_default='0'))
        batch_op.add_column(sa.Column('views_calibrated', sa.Integer(), nullable=False, server_default='0'))
        batch_op.add_column(sa.Column('views_admitted', sa.Integer(), nullable=False, server_default='0'))
        batch_op.add_column(sa.Column('views_labelled', sa.Integer(), nullable=False, server_default='0'))
        batch_op.add_column(sa.Column('lowest_jac', sa.Double(), nullable=True))
        batch_op.add_column(sa.Column('worst_error_px', sa.Double(), nullable=True))
        batch_op.add_column(sa.Column('views_flagged', sa.Integer(), nullable=False, server_default='0'))
        batch_op.add_column(sa.Column('views_above_tau', sa.Integer(), nullable=False, server_default='0'))
        batch_op.add_column(sa.Column('derived_version', sa.Integer(), nullable=False, server_default='0'))
        batch_op.add_column(sa.Column('review_status',
                                      sa.Enum('pending', 'accepted', 'rejected', 'needs_fix',
                                              name='system_review_status', native_enum=False, create_constraint=True),
                                      nullable=False, server_default='pending'))
        batch_op.create_index(batch_op.f('ix_systems_review_status'), ['review_status'], unique=False)
        batch_op.create_index('ix_systems_label_doubts_worst_error_px', ['label_doubts', 'worst_error_px'],
                              unique=False)
        batch_op.create_index(batch_op.f('ix_systems_lowest_jac'), ['lowest_jac'], unique=False)
        batch_op.create_index(batch_op.f('ix_systems_worst_error_px'), ['worst_error_px'], unique=False)



def downgrade() -> None:
    with op.batch_alter_table('systems', schema=None) as batch_op:
        batch_op.drop_index(batch_op.f('ix_systems_worst_error_px'))
        batch_op.drop_index(batch_op.f('ix_systems_lowest_jac'))
        batch_op.drop_index('ix_systems_label_doubts_worst_error_px')
        batch_op.drop_index(batch_op.f('ix_systems_review_status'))
        batch_op.drop_constraint('system_review_status', type_='check')
        batch_op.drop_column('review_status')
        batch_op.drop_column('derived_version')
        batch_op.drop_column('views_above_tau')
        batch_op.drop_column('views_flagged')
        batch_op.drop_column('worst_error_px')
        batch_op.drop_column('lowest_jac')
        batch_op.drop_column('views_labelled')
        batch_op.drop_column('views_admitted')
        batch_op.drop_column('views_calibrated')
        batch_op.drop_column('views_total')
        batch_op.drop_column('label_doubts')
        batch_op.drop_column('doubt_counts')

    with op.batch_alter_table('review_decisions', schema=None) as batch_op:
        batch_op.drop_column('excluded')

    with op.batch_alter_table('doubts', schema=None) as batch_op:
        batch_op.drop_index(batch_op.f('ix_doubts_system_id'))
        batch_op.drop_index('ix_doubts_kind_system_id')

    op.drop_table('doubts')
