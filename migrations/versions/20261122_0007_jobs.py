"""Background jobs (issues 7 and 8): the ``jobs`` table of ``app.services.jobs.runner`` (imports, full
recomputes and exports run by a runner that a killed process's successor resumes).

Revision ID: 0007
Revises: 0006
Create Date: 2026-11-22 00:45:00+00:00
"""
from __future__ import annotations

from typing import Sequence, Union

import sqlalchemy as sa
from alembic import op
from sqlalchemy.dialects import postgresql

import app.db.types

revision: str = '0007'
down_revision: Union[str, None] = '0006'
branch_labels: Union[str, Sequence[str], None] = None
depends_on: Union[str, Sequence[str], None] = None

_JSON = sa.JSON().with_variant(postgresql.JSONB(astext_type=sa.Text()), 'postgresql')


def upgrade() -> None:
    op.create_table(
        'jobs',
        sa.Column('id', sa.Integer(), nullable=False),
        sa.Column('kind', sa.String(length=20), nullable=False),
        sa.Column('params', _JSON, nullable=False),
        sa.Column('state', sa.Enum('queued', 'running', 'done', 'failed', name='job_state', native_enum=False,
                                   create_constraint=True, length=7), nullable=False),
        sa.Column('stage', sa.String(length=40), nullable=True),
        sa.Column('done', sa.Integer(), nullable=False),
        sa.Column('total', sa.Integer(), nullable=False),
        sa.Column('message', sa.Text(), nullable=True),
        sa.Column('result', _JSON, nullable=True),
        sa.Column('owner', sa.String(length=200), nullable=True),
        sa.Column('attempts', sa.Integer(), nullable=False),
        sa.Column('created_at', app.db.types.UTCDateTime(timezone=True), nullable=False),
        sa.Column('started_at', app.db.types.UTCDateTime(timezone=True), nullable=True),
        sa.Column('finished_at', app.db.types.UTCDateTime(timezone=True), nullable=True),
        sa.Column('heartbeat_at', app.db.types.UTCDateTime(timezone=True), nullable=True),
        sa.PrimaryKeyConstraint('id', name=op.f('pk_jobs')),
    )
    op.create_index('ix_jobs_state_id', 'jobs', ['state', 'id'], unique=False)


def downgrade() -> None:
    op.drop_index('ix_jobs_state_id', table_name='jobs')
    op.drop_table('jobs')
