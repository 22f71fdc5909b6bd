"""Every audit entry's change in one line of words (issue 28, item 4): ``audit_entries.summary``, text or NULL,
written when the entry is recorded (``app.services.audit.summaries.summarize``). Entries recorded before this
revision keep NULL (the table is append-only: no row is rewritten) and get the same function's summary when read.

Plain ``ADD COLUMN`` / ``DROP COLUMN`` (no batch copy): the append-only triggers of the table stay in place.

Revision ID: 0022
Revises: 0021
Create Date: 2026-11-23 21:30:00+00:00
"""
from __future__ import annotations

from typing import Sequence, Union

import sqlalchemy as sa
from alembic import op

revision: str = '0022'
down_revision: Union[str, None] = '0021'
branch_labels: Union[str, Sequence[str], None] = None
depends_on: Union[str, Sequence[str], None] = None


def upgrade() -> None:
    op.add_column('audit_entries', sa.Column('summary', sa.String(length=300), nullable=True))


def downgrade() -> None:
    op.drop_column('audit_entries', 'summary')
