"""A calibration dataset's learned camera prior (issue 17): ``games.camera_prior``, JSON or NULL, the
:class:`~app.geometry.calibration.priors.CameraPrior` its import learned from its own confident fits
(``CameraPrior.to_json``). Every later recalibration of the dataset's frames (a line edit, the mirror fix, an
import of changed lines) refits with it where the lines leave the camera open, as the import did: without it an
edit of a frame the import had fitted with the prior would refit it without, and move its camera.

Datasets imported before this revision have NULL (no prior) until they are imported again.

Revision ID: 0019
Revises: 0018
Create Date: 2026-11-23 13:30:00+00:00
"""
from __future__ import annotations

from typing import Sequence, Union

import sqlalchemy as sa
from alembic import op
from sqlalchemy.dialects import postgresql

revision: str = '0019'
down_revision: Union[str, None] = '0018'
branch_labels: Union[str, Sequence[str], None] = None
depends_on: Union[str, Sequence[str], None] = None


def upgrade() -> None:
    with op.batch_alter_table('games', schema=None) as batch_op:
        batch_op.add_column(sa.Column('camera_prior',
                                      sa.JSON().with_variant(postgresql.JSONB(astext_type=sa.Text()), 'postgresql'),
                                      nullable=True))


def downgrade() -> None:
    with op.batch_alter_table('games', schema=None) as batch_op:
        batch_op.drop_column('camera_prior')
