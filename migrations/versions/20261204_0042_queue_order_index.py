"""An index for the review queue's default order (app/db/models/labels.py: System's indexes): the work still to do
first (``REVIEW_ORDER_SQL``, the statuses as literals), then the most severe doubt, the largest reprojection error,
the count of label doubts and the id, so that the first page of the queue and a system page's neighbours are seeks in
it instead of a sort of every system (SQLite's ``SCAN systems``, PostgreSQL's ``Seq Scan``, per request). The index
of that order within a review status gains the count of label doubts and the id, so that the pending queue's page is
read in its order too instead of sorting every pending system.

Revision ID: 0042
Revises: 0041
Create Date: 2026-12-04 00:00:00+00:00
"""
from __future__ import annotations

from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op

revision: str = '0042'
down_revision: str | None = '0041'
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None

#: As ``app.db.models.labels.REVIEW_ORDER_SQL`` was when this revision was written (a migration never changes).
REVIEW_ORDER_SQL = "CASE review_status\nWHEN 'pending' THEN 0\nWHEN 'fixed' THEN 0\nELSE 1\nEND"


def upgrade() -> None:
    op.create_index('ix_systems_review_order_severity', 'systems',
                    [sa.text(f'(\n{REVIEW_ORDER_SQL})'), 'label_severity', 'worst_error_px', 'label_doubts', 'id'],
                    unique=False)
    op.create_index('ix_systems_review_status_severity_error_doubts_id', 'systems',
                    ['review_status', 'label_severity', 'worst_error_px', 'label_doubts', 'id'], unique=False)
    op.drop_index('ix_systems_review_status_label_severity_worst_error_px', table_name='systems')


def downgrade() -> None:
    op.create_index('ix_systems_review_status_label_severity_worst_error_px', 'systems',
                    ['review_status', 'label_severity', 'worst_error_px'], unique=False)
    op.drop_index('ix_systems_review_status_severity_error_doubts_id', table_name='systems')
    op.drop_index('ix_systems_review_order_severity', table_name='systems')
