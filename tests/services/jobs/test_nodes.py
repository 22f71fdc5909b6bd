"""Nodes sharing one database (``Settings.node_name`` in job owners): a node judges another node's job by its
heartbeat alone, and takes it over once the heartbeat is older than ``job_stale_seconds``."""
from __future__ import annotations

import os
import socket
import time
from pathlib import Path

import pydantic
import pytest

from app.core.config import Settings, node_name
from app.db.models import Job, JobState
from app.db.session import make_engine, make_session_factory
from app.services.jobs import runner as jobs
from tests.conftest import PG_ADMIN_URL, fresh_postgresql_database, migrate_new_database


@pytest.fixture(params=["sqlite", pytest.param("postgresql", marks=pytest.mark.postgres)])
def database(request, tmp_path: Path):
    if request.param == "sqlite":
        yield f"sqlite:///{tmp_path / 'nodes.sqlite3'}"
        return
    with fresh_postgresql_database(PG_ADMIN_URL, migrated=True) as url:
        yield url


def test_the_node_name_defaults_to_the_host_name_and_refuses_a_colon() -> None:
    assert node_name(Settings(_env_file=None)) == socket.gethostname()
    assert jobs.owner_name(Settings(_env_file=None, node_name="node-a")).startswith(f"node-a:{os.getpid()}:")
    for bad in ("a:b", "a b", ""):  # the node is the owner up to its first colon
        with pytest.raises(pydantic.ValidationError, match="node_name"):
            Settings(_env_file=None, node_name=bad)


def test_a_job_whose_node_stopped_is_taken_over_by_another_node_after_its_heartbeat_goes_stale(database) -> None:
    migrate_new_database(database)
    engine = make_engine(database)
    make = make_session_factory(engine)
    try:
        a, b = (Settings(_env_file=None, database_url=database, node_name=name, job_stale_seconds=1.5,
                         job_heartbeat_seconds=0.2) for name in ("node-a", "node-b"))
        with make() as session:
            job_id = jobs.submit(session, "recompute", {}).id
        owner_a = jobs.owner_name(a)
        assert jobs.claim_next(make, owner_a, a) == job_id
        # node A stops beating (its process is this live one, but B cannot see A's processes: only the heartbeat)
        owner_b = jobs.owner_name(b)
        assert jobs.claim_next(make, owner_b, b) is None  # A's heartbeat is fresh
        with make() as session:
            running = session.get(Job, job_id)
            assert jobs.on_this_node(running.owner, a) and not jobs.on_this_node(running.owner, b)
            assert not jobs.is_stale(running, b) and not jobs.is_stale(running, a)
        time.sleep(1.7)
        assert jobs.claim_next(make, owner_b, b) == job_id
        ran = jobs.run_job(make, job_id, b, owner_b)
        assert (ran.state, ran.owner, ran.attempts) == (JobState.DONE, owner_b, 2)
    finally:
        engine.dispose()


def test_a_dead_process_makes_a_job_stale_at_once_only_on_its_own_node(database) -> None:
    import subprocess

    proc = subprocess.Popen(["true"])
    proc.wait()
    from app.db.types import utcnow

    job = Job(kind="import", params={}, state=JobState.RUNNING, owner=f"node-a:{proc.pid}:t", heartbeat_at=utcnow())
    a, b = (Settings(_env_file=None, database_url=database, node_name=name, job_stale_seconds=60)
            for name in ("node-a", "node-b"))
    assert jobs.is_stale(job, a)  # on its node: the process is gone
    assert not jobs.is_stale(job, b)  # elsewhere the pid means nothing: wait for the heartbeat
