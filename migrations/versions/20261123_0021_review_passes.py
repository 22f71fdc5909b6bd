"""Review passes (issue 28): ``review_passes``, one row per pass a user began from the review queue: the
queue's filters and sort as they stood, the frozen ids of every system of that queue across all its pages
in that order, and where the user is (``position``, an index into ``system_ids``). Decisions are not copied:
the next pending system of a pass is read from the systems' current review status.

Revision ID: 0021
Revises: 0020
Create Date: 2026-11-23 21:30:00+00:00
"""
from __future__ import annotations

from typing import Sequence, Union

import sqlalchemy as sa
from alembic import op
from sqlalchemy.dialects import postgresql

import app.db.types

revision: str = '0021'
down_revision: Union[str, None] = '0020'
branch_labels: Union[str, Sequence[str], None] = None
depends_on: Union[str, Sequence[str], None] = None

_JSON = sa.JSON().with_variant(postgresql.JSONB(astext_type=sa.Text()), 'postgresql')


def upgrade() -> None:
    op.create_table(
        'review_passes',
        sa.Column('id', sa.Integer(), nullable=False),
        sa.Column('user_name', sa.String(length=200), nullable=False),
        sa.Column('filters', _JSON, nullable=False),
        sa.Column('sort', sa.String(length=20), nullable=False),
        sa.Column('system_ids', _JSON, nullable=False),
        sa.Column('position', sa.Integer(), nullable=False),
        sa.Column('created_at', app.db.types.UTCDateTime(timezone=True), nullable=False),
        sa.Column('visited_at', app.db.types.UTCDateTime(timezone=True), nullable=False),
        sa.PrimaryKeyConstraint('id', name=op.f('pk_review_passes')),
    )
    op.create_index('ix_review_passes_user_name_id', 'review_passes', ['user_name', 'id'], unique=False)


def downgrade() -> None:
    op.drop_index('ix_review_passes_user_name_id', table_name='review_passes')
    op.drop_table('review_passes')
