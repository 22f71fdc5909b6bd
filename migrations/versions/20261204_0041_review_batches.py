"""Batches of vouched systems accepted after a random sample: ``review_batches`` (one row per batch: the queue's
filters, the sampling plan's confidence and largest wrong share, the systems it selected with their versions then,
the random sample, its state and what it accepted) and ``review_decisions.batch_id`` (the batch that accepted a
system, NULL for a person's decision: every decision stored before was a person's).

Revision ID: 0041
Revises: 0040
Create Date: 2026-12-04 00:00:00+00:00
"""
from __future__ import annotations

from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op
from sqlalchemy.dialects import postgresql

import app.db.types

revision: str = '0041'
down_revision: str | None = '0040'
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None

_JSON = sa.JSON().with_variant(postgresql.JSONB(astext_type=sa.Text()), 'postgresql')


def upgrade() -> None:
    op.create_table(
        'review_batches',
        sa.Column('id', sa.Integer(), nullable=False),
        sa.Column('created_by', sa.String(length=200), nullable=False),
        sa.Column('created_at', app.db.types.UTCDateTime(timezone=True), nullable=False),
        sa.Column('filters', _JSON, nullable=False),
        sa.Column('confidence', sa.Double(), nullable=False),
        sa.Column('max_wrong_share', sa.Double(), nullable=False),
        sa.Column('system_ids', _JSON, nullable=False),
        sa.Column('versions', _JSON, nullable=False),
        sa.Column('sample_ids', _JSON, nullable=False),
        sa.Column('state', sa.String(length=20), nullable=False),
        sa.Column('refusal', sa.Text(), nullable=True),
        sa.Column('decided_by', sa.String(length=200), nullable=True),
        sa.Column('decided_at', app.db.types.UTCDateTime(timezone=True), nullable=True),
        sa.Column('accepted_ids', _JSON, nullable=True),
        sa.Column('undone_at', app.db.types.UTCDateTime(timezone=True), nullable=True),
        sa.PrimaryKeyConstraint('id', name=op.f('pk_review_batches')),
    )
    op.add_column('review_decisions', sa.Column('batch_id', sa.Integer(), nullable=True))


def downgrade() -> None:
    with op.batch_alter_table('review_decisions') as batch:
        batch.drop_column('batch_id')
    op.drop_table('review_batches')
