"""Several statements of one transaction sent in one round trip to PostgreSQL (issue 29: an edit's time on PostgreSQL
was its round trips).

On PostgreSQL an edit's statements are round trips to the server, each costing the wait for its answer and
SQLAlchemy's and psycopg's work per statement (about 0.3-0.5 ms on this project's 2-core machine), where SQLite's
are calls inside the process. Statements whose parameters do not depend on each other's results (the lock of a
system, the rig rows and the digest its edit compares; the derived rows an edit updates and the digest of what it
wrote) are sent by :func:`send_together` through psycopg's pipeline mode
(https://www.psycopg.org/psycopg3/docs/advanced/pipeline.html): all of them, then one ``Sync``, one wait. PostgreSQL
still runs them one after the other, each at READ COMMITTED with its own snapshot taken when it starts, so a
statement queued after a ``SELECT ... FOR UPDATE`` reads what the database holds once that lock is granted, as it
would when sent after the lock's answer came back.

A pipeline that opens its transaction carries the ``BEGIN`` itself (:func:`begin_in_pipeline`): psycopg's own
implicit ``BEGIN`` in pipeline mode waits for its answer before the statements go (libpq tells the transaction's
state only at a ``Sync``), one more round trip before every edit's lock.

Each statement is compiled once (:func:`driver_statement`) and executed on the driver's own cursor, its parameters
and result values converted by the statement's SQLAlchemy types as ``Connection.execute`` converts them. psycopg
prepares a statement on the server after it ran a few times on a connection, pipelined or not. Other databases and
drivers (SQLite) execute the same calls one after the other through SQLAlchemy, as before.
"""
from __future__ import annotations

import functools
import weakref
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any, Optional, Union

import sqlalchemy as sa
from sqlalchemy.orm import Session

#: Parameters of one execution, or of each of several (an ``executemany``).
Params = Union[dict[str, Any], list[dict[str, Any]]]


@dataclass(frozen=True)
class Call:
    """One statement of :func:`send_together` and its parameters: a dict (executed once; its rows are answered when
    it returns rows, else the number of rows it matched) or a non-empty list of dicts (executed once per dict; the
    number of rows matched in all is answered)."""

    stmt: sa.Executable
    params: Params


@dataclass(frozen=True)
class DriverStatement:
    """A statement compiled for one dialect: its SQL text in the driver's parameter style, the conversion of each
    parameter (SQLAlchemy's bind processors: JSON documents, enums) and of each result column (result processors)."""

    sql: str
    compiled: Any
    bind_processors: dict[str, Callable[[Any], Any]]
    result_processors: tuple[Optional[Callable[[Any], Any]], ...]

    def params(self, values: dict[str, Any]) -> dict[str, Any]:
        """The driver's parameters for ``values`` (the statement's own bound values, e.g. literals built into it,
        filled in by ``Compiled.construct_params``), converted by the parameters' types."""
        out = self.compiled.construct_params(values)
        for name, process in self.bind_processors.items():
            if out.get(name) is not None:
                out[name] = process(out[name])
        return out

    def row(self, raw: Sequence[Any]) -> tuple[Any, ...]:
        """A row of the driver as SQLAlchemy would answer it (its columns converted by their types)."""
        if len(raw) != len(self.result_processors):
            raise ValueError(f"driver_statement: {len(raw)} columns answered, {len(self.result_processors)} known")
        return tuple(v if p is None or v is None else p(v) for p, v in zip(self.result_processors, raw))


@functools.lru_cache(maxsize=256)
def driver_statement(stmt: sa.Executable, dialect: sa.Dialect) -> DriverStatement:
    """``stmt`` compiled once for ``dialect`` (statements are cached by identity: pass the ones built once, as the
    edit path's are).

    Raises:
        ValueError: the dialect compiles ``stmt`` with positional parameters (``send_together`` names them), or
            ``stmt`` has an expanding parameter (compiled anew for each number of values).
    """
    compiled = stmt.compile(dialect=dialect)
    if compiled.positional:
        raise ValueError(f"driver_statement: {dialect.name} compiles positional parameters; named ones are sent")
    if compiled.post_compile_params:
        raise ValueError("driver_statement: expanding parameters (IN lists) are rendered per execution; send an array")
    binds = {name: bp.type.dialect_impl(dialect).bind_processor(dialect) for name, bp in compiled.binds.items()}
    columns = getattr(stmt, "exported_columns", None) or []  # a SELECT's columns, or an UPDATE's RETURNING
    results = tuple(c.type.dialect_impl(dialect).result_processor(dialect, None) for c in columns)
    return DriverStatement(compiled.string, compiled, {k: p for k, p in binds.items() if p is not None}, results)


def send_together(session: Session, calls: Sequence[Call]) -> list[Any]:
    """Execute ``calls`` in order in the session's transaction (begun if it has none) and answer, per call, its rows
    (a list of tuples) when it returns rows, else the number of rows it matched (an UPDATE's). PostgreSQL through
    psycopg: one pipeline, one round trip (module docstring); elsewhere one after the other through SQLAlchemy.

    Raises:
        sqlalchemy.exc.DBAPIError: a statement failed (its subclass by the driver's error, e.g. ``OperationalError``
            for a lock timeout, as ``Connection.execute`` raises it; the calls after it were not run). The transaction
            is then aborted: the caller rolls back.
    """
    conn = session.connection()
    if conn.dialect.driver != "psycopg" or not calls:
        return [_executed(conn, c) for c in calls]
    import psycopg

    raw = conn.connection.dbapi_connection
    statements = [driver_statement(c.stmt, conn.dialect) for c in calls]
    cursors = []
    current = statements[0]
    try:
        begin = begin_in_pipeline(raw)
        with raw.pipeline():
            if begin is not None:  # its cursor answers nothing: closed with the others, left out of the answers
                cursors.append(raw.cursor())
                cursors[0].execute(begin)
            answering = len(cursors)
            for current, call in zip(statements, calls):
                cur = raw.cursor()
                if isinstance(call.params, list):
                    cur.executemany(current.sql, [current.params(p) for p in call.params])
                else:
                    cur.execute(current.sql, current.params(call.params))
                cursors.append(cur)
        return [[current.row(r) for r in cur.fetchall()] if cur.description is not None else cur.rowcount
                for current, cur in zip(statements, cursors[answering:])]
    except psycopg.Error as exc:
        invalidated = conn.dialect.is_disconnect(exc, raw, None)
        if invalidated:
            conn.invalidate(exc)
        raise sa.exc.DBAPIError.instance(current.sql, None, exc, psycopg.Error, connection_invalidated=invalidated,
                                         dialect=conn.dialect) from exc
    finally:
        for cur in cursors:
            cur.close()


def _executed(conn: sa.Connection, call: Call) -> Any:
    """:func:`send_together`'s answer for ``call`` executed through SQLAlchemy."""
    result = conn.execute(call.stmt, call.params)
    if result.returns_rows:
        return [tuple(r) for r in result.all()]
    return result.rowcount


#: psycopg connections whose transaction :func:`begin_in_pipeline` began (their driver-level ``autocommit`` is on
#: until :func:`end_of_transaction` sees the transaction end).
_BEGUN_IN_PIPELINE: "weakref.WeakSet[Any]" = weakref.WeakSet()


def begin_in_pipeline(raw: Any) -> Optional[bytes]:
    """The ``BEGIN`` statement a pipeline about to run on the psycopg connection ``raw`` sends first, or None when
    ``raw`` is in a transaction already or runs without one (``autocommit``, SQLAlchemy's ``AUTOCOMMIT``).

    psycopg begins a transaction implicitly before a statement when the connection is idle; in pipeline mode it
    sends that ``BEGIN`` alone and waits for its answer (libpq reports the transaction's state only after a
    ``Sync``; psycopg/psycopg#401). To send it with the pipeline's statements instead, the connection's driver-level
    ``autocommit`` is set (allowed while idle; psycopg then begins nothing) and this ``BEGIN``, built from the
    connection's isolation level, read-only and deferrable settings as psycopg builds its own, is the pipeline's
    first statement: the server holds one transaction from it to the ``COMMIT`` or ``ROLLBACK`` as before (psycopg's
    ``commit()`` and ``rollback()`` act on the server's transaction state, not on ``autocommit``). The engine
    (``app.db.session.make_engine``) calls :func:`end_of_transaction` when the transaction ends, which sets
    ``autocommit`` back, so the connection's next transaction begins implicitly again."""
    from psycopg import pq

    end_of_transaction(raw)  # (a transaction of this kind that ended without passing the engine's hooks)
    if raw.autocommit or raw.pgconn.transaction_status != pq.TransactionStatus.IDLE:
        return None
    parts = [b"BEGIN"]
    if raw.isolation_level is not None:
        parts.append(b"ISOLATION LEVEL " + raw.isolation_level.name.replace("_", " ").encode())
    if raw.read_only is not None:
        parts.append(b"READ ONLY" if raw.read_only else b"READ WRITE")
    if raw.deferrable is not None:
        parts.append(b"DEFERRABLE" if raw.deferrable else b"NOT DEFERRABLE")
    raw.autocommit = True
    _BEGUN_IN_PIPELINE.add(raw)
    return b" ".join(parts)


def end_of_transaction(raw: Any) -> None:
    """Set the driver-level ``autocommit`` of the psycopg connection ``raw`` (or SQLAlchemy's pool proxy of one) back
    off once the transaction :func:`begin_in_pipeline` began has ended (the connection is idle); does nothing for any
    other connection or while the transaction goes on."""
    import psycopg

    if not isinstance(raw, psycopg.Connection):  # the pool's proxy (SQLAlchemy's dialect hooks get it)
        raw = raw.dbapi_connection
    if raw in _BEGUN_IN_PIPELINE:
        if raw.pgconn.transaction_status == psycopg.pq.TransactionStatus.IDLE:
            _BEGUN_IN_PIPELINE.discard(raw)
            raw.autocommit = False


#: ``Session.info`` key of the :class:`ReadsAfterWrites` a session's next write sends.
_READS_AFTER_WRITES = "v3d.together.reads_after_writes"


@dataclass
class ReadsAfterWrites:
    """Reads a request makes once its write has committed (its answer's), sent instead in the write's own round
    trip, after its writes and before its ``COMMIT`` (:func:`read_after_writes`): they see what the write wrote, as
    they would after its commit, and whatever else was committed before them (READ COMMITTED: a snapshot per
    statement), as they would a moment later."""

    key: Any  # what the reads answer (the reader's own key: its page's queue, say)
    build: Callable[[Any], Optional[Sequence[Call]]]  # the reads of the written subject (None: none)
    subject_id: Optional[int] = None  # the subject the reads were built for
    calls: list[Call] = field(default_factory=list)
    answers: Optional[list[Any]] = None


def read_after_writes(session: Session, key: Any, build: Callable[[Any], Optional[Sequence[Call]]]) -> None:
    """Let the next write of ``session`` that sends its writes together (:func:`calls_after_writes`) send the reads
    ``build(subject)`` after them in the same round trip (``subject``: what it wrote, its system as committed), for
    :func:`answers_after_writes` to answer under ``key``. PostgreSQL only (elsewhere statements are calls in the
    process: nothing to spare); a write that sends no such calls leaves the reader to read as before."""
    if session.get_bind().dialect.driver == "psycopg":
        session.info[_READS_AFTER_WRITES] = ReadsAfterWrites(key, build)


def calls_after_writes(session: Session, subject: Any) -> list[Call]:
    """The reads :func:`read_after_writes` asked for, built for ``subject`` (an object with an ``id``), to send
    after the write's own calls; their answers go to :func:`keep_answers_after_writes`. [] when none were asked
    for, or asked for already."""
    reads: Optional[ReadsAfterWrites] = session.info.get(_READS_AFTER_WRITES)
    if reads is None or reads.subject_id is not None or subject is None:
        return []
    reads.subject_id, reads.calls = subject.id, list(reads.build(subject) or [])
    return reads.calls


def keep_answers_after_writes(session: Session, answers: Sequence[Any]) -> None:
    """Keep ``answers``, the last answers of the write's round trip, as those of :func:`calls_after_writes`'s."""
    reads: Optional[ReadsAfterWrites] = session.info.get(_READS_AFTER_WRITES)
    if reads is not None and reads.calls:
        reads.answers = list(answers[len(answers) - len(reads.calls):])


def answers_after_writes(session: Session, key: Any, subject_id: int) -> Optional[list[Any]]:
    """The answers of the reads asked for under ``key`` (:func:`read_after_writes`), when the session's write sent
    them for subject ``subject_id`` (and they are taken: asked once); else None (read them now)."""
    reads: Optional[ReadsAfterWrites] = session.info.pop(_READS_AFTER_WRITES, None)
    if reads is None or reads.key != key or reads.subject_id != subject_id or reads.answers is None:
        return None
    return reads.answers
