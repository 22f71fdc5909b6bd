"""The players a dataset boxed as their own rows (``player_boxes``: frame, class, ID, box in px) and, on a
calibration the players placed, what it was fitted to (``calibrations.players``: the foot points, the rig position).

SoccerNet-v3 boxes every player of a multi-view system with a class and an ID that name the same person across its
views; a player stands on the grass, so a view its lines cannot calibrate is fitted to the players it shares with the
well-calibrated views (``app.geometry.calibration.players``). The release keeps the file's ``bboxes`` as they came
(``frames.release``): these rows are read by the calibration only. Indexed by frame (a system's views are read).

Revision ID: 0032
Revises: 0031
Create Date: 2026-11-30 09:00:00+00:00
"""
from __future__ import annotations

from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op
from sqlalchemy.dialects import postgresql

revision: str = '0032'
down_revision: str | None = '0031'
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None


def upgrade() -> None:
    op.create_table(
        'player_boxes',
        sa.Column('id', sa.Integer(), nullable=False),
        sa.Column('frame_id', sa.Integer(), nullable=False),
        sa.Column('cls', sa.String(length=200), nullable=False),
        sa.Column('ident', sa.String(length=200), nullable=True),
        sa.Column('x1', sa.Double(), nullable=False),
        sa.Column('y1', sa.Double(), nullable=False),
        sa.Column('x2', sa.Double(), nullable=False),
        sa.Column('y2', sa.Double(), nullable=False),
        sa.ForeignKeyConstraint(['frame_id'], ['frames.id'], name=op.f('fk_player_boxes_frame_id_frames'),
                                ondelete='CASCADE'),
        sa.PrimaryKeyConstraint('id', name=op.f('pk_player_boxes')),
    )
    op.create_index('ix_player_boxes_frame_id', 'player_boxes', ['frame_id'], unique=False)
    with op.batch_alter_table('calibrations') as batch:
        batch.add_column(sa.Column('players', sa.JSON().with_variant(postgresql.JSONB(astext_type=sa.Text()),
                                                                     'postgresql'), nullable=True))


def downgrade() -> None:
    with op.batch_alter_table('calibrations') as batch:
        batch.drop_column('players')
    op.drop_index('ix_player_boxes_frame_id', table_name='player_boxes')
    op.drop_table('player_boxes')
