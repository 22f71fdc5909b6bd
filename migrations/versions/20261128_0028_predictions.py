"""A ball detector's predictions as their own rows (``predictions``): source, frame, score, box in px.

``v3d import predictions`` / ``POST /api/imports`` (kind ``predictions``) fills it, replacing a source's rows as a
whole; the doubts check each prediction against the other views and offer a checked one as a fix. A prediction is
never a label: one placed by a fix key is a ball label with its provenance (``ball_labels.provenance``, revision
0017, with the detector's source and score) until a person confirms it. Indexed by frame (the doubts read a
system's) and by source (replace, remove, the monocular benchmark).

Revision ID: 0028
Revises: 0027
Create Date: 2026-11-28 09:00:00+00:00
"""
from __future__ import annotations

from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op

import app.db.types

revision: str = '0028'
down_revision: str | None = "0027"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None


def upgrade() -> None:
    op.create_table(
        'predictions',
        sa.Column('id', sa.Integer(), nullable=False),
        sa.Column('source', sa.String(length=200), nullable=False),
        sa.Column('frame_id', sa.Integer(), nullable=False),
        sa.Column('score', sa.Double(), nullable=False),
        sa.Column('x1', sa.Double(), nullable=False),
        sa.Column('y1', sa.Double(), nullable=False),
        sa.Column('x2', sa.Double(), nullable=False),
        sa.Column('y2', sa.Double(), nullable=False),
        sa.Column('created_at', app.db.types.UTCDateTime(timezone=True), nullable=False),
        sa.CheckConstraint('x2 > x1 AND y2 > y1', name=op.f('ck_predictions_positive_box')),
        sa.ForeignKeyConstraint(['frame_id'], ['frames.id'], name=op.f('fk_predictions_frame_id_frames'),
                                ondelete='CASCADE'),
        sa.PrimaryKeyConstraint('id', name=op.f('pk_predictions')),
    )
    op.create_index('ix_predictions_frame_id', 'predictions', ['frame_id'], unique=False)
    op.create_index('ix_predictions_source', 'predictions', ['source'], unique=False)


def downgrade() -> None:
    op.drop_index('ix_predictions_source', table_name='predictions')
    op.drop_index('ix_predictions_frame_id', table_name='predictions')
    op.drop_table('predictions')
