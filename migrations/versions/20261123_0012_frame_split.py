"""A frame's split as a release names it (issue 19): ``frames.split`` ("train", "test" or NULL), set by
``v3d import split FILE --set train|test`` (a released ``SNv3D-train.txt`` / ``SNv3D-test.txt``); exports and
benchmarks use it in place of the kind's own split where it is set (``app.services.kinds``).

Revision ID: 0012
Revises: 0011
Create Date: 2026-11-23 01:00:00+00:00
"""
from __future__ import annotations

from typing import Sequence, Union

import sqlalchemy as sa
from alembic import op

revision: str = '0012'
down_revision: Union[str, None] = '0011'
branch_labels: Union[str, Sequence[str], None] = None
depends_on: Union[str, Sequence[str], None] = None


def upgrade() -> None:
    with op.batch_alter_table('frames', schema=None) as batch_op:
        batch_op.add_column(sa.Column('split', sa.String(length=8), nullable=True))


def downgrade() -> None:
    with op.batch_alter_table('frames', schema=None) as batch_op:
        batch_op.drop_column('split')
