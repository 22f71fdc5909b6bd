"""Precise ball boxes (issue 19, Table 1): ``frames.precise_box`` (JSON ``[x1, y1, x2, y2]`` pixels of the image, or
NULL), stored by ``v3d import precise-boxes`` and read by ``v3d evaluate boxes`` and the system page.

Revision ID: 0014
Revises: 0013
Create Date: 2026-11-23 01:05:00+00:00
"""
from __future__ import annotations

from typing import Sequence, Union

import sqlalchemy as sa
from alembic import op
from sqlalchemy.dialects import postgresql

revision: str = '0014'
down_revision: Union[str, None] = '0013'
branch_labels: Union[str, Sequence[str], None] = None
depends_on: Union[str, Sequence[str], None] = None


def upgrade() -> None:
    with op.batch_alter_table('frames', schema=None) as batch_op:
        batch_op.add_column(sa.Column(
            'precise_box', sa.JSON().with_variant(postgresql.JSONB(astext_type=sa.Text()),
                                                  'postgresql'), nullable=True))


def downgrade() -> None:
    with op.batch_alter_table('frames', schema=None) as batch_op:
        batch_op.drop_column('precise_box')
