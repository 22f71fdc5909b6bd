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


def test_alembic_command_line_takes_the_url_from_the_settings(tmp_path):
    """``alembic upgrade head`` then ``alembic check``, as CI runs them, with ``V3D_DATABASE_URL``."""
    import os
    import subprocess
    import sys

    from app.core.paths import PROJECT_ROOT

    db = tmp_path / "cli.sqlite3"
    env = {**os.environ, "V3D_DATABASE_URL": f"sqlite:///{db}"}
    alembic = [sys.executable, "-m", "alembic", "-c", str(PROJECT_ROOT / "alembic.ini")]
    for args in (["upgrade", "head"], ["check"]):
        done = subprocess.run(alembic + args, cwd=tmp_path, env=env, capture_output=True, text=True, timeout=120)
        assert done.returncode == 0, done.stderr
    assert "No new upgrade operations detected" in done.stdout + done.stderr
    assert db.is_file()
