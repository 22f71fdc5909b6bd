"""A ball label made from a doubt's suggestion keeps its provenance (issue 18).

``ball_labels.provenance`` (new, JSON, nullable): ``{"source": "suggestion", "doubt": <kind>, "code": <code>,
"from_views": [frame ids]}`` for a label a fix key (or a script sending ``suggestion.request``) snapped to where
other views put the ball; null for a label a person placed (imported, drawn, moved, or a suggestion confirmed).
A label with a provenance is not independent evidence: it joins no triangulation and no doubt vote until a
person has placed it. Existing rows keep null.

Revision ID: 0017
Revises: 0016
Create Date: 2026-11-23 07:00:00+00:00
"""
from __future__ import annotations

from typing import Sequence, Union

import sqlalchemy as sa
from alembic import op
from sqlalchemy.dialects import postgresql

revision: str = '0017'
down_revision: Union[str, None] = '0016'
branch_labels: Union[str, Sequence[str], None] = None
depends_on: Union[str, Sequence[str], None] = None


def upgrade() -> None:
    with op.batch_alter_table('ball_labels') as batch_op:
        batch_op.add_column(sa.Column('provenance',
                                      sa.JSON().with_variant(postgresql.JSONB(astext_type=sa.Text()), 'postgresql'),
                                      nullable=True))


def downgrade() -> None:
    with op.batch_alter_table('ball_labels') as batch_op:
        batch_op.drop_column('provenance')
