"""Nodes started at once on a fresh PostgreSQL database all come up: ``v3d serve`` migrates under an advisory lock
(``migrations/env.py``), so one node migrates while the others wait, then find the schema at head."""
from __future__ import annotations

import os
import subprocess
import sys
import time

import pytest
import sqlalchemy as sa

from app.core.paths import PROJECT_ROOT
from app.db.session import make_engine

pytestmark = [pytest.mark.engine, pytest.mark.processes]

#: Each process, once it has imported the app, says so (its ready file), waits for the start file, then runs the
#: start-up migration of ``v3d serve``.
_MIGRATE = """
import os, pathlib, sys, time
from app.db.session import upgrade_database
pathlib.Path(sys.argv[3]).touch()
while not os.path.exists(sys.argv[2]):
    time.sleep(0.005)
upgrade_database(sys.argv[1])
"""
#: How long the four processes may take to import the app on a loaded machine: a bound, not a measure.
READY_TIMEOUT_S = 300


@pytest.mark.postgres
def test_nodes_started_at_once_on_a_fresh_database_all_migrate(pg_url, tmp_path):
    start = tmp_path / "go"
    ready = [tmp_path / f"ready-{i}" for i in range(4)]
    env = {**os.environ, "PYTHONPATH": str(PROJECT_ROOT)}
    procs = [subprocess.Popen([sys.executable, "-c", _MIGRATE, pg_url, str(start), str(flag)], env=env,
                              cwd=PROJECT_ROOT, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
             for flag in ready]
    try:
        # every process has imported the app and waits at the start line: all four then migrate at once
        deadline = time.monotonic() + READY_TIMEOUT_S
        while not all(flag.exists() for flag in ready):
            ended = [p.returncode for p in procs if p.poll() is not None]
            assert not ended, f"a process ended before the start: {ended}\n" + "\n".join(
                p.communicate()[0] for p in procs if p.poll() is not None)
            assert time.monotonic() < deadline, f"not all ready after {READY_TIMEOUT_S} s"
            time.sleep(0.01)
    except BaseException:
        for p in procs:
            p.kill()
            p.wait()
        raise
    start.touch()
    outputs = [p.communicate(timeout=300)[0] for p in procs]
    assert [p.returncode for p in procs] == [0] * 4, "\n".join(outputs)
    engine = make_engine(pg_url)
    try:
        with engine.connect() as conn:
            versions = conn.execute(sa.text("SELECT version_num FROM alembic_version")).scalars().all()
            # this database's advisory locks only: pg_locks lists the whole server's, where the other worker's tests
            # take theirs (a run beside a coverage run counted one of them)
            held = conn.execute(sa.text(
                "SELECT count(*) FROM pg_locks WHERE locktype = 'advisory' AND database = "
                "(SELECT oid FROM pg_database WHERE datname = current_database())")).scalar()
    finally:
        engine.dispose()
    from alembic.script import ScriptDirectory

    from app.db.session import alembic_config

    assert versions == [ScriptDirectory.from_config(alembic_config()).get_current_head()]
    assert held == 0  # every process let the lock go
