"""Engine and session factories, and the programmatic Alembic upgrade.

Nothing here runs at import time: the API, the CLI and the tests each build their own engine from a
URL (``Settings.database_url``), so a test can point the whole service at a throw-away database.
"""
from __future__ import annotations

import sys
from pathlib import Path
from typing import Any

import sqlalchemy as sa
from sqlalchemy import event
from sqlalchemy.engine import Engine, make_url
from sqlalchemy.orm import Session, sessionmaker

from app.core.paths import PROJECT_ROOT

#: The Alembic configuration of the project (``script_location = migrations``).
ALEMBIC_INI = PROJECT_ROOT / "alembic.ini"


def _prepare_sqlite(engine: Engine, url: sa.URL) -> None:
    """Foreign keys ON, WAL journal for file databases, and SQLAlchemy's pysqlite recipe for working
    SAVEPOINTs: the driver's own implicit BEGIN is disabled and SQLAlchemy emits ``BEGIN`` itself, so
    that ``Session.begin_nested()`` and ``join_transaction_mode="create_savepoint"`` behave as on
    PostgreSQL."""
    in_memory = url.database in (None, "", ":memory:") or "mode=memory" in str(url)

    @event.listens_for(engine, "connect")
    def _on_connect(dbapi_connection: Any, _record: Any) -> None:
        dbapi_connection.isolation_level = None
        cursor = dbapi_connection.cursor()
        cursor.execute("PRAGMA foreign_keys=ON")
        if not in_memory:
            cursor.execute("PRAGMA journal_mode=WAL")
            cursor.execute("PRAGMA synchronous=NORMAL")
        cursor.close()

    @event.listens_for(engine, "begin")
    def _on_begin(conn: sa.Connection) -> None:
        conn.exec_driver_sql("BEGIN")


def make_engine(url: str | sa.URL, **kwargs: Any) -> Engine:
    """A SQLAlchemy engine for ``url`` (SQLite or PostgreSQL).

    SQLite engines enforce foreign keys, use WAL for files, allow use from the API's worker threads
    and support savepoints (see :func:`_prepare_sqlite`). Extra ``kwargs`` go to ``create_engine``.
    """
    u = make_url(url)
    if u.get_backend_name() == "sqlite":
        kwargs.setdefault("connect_args", {}).setdefault("check_same_thread", False)
        kwargs["connect_args"].setdefault("timeout", 30)
        engine = sa.create_engine(u, **kwargs)
        _prepare_sqlite(engine, u)
        return engine
    kwargs.setdefault("pool_pre_ping", True)
    return sa.create_engine(u, **kwargs)


def make_session_factory(engine: Engine) -> sessionmaker[Session]:
    """Sessions bound to ``engine``; objects stay readable after commit (``expire_on_commit=False``)
    so that services can return the ORM rows they just committed."""
    return sessionmaker(bind=engine, expire_on_commit=False)


def alembic_config(url: str | sa.URL | None = None, connection: sa.Connection | None = None) -> Any:
    """The project's Alembic ``Config``; ``url`` or an open ``connection`` override the settings'
    database (``migrations/env.py`` reads them from ``config.attributes``)."""
    from alembic.config import Config

    # Alembic's default ``stdout`` is bound when alembic.config is first imported; pass the current
    # one, or a first import under a redirected stdout (a CLI test runner) leaves a closed stream.
    cfg = Config(str(ALEMBIC_INI), stdout=sys.stdout)
    cfg.attributes["configure_logger"] = False  # leave the caller's logging alone
    cfg.set_main_option("script_location", str(PROJECT_ROOT / "migrations"))
    if url is not None:
        cfg.attributes["url"] = make_url(url)
    if connection is not None:
        cfg.attributes["connection"] = connection
    return cfg


def upgrade_database(url: str | sa.URL, revision: str = "head") -> None:
    """Create or migrate the database at ``url`` to ``revision`` with Alembic.

    The parent folder of a SQLite file is created if missing. This is the only way v3d creates its
    tables (never ``Base.metadata.create_all``), so every run exercises the migrations.
    """
    from alembic import command

    u = make_url(url)
    if u.get_backend_name() == "sqlite" and u.database not in (None, "", ":memory:"):
        Path(u.database).expanduser().parent.mkdir(parents=True, exist_ok=True)
    command.upgrade(alembic_config(u), revision)
