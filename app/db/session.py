"""Engine and session factories, write transactions, and the programmatic Alembic upgrade.

Nothing here runs at import time: the API, the CLI and the tests each build their own engine from a
URL (``Settings.database_url``), so a test can point the whole service at a throw-away database.

Concurrency (several server processes on one database, issue 7): a unit of work that writes starts its
transaction with :func:`begin_write`. On SQLite that transaction is ``BEGIN IMMEDIATE``: it takes the
database's write lock before its first read, waiting its turn up to :data:`SQLITE_BUSY_TIMEOUT_S`
behind another writer, so no read-modify-write ever has to upgrade a read lock (a deferred ``BEGIN``
that reads and then writes fails at once with "database is locked" when another process committed in
between: WAL cannot upgrade a stale snapshot, and no busy timeout helps). Reads keep a deferred
``BEGIN`` and never wait for writers (WAL). On PostgreSQL the option changes nothing; the services lock
the rows they read-modify-write (``SELECT ... FOR UPDATE``, ``app.services.curation.editing``).

How long a write waits (issue 27): the served processes' engines are made with ``write_lock_timeout_s``
(``V3D_WRITE_LOCK_TIMEOUT_S``, a few seconds: SQLite's turn and busy timeout, PostgreSQL's ``lock_timeout``);
past it the wait fails with an ``OperationalError`` that :func:`is_lock_timeout` recognises and the API answers
503 with ``Retry-After``. Edits hold the lock only to compare and write (they compute before it), so such a wait
means overload, never another annotator's geometry. Command-line engines keep :data:`SQLITE_BUSY_TIMEOUT_S`.
"""
from __future__ import annotations

import sys
import threading
import weakref
import time
from pathlib import Path
from typing import Any

import sqlalchemy as sa
from sqlalchemy import event
from sqlalchemy.engine import Engine, make_url
from sqlalchemy.orm import Session, sessionmaker

from app.core.paths import PROJECT_ROOT
from app.db.together import end_of_transaction
from app.db.types import json_dumps, json_loads

#: The Alembic configuration of the project (``script_location = migrations``).
ALEMBIC_INI = PROJECT_ROOT / "alembic.ini"
#: Execution option of a connection whose transaction writes: SQLite begins it ``BEGIN IMMEDIATE``.
WRITE_OPTION = "v3d_write"
#: How long a SQLite write transaction of a command-line engine waits for the write lock before "database is
#: locked" (seconds): an import in the CLI may queue behind a server's import batch. Served engines wait
#: ``Settings.write_lock_timeout_s`` instead (``make_engine(write_lock_timeout_s=)``).
SQLITE_BUSY_TIMEOUT_S = 60.0
#: ``Session.info`` keys: the transaction :func:`begin_write` began, the last transaction that flushed, the read
#: snapshot :func:`begin_snapshot` began or kept.
_WRITE_TX, _FLUSHED_TX, _SNAPSHOT_TX = "v3d_write_transaction", "v3d_flushed_transaction", "v3d_snapshot_transaction"
#: ``Connection.info`` key (the pooled connection's): the :class:`_WriteTurns` whose turn it holds.
_HOLDS_TURN = "v3d_write_turn"


class _WriteTurns:
    """Fair turns at SQLite's write lock for the threads and processes of one database.

    SQLite's own busy handler makes a waiting writer sleep longer and longer (up to 100 ms between
    tries), so a writer that has waited long loses the lock to every newcomer, and under 20 annotators
    some edits waited past a minute. Instead: one writer per process queues for the database (the
    others wait on :attr:`lock`, woken one at a time), and that one tries ``BEGIN IMMEDIATE`` every few
    milliseconds (:data:`_TRY_MS`) until ``timeout_s``, so the processes' queues take turns.
    """

    #: Busy timeout of one try at the write lock (milliseconds).
    _TRY_MS = 5

    def __init__(self, timeout_s: float) -> None:
        self.timeout_s = timeout_s
        self.lock = threading.Lock()

    def begin(self, conn: sa.Connection) -> None:
        """``BEGIN IMMEDIATE`` on ``conn`` once it is this process's turn and the database's write lock
        is free; raises ``sqlalchemy.exc.OperationalError`` ("database is locked") after ``timeout_s``."""
        import sqlite3

        deadline = time.monotonic() + self.timeout_s
        if not self.lock.acquire(timeout=self.timeout_s):
            raise sa.exc.OperationalError("BEGIN IMMEDIATE", None, sqlite3.OperationalError(
                "database is locked (no turn at the write lock in this process)"))
        conn.info[_HOLDS_TURN] = self
        raw = conn.connection.dbapi_connection
        raw.execute(f"PRAGMA busy_timeout = {self._TRY_MS}")
        try:
            while True:
                try:
                    raw.execute("BEGIN IMMEDIATE")
                    return
                except sqlite3.OperationalError as exc:
                    if "locked" not in str(exc) or time.monotonic() > deadline:
                        self.release(conn)
                        raise sa.exc.OperationalError("BEGIN IMMEDIATE", None, exc) from None
        finally:
            raw.execute(f"PRAGMA busy_timeout = {int(self.timeout_s * 1000)}")

    @staticmethod
    def release(conn: Any) -> None:
        """End the turn ``conn`` holds, if any (at its commit or rollback)."""
        turns = conn.info.pop(_HOLDS_TURN, None)
        if turns is not None:
            turns.lock.release()


#: Each SQLite engine's :class:`_WriteTurns` (:func:`begin_write_keeping_objects` takes a turn as ``begin`` does).
_TURNS: "weakref.WeakKeyDictionary[Engine, _WriteTurns]" = weakref.WeakKeyDictionary()


def _prepare_sqlite(engine: Engine, url: sa.URL, busy_timeout_s: float) -> None:
    """Foreign keys ON, WAL journal for file databases, and SQLAlchemy's pysqlite recipe for working
    SAVEPOINTs: the driver's own implicit BEGIN is disabled and SQLAlchemy emits ``BEGIN`` itself, so
    that ``Session.begin_nested()`` and ``join_transaction_mode="create_savepoint"`` behave as on
    PostgreSQL. Write transactions (:func:`begin_write`) begin with ``BEGIN IMMEDIATE`` in fair turns
    (:class:`_WriteTurns`)."""
    in_memory = url.database in (None, "", ":memory:") or "mode=memory" in str(url)
    turns = _WriteTurns(busy_timeout_s)
    _TURNS[engine] = turns

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
        # A write transaction takes the write lock now (waiting its turn), a read transaction stays
        # deferred (WAL: it never waits). See the module docstring.
        if conn.get_execution_options().get(WRITE_OPTION):
            turns.begin(conn)
        else:
            conn.exec_driver_sql("BEGIN")

    for name in ("commit", "rollback"):  # the turn ends with the transaction
        event.listen(engine, name, _WriteTurns.release)
    event.listen(engine.pool, "checkin", lambda _dbapi, record: _WriteTurns.release(record))  # never leaked


def make_engine(url: str | sa.URL, write_lock_timeout_s: float | None = None, **kwargs: Any) -> Engine:
    """A SQLAlchemy engine for ``url`` (SQLite or PostgreSQL).

    Both encode and decode JSON columns with orjson (:func:`app.db.types.json_dumps`, :func:`app.db.types.json_loads`;
    psycopg's own loader would use ``json.loads``). SQLite engines enforce foreign keys, use WAL for files, allow use
    from the API's worker threads, support savepoints (see :func:`_prepare_sqlite`), wait up to
    ``write_lock_timeout_s`` (None: :data:`SQLITE_BUSY_TIMEOUT_S`; an explicit ``connect_args={"timeout": ...}``
    wins) for the write lock, and begin the transactions of :func:`begin_write` with ``BEGIN IMMEDIATE``.
    PostgreSQL connections run with :data:`POSTGRES_OPTIONS` (JIT off; options in the URL's query or in
    ``connect_args`` win); engines given ``write_lock_timeout_s`` set the connections' ``lock_timeout`` to it (a row lock waited
    for longer fails, :func:`is_lock_timeout`), and roll back without forgetting the statements psycopg prepared
    (:func:`_rollback_keeping_prepared`).
    Extra ``kwargs`` go to ``create_engine``.
    """
    u = make_url(url)
    kwargs.setdefault("json_deserializer", json_loads)
    kwargs.setdefault("json_serializer", json_dumps)
    if u.get_backend_name() == "sqlite":
        kwargs.setdefault("connect_args", {}).setdefault("check_same_thread", False)
        timeout = kwargs["connect_args"].setdefault(
            "timeout", SQLITE_BUSY_TIMEOUT_S if write_lock_timeout_s is None else write_lock_timeout_s)
        engine = sa.create_engine(u, **kwargs)
        _prepare_sqlite(engine, u, timeout)
        return engine
    ping_when_idle = "pool_pre_ping" not in kwargs  # see _ping_when_idle
    if u.get_backend_name() == "postgresql":
        url_options = u.query.get("options", "")  # the URL's own (the connect_args' below replace them: merged)
        url_options = " ".join(url_options) if isinstance(url_options, tuple) else url_options
        options = f'{url_options} {kwargs.setdefault("connect_args", {}).get("options", "")}'.strip()
        for name, value in POSTGRES_OPTIONS.items():  # see POSTGRES_OPTIONS; an explicit option wins
            if name not in options:
                options = f"{options} -c {name}={value}".strip()
        if write_lock_timeout_s is not None:
            options = f"{options} -c lock_timeout={max(1, int(write_lock_timeout_s * 1000))}".strip()
        kwargs["connect_args"]["options"] = options
    engine = sa.create_engine(u, **kwargs)
    if ping_when_idle:
        _ping_when_idle(engine, PING_AFTER_IDLE_S)
    if engine.dialect.driver == "psycopg":
        engine.dialect.do_rollback = _rollback_keeping_prepared  # type: ignore[method-assign]
        engine.dialect.do_commit = _commit  # type: ignore[method-assign]
    return engine


def _commit(dbapi_connection: Any) -> None:
    """Commit a psycopg connection's transaction (``Connection.commit()``), then let its next transaction begin as
    psycopg begins one (``app.db.together.end_of_transaction``: a transaction whose ``BEGIN`` went in a pipeline)."""
    dbapi_connection.commit()
    end_of_transaction(dbapi_connection)


#: A pooled connection to a database server (PostgreSQL) is pinged before it is handed out when it has been idle in
#: the pool for longer than this (seconds): :func:`_ping_when_idle`.
PING_AFTER_IDLE_S = 10.0
#: ``ConnectionPoolEntry.info`` key: when the connection went back to the pool (``time.monotonic()``).
_IDLE_SINCE = "v3d_idle_since"


def _ping_when_idle(engine: Engine, idle_s: float) -> None:
    """Ping a pooled connection before handing it out only when it has been idle for more than ``idle_s`` seconds.

    SQLAlchemy's ``pool_pre_ping`` pings at every checkout: a round trip before every transaction, three per served
    edit (its authentication, its edit, its answer), where the connection was last used milliseconds before (issue
    29). A server restart, a network cut or an idle timeout on the server's side strike connections that waited in
    the pool; those are still pinged. A connection that dies within ``idle_s`` of its last use fails the request
    using it, and SQLAlchemy then invalidates the pool's connections (``is_disconnect``), so later requests connect
    afresh. A failed ping raises ``DisconnectionError``: the pool discards the connection and checks out another
    (SQLAlchemy's recipe for custom pessimistic disconnect handling,
    https://docs.sqlalchemy.org/en/20/core/pooling.html#disconnect-handling-pessimistic)."""

    @event.listens_for(engine, "checkin")
    def _idle_from(_dbapi_connection: Any, record: Any) -> None:
        record.info[_IDLE_SINCE] = time.monotonic()

    @event.listens_for(engine, "checkout")
    def _ping(dbapi_connection: Any, record: Any, _proxy: Any) -> None:
        since = record.info.get(_IDLE_SINCE)
        if since is None or time.monotonic() - since <= idle_s:
            return
        try:
            engine.dialect.do_ping(dbapi_connection)
        except engine.dialect.loaded_dbapi.Error as exc:
            raise sa.exc.DisconnectionError(f"the pooled connection did not answer a ping: {exc}") from exc


def reads_on_their_own(session: Session) -> None:
    """Let the session's next reads run without a transaction of their own on PostgreSQL (``AUTOCOMMIT``: each
    statement sees the database as of its start; no ``BEGIN``, no ``ROLLBACK``: two round trips fewer), for reads that
    need no common snapshot: a request's authentication lookup, an edit's answer besides the system it holds (its
    queue neighbours, who has it open). Does nothing when the session is in a transaction already, on SQLite (its
    statements are calls in the process), or for a session joined to its caller's transaction. A write in such a
    session commits at once."""
    bind = session.get_bind()
    if isinstance(bind, sa.Connection) or bind.dialect.name != "postgresql" or session.in_transaction():
        return
    session.connection(execution_options={"isolation_level": "AUTOCOMMIT"})


def _rollback_keeping_prepared(dbapi_connection: Any) -> None:
    """Roll a psycopg connection's transaction back, keeping the statements psycopg has prepared on it.

    psycopg prepares a statement on the server after it ran ``prepare_threshold`` (5) times on a connection, so
    PostgreSQL parses and plans it once instead of at every execution; but its ``Connection.rollback()`` forgets
    every prepared statement (it cannot tell whether the transaction rolled back a DDL change they depend on).
    v3d ends every read-only transaction by a rollback (a request's lookups, an edit's read snapshot, the pool's
    reset when a session closes), so no statement ever stayed prepared: every statement of every edit was planned
    anew (about 5 ms of PostgreSQL CPU per ball edit, issue 29). v3d changes no schema while it serves
    (migrations run before, in their own connections), and a statement prepared in a transaction outlives its
    rollback (PostgreSQL's ``PREPARE`` is not transactional), so the rollback is sent through the libpq connection
    (``Connection.pgconn``, psycopg's public low-level interface), which leaves psycopg's cache as it is; the
    connection's transaction state is libpq's, read by psycopg from there. The engine's dialect uses it for every
    rollback: a session's, the pool's reset on return. A transaction whose ``BEGIN`` went in a pipeline hands the
    connection back to psycopg's implicit ``BEGIN`` once rolled back (``app.db.together.end_of_transaction``).

    Raises:
        psycopg.Error: PostgreSQL did not roll back: the class of the SQLSTATE it sent (``psycopg.errors.lookup``),
            else ``OperationalError`` (a connection the server closed: the pool discards it, as after psycopg's own
            rollback).
    """
    from psycopg import OperationalError, errors, pq

    pgconn = dbapi_connection.pgconn
    if pgconn.transaction_status == pq.TransactionStatus.IDLE:
        end_of_transaction(dbapi_connection)
        return
    result = pgconn.exec_(b"ROLLBACK")
    end_of_transaction(dbapi_connection)
    if result.status != pq.ExecStatus.COMMAND_OK:
        sqlstate = result.error_field(pq.DiagnosticField.SQLSTATE)
        try:
            cls = errors.lookup(sqlstate.decode()) if sqlstate else OperationalError
        except KeyError:
            cls = OperationalError
        raise cls(f"ROLLBACK failed: {pgconn.error_message.decode(errors='replace').strip()}")


#: Options of v3d's PostgreSQL connections (an option named in the URL's or the caller's ``options`` wins). JIT off:
#: v3d's queries read a few rows by key, yet on a database without statistics the planner's estimates passed the JIT
#: threshold and one edit's frames query spent about 64 ms compiling, twice per edit (issue 29).
POSTGRES_OPTIONS = {"jit": "off"}


def refresh_statistics(session: Session) -> None:
    """Refresh the planner's statistics after a bulk change (migrations, an import), in their own step:
    ``ANALYZE`` on PostgreSQL (a server whose autovacuum is off, or has not run yet, would plan the edits' queries
    on empty statistics), ``PRAGMA optimize`` on SQLite (analyses the tables whose statistics it needs). Commits
    the session first."""
    session.commit()
    if session.get_bind().dialect.name == "postgresql":
        session.execute(sa.text("ANALYZE"))
    else:
        session.execute(sa.text("PRAGMA optimize"))
    session.commit()


#: PostgreSQL's SQLSTATE of a lock not obtained within ``lock_timeout`` (lock_not_available).
_PG_LOCK_NOT_AVAILABLE = "55P03"


def is_lock_timeout(exc: BaseException) -> bool:
    """True when ``exc`` is a write that gave up waiting for a lock: SQLite's "database is locked" / "database
    is busy" (the write lock, :func:`begin_write`) or PostgreSQL's ``lock_timeout`` (SQLSTATE 55P03, a row lock
    of ``SELECT ... FOR UPDATE``). The API answers it 503 with ``Retry-After`` (``app.api.errors``): the request
    may be sent again as it was."""
    if not isinstance(exc, sa.exc.OperationalError):
        return False
    orig = exc.orig
    if getattr(orig, "sqlstate", None) == _PG_LOCK_NOT_AVAILABLE or getattr(orig, "pgcode", None) == _PG_LOCK_NOT_AVAILABLE:
        return True
    text = str(orig if orig is not None else exc).lower()
    return any(w in text for w in ("database is locked", "database is busy", "lock timeout"))


def make_session_factory(engine: Engine, info: dict[str, Any] | None = None) -> sessionmaker[Session]:
    """Sessions bound to ``engine``; objects stay readable after commit (``expire_on_commit=False``)
    so that services can return the ORM rows they just committed. Each session's ``info`` starts as a copy of
    ``info`` (the app's: its edits' turns, ``app.services.curation.writing.EditSlots``)."""
    return sessionmaker(bind=engine, expire_on_commit=False, info=dict(info or {}))


@event.listens_for(Session, "after_flush")
def _note_flush(session: Session, _context: Any) -> None:
    """Remember which transaction wrote (so :func:`begin_write` never discards flushed work)."""
    session.info[_FLUSHED_TX] = session.get_transaction()


def has_written(session: Session) -> bool:
    """True when the session holds changes of its current transaction: pending objects or a flush."""
    tx = session.get_transaction()
    return bool(session.new or session.dirty or session.deleted
                or (tx is not None and session.info.get(_FLUSHED_TX) is tx))


def begin_snapshot(session: Session, *, fresh: bool = False) -> None:
    """Begin a read transaction that sees one state of the database from its first read to its end, for work
    done before a write lock (an edit's recomputation, ``app.services.curation.editing``), or keep the one the session
    holds when it is such a snapshot already: on SQLite every read transaction (a deferred ``BEGIN`` under WAL reads
    the snapshot of its first read and never waits for writers), on PostgreSQL one this function began
    (``REPEATABLE READ``). So an edit's lookups before its computation (its frame, its validation) and the computation
    read one snapshot, in one transaction. Any other transaction, or any with ``fresh`` (the caller waited and wants
    what was committed meanwhile), is ended first (its objects expire). A session joined to its caller's transaction
    is left alone (its caller rolls back what it reads).

    Raises:
        RuntimeError: the session's transaction has written (:func:`has_written`): ending it would lose that.
    """
    if has_written(session):
        raise RuntimeError("begin_snapshot: the session's transaction has written")
    if isinstance(session.get_bind(), sa.Connection):
        return
    tx = session.get_transaction()
    postgresql = session.get_bind().dialect.name == "postgresql"
    if tx is not None:
        if not fresh and session.info.get(_WRITE_TX) is not tx and (
                session.info.get(_SNAPSHOT_TX) is tx or not postgresql):
            session.info[_SNAPSHOT_TX] = tx
            return
        session.rollback()
    if postgresql:
        session.connection(execution_options={"isolation_level": "REPEATABLE READ"})
    session.info[_SNAPSHOT_TX] = session.get_transaction()


def begin_write(session: Session) -> None:
    """Make the session's transaction a write transaction, before the unit of work reads anything.

    SQLite: the transaction starts with ``BEGIN IMMEDIATE`` (the write lock, waited for up to
    :data:`SQLITE_BUSY_TIMEOUT_S`). A read-only transaction the session already holds (an API request's
    lookups, say) is ended first: nothing was written in it, and the objects it loaded are expired, so
    the unit of work reads them again under the lock. A session joined to a transaction its caller
    began (a ``Connection`` bind: the tests' rolled-back transaction) is left alone: that caller owns
    the transaction. PostgreSQL: the transaction is an ordinary one; lock the rows you read-modify-write.
    Calling it again in the same write transaction does nothing. A thread holds one SQLite write
    transaction at a time (a second one, on another connection of the same engine, would wait for the
    first: the turns are per process).

    Raises:
        RuntimeError: the session's current transaction has written (flushed or pending changes):
            a write unit of work must begin its transaction, not join a read-modify-write already begun.
    """
    if isinstance(session.get_bind(), sa.Connection):
        return
    tx = session.get_transaction()
    if tx is not None:
        if session.info.get(_WRITE_TX) is tx:
            return
        if has_written(session):
            raise RuntimeError("begin_write: the session's transaction has already written; "
                               "begin the write transaction before the unit of work changes anything")
        session.rollback()
    session.connection(execution_options={WRITE_OPTION: True})
    session.info[_WRITE_TX] = session.get_transaction()


def begin_write_keeping_objects(session: Session) -> None:
    """End the session's read snapshot (:func:`begin_snapshot`) and begin its write transaction (as
    :func:`begin_write`) on the same connection, keeping every object the snapshot loaded, and every change made
    to them in memory and not flushed, as they are. SQLAlchemy's own end of a transaction would not: its rollback
    expires every object (and drops what was changed in memory), so an edit that computed before its lock
    loaded its system a second time under it (issue 29: an edit loads what it recomputes once).

    The snapshot has ended: rows it read may have changed since. The caller compares what it read with the
    database under the lock it takes next, and rolls back (which expires everything, as usual) when they differ.
    SQLite: the read transaction, which wrote nothing, ends at the driver and ``BEGIN IMMEDIATE`` is taken in this
    process's turn (:class:`_WriteTurns`); PostgreSQL: the ``REPEATABLE READ`` transaction ends at the driver and
    the next one begins at the connection's default level, as :func:`begin_write`'s does. A session joined to
    its caller's transaction (a ``Connection`` bind: the tests') is left alone.

    Raises:
        RuntimeError: the session has no transaction, or its transaction has flushed (it is no read snapshot).
    """
    if isinstance(session.get_bind(), sa.Connection):
        return
    tx = session.get_transaction()
    if tx is None or session.info.get(_FLUSHED_TX) is tx:
        raise RuntimeError("begin_write_keeping_objects: the session holds no read snapshot")
    conn = session.connection()
    raw = conn.connection.dbapi_connection
    if conn.dialect.name == "sqlite":
        raw.execute("COMMIT")
        _TURNS[conn.engine].begin(conn)
    else:
        raw.commit()
        end_of_transaction(raw)
        conn.dialect.set_isolation_level(raw, conn.dialect.default_isolation_level)
    session.info[_WRITE_TX] = tx


def data_version(session: Session) -> int | None:
    """SQLite's ``PRAGMA data_version`` on the session's connection: it changes when another connection commits a
    change to the database, and only then (https://sqlite.org/pragma.html#pragma_data_version); None on
    PostgreSQL, where nothing says as cheaply that nobody wrote."""
    conn = session.connection()
    if conn.dialect.name != "sqlite":
        return None
    return int(conn.exec_driver_sql("PRAGMA data_version").scalar_one())


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
    engine = make_engine(u)
    try:
        with Session(engine) as session:
            refresh_statistics(session)
    finally:
        engine.dispose()
