"""Which v3d processes use a database now: every v3d server process (each uvicorn worker) and ``v3d jobs run`` hold a
*shared in-use lock* on their database for as long as they run (:func:`using`); ``v3d restore`` takes it
*exclusively* for its whole run (:func:`exclusive`), so it refuses, in words, while any of them holds it, and none of
them starts while a restore runs.

The lock is one the database's own machinery releases when its holder ends, however it ends (a crash, SIGKILL, a
machine that lost power): a server that died never blocks a restore, and there is no marker to clear.

* PostgreSQL: a session-level advisory lock (PostgreSQL's documented application-defined locks,
  ``pg_try_advisory_lock_shared`` / ``pg_try_advisory_lock`` on key :data:`LOCK_KEY`, scoped to the database), held
  on a connection of its own named ``v3d <role> <node>:<pid>`` (``application_name``); a refusal lists the holders
  from ``pg_locks`` and ``pg_stat_activity``. The server ends the session of a process that died.
* SQLite: an ``flock(2)`` on ``<database file>.in-use`` beside the file (SQLite serves one machine); the kernel drops
  it with its process. ``fuser -v`` or ``lsof`` on that file name the holders.
"""
from __future__ import annotations

import contextlib
import fcntl
import os
from pathlib import Path
from typing import Iterator, Optional

import sqlalchemy as sa
from sqlalchemy.engine import make_url
from sqlalchemy.pool import NullPool

from app.core.errors import ConflictError

#: The advisory lock's key on PostgreSQL (``'v3du'`` as an int, below 2**31 so that ``pg_locks`` shows it as
#: ``classid`` 0, ``objid`` the key).
LOCK_KEY = 0x76336475
#: The suffix of SQLite's lock file beside the database file.
LOCK_SUFFIX = ".in-use"
#: How to stop the processes holding the lock, as a refusal says.
HOW_TO_STOP = ("stop them (Ctrl-C in their terminal, `systemctl stop v3d`, `docker compose stop`) and run the restore "
               "again")


class DatabaseInUse(ConflictError):
    """The database's in-use lock is held: by a v3d server or job runner (a restore refused), or by a restore (a
    server refused). The message says who and what to do."""


def lock_file(url: str | sa.URL) -> Optional[Path]:
    """SQLite's lock file for the database at ``url`` (``<file>.in-use``); None for PostgreSQL or an in-memory
    database."""
    u = make_url(url)
    if u.get_backend_name() != "sqlite" or u.database in (None, "", ":memory:"):
        return None
    return Path(str(u.database)).expanduser().with_name(Path(str(u.database)).name + LOCK_SUFFIX)


@contextlib.contextmanager
def using(url: str | sa.URL, role: str) -> Iterator[None]:
    """Hold the shared in-use lock of the database at ``url`` while the block runs (a server process, ``v3d jobs
    run``: ``role`` names it in PostgreSQL's ``pg_stat_activity``).

    Raises:
        DatabaseInUse: a restore holds it now (the server does not start).
    """
    with _held(url, role, shared=True):
        yield


@contextlib.contextmanager
def exclusive(url: str | sa.URL) -> Iterator[None]:
    """Hold the in-use lock of the database at ``url`` alone while the block runs (``v3d restore``).

    Raises:
        DatabaseInUse: a server or job runner holds it, named with how it is known and how to stop them; nothing
            was done.
    """
    with _held(url, "restore", shared=False):
        yield


@contextlib.contextmanager
def _held(url: str | sa.URL, role: str, shared: bool) -> Iterator[None]:
    u = make_url(url)
    if u.get_backend_name() == "postgresql":
        with _postgresql(u, role, shared):
            yield
        return
    path = lock_file(u)
    if path is None or not path.parent.is_dir():  # no file to serve yet: nobody uses it
        yield
        return
    fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o600)
    try:
        try:
            fcntl.flock(fd, (fcntl.LOCK_SH if shared else fcntl.LOCK_EX) | fcntl.LOCK_NB)
        except BlockingIOError:
            raise DatabaseInUse(_refusal(str(u.database), shared, f"its in-use lock {path} is held (`fuser -v "
                                         f"{path}` lists the processes)")) from None
        yield
    finally:
        os.close(fd)  # the lock goes with the file's last descriptor


@contextlib.contextmanager
def _postgresql(u: sa.URL, role: str, shared: bool) -> Iterator[None]:
    from app.core.config import get_settings, node_name

    try:
        node = node_name(get_settings())
    except Exception:  # noqa: BLE001  # a name for the holder only: the lock works without one
        node = "?"
    engine = sa.create_engine(u, poolclass=NullPool,
                              connect_args={"application_name": f"v3d {role} {node}:{os.getpid()}"[:63]})
    try:
        with engine.connect() as conn:
            fn = "pg_try_advisory_lock_shared" if shared else "pg_try_advisory_lock"
            took = conn.execute(sa.text(f"SELECT {fn}(:k)"), {"k": LOCK_KEY}).scalar()
            holders = [] if took else _pg_holders(conn)
            conn.commit()  # the lock is the session's: it outlives the transaction, which must not stay open
            if not took:
                listed = "; ".join(holders) or "a session that has just ended"
                raise DatabaseInUse(_refusal(f"{u.database} on {u.host or 'localhost'}", shared,
                                             f"PostgreSQL's advisory lock {LOCK_KEY} on it is held by: {listed}"))
            try:
                yield
            finally:
                with contextlib.suppress(sa.exc.DBAPIError):
                    conn.execute(sa.text("SELECT pg_advisory_unlock_all()"))
                    conn.commit()
    finally:
        engine.dispose()


def _pg_holders(conn: sa.Connection) -> list[str]:
    rows = conn.execute(sa.text(
        "SELECT a.pid, a.application_name, a.client_addr, a.backend_start FROM pg_locks l "
        "JOIN pg_stat_activity a ON a.pid = l.pid WHERE l.locktype = 'advisory' AND l.granted AND l.classid = 0 "
        "AND l.objid = :k AND l.objsubid = 1 AND l.database = (SELECT oid FROM pg_database "
        "WHERE datname = current_database()) ORDER BY a.backend_start"), {"k": LOCK_KEY})
    return [f"{name or 'a session'} (backend pid {pid}, from {addr or 'a local socket'}, since "
            f"{start:%Y-%m-%d %H:%M:%S})" for pid, name, addr, start in rows]


def _refusal(database: str, shared: bool, how: str) -> str:
    if shared:
        return (f"a restore is running into the database {database} ({how}): this process does not start until it "
                f"has finished")
    return (f"the database {database} is in use by a v3d server or job runner: {how}. Restoring under them would "
            f"drop the tables they read and write; {HOW_TO_STOP}. Nothing was restored. A server that died holds no "
            f"lock: the operating system or PostgreSQL released it with its process")
