"""PostgreSQL connections are pinged when they leave the pool only after being idle (``app.db.session``): a connection
used a moment ago is handed out as it is, one that waited longer is pinged and, dead, replaced without the request
seeing an error. Reads that need no snapshot run without a transaction of their own (``reads_on_their_own``)."""
from __future__ import annotations

import pytest
import sqlalchemy as sa

from app.db import session as db_session_module
from app.db.session import (
    PING_AFTER_IDLE_S,
    make_engine,
    make_session_factory,
    reads_as_one_snapshot,
    reads_on_their_own,
)

pytestmark = pytest.mark.engine


def test_a_pooled_connection_is_pinged_only_after_idling_and_replaced_when_dead(pg_url: str, monkeypatch) -> None:
    engine = make_engine(pg_url)
    pings = []
    real_ping = engine.dialect.do_ping
    monkeypatch.setattr(engine.dialect, "do_ping", lambda conn: pings.append(1) or real_ping(conn))
    with engine.connect() as c:  # a new connection: not pinged
        first_pid = c.exec_driver_sql("SELECT pg_backend_pid()").scalar()
    with engine.connect() as c:  # back from the pool a moment ago: not pinged
        assert c.exec_driver_sql("SELECT pg_backend_pid()").scalar() == first_pid
    assert pings == []

    record = engine.pool._pool.queue[0]  # the pooled connection's entry: make it idle for longer than the limit
    record.info[db_session_module._IDLE_SINCE] -= PING_AFTER_IDLE_S + 1
    with engine.connect() as c:
        assert c.exec_driver_sql("SELECT pg_backend_pid()").scalar() == first_pid  # pinged, alive, kept
    assert pings == [1]

    with make_engine(pg_url, pool_pre_ping=False).connect() as admin:  # the server ends the idle connection
        admin.exec_driver_sql(f"SELECT pg_terminate_backend({first_pid})")
        admin.commit()
    engine.pool._pool.queue[0].info[db_session_module._IDLE_SINCE] -= PING_AFTER_IDLE_S + 1
    with engine.connect() as c:  # the ping fails: a fresh connection is handed out, no error
        assert c.exec_driver_sql("SELECT 1").scalar() == 1
        assert c.exec_driver_sql("SELECT pg_backend_pid()").scalar() != first_pid
    assert len(pings) == 2
    engine.dispose()


def test_reads_on_their_own_run_without_a_transaction_on_postgresql_only(pg_url: str, tmp_path) -> None:
    for url, postgresql in ((pg_url, True), (f"sqlite:///{tmp_path / 'plain.sqlite3'}", False)):
        engine = make_engine(url)
        factory = make_session_factory(engine)
        with factory() as s:
            reads_on_their_own(s)
            assert s.in_transaction() is postgresql  # SQLite: nothing begun, nothing changed
            if postgresql:
                assert s.connection().connection.dbapi_connection.autocommit
            assert s.execute(sa.text("SELECT 1")).scalar() == 1
        with factory() as s:  # a transaction begun already is left as it is
            s.execute(sa.text("SELECT 1"))
            reads_on_their_own(s)
            assert not getattr(s.connection().connection.dbapi_connection, "autocommit", False)
        with factory() as s:  # the pool hands the connection back at its default level
            assert not getattr(s.connection().connection.dbapi_connection, "autocommit", False)
        engine.dispose()


def test_reads_as_one_snapshot_do_not_see_a_commit_made_between_them_on_postgresql(pg_url: str) -> None:
    engine = make_engine(pg_url)
    with engine.begin() as c:
        c.exec_driver_sql("CREATE TABLE snapshot_probe (n integer)")
    factory = make_session_factory(engine)
    try:
        with factory() as reader, factory() as writer:
            reader.execute(sa.text("SELECT 1"))  # a read-only transaction begun already is ended first
            reads_as_one_snapshot(reader)
            count = "SELECT count(*) FROM snapshot_probe"
            assert reader.execute(sa.text(count)).scalar() == 0
            writer.execute(sa.text("INSERT INTO snapshot_probe VALUES (1)"))
            writer.commit()
            assert reader.execute(sa.text(count)).scalar() == 0  # READ COMMITTED would see 1 here
            reader.commit()
            assert reader.execute(sa.text(count)).scalar() == 1  # the next transaction is at the default level
            assert reader.execute(sa.text("SHOW transaction_isolation")).scalar() == "read committed"
    finally:
        with engine.begin() as c:
            c.exec_driver_sql("DROP TABLE snapshot_probe")
        engine.dispose()
