"""A calibration decision per view beside its ball decision, and why a decision went back to pending (issue 16).

``review_decisions`` gains (frame decisions use all of them, system decisions the ``reset_reason``):

* ``calibration_status`` (pending / accepted / rejected / needs_fix, default pending), ``calibration_comment``
  (text, default empty) and ``calibration_decided_at`` (UTC, null when never decided): the reviewer's decision on
  the view's calibration (its field lines and the camera fitted to them), apart from the decision on its ball;
* ``calibration_reset_reason`` (text, null): why the calibration decision is pending again (an edit of the
  view's field lines recalibrated it after it was decided); cleared by the next decision;
* ``reset_reason`` (text, null): why the decision (a system's) is pending again: a view's calibration changed
  after the system was decided; cleared by the next decision.

Existing rows: calibration pending, no reasons.

Revision ID: 0018
Revises: 0017
Create Date: 2026-11-23 09:00:00+00:00
"""
from __future__ import annotations

from typing import Sequence, Union

import sqlalchemy as sa
from alembic import op

import app.db.types

revision: str = '0018'
down_revision: Union[str, None] = '0017'
branch_labels: Union[str, Sequence[str], None] = None
depends_on: Union[str, Sequence[str], None] = None


#: Reflect only the rebuilt table, not the tables its foreign keys name (the systems table): SQLite's reflection of
#: the systems table's expression index warns at every fresh upgrade, and the rebuild never needs that table.
_OWN_TABLE_ONLY = {"resolve_fks": False}


def upgrade() -> None:
    with op.batch_alter_table('review_decisions', schema=None, reflect_kwargs=_OWN_TABLE_ONLY) as batch_op:
        batch_op.add_column(sa.Column('calibration_status',
                                      sa.Enum('pending', 'accepted', 'rejected', 'needs_fix',
                                              name='calibration_review_status', native_enum=False,
                                              create_constraint=True),
                                      nullable=False, server_default='pending'))
        batch_op.add_column(sa.Column('calibration_comment', sa.Text(), nullable=False, server_default=''))
        batch_op.add_column(sa.Column('calibration_decided_at', app.db.types.UTCDateTime(timezone=True), nullable=True))
        batch_op.add_column(sa.Column('calibration_reset_reason', sa.Text(), nullable=True))
        batch_op.add_column(sa.Column('reset_reason', sa.Text(), nullable=True))


def downgrade() -> None:
    with op.batch_alter_table('review_decisions', schema=None, reflect_kwargs=_OWN_TABLE_ONLY) as batch_op:
        batch_op.drop_column('reset_reason')
        batch_op.drop_column('calibration_reset_reason')
        batch_op.drop_column('calibration_decided_at')
        batch_op.drop_column('calibration_comment')
        batch_op.drop_constraint('calibration_review_status', type_='check')
        batch_op.drop_column('calibration_status')
