"""Alembic environment of v3d.

The database comes, in order, from ``config.attributes["connection"]`` (an open connection, used by
tests), ``config.attributes["url"]`` (``app.db.session.upgrade_database``), or
``app.core.config.get_settings().database_url`` (the ``alembic`` command line).
"""
from __future__ import annotations

from contextlib import contextmanager
from logging.config import fileConfig

import sqlalchemy as sa
from alembic import context

from app.db.models import Base
from app.db.session import make_engine

config = context.config
if config.config_file_name is not None and config.attributes.get("configure_logger", True):
    fileConfig(config.config_file_name, disable_existing_loggers=False)

target_metadata = Base.metadata


def _url():
    url = config.attributes.get("url")
    if url is None:
        from app.core.config import get_settings

        url = get_settings().database_url
    return url


def _configure(**kwargs) -> None:
    context.configure(
        target_metadata=target_metadata,
        compare_type=True,
        render_as_batch=True,  # SQLite cannot ALTER most things; batch mode copies the table
        **kwargs,
    )


def run_migrations_offline() -> None:
    """Emit SQL without a database connection (``alembic upgrade --sql``)."""
    _configure(url=str(_url()), literal_binds=True, dialect_opts={"paramstyle": "named"})
    with context.begin_transaction():
        context.run_migrations()


def run_migrations_online() -> None:
    """Run against a live database."""
    connection = config.attributes.get("connection")
    if connection is not None:
        _configure(connection=connection)
        with context.begin_transaction():
            context.run_migrations()
        return
    engine = make_engine(_url())
    try:
        with engine.connect() as conn:
            sqlite = conn.dialect.name == "sqlite"
            if sqlite:
                _sqlite_foreign_keys(conn, on=False)
            with _migration_lock(conn):
                _configure(connection=conn)
                with context.begin_transaction():
                    context.run_migrations()
            if sqlite:
                _sqlite_foreign_keys(conn, on=True)
    finally:
        engine.dispose()


#: Key of the PostgreSQL advisory lock held while migrating (any fixed 64-bit number; these are the bytes "v3d-migr").
MIGRATION_LOCK_KEY = 0x7633642D6D696772


@contextmanager
def _migration_lock(conn):
    """On PostgreSQL, hold a session-level advisory lock on :data:`MIGRATION_LOCK_KEY` around the migrations, on
    the connection that runs them: nodes started at once (or a rolling upgrade) migrate one after another, and each
    later one finds the schema at head and does nothing. Without it two fresh nodes both created
    ``alembic_version`` and one failed with a unique violation. SQLite needs none: its write lock orders them.

    The lock is taken and released in transactions of their own (committed at once), so that Alembic begins its
    transaction on a connection that holds none."""
    if conn.dialect.name != "postgresql":
        yield
        return
    conn.execute(sa.text("SELECT pg_advisory_lock(:key)"), {"key": MIGRATION_LOCK_KEY})
    conn.commit()
    try:
        yield
    finally:
        if conn.in_transaction():  # a failed migration: end its transaction so that the unlock can run
            conn.rollback()
        conn.execute(sa.text("SELECT pg_advisory_unlock(:key)"), {"key": MIGRATION_LOCK_KEY})
        conn.commit()


def _sqlite_foreign_keys(conn, on: bool) -> None:
    """Foreign keys off while SQLite migrates, then checked and on again.

    Batch mode rebuilds a table by copying it and dropping the original; with foreign keys on, dropping
    a parent table (``systems``) cascades to its children (every frame, calibration and label), so
    an upgrade of a filled database would empty it. The pragma is a no-op inside a transaction, so it
    goes to the driver's connection before Alembic begins one. After the migrations,
    ``PRAGMA foreign_key_check`` must find nothing.

    Raises:
        RuntimeError: the migrated database has rows whose foreign keys point nowhere.
    """
    raw = conn.connection.driver_connection
    if on:
        broken = raw.execute("PRAGMA foreign_key_check").fetchall()
        if broken:
            raise RuntimeError(f"migration left rows with dangling foreign keys: {broken[:5]}")
    raw.execute(f"PRAGMA foreign_keys={'ON' if on else 'OFF'}")


if context.is_offline_mode():
    run_migrations_offline()
else:
    run_migrations_online()
