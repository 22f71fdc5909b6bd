"""An index for the queue's keyset pages in name order (issue 16 item 6; app/db/models/labels.py: System's indexes):
the numeric name order within a game (``game_id, length(name), name``), so that every slice of a page
(``app.services.curation.queue._slices``) and a deep ``offset`` walk an index in its order instead of
sorting each game's systems (the last page by offset sorted all 12,800 systems game by game).

Revision ID: 0013
Revises: 0012
Create Date: 2026-11-23 00:55:00+00:00
"""
from __future__ import annotations

from typing import Sequence, Union

import sqlalchemy as sa
from alembic import op

revision: str = '0013'
down_revision: Union[str, None] = '0012'
branch_labels: Union[str, Sequence[str], None] = None
depends_on: Union[str, Sequence[str], None] = None


def upgrade() -> None:
    op.create_index('ix_systems_game_id_name_length_name', 'systems',
                    ['game_id', sa.text('length(name)'), 'name'], unique=False)


def downgrade() -> None:
    op.drop_index('ix_systems_game_id_name_length_name', table_name='systems')
