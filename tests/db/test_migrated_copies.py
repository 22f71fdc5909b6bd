"""The suite's new SQLite databases are copies of one migrated once per test process
(``tests.conftest.migrate_new_database``), and its migrated PostgreSQL databases copies of a template database
(``tests.conftest.fresh_postgresql_database``): each must be what the migrations make, its session key its own."""
from __future__ import annotations

import sqlite3
from pathlib import Path

import pytest
import sqlalchemy as sa

from app.db.session import alembic_config, upgrade_database
from tests.conftest import PG_ADMIN_URL, fresh_postgresql_database, migrate_new_database


def _facts(path: Path) -> tuple[dict[str, list[str]], str, str]:
    """Each table's and index's definition (its clauses sorted: Alembic's batch moves write a rebuilt table's
    constraints in an order that changes from one run of the migrations to the next), the revision, the session key."""
    with sqlite3.connect(path) as db:
        rows = db.execute("SELECT name, sql FROM sqlite_master WHERE name NOT LIKE 'sqlite_stat%'").fetchall()
        revision = db.execute("SELECT version_num FROM alembic_version").fetchone()[0]
        key = db.execute("SELECT value FROM server_secrets WHERE name = 'session'").fetchone()[0]
    return {name: _clauses(sql or "") for name, sql in rows}, revision, key


def _clauses(sql: str) -> list[str]:
    """A definition's head, then the clauses between its outer parentheses, sorted."""
    text = " ".join(sql.split())
    if "(" not in text or not text.endswith(")"):
        return [text]
    head, body = text.split("(", 1)
    return [head.strip(), *sorted(part.strip() for part in body[:-1].split(", "))]


def test_a_copied_database_is_what_the_migrations_make_with_a_session_key_of_its_own(tmp_path: Path) -> None:
    upgrade_database(f"sqlite:///{tmp_path / 'migrated.sqlite3'}")
    migrate_new_database(f"sqlite:///{tmp_path / 'a' / 'copy.sqlite3'}")
    migrate_new_database(f"sqlite:///{tmp_path / 'b' / 'copy.sqlite3'}")
    migrated, a, b = (_facts(p) for p in (tmp_path / "migrated.sqlite3", tmp_path / "a" / "copy.sqlite3",
                                           tmp_path / "b" / "copy.sqlite3"))
    assert a[:2] == migrated[:2] and b[:2] == migrated[:2]  # the same tables, indexes and revision
    assert len({migrated[2], a[2], b[2]}) == 3  # each its own session key, as the migration draws one


def test_an_existing_database_is_migrated_not_replaced(tmp_path: Path) -> None:
    url = f"sqlite:///{tmp_path / 'kept.sqlite3'}"
    migrate_new_database(url)
    with sqlite3.connect(tmp_path / "kept.sqlite3") as db:
        db.execute("INSERT INTO games (league, season, match, source_path, created_at) "
                   "VALUES ('l', 's', 'kept', '/x', '2026-11-29 08:00:00')")
    migrate_new_database(url)
    with sqlite3.connect(tmp_path / "kept.sqlite3") as db:
        assert db.execute("SELECT match FROM games").fetchall() == [("kept",)]


@pytest.mark.postgres
def test_a_copied_postgresql_database_is_what_the_migrations_make_with_a_session_key_of_its_own() -> None:
    """``fresh_postgresql_database(migrated=True)`` copies a database migrated once per test process: each copy
    matches the models as a migrated database does (Alembic's ``check``), is at the head, and draws its own key."""
    from alembic import command
    from alembic.script import ScriptDirectory

    def facts(url: str) -> tuple[str, str]:
        engine = sa.create_engine(url)
        try:
            with engine.connect() as conn:
                return (conn.execute(sa.text("SELECT version_num FROM alembic_version")).scalar_one(),
                        conn.execute(sa.text("SELECT value FROM server_secrets WHERE name = 'session'")).scalar_one())
        finally:
            engine.dispose()

    with fresh_postgresql_database(PG_ADMIN_URL, migrated=True) as a, \
            fresh_postgresql_database(PG_ADMIN_URL, migrated=True) as b:
        command.check(alembic_config(a))  # raises when the copy's schema differs from the models
        (rev_a, key_a), (rev_b, key_b) = facts(a), facts(b)
        head = ScriptDirectory.from_config(alembic_config(a)).get_current_head()
        assert rev_a == rev_b == head
        assert key_a != key_b
