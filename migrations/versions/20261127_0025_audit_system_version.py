"""The system's version each audit entry left (``audit_entries.system_version``), integer or NULL; and the time of the
newest change a game's SoccerNet-v3D import said it held (``games.as_of``), or NULL.

A write of a system records its entries with the version it gave the system (``System.version``, the system's ETag),
so that the entries after the version a client saw are the changes it did not see: a stale decision's 412 lists
them, and the undo of an edit finds the decisions that edit set back to pending (the entries of its own write) and
what the system's labels were when it was made. Entries recorded before this revision keep NULL (the table is
append-only: no row is rewritten) and count as unknown. A game's ``as_of`` is what its exports say they hold it as
of when nothing of its own is newer (``GameMetadata.v3d_as_of``, which a ``keep-newer`` merge compares with).

Plain ``ADD COLUMN`` / ``DROP COLUMN`` (no batch copy): the append-only triggers of the table stay in place.

Revision ID: 0025
Revises: 0024
Create Date: 2026-11-27 09:00:00+00:00
"""
from __future__ import annotations

from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op

import app.db.types

revision: str = '0025'
down_revision: str | None = '0024'
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None


def upgrade() -> None:
    op.add_column('audit_entries', sa.Column('system_version', sa.Integer(), nullable=True))
    op.add_column('games', sa.Column('as_of', app.db.types.UTCDateTime(timezone=True), nullable=True))


def downgrade() -> None:
    op.drop_column('games', 'as_of')
    op.drop_column('audit_entries', 'system_version')
