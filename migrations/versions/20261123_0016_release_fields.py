"""What a release carries that v3d does not edit (issue 19, exports that lose nothing): ``games.release`` (the
imported labels file's top-level keys but its frames: ``GameMetadata`` and the replays no action links) and
``frames.release`` (each frame's entry as imported: ``imageMetadata``, every ``bboxes`` entry, the links), both JSON
or NULL, written at import and read by the exports, which no longer read the source files. And
``systems.derived_settings``: the fingerprint of the settings a system's derived rows were computed with
(``Settings.derived_fingerprint``: ``V3D_PROFILE``'s choices among them), so that a changed profile shows as stale.

Games imported before this revision have NULL: their SoccerNet-v3D export carries v3d's fields and the ball only,
as before, until they are imported again (an import is idempotent and fills them in).

Revision ID: 0016
Revises: 0015
Create Date: 2026-11-23 06:00:00+00:00
"""
from __future__ import annotations

from typing import Sequence, Union

import sqlalchemy as sa
from alembic import op
from sqlalchemy.dialects import postgresql

revision: str = '0016'
down_revision: Union[str, None] = '0015'
branch_labels: Union[str, Sequence[str], None] = None
depends_on: Union[str, Sequence[str], None] = None


def _json() -> sa.types.TypeEngine:
    return sa.JSON().with_variant(postgresql.JSONB(astext_type=sa.Text()), 'postgresql')


def upgrade() -> None:
    with op.batch_alter_table('games', schema=None) as batch_op:
        batch_op.add_column(sa.Column('release', _json(), nullable=True))
    with op.batch_alter_table('frames', schema=None) as batch_op:
        batch_op.add_column(sa.Column('release', _json(), nullable=True))
    with op.batch_alter_table('systems', schema=None) as batch_op:
        batch_op.add_column(sa.Column('derived_settings', sa.String(length=16), nullable=True))


def downgrade() -> None:
    # ALTER TABLE ... DROP COLUMN (SQLite >= 3.35), never a copy of the table: a copy would lose the expression
    # index of migration 0013, which SQLite cannot reflect
    with op.batch_alter_table('systems', schema=None, recreate='never') as batch_op:
        batch_op.drop_column('derived_settings')
    with op.batch_alter_table('frames', schema=None) as batch_op:
        batch_op.drop_column('release')
    with op.batch_alter_table('games', schema=None) as batch_op:
        batch_op.drop_column('release')
