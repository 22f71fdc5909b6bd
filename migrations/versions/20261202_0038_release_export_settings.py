"""Releases record the settings their exports are rendered with (``releases.export_settings``).

A release's YOLO and COCO exports choose each view's ball box (refined, optimised or annotated) with settings
(``Settings.ball_diameter_m``, ``Settings.export_ball_box``): read when exporting, a later change of them would change
an old release's files. A release now records them when it is made, in its row beside its hash (not in its documents:
their digests and the release's hash stay as they are). Releases made before hold NULL and render with the values
their documents' version had then (``app.services.releases.render.v1``). Nullable: the table is append-only (its
triggers refuse UPDATE), and SQLite adds a nullable column without rebuilding the table and its triggers.

Revision ID: 0038
Revises: 0037
Create Date: 2026-12-02 00:00:00+00:00
"""
from __future__ import annotations

from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op
from sqlalchemy.dialects import postgresql

revision: str = '0038'
down_revision: str | None = '0037'
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None


def upgrade() -> None:
    op.add_column('releases', sa.Column(
        'export_settings', sa.JSON().with_variant(postgresql.JSONB(astext_type=sa.Text()), 'postgresql'),
        nullable=True))


def downgrade() -> None:
    if op.get_bind().dialect.name == "postgresql":
        op.drop_column('releases', 'export_settings')
    else:  # SQLite drops the column in place (3.35+): a batch rebuild would lose the append-only triggers
        op.execute("ALTER TABLE releases DROP COLUMN export_settings")
