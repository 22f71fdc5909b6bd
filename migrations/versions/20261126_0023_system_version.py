"""One version per multi-view system and per game, for the edit path's optimistic concurrency.

``systems.review_version`` (bumped by decisions only) becomes ``systems.version``: bumped in the same transaction
by every write of the rows an edit of the system reads (its labels, lines, exclusions, calibrations, decisions and
derived rows; ``app.services.derivation.scope``), so an edit compares one number under its lock, and the system's
ETag covers what its reviewer saw. ``games.version`` is bumped by every change of what an edit reads beyond its
system: the calibrations that make the game's camera rig and the game's camera prior.

Plain ``RENAME COLUMN`` and ``ADD COLUMN`` (SQLite >= 3.25 and PostgreSQL), no batch copy of the tables.

Revision ID: 0023
Revises: 0022
Create Date: 2026-11-26 10:40:00+00:00
"""
from __future__ import annotations

from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op

revision: str = '0023'
down_revision: str | None = '0022'
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None


def upgrade() -> None:
    op.execute("ALTER TABLE systems RENAME COLUMN review_version TO version")
    op.add_column('games', sa.Column('version', sa.Integer(), nullable=False, server_default='1'))


def downgrade() -> None:
    op.drop_column('games', 'version')
    op.execute("ALTER TABLE systems RENAME COLUMN version TO review_version")
