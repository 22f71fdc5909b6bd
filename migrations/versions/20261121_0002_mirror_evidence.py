"""Calibrations keep the evidence on mirrored field-line labels (app.geometry.mirror).

Revision ID: 0002
Revises: 0001
Create Date: 2026-11-21 17:45:00+00:00
"""
from __future__ import annotations

from typing import Sequence, Union

import sqlalchemy as sa
from alembic import op
from sqlalchemy.dialects import postgresql

revision: str = '0002'
down_revision: Union[str, None] = '0001'
branch_labels: Union[str, Sequence[str], None] = None
depends_on: Union[str, Sequence[str], None] = None


def upgrade() -> None:
    with op.batch_alter_table('calibrations') as batch_op:
        batch_op.add_column(sa.Column('mirror_evidence',
                                      sa.JSON().with_variant(postgresql.JSONB(astext_type=sa.Text()), 'postgresql'),
                                      nullable=True))


def downgrade() -> None:
    with op.batch_alter_table('calibrations') as batch_op:
        batch_op.drop_column('mirror_evidence')
