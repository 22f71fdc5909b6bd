"""Each system stores what backs its 3D ball (``systems.ball_evidence``, ``systems.ball_evidence_reasons``).

The tier (``vouched``: no label doubt and evidence independent of the two rays that make a ball agrees;
``unconfirmed``: nothing but the views' own agreement; ``doubted``: a label doubt names a view the ball uses;
``none``: no ball) and its reasons are written with the ball by every recomputation
(``app.geometry.ball_evidence``), so that the review queue filters and sorts by the tier without computing it; the
index by review status serves the pending vouched systems. The rows stored before read ``none`` and no reason until
they are recomputed (the derived version is raised with this revision, so every system is recomputed before it is
served).

The CHECK constraint is named as the model's (``system_ball_evidence``) and written in the column's definition on
SQLite, which cannot add a constraint to a table but by rebuilding it (a rebuild would lose the expression index on
the systems' names, ``ix_systems_game_id_name_length_name``, which SQLite cannot reflect).

Revision ID: 0040
Revises: 0039
Create Date: 2026-12-04 00:00:00+00:00
"""
from __future__ import annotations

from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op
from sqlalchemy.dialects import postgresql

revision: str = '0040'
down_revision: str | None = '0039'
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None

# The tiers as this revision knows them, so that a later change of ``BallEvidence`` leaves this revision alone.
_TIERS = ('vouched', 'unconfirmed', 'doubted', 'none')
_CHECK = "ball_evidence IN ({})".format(", ".join(f"'{t}'" for t in _TIERS))


def upgrade() -> None:
    if op.get_bind().dialect.name == 'sqlite':
        op.execute("ALTER TABLE systems ADD COLUMN ball_evidence VARCHAR(11) DEFAULT 'none' NOT NULL "
                   f"CONSTRAINT system_ball_evidence CHECK ({_CHECK})")
    else:
        op.add_column('systems', sa.Column('ball_evidence', sa.String(11), server_default='none', nullable=False))
        op.create_check_constraint('system_ball_evidence', 'systems', _CHECK)
    op.add_column('systems', sa.Column('ball_evidence_reasons',
                                       sa.JSON().with_variant(postgresql.JSONB(astext_type=sa.Text()), 'postgresql'),
                                       server_default='[]', nullable=False))
    op.create_index('ix_systems_review_status_ball_evidence', 'systems', ['review_status', 'ball_evidence'],
                    unique=False)


def downgrade() -> None:
    op.drop_index('ix_systems_review_status_ball_evidence', table_name='systems')
    # plain DROP COLUMNs (SQLite 3.35+, PostgreSQL) for the reason above; the column's own CHECK goes with it
    op.execute('ALTER TABLE systems DROP COLUMN ball_evidence_reasons')
    if op.get_bind().dialect.name != 'sqlite':
        op.drop_constraint('system_ball_evidence', 'systems', type_='check')
    op.execute('ALTER TABLE systems DROP COLUMN ball_evidence')
