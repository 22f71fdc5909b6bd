"""Initial schema: games, systems, frames and their annotations, calibrations, triangulations,
optimised boxes and review decisions (see app/db/models/).

Revision ID: 0001
Revises:
Create Date: 2026-11-21 16:53:46.054127+00:00
"""
from __future__ import annotations

from typing import Sequence, Union

import sqlalchemy as sa
from alembic import op
from sqlalchemy.dialects import postgresql

import app.db.types

revision: str = '0001'
down_revision: Union[str, None] = None
branch_labels: Union[str, Sequence[str], None] = None
depends_on: Union[str, Sequence[str], None] = None


def upgrade() -> None:
    op.create_table('games',
    sa.Column('id', sa.Integer(), nullable=False),
    sa.Column('league', sa.String(length=200), nullable=False),
    sa.Column('season', sa.String(length=200), nullable=False),
    sa.Column('match', sa.String(length=400), nullable=False),
    sa.Column('source_path', sa.Text(), nullable=False),
    sa.Column('created_at', app.db.types.UTCDateTime(timezone=True), nullable=False),
    sa.PrimaryKeyConstraint('id', name=op.f('pk_games')),
    sa.UniqueConstraint('league', 'season', 'match', name=op.f('uq_games_league_season_match'))
    )
    op.create_table('systems',
    sa.Column('id', sa.Integer(), nullable=False),
    sa.Column('game_id', sa.Integer(), nullable=False),
    sa.Column('name', sa.String(length=200), nullable=False),
    sa.Column('kind',
              sa.Enum('soccernet-v3', 'single-view', name='system_kind', native_enum=False, create_constraint=True),
              nullable=False),
    sa.Column('created_at', app.db.types.UTCDateTime(timezone=True), nullable=False),
    sa.ForeignKeyConstraint(['game_id'], ['games.id'], name=op.f('fk_systems_game_id_games'), ondelete='CASCADE'),
    sa.PrimaryKeyConstraint('id', name=op.f('pk_systems')),
    sa.UniqueConstraint('game_id', 'name', name=op.f('uq_systems_game_id_name'))
    )
    with op.batch_alter_table('systems', schema=None) as batch_op:
        batch_op.create_index(batch_op.f('ix_systems_game_id'), ['game_id'], unique=False)

    op.create_table('frames',
    sa.Column('id', sa.Integer(), nullable=False),
    sa.Column('system_id', sa.Integer(), nullable=False),
    sa.Column('name', sa.String(length=200), nullable=False),
    sa.Column('role',
              sa.Enum('action', 'replay', 'camera', name='frame_role', native_enum=False, create_constraint=True),
              nullable=False),
    sa.Column('position', sa.Integer(), nullable=False),
    sa.Column('width', sa.Integer(), nullable=False),
    sa.Column('height', sa.Integer(), nullable=False),
    sa.Column('image_zip', sa.Text(), nullable=True),
    sa.Column('image_member', sa.Text(), nullable=True),
    sa.Column('image_path', sa.Text(), nullable=True),
    sa.CheckConstraint('width > 0 AND height > 0', name=op.f('ck_frames_positive_size')),
    sa.ForeignKeyConstraint(['system_id'], ['systems.id'], name=op.f('fk_frames_system_id_systems'),
                            ondelete='CASCADE'),
    sa.PrimaryKeyConstraint('id', name=op.f('pk_frames')),
    sa.UniqueConstraint('system_id', 'name', name=op.f('uq_frames_system_id_name'))
    )
    with op.batch_alter_table('frames', schema=None) as batch_op:
        batch_op.create_index(batch_op.f('ix_frames_system_id'), ['system_id'], unique=False)

    op.create_table('triangulations',
    sa.Column('system_id', sa.Integer(), nullable=False),
    sa.Column('status',
              sa.Enum('triangulated', 'insufficient_views', 'no_pair_kept', name='triangulation_status',
                      native_enum=False, create_constraint=True), nullable=False),
    sa.Column('ball3d', sa.JSON().with_variant(postgresql.JSONB(astext_type=sa.Text()), 'postgresql'), nullable=True),
    sa.Column('tau_px', sa.Double(), nullable=False),
    sa.Column('rule', sa.String(length=40), nullable=False),
    sa.Column('min_baseline_m', sa.Double(), nullable=False),
    sa.Column('computed_at', app.db.types.UTCDateTime(timezone=True), nullable=False),
    sa.ForeignKeyConstraint(['system_id'], ['systems.id'], name=op.f('fk_triangulations_system_id_systems'),
                            ondelete='CASCADE'),
    sa.PrimaryKeyConstraint('system_id', name=op.f('pk_triangulations'))
    )
    op.create_table('ball_labels',
    sa.Column('frame_id', sa.Integer(), nullable=False),
    sa.Column('kind', sa.Enum('box', 'point', name='ball_kind', native_enum=False, create_constraint=True),
              nullable=True),
    sa.Column('box', sa.JSON().with_variant(postgresql.JSONB(astext_type=sa.Text()), 'postgresql'), nullable=True),
    sa.Column('point', sa.JSON().with_variant(postgresql.JSONB(astext_type=sa.Text()), 'postgresql'), nullable=True),
    sa.Column('original_kind',
              sa.Enum('box', 'point', name='ball_original_kind', native_enum=False, create_constraint=True),
              nullable=True),
    sa.Column('original_box', sa.JSON().with_variant(postgresql.JSONB(astext_type=sa.Text()), 'postgresql'),
              nullable=True),
    sa.Column('original_point', sa.JSON().with_variant(postgresql.JSONB(astext_type=sa.Text()), 'postgresql'),
              nullable=True),
    sa.Column('edited_at', app.db.types.UTCDateTime(timezone=True), nullable=True),
    sa.ForeignKeyConstraint(['frame_id'], ['frames.id'], name=op.f('fk_ball_labels_frame_id_frames'),
                            ondelete='CASCADE'),
    sa.PrimaryKeyConstraint('frame_id', name=op.f('pk_ball_labels'))
    )
    op.create_table('ball_reprojections',
    sa.Column('frame_id', sa.Integer(), nullable=False),
    sa.Column('point', sa.JSON().with_variant(postgresql.JSONB(astext_type=sa.Text()), 'postgresql'), nullable=False),
    sa.Column('error_px', sa.Double(), nullable=True),
    sa.ForeignKeyConstraint(['frame_id'], ['frames.id'], name=op.f('fk_ball_reprojections_frame_id_frames'),
                            ondelete='CASCADE'),
    sa.PrimaryKeyConstraint('frame_id', name=op.f('pk_ball_reprojections'))
    )
    op.create_table('calibrations',
    sa.Column('frame_id', sa.Integer(), nullable=False),
    sa.Column('source',
              sa.Enum('imported', 'computed', 'edited', name='calibration_source', native_enum=False,
                      create_constraint=True), nullable=False),
    sa.Column('status',
              sa.Enum('calibrated', 'refused', name='calibration_status', native_enum=False, create_constraint=True),
              nullable=False),
    sa.Column('camera', sa.JSON().with_variant(postgresql.JSONB(astext_type=sa.Text()), 'postgresql'), nullable=True),
    sa.Column('reason', sa.Text(), nullable=True),
    sa.Column('flags', sa.JSON().with_variant(postgresql.JSONB(astext_type=sa.Text()), 'postgresql'), nullable=False),
    sa.Column('residuals_px', sa.JSON().with_variant(postgresql.JSONB(astext_type=sa.Text()), 'postgresql'),
              nullable=False),
    sa.Column('jac_0005', sa.Double(), nullable=True),
    sa.Column('jac_001', sa.Double(), nullable=True),
    sa.Column('jac_002', sa.Double(), nullable=True),
    sa.Column('admitted', sa.Boolean(), nullable=False),
    sa.Column('updated_at', app.db.types.UTCDateTime(timezone=True), nullable=False),
    sa.ForeignKeyConstraint(['frame_id'], ['frames.id'], name=op.f('fk_calibrations_frame_id_frames'),
                            ondelete='CASCADE'),
    sa.PrimaryKeyConstraint('frame_id', name=op.f('pk_calibrations'))
    )
    op.create_table('field_lines',
    sa.Column('frame_id', sa.Integer(), nullable=False),
    sa.Column('lines', sa.JSON().with_variant(postgresql.JSONB(astext_type=sa.Text()), 'postgresql'), nullable=False),
    sa.Column('original_lines', sa.JSON().with_variant(postgresql.JSONB(astext_type=sa.Text()), 'postgresql'),
              nullable=False),
    sa.Column('edited_at', app.db.types.UTCDateTime(timezone=True), nullable=True),
    sa.ForeignKeyConstraint(['frame_id'], ['frames.id'], name=op.f('fk_field_lines_frame_id_frames'),
                            ondelete='CASCADE'),
    sa.PrimaryKeyConstraint('frame_id', name=op.f('pk_field_lines'))
    )
    op.create_table('optimised_boxes',
    sa.Column('frame_id', sa.Integer(), nullable=False),
    sa.Column('box', sa.JSON().with_variant(postgresql.JSONB(astext_type=sa.Text()), 'postgresql'), nullable=False),
    sa.Column('d_opt_px', sa.Double(), nullable=False),
    sa.Column('error_m', sa.Double(), nullable=False),
    sa.ForeignKeyConstraint(['frame_id'], ['frames.id'], name=op.f('fk_optimised_boxes_frame_id_frames'),
                            ondelete='CASCADE'),
    sa.PrimaryKeyConstraint('frame_id', name=op.f('pk_optimised_boxes'))
    )
    op.create_table('review_decisions',
    sa.Column('id', sa.Integer(), nullable=False),
    sa.Column('system_id', sa.Integer(), nullable=True),
    sa.Column('frame_id', sa.Integer(), nullable=True),
    sa.Column('status',
              sa.Enum('pending', 'accepted', 'rejected', 'needs_fix', name='review_status', native_enum=False,
                      create_constraint=True), nullable=False),
    sa.Column('comment', sa.Text(), nullable=False),
    sa.Column('decided_at', app.db.types.UTCDateTime(timezone=True), nullable=True),
    sa.CheckConstraint('(system_id IS NULL) <> (frame_id IS NULL)', name=op.f('ck_review_decisions_one_subject')),
    sa.ForeignKeyConstraint(['frame_id'], ['frames.id'], name=op.f('fk_review_decisions_frame_id_frames'),
                            ondelete='CASCADE'),
    sa.ForeignKeyConstraint(['system_id'], ['systems.id'], name=op.f('fk_review_decisions_system_id_systems'),
                            ondelete='CASCADE'),
    sa.PrimaryKeyConstraint('id', name=op.f('pk_review_decisions')),
    sa.UniqueConstraint('frame_id', name=op.f('uq_review_decisions_frame_id')),
    sa.UniqueConstraint('system_id', name=op.f('uq_review_decisions_system_id'))
    )
    op.create_table('triangulation_pairs',
    sa.Column('id', sa.Integer(), nullable=False),
    sa.Column('system_id', sa.Integer(), nullable=False),
    sa.Column('frame_a_id', sa.Integer(), nullable=False),
    sa.Column('frame_b_id', sa.Integer(), nullable=False),
    sa.Column('point', sa.JSON().with_variant(postgresql.JSONB(astext_type=sa.Text()), 'postgresql'), nullable=True),
    sa.Column('error_px', sa.Double(), nullable=True),
    sa.Column('parallax_deg', sa.Double(), nullable=True),
    sa.Column('baseline_m', sa.Double(), nullable=False),
    sa.Column('kept', sa.Boolean(), nullable=False),
    sa.Column('reason', sa.Text(), nullable=True),
    sa.ForeignKeyConstraint(['frame_a_id'], ['frames.id'], name=op.f('fk_triangulation_pairs_frame_a_id_frames'),
                            ondelete='CASCADE'),
    sa.ForeignKeyConstraint(['frame_b_id'], ['frames.id'], name=op.f('fk_triangulation_pairs_frame_b_id_frames'),
                            ondelete='CASCADE'),
    sa.ForeignKeyConstraint(['system_id'], ['triangulations.system_id'],
                            name=op.f('fk_triangulation_pairs_system_id_triangulations'), ondelete='CASCADE'),
    sa.PrimaryKeyConstraint('id', name=op.f('pk_triangulation_pairs'))
    )
    with op.batch_alter_table('triangulation_pairs', schema=None) as batch_op:
        batch_op.create_index(batch_op.f('ix_triangulation_pairs_system_id'), ['system_id'], unique=False)



def downgrade() -> None:
    with op.batch_alter_table('triangulation_pairs', schema=None) as batch_op:
        batch_op.drop_index(batch_op.f('ix_triangulation_pairs_system_id'))

    op.drop_table('triangulation_pairs')
    op.drop_table('review_decisions')
    op.drop_table('optimised_boxes')
    op.drop_table('field_lines')
    op.drop_table('calibrations')
    op.drop_table('ball_reprojections')
    op.drop_table('ball_labels')
    op.drop_table('triangulations')
    with op.batch_alter_table('frames', schema=None) as batch_op:
        batch_op.drop_index(batch_op.f('ix_frames_system_id'))

    op.drop_table('frames')
    with op.batch_alter_table('systems', schema=None) as batch_op:
        batch_op.drop_index(batch_op.f('ix_systems_game_id'))

    op.drop_table('systems')
    op.drop_table('games')
