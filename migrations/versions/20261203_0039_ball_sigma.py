"""Each stored 3D ball carries its sigma (``triangulations.sigma_m``, metres along its least certain direction).

Its sigma (``app.geometry.evidence.kept_pairs_sigma_m``, whatever ``ball_rule`` made the ball) says how far it may
lie off; the system page shows it and the queue filters by it. Nullable: NULL for a ball stored before (the derived
version is raised, so every system is recomputed before it is served) and for a system without a ball.

Revision ID: 0039
Revises: 0038
Create Date: 2026-12-03 00:00:00+00:00
"""
from __future__ import annotations

from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op

revision: str = '0039'
down_revision: str | None = '0038'
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None


def upgrade() -> None:
    op.add_column('triangulations', sa.Column('sigma_m', sa.Double(), nullable=True))


def downgrade() -> None:
    with op.batch_alter_table('triangulations') as batch:
        batch.drop_column('sigma_m')
