"""Engine and session factories, write transactions, and the programmatic Alembic upgrade.

Nothing here runs at import time: the API, the CLI and the tests each build their own engine from a
URL (``Settings.database_url``), so a test can point the whole service at a throw-away database.

Concurrency (several server processes on one database): a unit of work that writes starts its
transaction with :func:`begin_write`. On SQLite that transaction is ``BEGIN IMMEDIATE``: it takes the
database's write lock before its first read, waiting its turn up to :data:`SQLITE_BUSY_TIMEOUT_S`
behind another writer, so no read-modify-write ever has to upgrade a read lock (a deferred ``BEGIN``
that reads and then writes fails at once with "database is locked" when another process committed in
between: WAL cannot upgrade a stale snapshot, and no busy timeout helps). Reads keep a deferred
``BEGIN`` and never wait for writers (WAL). On PostgreSQL the option changes nothing; the services lock
the rows they read-modify-write (``SELECT ... FOR UPDATE``, ``app.services.curation.editing``).

How long a write waits: the served processes' engines are made with ``write_lock_timeout_s``
(``V3D_WRITE_LOCK_TIMEOUT_S``, a few seconds: SQLite's turn and busy timeout, PostgreSQL's ``lock_timeout``);
past it the wait fails with an ``OperationalError`` that :func:`is_lock_timeout` recognises and the API answers
503 with ``Retry-After``. Edits hold the lock only to compare and write (they compute before it), so such a wait
means overload, never another annotator's geometry. Command-line engines keep :data:`SQLITE_BUSY_TIMEOUT_S`.
"""
from __future__ import annotations

import sys
import threading
import time
from pathlib import Path
from typing import Any

import sqlalchemy as sa
from sqlalchemy import event
from sqlalchemy.engine import Engine, make_url
from sqlalchemy.orm import Session, sessionmaker

from app.core.paths import PROJECT_ROOT
from app.db.types import json_dumps, json_loads

#: The Alembic configuration of the project (``script_location = migrations``).
ALEMBIC_INI = PROJECT_ROOT / "alembic.ini"
#: Execution option of a connection whose transaction writes: SQLite begins it ``BEGIN IMMEDIATE``.
WRITE_OPTION = "v3d_write"
#: How long a SQLite write transaction of a command-line engine waits for the write lock before "database is
#: locked" (seconds): an import in the CLI may queue behind a server's import batch. Served engines wait
#: ``Settings.write_lock_timeout_s`` instead (``make_engine(write_lock_timeout_s=)``).
SQLITE_BUSY_TIMEOUT_S = 60.0
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
        assert raw is not None  # the connection is checked out: its DBAPI connection is live
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


def _prepare_sqlite(engine: Engine, url: sa.URL, busy_timeout_s: float) -> None:
    """Foreign keys ON, WAL journal for file databases, and SQLAlchemy's pysqlite recipe for working
    SAVEPOINTs: the driver's own implicit BEGIN is disabled and SQLAlchemy emits ``BEGIN`` itself, so
    that ``Session.begin_nested()`` and ``join_transaction_mode="create_savepoint"`` behave as on
    PostgreSQL. Write transactions (:func:`begin_write`) begin with ``BEGIN IMMEDIATE`` in fair turns
    (:class:`_WriteTurns`)."""
    in_memory = url.database in (None, "", ":memory:") or "mode=memory" in str(url)
    turns = _WriteTurns(busy_timeout_s)

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
    ``connect_args`` win); engines given ``write_lock_timeout_s`` set the connections' ``lock_timeout`` to it (a row
    lock waited for longer fails, :func:`is_lock_timeout`).
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
    return engine


#: A pooled connection to a database server (PostgreSQL) is pinged before it is handed out when it has been idle in
#: the pool for longer than this (seconds): :func:`_ping_when_idle`.
PING_AFTER_IDLE_S = 10.0
#: ``ConnectionPoolEntry.info`` key: when the connection went back to the pool (``time.monotonic()``).
_IDLE_SINCE = "v3d_idle_since"


def _ping_when_idle(engine: Engine, idle_s: float) -> None:
    """Ping a pooled connection before handing it out only when it has been idle for more than ``idle_s`` seconds.

    SQLAlchemy's ``pool_pre_ping`` pings at every checkout: a round trip before every transaction, several per
    served edit (its authentication, its reads, its write), where the connection was last used milliseconds before. A
    server restart, a network cut or an idle timeout on the server's side strike connections that waited in the pool;
    those are still pinged. A connection that dies within ``idle_s`` of its last use fails the request using it, and
    SQLAlchemy then invalidates the pool's connections (``is_disconnect``), so later requests connect afresh. A failed
    ping raises ``DisconnectionError``: the pool discards the connection and checks out another (SQLAlchemy's recipe for
    custom pessimistic disconnect handling,
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


def reads_as_one_snapshot(session: Session) -> None:
    """Give the session's next transaction one snapshot for all its statements on PostgreSQL (``REPEATABLE READ``),
    for work that reads the same database in several queries and must see it as of one moment (a release reads the
    accepted systems, their 3D results and games in separate queries; under ``READ COMMITTED`` an edit committed in
    between would be half in it). Ends a read-only transaction the session is in first (:func:`end_reads`). Does
    nothing on SQLite (a transaction there reads one snapshot already) or for a session joined to its caller's
    transaction.

    Raises:
        RuntimeError: the session holds changes not flushed yet (from :func:`end_reads`).
    """
    bind = session.get_bind()
    if isinstance(bind, sa.Connection) or bind.dialect.name != "postgresql":
        return
    end_reads(session)
    session.connection(execution_options={"isolation_level": "REPEATABLE READ"})


#: Options of v3d's PostgreSQL connections (an option named in the URL's or the caller's ``options`` wins). JIT off:
#: v3d's queries read a few rows by key, yet on a database without statistics the planner's estimates passed the JIT
#: threshold and one edit's frames query spent about 64 ms compiling, twice per edit.
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
    if _PG_LOCK_NOT_AVAILABLE in (getattr(orig, "sqlstate", None), getattr(orig, "pgcode", None)):
        return True
    text = str(orig if orig is not None else exc).lower()
    return any(w in text for w in ("database is locked", "database is busy", "lock timeout"))


class V3dSession(Session):
    """v3d's own ORM sessions (:func:`make_session_factory`'s): a ``Session`` whose flushes are noted, so that
    :func:`end_reads` can refuse to commit a transaction that wrote outside a write unit. The listeners are on this
    class alone: another library's sessions in the same process are left as they are."""


def make_session_factory(engine: Engine) -> sessionmaker[V3dSession]:
    """Sessions (:class:`V3dSession`) bound to ``engine``; objects stay readable after commit
    (``expire_on_commit=False``) so that services can return the ORM rows they just committed, and an edit keeps the
    rows it read once its read transaction has ended (``app.services.curation.writing``)."""
    return sessionmaker(bind=engine, class_=V3dSession, expire_on_commit=False)


#: ``Session.info`` key: the session's current transaction has flushed changes (sent INSERT, UPDATE or DELETE), set by
#: a listener on v3d's sessions' flushes and cleared when its outermost transaction ends.
_FLUSHED = "v3d_flushed"


@event.listens_for(V3dSession, "after_flush")
def _note_flush(session: Session, _context: Any) -> None:
    session.info[_FLUSHED] = True


@event.listens_for(V3dSession, "after_transaction_end")
def _forget_flush(session: Session, transaction: Any) -> None:
    if transaction.parent is None:
        session.info.pop(_FLUSHED, None)


def end_reads(session: Session) -> None:
    """End the session's read-only transaction, keeping its objects as they are, and give its connection back to
    the pool (an edit computing after its reads, ``app.services.curation.writing``). A commit, not a rollback: the
    transaction wrote nothing, a commit does not expire the objects (``expire_on_commit`` off) and psycopg forgets the
    statements it prepared on a rollback only. Does nothing outside a transaction. The flushes checked are those
    a :class:`V3dSession` notes (every session of v3d's).

    Raises:
        RuntimeError: the session holds changes not flushed yet (they would be written), or its transaction flushed
            changes already (an autoflush, or a flush, outside a write unit: committing them here would write without
            the lock, the version check and the audit of ``app.db.unit.write_unit``); nothing is committed.
    """
    if session.new or session.dirty or session.deleted:
        raise RuntimeError("end_reads: the session holds changes; only a read-only transaction is ended here")
    if session.info.get(_FLUSHED) and session.in_transaction():
        raise RuntimeError("end_reads: the session's transaction flushed changes outside a write unit; only a "
                           "read-only transaction is ended here (write through app.db.unit.write_unit)")
    if session.in_transaction():
        session.commit()


def begin_write(session: Session) -> None:
    """Begin the session's write transaction, before the unit of work reads anything under the lock.

    SQLite: the transaction starts with ``BEGIN IMMEDIATE`` (the write lock, waited for in this process's turn up to
    the engine's timeout, :class:`_WriteTurns`). PostgreSQL: an ordinary transaction; the caller locks the rows it
    read-modify-writes (``SELECT ... FOR UPDATE``, or a compare of a version column). A transaction the session holds
    with nothing left to flush (an API request's lookups, say) is ended first (:func:`end_reads`) and its objects
    expired, so that what the caller reads next is read under the lock. Changes the session holds in memory without
    having read since its last transaction ended (an edit computed after its reads) are kept, to be flushed in the
    write transaction. A session joined to a transaction its caller began (a ``Connection`` bind: the tests'
    rolled-back transaction, SQLAlchemy's recipe) is left alone: that caller owns the transaction. A thread holds one
    SQLite write transaction at a time (a second one, on another connection of the same engine, would wait for the
    first: the turns are per process).

    A transaction that flushed writes without this function is committed by it: begin the write before the unit
    of work changes anything.

    Raises:
        RuntimeError: the session holds changes and read in its current transaction (its connection was taken
            without the write lock): an edit's computation read a row it did not declare
            (``app.db.scope``), or a caller changed objects before beginning its write.
    """
    if isinstance(session.get_bind(), sa.Connection):
        return
    held = held_connection(session)
    if held is not None:
        if held.get_execution_options().get(WRITE_OPTION):
            return
        if session.new or session.dirty or session.deleted:
            raise RuntimeError("begin_write: the session read in its transaction while holding changes, so its "
                               "connection has no write lock; read before changing objects, then begin the write")
        end_reads(session)
        session.expire_all()
    session.connection(execution_options={WRITE_OPTION: True})


def held_connection(session: Session) -> sa.Connection | None:
    """The connection the session's transaction holds, None when it holds none (no transaction, or one begun by a
    change of an object in memory that has not read yet): SQLAlchemy's ``SessionTransaction.connections``, which
    never acquires one."""
    tx = session.get_transaction()
    return next(iter(tx.connections), None) if tx is not None else None


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


#: The table a restore (``app.services.backup.restore``) makes in its target before it writes anything and drops when
#: the target is whole: outside Alembic's schema, so that it exists at whatever revision the archive was made at. While
#: it holds a row, :func:`upgrade_database` (every ``v3d serve`` and command) refuses the database.
RESTORING_TABLE = "v3d_restore_unfinished"


class RestoreUnfinished(RuntimeError):
    """The database is the target of a restore that has not finished (running, or killed midway): it is not whole."""


def unfinished_restore(engine: Engine) -> str | None:
    """The archive a restore left unfinished in the database of ``engine`` (:data:`RESTORING_TABLE`), or None."""
    with engine.connect() as conn:
        if not sa.inspect(conn).has_table(RESTORING_TABLE):
            return None
        row = conn.execute(sa.text(f"SELECT archive FROM {RESTORING_TABLE}")).first()
    return None if row is None else str(row[0])


def refuse_unfinished_restore(engine: Engine) -> None:
    """Raise :class:`RestoreUnfinished`, with what to do, when a restore into this database has not finished."""
    archive = unfinished_restore(engine)
    if archive is not None:
        raise RestoreUnfinished(
            f"this database is the target of an unfinished restore of {archive}: it holds part of that backup only "
            f"and is not served. Run `v3d restore {archive}` again to finish it (or `v3d restore --replace ARCHIVE` "
            f"with another archive).")


def upgrade_database(url: str | sa.URL, revision: str = "head", *, restoring: bool = False) -> None:
    """Create or migrate the database at ``url`` to ``revision`` with Alembic.

    The parent folder of a SQLite file is created if missing. This is the only way v3d creates its
    tables (never ``Base.metadata.create_all``), so every run exercises the migrations.

    Raises:
        RestoreUnfinished: the database is a restore's target left unfinished (unless ``restoring``: the restore
            itself migrating it).
    """
    from alembic import command

    u = make_url(url)
    if u.get_backend_name() == "sqlite" and u.database not in (None, "", ":memory:"):
        Path(u.database).expanduser().parent.mkdir(parents=True, exist_ok=True)
    if not restoring:
        engine = make_engine(u)
        try:
            refuse_unfinished_restore(engine)
        finally:
            engine.dispose()
    command.upgrade(alembic_config(u), revision)
    engine = make_engine(u)
    try:
        with V3dSession(engine) as session:
            refresh_statistics(session)
    finally:
        engine.dispose()
