"""The job queue (``app.services.jobs.runner``) on real databases: claims are compare-and-set, a job whose
process is gone is stale at once, and a server's runner thread resumes it and runs queued imports."""
from __future__ import annotations

import logging
import os
import socket
import sqlite3
import subprocess
import time
from datetime import timedelta
from pathlib import Path

import httpx
import pytest
import sqlalchemy as sa

from app.core.config import Settings
from app.db.models import Game, Job, JobState
from app.db.session import make_engine, make_session_factory
from app.db.types import utcnow
from app.services.jobs import runner as jobs
from tests.conftest import migrate_new_database

from ..datasets import write_v3_game


@pytest.fixture
def factory(tmp_path: Path):
    url = f"sqlite:///{tmp_path / 'jobs.sqlite3'}"
    migrate_new_database(url)
    engine = make_engine(url)
    yield url, make_session_factory(engine)
    engine.dispose()


def _dead_pid() -> int:
    proc = subprocess.Popen(["true"])
    proc.wait()
    return proc.pid


def test_a_claim_is_taken_once(factory) -> None:
    url, make = factory
    with make() as session:
        job = jobs.submit(session, "recompute", {})
    with make() as a, make() as b:
        seen_a, seen_b = a.get(Job, job.id), b.get(Job, job.id)  # both runners read it queued
        assert jobs.claim(a, seen_a, "host:1:a") is True
        assert jobs.claim(b, seen_b, "host:2:b") is False  # the row changed since b read it
    with make() as session:
        stored = session.get(Job, job.id)
        assert (stored.state, stored.owner, stored.attempts) == (JobState.RUNNING, "host:1:a", 1)
    with pytest.raises(jobs.InvalidInputError, match="unknown job kind 'defragment'"):
        with make() as session:
            jobs.submit(session, "defragment", {})


def test_staleness(factory) -> None:
    url, make = factory
    here = socket.gethostname()
    sqlite, pg = Settings(database_url=url, job_stale_seconds=60), Settings(
        database_url="postgresql+psycopg://x@h/db", job_stale_seconds=60)
    old = utcnow() - timedelta(seconds=3600)
    gone = Job(kind="import", params={}, state=JobState.RUNNING, owner=f"{here}:{_dead_pid()}:t", heartbeat_at=utcnow())
    alive_quiet = Job(kind="import", params={}, state=JobState.RUNNING, owner=f"{here}:{os.getpid()}:t",
                      heartbeat_at=old)
    elsewhere = Job(kind="import", params={}, state=JobState.RUNNING, owner="other-host:1:t", heartbeat_at=old)
    fresh_elsewhere = Job(kind="import", params={}, state=JobState.RUNNING, owner="other-host:1:t",
                          heartbeat_at=utcnow())
    assert jobs.is_stale(gone, sqlite) and jobs.is_stale(gone, pg)  # its process is gone: at once
    # a live local process beats only between its transactions on SQLite: never stale while it lives
    assert not jobs.is_stale(alive_quiet, sqlite) and jobs.is_stale(alive_quiet, pg)
    assert jobs.is_stale(elsewhere, pg) and not jobs.is_stale(fresh_elsewhere, pg)
    assert not jobs.is_stale(Job(kind="import", params={}, state=JobState.DONE, owner=gone.owner), sqlite)


def test_a_server_runner_resumes_a_killed_job_and_runs_a_queued_import(shared_dir: Path, tmp_path: Path,
                                                                        factory) -> None:
    """A job left running by a process that is gone, and a queued import, both run by the runner
    thread a served app starts (the real thread, the real HTTP API)."""
    from app.main import create_app
    from tests.accounts import make_accounts
    from tests.live_server import serve_app

    url, make = factory
    game = write_v3_game(shared_dir, tmp_path / "tree", with_images=False)
    with make() as session:
        killed = Job(kind="recompute", params={}, state=JobState.RUNNING,
                     owner=f"{socket.gethostname()}:{_dead_pid()}:x",
                     attempts=1, heartbeat_at=utcnow(), stage="recompute", done=0, total=0)
        session.add(killed)
        session.commit()
    admin = make_accounts(url, login=False, roles=("admin",))["admin"]
    settings = Settings(database_url=url, calibration_workers=2, data_root=tmp_path, job_poll_seconds=0.1,
                        job_heartbeat_seconds=0.2)
    with serve_app(create_app(settings)) as base:
        queued = httpx.post(f"{base}/api/imports",
                            json={"kind": "soccernet-v3", "path": str(game.parent.parent.parent)},
                            headers=admin.bearer)
        assert queued.status_code == 202
        deadline = time.monotonic() + 300
        while True:
            states = {j["id"]: j for j in httpx.get(f"{base}/api/jobs", headers=admin.bearer).json()["items"]}
            if all(j["state"] in ("done", "failed") for j in states.values()):
                break
            assert time.monotonic() < deadline, states
            time.sleep(0.2)
    resumed, imported = states[killed.id], states[queued.json()["id"]]
    assert (resumed["state"], resumed["attempts"], resumed["result"]) == (
        "done", 2, {"systems": 0, "triangulated": 0,
                    "summary": {"words": "0 systems recomputed, 0 with a 3D ball", "links": []}})
    assert imported["state"] == "done" and imported["result"]["systems"] == 3 and imported["attempts"] == 1
    assert resumed["owner"] == imported["owner"] and resumed["owner"].startswith(f"{socket.gethostname()}:")
    with make() as session:
        assert session.scalar(sa.select(sa.func.count(Game.id))) == 1


def test_token_bookkeeping_never_fails_an_import_and_a_failed_job_says_words(shared_dir: Path, tmp_path: Path,
                                                                            factory) -> None:
    """On SQLite an import's batch reads, calibrates, then writes, and a write committed by another connection in
    between would fail it: a scrape with a fresh API token at each calibration step (each one's ``last_used_at`` due)
    leaves the import done, the tokens' bookkeeping waiting for a later request. A job failed by the database says
    so in words, without the statement and its parameters."""
    from app.services.accounts import users
    from app.services.jobs.work import import_params

    url, make = factory
    game = write_v3_game(shared_dir, tmp_path / "tree", with_images=False)
    settings = Settings(database_url=url, calibration_workers=1)
    owner = jobs.owner_name(settings)
    with make() as session:
        tokens = [users.create_user(session, "scraper", "admin", "pw")[1]]
        tokens += [users.issue_token(session, "scraper").token for _ in range(39)]
        job_id = jobs.submit(session, "import", import_params("soccernet-v3", game.parent.parent.parent),
                             owner=owner).id
    used: list[str] = []

    def scrape(stage: str, done: int, total: int) -> None:  # inside the batch: read, not written yet
        if stage == "calibrate" and len(used) < len(tokens):
            token = tokens[len(used)]
            used.append(token)
            with make() as other:
                assert users.resolve_token(other, token) is not None  # the request itself is answered

    job = jobs.run_job(make, job_id, settings, owner, progress=scrape, command_line=True)  # as `v3d import`
    assert (job.state, job.message, job.attempts) == (JobState.DONE, None, 1), job.message
    assert used and job.result["systems"] == 3
    with make() as session:
        assert session.scalar(sa.select(sa.func.count(Game.id))) == 1
        assert [t.last_used_at for t in users.list_tokens(session, "scraper")] == [None] * 40  # skipped meanwhile
        users.resolve_token(session, tokens[0])
        assert users.list_tokens(session, "scraper")[0].last_used_at is not None  # and written once it ended

    # a database that stays locked fails a job: its message is words, not SQL
    busy = make_session_factory(make_engine(url, write_lock_timeout_s=0.2))
    with make() as session:
        recompute_id = jobs.submit(session, "recompute", {}, owner=owner).id
    holder = sqlite3.connect(sa.make_url(url).database, isolation_level=None, check_same_thread=False)
    holder.execute("BEGIN IMMEDIATE")

    class ReleaseWhenFailed(logging.Handler):  # the job's work has failed for good: let its failure be stored
        def emit(self, record: logging.LogRecord) -> None:
            if record.getMessage().startswith(f"job {recompute_id} (recompute) failed"):
                holder.rollback()

    release = ReleaseWhenFailed()
    jobs.log.addHandler(release)
    level = jobs.log.level
    jobs.log.setLevel(logging.INFO)
    try:
        failed = jobs.run_job(busy, recompute_id, settings, owner)
    finally:
        jobs.log.removeHandler(release)
        jobs.log.setLevel(level)
        holder.close()
    assert failed.state == JobState.FAILED
    assert failed.message.startswith("The database stayed busy with other writes"), failed.message
    assert not any(w in failed.message for w in ("[SQL", "BEGIN", "sqlalche.me", "?", "OperationalError"))


def test_a_page_claiming_its_system_during_an_import_batch_never_fails_the_import(shared_dir: Path, tmp_path: Path,
                                                                                  factory) -> None:
    """A reviewer's page keeps claiming the system it has open (``app.services.curation.presence``: a write every
    30 s) while an import runs: on SQLite such a commit between an import batch's first read and its first write
    failed the batch, each of the job's runs again met the next one, and the import failed. The batch now runs again
    once holding the write lock from its start: the claims landing then wait for it, the import is done in one run of
    its job, and every claim is stored."""
    import threading

    from app.db.models import System, SystemPresence
    from app.services.accounts import users
    from app.services.curation import presence
    from app.services.jobs.work import import_params
    from app.services.transfer.importing import import_soccernet_v3

    url, make = factory
    settings = Settings(database_url=url, calibration_workers=1)
    owner = jobs.owner_name(settings)
    with make() as session:
        import_soccernet_v3(session, write_v3_game(shared_dir, tmp_path / "open").parent.parent.parent, settings)
        system_id = session.scalars(sa.select(System.id).order_by(System.id)).first()
        reviewer = users.create_user(session, "rev", "reviewer", "pw")[0].id
        other = write_v3_game(shared_dir, tmp_path / "next", game=("league", "season", "next match"),
                              with_images=False)
        job_id = jobs.submit(session, "import", import_params("soccernet-v3", other.parent.parent.parent),
                             owner=owner).id
    claims: list[threading.Thread] = []
    answers: list[object] = []

    def claim(k: int) -> None:  # one heartbeat of the page, its claim due (30 s after the last)
        try:
            with make() as s:
                answers.append(presence.claim(s, system_id, reviewer, utcnow() + timedelta(seconds=31 * k)).wrote)
        except Exception as exc:  # noqa: BLE001  # the request's failure, asserted on below
            answers.append(exc)

    def heartbeat(stage: str, done: int, total: int) -> None:  # inside the batch: read, not written yet
        if stage == "calibrate":
            claims.append(threading.Thread(target=claim, args=(len(claims),)))
            claims[-1].start()
            claims[-1].join(timeout=0.5)  # committed unless it waits for the import's write lock

    job = jobs.run_job(make, job_id, settings, owner, progress=heartbeat, command_line=True)  # as `v3d import`
    for t in claims:
        t.join(timeout=120)
    assert (job.state, job.message) == (JobState.DONE, None), job.message
    assert job.result["systems"] == 3 and claims
    assert answers == [True] * len(claims)  # every claim written: after the batch when it landed in its retry
    with make() as session:
        assert session.scalar(sa.select(sa.func.count(Game.id))) == 2
        assert session.scalar(sa.select(SystemPresence.expires_at)) is not None
