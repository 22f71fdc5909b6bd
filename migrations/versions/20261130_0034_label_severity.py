"""Systems store their label doubts' severity (``systems.label_severity``), written with the doubts.

The review queue's default order (``-severity``: the work still to do first, the most severe doubt first) read each
system's severity through a correlated subquery over its doubts, which made every page of a 12,800-system queue
aggregate every system's doubts (about 60 times the SQLite work of a page by the stored doubt count). The severity
is now a column beside ``label_doubts``, written by the same recomputation, with an index by review status; this
revision fills it for the systems stored before from their stored doubts (``LABEL_KIND_SEVERITY`` as it stands:
mirrored field lines 3; a ball off the others or views that disagree 2; a missing, redundant or detected ball 1).

Revision ID: 0034
Revises: 0032
Create Date: 2026-11-30 12:00:00+00:00
"""
from __future__ import annotations

from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op

revision: str = '0034'
down_revision: str | None = '0032'
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None

# The table as this revision knows it, so that a later change of the constant leaves this revision's fill alone.
_SEVERITY = {"mirrored_labels": 3, "ball_off_consensus": 2, "views_disagree": 2, "ball_missing": 1,
             "near_duplicate_view": 1, "ball_detected": 1}


def upgrade() -> None:
    op.add_column('systems', sa.Column('label_severity', sa.Integer(), server_default='0', nullable=False))
    op.create_index('ix_systems_review_status_label_severity_worst_error_px', 'systems',
                    ['review_status', 'label_severity', 'worst_error_px'], unique=False)
    systems = sa.table('systems', sa.column('id', sa.Integer), sa.column('label_severity', sa.Integer))
    doubts = sa.table('doubts', sa.column('system_id', sa.Integer), sa.column('kind', sa.String))
    weight = sa.case(_SEVERITY, value=doubts.c.kind, else_=0)
    worst = (sa.select(sa.func.coalesce(sa.func.max(weight), 0)).where(doubts.c.system_id == systems.c.id)
             .scalar_subquery())
    op.execute(systems.update().values(label_severity=worst))


def downgrade() -> None:
    op.drop_index('ix_systems_review_status_label_severity_worst_error_px', table_name='systems')
    # a plain DROP COLUMN (SQLite 3.35+, PostgreSQL): a batch rebuild of the table would lose the expression index
    # on the systems' names (``ix_systems_game_id_name_length_name``), which SQLite cannot reflect
    op.execute('ALTER TABLE systems DROP COLUMN label_severity')
