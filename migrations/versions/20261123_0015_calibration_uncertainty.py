"""Calibrations keep their uncertainty: standard deviations of camera position, angles and focal (issue 17).

``calibrations.uncertainty`` (new, JSON, nullable): ``app.geometry.calibration.CalibrationUncertainty.to_json``
of a camera fitted from lines (``{"position_m": {"x", "y", "z"}, "pan_deg", "tilt_deg", "roll_deg",
"focal_px", "line_noise_px", "points"}``, null for an undetermined parameter). Existing rows keep null until
they are calibrated again; imported calibrations (SoccerNet-v3D, ISSIA) have none.

Revision ID: 0015
Revises: 0014
Create Date: 2026-11-23 01:00:00+00:00
"""
from __future__ import annotations

from typing import Sequence, Union

import sqlalchemy as sa
from alembic import op
from sqlalchemy.dialects import postgresql

revision: str = '0015'
down_revision: Union[str, None] = '0014'
branch_labels: Union[str, Sequence[str], None] = None
depends_on: Union[str, Sequence[str], None] = None


def upgrade() -> None:
    with op.batch_alter_table('calibrations') as batch_op:
        batch_op.add_column(sa.Column('uncertainty',
                                      sa.JSON().with_variant(postgresql.JSONB(astext_type=sa.Text()), 'postgresql'),
                                      nullable=True))


def downgrade() -> None:
    with op.batch_alter_table('calibrations') as batch_op:
        batch_op.drop_column('uncertainty')
