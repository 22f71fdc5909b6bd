"""Releases: a named, immutable snapshot of the accepted systems (``app.services.releases``).

``releases`` (name unique, note, created_at, created_by, the counts ``systems`` and ``views``, ``hash``: the SHA-256
of the release's canonical content, docs/exports.md gives the recipe); its content as canonical JSON documents stored
once by digest (``release_documents``: ``digest`` the SHA-256 of the canonical JSON, ``body`` that JSON compressed
with zlib), named per release by ``release_games`` (one document per game: its folder names, metadata and as-of
time) and ``release_systems`` (one per accepted system: its frames' labels, lines, calibration, decisions and 3D
result). A system unchanged since the previous release names the same document: a release costs the rows naming
its documents and the documents of what changed. Every table is append-only: triggers refuse UPDATE and DELETE on
SQLite and PostgreSQL, as for the audit log (migrations 0006 and 0024).

Revision ID: 0027
Revises: 0026
Create Date: 2026-11-28 00:00:00+00:00
"""
from __future__ import annotations

from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op

import app.db.types

revision: str = '0027'
down_revision: str | None = '0026'
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None

_TABLES = ("releases", "release_documents", "release_games", "release_systems")
_REFUSAL = "releases are append-only"


def _append_only(table: str) -> None:
    if op.get_bind().dialect.name == "postgresql":
        op.execute(f"CREATE TRIGGER {table}_append_only BEFORE UPDATE OR DELETE ON {table} "
                   "FOR EACH ROW EXECUTE FUNCTION releases_append_only()")
        return
    for event in ("UPDATE", "DELETE"):
        op.execute(f"CREATE TRIGGER {table}_no_{event.lower()} BEFORE {event} ON {table} "
                   f"BEGIN SELECT RAISE(ABORT, '{_REFUSAL}'); END")


def upgrade() -> None:
    op.create_table('releases',
                    sa.Column('id', sa.Integer(), nullable=False),
                    sa.Column('name', sa.String(length=200), nullable=False),
                    sa.Column('note', sa.Text(), nullable=False),
                    sa.Column('created_at', app.db.types.UTCDateTime(timezone=True), nullable=False),
                    sa.Column('created_by', sa.String(length=200), nullable=False),
                    sa.Column('systems', sa.Integer(), nullable=False),
                    sa.Column('views', sa.Integer(), nullable=False),
                    sa.Column('hash', sa.String(length=64), nullable=False),
                    sa.PrimaryKeyConstraint('id', name=op.f('pk_releases')),
                    sa.UniqueConstraint('name', name=op.f('uq_releases_name')))
    op.create_table('release_documents',
                    sa.Column('digest', sa.String(length=64), nullable=False),
                    sa.Column('body', sa.LargeBinary(), nullable=False),
                    sa.PrimaryKeyConstraint('digest', name=op.f('pk_release_documents')))
    op.create_table('release_games',
                    sa.Column('release_id', sa.Integer(), nullable=False),
                    sa.Column('game_id', sa.Integer(), nullable=False),
                    sa.Column('digest', sa.String(length=64), nullable=False),
                    sa.ForeignKeyConstraint(['release_id'], ['releases.id'],
                                            name=op.f('fk_release_games_release_id_releases')),
                    sa.ForeignKeyConstraint(['digest'], ['release_documents.digest'],
                                            name=op.f('fk_release_games_digest_release_documents')),
                    sa.PrimaryKeyConstraint('release_id', 'game_id', name=op.f('pk_release_games')))
    op.create_table('release_systems',
                    sa.Column('release_id', sa.Integer(), nullable=False),
                    sa.Column('system_id', sa.Integer(), nullable=False),
                    sa.Column('game_id', sa.Integer(), nullable=False),
                    sa.Column('name', sa.String(length=400), nullable=False),
                    sa.Column('digest', sa.String(length=64), nullable=False),
                    sa.ForeignKeyConstraint(['release_id'], ['releases.id'],
                                            name=op.f('fk_release_systems_release_id_releases')),
                    sa.ForeignKeyConstraint(['digest'], ['release_documents.digest'],
                                            name=op.f('fk_release_systems_digest_release_documents')),
                    sa.PrimaryKeyConstraint('release_id', 'system_id', name=op.f('pk_release_systems')))
    if op.get_bind().dialect.name == "postgresql":
        op.execute("CREATE FUNCTION releases_append_only() RETURNS trigger LANGUAGE plpgsql AS "
                   f"$$ BEGIN RAISE EXCEPTION '{_REFUSAL}'; END $$")
    for table in _TABLES:
        _append_only(table)


def downgrade() -> None:
    for table in reversed(_TABLES):
        op.drop_table(table)  # its triggers go with it
    if op.get_bind().dialect.name == "postgresql":
        op.execute("DROP FUNCTION IF EXISTS releases_append_only()")
