"""Background jobs: imports, full recomputes and exports that outlive a request and survive a killed
process.

A job is a row (``app.db.models.Job``): its kind and ``params`` (enough to run it again from the
start), its state (queued -> running -> done | failed), its progress (``stage``, ``done``,
``total``) and the process running it (``owner`` = ``node:pid:token``, ``node`` being ``V3D_NODE_NAME``) with
that process's ``heartbeat_at``. Any process may run jobs:

* a server process runs queued jobs in a thread (:class:`JobRunner`, started by ``create_app`` when
  ``Settings.job_runner``); every uvicorn worker has one, and a claim is a compare-and-set on
  ``Job.attempts`` (:func:`claim`), so each job runs once;
* ``v3d import`` creates its job already claimed (:func:`submit` with ``owner``) and runs it in its
  own process (:func:`run_job`), so no server takes it first; run again after a kill it resumes the
  same job (:func:`find_resumable`).

While a job runs, a heartbeat thread stores its progress and ``heartbeat_at`` every
``Settings.job_heartbeat_seconds`` on a connection of its own (the job's thread never writes progress
itself: on SQLite that would wait for its own write transaction). A running job is *stale*
(:func:`is_stale`) when its heartbeat is older than ``Settings.job_stale_seconds``, or at once when its
owner ran on this node and that process is gone (SIGKILL, a crash); so a job whose node stopped is taken over by
any other node sharing the database once its heartbeat is stale. A stale job is claimed again and
run from the start: imports are idempotent (whole games already stored are matched by their natural
keys and left as they are), a recompute recomputes every system again, an export rewrites its file.
A runner whose job was taken over (its heartbeat found another owner) stops at its next progress
report (:class:`JobLost`) without writing anything more.

What each kind does is in ``app.services.jobs.work``.
"""
from __future__ import annotations

import logging
import os
import secrets
import threading
import time
from dataclasses import dataclass
from datetime import timedelta
from typing import Any, Callable, cast

import sqlalchemy as sa
from sqlalchemy import select
from sqlalchemy.engine import CursorResult
from sqlalchemy.orm import Session, sessionmaker

from app.core.config import Settings, jobs_dir, node_name
from app.core.errors import InvalidInputError, ServiceError, found
from app.core.progress import Progress
from app.db.models import Job, JobState
from app.db.session import is_lock_timeout
from app.db.types import json_safe, utcnow
from app.db.unit import write_unit
from app.services.jobs.progress import LIVE_EVERY_S, remove_live, write_live
from app.services.jobs.work import COMMAND_LINE, WORK

log = logging.getLogger(__name__)

#: The kinds of job and what each does (``app.services.jobs.work``).
JOB_KINDS = tuple(WORK)
UNFINISHED = (JobState.QUEUED, JobState.RUNNING)


class JobNotReady(ServiceError):
    """A job's result asked for before it exists (HTTP 409)."""


class JobLost(Exception):
    """The job was taken over by another runner (this one's heartbeat was found stale)."""


def owner_name(settings: Settings) -> str:
    """A name for this runner: ``node:pid:token`` with ``app.core.config.node_name`` (the token tells two runners of one
    process apart)."""
    return f"{node_name(settings)}:{os.getpid()}:{secrets.token_hex(4)}"


def on_this_node(owner: str | None, settings: Settings) -> bool:
    """True when the runner named ``owner`` (:func:`owner_name`) runs on this node (``app.core.config.node_name``): only
    then are its process and its live progress file (``app.services.jobs.progress``) visible here."""
    return owner is not None and owner.partition(":")[0] == node_name(settings)


def _owner_gone(owner: str | None, settings: Settings) -> bool:
    """True when ``owner`` ran on this node and its process no longer exists."""
    if not owner or not on_this_node(owner, settings):
        return False
    pid = owner.partition(":")[2].partition(":")[0]
    if not pid.isdigit():
        return False
    try:
        os.kill(int(pid), 0)
    except ProcessLookupError:
        return True
    except PermissionError:
        return False
    return False


def is_sqlite(settings: Settings) -> bool:
    """True when the database is SQLite (one host; heartbeats only between the job's transactions)."""
    return sa.engine.make_url(settings.database_url).get_backend_name() == "sqlite"


def is_stale(job: Job, settings: Settings) -> bool:
    """True for a running job whose runner is gone: its process (on this node) no longer exists, or
    its heartbeat is older than ``settings.job_stale_seconds`` (on SQLite, whose jobs all run on this
    node and beat only between their transactions, the process alone decides). Another node's processes cannot be
    seen from here: its jobs are judged by their heartbeat alone."""
    if job.state is not JobState.RUNNING:
        return False
    if _owner_gone(job.owner, settings):
        return True
    if on_this_node(job.owner, settings) and is_sqlite(settings):
        return False
    return job.heartbeat_at is None or utcnow() - job.heartbeat_at > timedelta(seconds=settings.job_stale_seconds)


def submit(session: Session, kind: str, params: dict[str, Any], *, owner: str | None = None) -> Job:
    """Store a new job and commit. With ``owner`` the job is created already claimed by that runner
    (running, heartbeat now), for a process that runs its own job (``v3d import``).

    Raises:
        InvalidInputError: ``kind`` is not one of :data:`JOB_KINDS`.
    """
    if kind not in JOB_KINDS:
        raise InvalidInputError(f"unknown job kind {kind!r}; one of {', '.join(JOB_KINDS)}", field="kind")
    job = Job(kind=kind, params=json_safe(params), state=JobState.QUEUED, done=0, total=0, attempts=0)
    if owner is not None:
        now = utcnow()
        job.state, job.owner, job.attempts, job.started_at, job.heartbeat_at = JobState.RUNNING, owner, 1, now, now
    with write_unit(session, lock=False):
        session.add(job)
    return job


def get_job(session: Session, job_id: int) -> Job:
    """The job ``job_id``; raises :class:`NotFoundError` naming it."""
    return found(session.get(Job, job_id), "job", job_id)


def list_jobs(session: Session, state: JobState | None = None, kind: str | None = None, limit: int = 50,
              offset: int = 0) -> tuple[list[Job], int]:
    """Jobs, newest first, with the total matching ``state`` and ``kind``."""
    where = [c for c in (Job.state == state if state else None, Job.kind == kind if kind else None) if c is not None]
    total = session.scalar(select(sa.func.count(Job.id)).where(*where)) or 0
    items = session.scalars(select(Job).where(*where).order_by(Job.id.desc()).limit(limit).offset(offset)).all()
    return list(items), total


def count_jobs(session: Session) -> dict[tuple[str, str], int]:
    """How many jobs of each ``(kind, state)`` the database holds (the pairs with none left out): what the
    metrics' job gauges show (``app.core.metrics.job_families``)."""
    rows = session.execute(select(Job.kind, Job.state, sa.func.count(Job.id)).group_by(Job.kind, Job.state))
    return {(kind, state.value): n for kind, state, n in rows}


def claim(session: Session, job: Job, owner: str) -> bool:
    """Take ``job`` (as read: queued, or running and stale) for ``owner`` and commit; False when another
    runner claimed it meanwhile (the update is a compare-and-set on ``attempts``)."""
    job_id, attempts, state = job.id, job.attempts, job.state
    # End the transaction that read the job first: on SQLite (WAL) a transaction that read before another
    # connection committed cannot write at all; the compare-and-set below is what makes the claim safe.
    session.rollback()
    now = utcnow()
    with write_unit(session, lock=False):
        result = cast(CursorResult, session.execute(
            sa.update(Job).where(Job.id == job_id, Job.attempts == attempts, Job.state == state)
            .values(state=JobState.RUNNING, owner=owner, attempts=attempts + 1, started_at=now, heartbeat_at=now,
                    message=None)
            .execution_options(synchronize_session=False)))
    return result.rowcount == 1


def claimable(session: Session, settings: Settings) -> list[Job]:
    """Queued jobs and stale running ones, oldest first."""
    jobs = session.scalars(select(Job).where(Job.state.in_(UNFINISHED)).order_by(Job.id)).all()
    return [j for j in jobs if j.state is JobState.QUEUED or is_stale(j, settings)]


def claim_next(session_factory: sessionmaker[Session], owner: str, settings: Settings) -> int | None:
    """Claim the oldest claimable job for ``owner``; its id, or None when there is none."""
    with session_factory() as session:
        for job_id, attempts, state in [(j.id, j.attempts, j.state) for j in claimable(session, settings)]:
            if claim(session, Job(id=job_id, attempts=attempts, state=state), owner):
                return job_id
    return None


def find_resumable(session: Session, kind: str, params: dict[str, Any], settings: Settings) -> Job | None:
    """The oldest unfinished job of ``kind`` with exactly these ``params`` that nobody runs (queued, or
    running and stale): what a command run again after a kill resumes."""
    params = json_safe(params)
    for job in claimable(session, settings):
        if job.kind == kind and job.params == params:
            return job
    return None


@dataclass
class _Live:
    """A running job's progress, written by its thread and stored by its heartbeat."""

    stage: str | None = None
    done: int = 0
    total: int = 0
    lost: bool = False


class _Gate:
    """SQLite only: the heartbeat writes only while the job's session holds no transaction. In WAL mode
    a transaction that has read and then writes fails at once (SQLITE_BUSY_SNAPSHOT) when another
    connection committed in between, so a beat inside an import's batch would break it. ``attach``
    follows the session's transactions; a beat holds ``lock`` and skips while ``busy``."""

    def __init__(self) -> None:
        self.lock = threading.Lock()
        self.busy = False

    def attach(self, session: Session) -> None:
        """Follow ``session``'s transactions."""
        sa.event.listen(session, "after_begin", self._begin)
        sa.event.listen(session, "after_commit", self._end)
        sa.event.listen(session, "after_rollback", self._end)

    def _begin(self, *_: Any) -> None:
        with self.lock:  # waits for a beat being written
            self.busy = True

    def _end(self, *_: Any) -> None:
        self.busy = False


class _Heartbeat(threading.Thread):
    """Stores the job's progress and ``heartbeat_at`` every ``interval`` seconds on its own connection;
    notes when the job has another owner now (``live.lost``). With a ``gate`` (SQLite), only between the
    job session's transactions."""

    def __init__(self, session_factory: sessionmaker[Session], job_id: int, owner: str, live: _Live,
                 interval: float, gate: _Gate | None = None) -> None:
        super().__init__(name=f"v3d-job-{job_id}-heartbeat", daemon=True)
        self.session_factory, self.job_id, self.owner, self.live, self.interval = (
            session_factory, job_id, owner, live, interval)
        self.gate = gate
        self.stopped = threading.Event()
        self.last = 0.0

    def due(self) -> bool:
        """True when the last beat is older than the interval."""
        return time.monotonic() - self.last >= self.interval

    def beat(self) -> None:
        """One heartbeat (a short transaction), skipped while the gate is shut or the database stays busy
        beyond its timeout."""
        if self.gate is None:
            self._write()
            return
        with self.gate.lock:
            if not self.gate.busy:
                self._write()

    def _write(self) -> None:
        self.last = time.monotonic()
        try:
            with self.session_factory() as session, write_unit(session, lock=False):
                result = cast(CursorResult, session.execute(
                    sa.update(Job).where(Job.id == self.job_id, Job.owner == self.owner)
                    .values(heartbeat_at=utcnow(), stage=self.live.stage, done=self.live.done, total=self.live.total)
                    .execution_options(synchronize_session=False)))
                if result.rowcount == 0:
                    self.live.lost = True
        except sa.exc.OperationalError as exc:  # SQLite busy past its timeout: the next beat tries again
            log.warning("job %s: heartbeat skipped: %s", self.job_id, exc)

    def run(self) -> None:
        while not self.stopped.wait(self.interval):
            self.beat()


#: ``work(session, params, settings, progress, job_id) -> result``: what a kind of job does.
Work = Callable[[Session, dict[str, Any], Settings, Progress, int], dict[str, Any]]


#: How many times a job's work is run again after a transient database error (SQLite busy, a
#: PostgreSQL serialization failure or deadlock) before the job fails: the work is idempotent.
TRANSIENT_RETRIES = 3


def _is_transient(exc: BaseException) -> bool:
    """True for a database error that running the same work again may not meet."""
    if isinstance(exc, sa.exc.DBAPIError) and exc.connection_invalidated:
        return True
    text = str(getattr(exc, "orig", exc)).lower()
    return isinstance(exc, sa.exc.OperationalError) and any(
        w in text for w in ("database is locked", "database is busy", "deadlock detected", "could not serialize"))


def _work_with_retries(session_factory: sessionmaker[Session], work: Work, params: dict[str, Any],
                       settings: Settings, report: Progress, job_id: int, gate: _Gate | None) -> dict[str, Any]:
    """``work`` on a fresh session, run again (from the start: it is idempotent) after a transient
    database error, up to :data:`TRANSIENT_RETRIES` times."""
    for attempt in range(TRANSIENT_RETRIES + 1):
        with session_factory() as session:
            if gate is not None:
                gate.attach(session)
            try:
                return work(session, params, settings, report, job_id)
            except sa.exc.DBAPIError as exc:
                if attempt == TRANSIENT_RETRIES or not _is_transient(exc):
                    raise
                log.warning("job %s: transient database error, running it again: %s", job_id, exc)
                time.sleep(0.5 * (attempt + 1))
    raise AssertionError("unreachable")


def failure_message(exc: BaseException) -> str:
    """What a failed job's ``message`` says of ``exc``, in words: a database error says what the database answered
    (its first line) and what to do, never the statement and its parameters that SQLAlchemy's message carries (they
    go to the server's log); any other error its own message, or its class's name."""
    if isinstance(exc, sa.exc.DBAPIError):
        if is_lock_timeout(exc):
            return ("The database stayed busy with other writes longer than its timeout; its unfinished "
                    "transaction was rolled back. Run the job again.")
        said = (str(exc.orig).strip().splitlines() or [""])[0] if exc.orig is not None else ""
        return (f"The database refused the job's work ({type(exc.orig or exc).__name__}"
                f"{': ' + said if said else ''}); its unfinished transaction was rolled back. The server's log "
                "has the details.")
    return str(exc) or type(exc).__name__


def run_job(session_factory: sessionmaker[Session], job_id: int, settings: Settings, owner: str,
            progress: Progress | None = None, *, command_line: bool = False) -> Job:
    """Run the job ``job_id`` that ``owner`` claimed, to its end: ``done`` with its ``result``, or
    ``failed`` with the error's message (``result["error"]`` its class name). ``progress`` (stage,
    done, total) is called as the work advances, in this thread (the CLI's bars). ``command_line``: the job is the
    one this process's operator typed (``v3d import``), so an import may read a folder outside the data root
    (``app.services.jobs.work.COMMAND_LINE``); every other job row is data and reads only under it.

    Returns:
        The job as stored at the end (as last read when it was taken over: :class:`JobLost`).
    """
    live = _Live()
    with session_factory() as session:
        job = get_job(session, job_id)
        kind, params = job.kind, dict(job.params)

    gate = _Gate() if is_sqlite(settings) else None
    heartbeat = _Heartbeat(session_factory, job_id, owner, live, settings.job_heartbeat_seconds, gate)

    folder = jobs_dir(settings)
    written = [0.0]  # when the live progress file was last written (``progress.write_live``)

    def report(stage: str, done: int, total: int) -> None:
        if live.lost:
            raise JobLost(f"job {job_id} was taken over by another runner")
        changed = stage != live.stage
        live.stage, live.done, live.total = stage, done, total
        if changed or done >= total or time.monotonic() - written[0] >= LIVE_EVERY_S:
            written[0] = time.monotonic()
            write_live(folder, job_id, stage, done, total)
        if gate is not None and not gate.busy and (changed or heartbeat.due()):
            heartbeat.beat()  # SQLite: between the job's transactions (e.g. after each batch of games)
        if progress is not None:
            progress(stage, done, total)

    heartbeat.beat()
    heartbeat.start()
    values: dict[str, Any]
    typed = COMMAND_LINE.set(command_line)
    try:
        result = _work_with_retries(session_factory, WORK[kind], params, settings, report, job_id, gate)
        values = {"state": JobState.DONE, "result": json_safe(result), "message": None}
    except JobLost:
        values = {}
    except Exception as exc:  # any exception: a job's failure is recorded, whatever it is
        log.info("job %s (%s) failed: %s", job_id, kind, exc)
        values = {"state": JobState.FAILED, "message": failure_message(exc),
                  "result": {"error": type(exc).__name__, "invalid_input": isinstance(exc, InvalidInputError)}}
    finally:
        COMMAND_LINE.reset(typed)
        heartbeat.stopped.set()
        heartbeat.join()
        remove_live(folder, job_id)
    with session_factory() as session:
        if values and not live.lost:
            with write_unit(session, lock=False):
                session.execute(
                    sa.update(Job).where(Job.id == job_id, Job.owner == owner)
                    .values(finished_at=utcnow(), heartbeat_at=utcnow(), stage=live.stage, done=live.done,
                            total=live.total, **values)
                    .execution_options(synchronize_session=False))
        return get_job(session, job_id)


class JobRunner:
    """Runs queued (and stale) jobs one at a time in a daemon thread of this process.

    ``start()`` begins polling every ``settings.job_poll_seconds``; ``stop()`` asks the thread to end
    after its current job and waits ``timeout`` seconds for it (a job still running then is left to
    the next runner: its process will be gone, or its heartbeat stale).
    """

    def __init__(self, session_factory: sessionmaker[Session], settings: Settings) -> None:
        self.session_factory, self.settings = session_factory, settings
        self.owner = owner_name(settings)
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None

    def start(self) -> None:
        """Start the runner's thread."""
        self._thread = threading.Thread(target=self._loop, name="v3d-job-runner", daemon=True)
        self._thread.start()

    def stop(self, timeout: float = 5.0) -> None:
        """Ask the thread to stop and wait up to ``timeout`` seconds."""
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout)

    def _loop(self) -> None:
        while not self._stop.is_set():
            try:
                job_id = claim_next(self.session_factory, self.owner, self.settings)
                if job_id is not None:
                    run_job(self.session_factory, job_id, self.settings, self.owner)
                    continue
            except Exception:  # any exception: a runner outlives a failed poll (database restarting, locked)
                log.exception("job runner: poll failed")
            self._stop.wait(self.settings.job_poll_seconds)
