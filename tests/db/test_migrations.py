"""The schema is built by Alembic, matches the models (``alembic check``), and migrates both ways,
on SQLite always and on the local PostgreSQL when it runs."""
from __future__ import annotations

import pytest
import sqlalchemy as sa
from alembic import command

from app.db.models import Base
from app.db.session import alembic_config, make_engine, upgrade_database


def test_upgrade_then_check_on_sqlite(tmp_path):
    url = f"sqlite:///{tmp_path / 'nested' / 'm.sqlite3'}"
    upgrade_database(url)  # also creates the missing parent folder
    command.check(alembic_config(url))  # raises when the models and the migrations disagree
    engine = make_engine(url)
    try:
        tables = set(sa.inspect(engine).get_table_names())
    finally:
        engine.dispose()
    assert set(Base.metadata.tables) <= tables
    assert "alembic_version" in tables


def test_downgrade_to_base_and_up_again(tmp_path):
    url = f"sqlite:///{tmp_path / 'm.sqlite3'}"
    upgrade_database(url)
    command.downgrade(alembic_config(url), "base")
    engine = make_engine(url)
    try:
        assert set(sa.inspect(engine).get_table_names()) == {"alembic_version"}
    finally:
        engine.dispose()
    upgrade_database(url)
    command.check(alembic_config(url))


def test_sqlite_engine_enforces_foreign_keys_and_uses_wal(db_engine):
    with db_engine.connect() as conn:
        assert conn.exec_driver_sql("PRAGMA foreign_keys").scalar() == 1
        assert conn.exec_driver_sql("PRAGMA journal_mode").scalar() == "wal"


@pytest.mark.postgres
def test_upgrade_then_check_on_postgres(pg_url):
    upgrade_database(pg_url)
    command.check(alembic_config(pg_url))
    engine = make_engine(pg_url)
    try:
        cols = {c["name"]: c for c in sa.inspect(engine).get_columns("calibrations")}
    finally:
        engine.dispose()
    assert type(cols["camera"]["type"]).__name__ == "JSONB"
    assert type(cols["jac_0005"]["type"]).__name__ == "DOUBLE_PRECISION"
