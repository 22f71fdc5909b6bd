"""Fault tests of ``v3d backup`` and ``v3d restore``: the real processes killed with SIGKILL midway.

* A backup killed while it writes leaves no archive at its destination (only its ``.part`` file, which
  ``v3d restore --verify-only`` refuses): nothing that looks complete.
* A restore killed while it writes leaves a target that ``v3d serve`` and every command refuse with words, and that
  the same command run again restores whole.

Data: a deployment whose store holds an export job's file of :data:`OBJECT_MB` MB (zeros, written sparse; 48 MB in CI's
suite, 400 MB in the slow tier), so that writing the archive and restoring it take long enough to be killed on a
condition (the file being written), never after a fixed pause.
"""
from __future__ import annotations

import os
import signal
import sqlite3
import stat
import subprocess
import sys
import time
from pathlib import Path

import pytest
import sqlalchemy as sa

from app.db.session import make_engine
from tests.conftest import migrate_new_database, sizes

pytestmark = pytest.mark.processes

V3D = str(Path(sys.executable).with_name("v3d"))
#: The export file's size (MB), CI's suite's and the slow tier's: long enough to write that a kill lands while it is
#: written.
OBJECT_MB = sizes(48, 400)
#: How long a condition is waited for (seconds: a loaded machine).
DEADLINE_S = 120.0


def _env(folder: Path) -> dict[str, str]:
    return {**os.environ, "V3D_DATABASE_URL": f"sqlite:///{folder / 'v3d.sqlite3'}",
            "V3D_STORAGE_URL": (folder / "store").as_uri(), "V3D_JOBS_DIR": str(folder / "jobs")}


@pytest.fixture(scope="module", params=OBJECT_MB)
def source(request: pytest.FixtureRequest, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A migrated deployment with one finished export job whose file (:data:`OBJECT_MB` MB) is in its store."""
    folder = tmp_path_factory.mktemp("source")
    url = f"sqlite:///{folder / 'v3d.sqlite3'}"
    migrate_new_database(url)
    engine = make_engine(url)
    with engine.begin() as conn:
        conn.execute(sa.text("INSERT INTO jobs (id, kind, params, state, done, total, attempts, created_at, result) "
                             "VALUES (1, 'export', '{}', 'done', 0, 0, 1, '2026-11-28 10:00:00', "
                             "'{\"file\": \"job-1-coco.zip\"}')"))
    engine.dispose()
    big = folder / "store" / "exports" / "job-1-coco.zip"
    big.parent.mkdir(parents=True)
    with open(big, "wb") as f:
        f.truncate(request.param << 20)
    return folder


def _wait(condition, what: str) -> None:
    deadline = time.monotonic() + DEADLINE_S
    while not condition():
        assert time.monotonic() < deadline, f"waited {DEADLINE_S} s for {what}"
        time.sleep(0.002)


def test_a_backup_killed_midway_leaves_nothing_that_looks_complete(source: Path, tmp_path: Path) -> None:
    dest = tmp_path / "v3d-backup.zip"
    part = tmp_path / ".v3d-backup.zip.part"
    proc = subprocess.Popen([V3D, "backup", str(dest)], env=_env(source), stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE)
    try:
        _wait(lambda: part.exists() and part.stat().st_size > (8 << 20) or proc.poll() is not None,
              "the archive being written")
        assert proc.poll() is None, proc.communicate()  # still writing: the kill lands midway
        os.kill(proc.pid, signal.SIGKILL)
    finally:
        proc.wait(30)
    assert not dest.exists()
    assert stat.S_IMODE(part.stat().st_mode) == 0o600  # what a kill leaves holds secrets: its owner's alone
    checked = subprocess.run([V3D, "restore", "--verify-only", str(part)], env=_env(tmp_path / "t"),
                             capture_output=True, text=True, timeout=120)
    assert checked.returncode == 2 and "not a complete zip archive" in checked.stderr, checked.stderr
    done = subprocess.run([V3D, "backup", str(dest)], env=_env(source), capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stderr
    assert dest.exists() and not part.exists() and stat.S_IMODE(dest.stat().st_mode) == 0o600
    assert f"{part} was left by a backup that did not finish" in done.stderr, done.stderr


def test_a_restore_killed_midway_refuses_to_serve_and_the_same_command_finishes_it(source: Path,
                                                                                   tmp_path: Path) -> None:
    archive = tmp_path / "a.zip"
    made = subprocess.run([V3D, "backup", str(archive)], env=_env(source), capture_output=True, text=True,
                          timeout=600)
    assert made.returncode == 0, made.stderr
    target = tmp_path / "target"
    target.mkdir()
    stored = target / "store" / "exports"

    def writing_the_file() -> bool:
        return stored.is_dir() and any(p.stat().st_size > (8 << 20) for p in stored.iterdir())

    proc = subprocess.Popen([V3D, "restore", str(archive)], env=_env(target), stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE)
    try:
        _wait(lambda: writing_the_file() or proc.poll() is not None, "the restore writing the store")
        assert proc.poll() is None, proc.communicate()
        os.kill(proc.pid, signal.SIGKILL)
    finally:
        proc.wait(30)
    with sqlite3.connect(target / "v3d.sqlite3") as conn:  # the rows are in, the mark too
        assert conn.execute("SELECT count(*) FROM jobs").fetchone() == (1,)
    served = subprocess.run([V3D, "serve", "--port", "1"], env=_env(target), capture_output=True, text=True,
                            timeout=120)
    assert served.returncode == 2 and "unfinished restore" in served.stderr and "v3d restore" in served.stderr, \
        served.stderr
    again = subprocess.run([V3D, "restore", str(archive)], env=_env(target), capture_output=True, text=True,
                           timeout=600)
    assert again.returncode == 0, again.stderr
    original = source / "store" / "exports" / "job-1-coco.zip"
    assert (stored / "job-1-coco.zip").stat().st_size == original.stat().st_size
    listed = subprocess.run([V3D, "jobs", "list"], env=_env(target), capture_output=True, text=True, timeout=120)
    assert listed.returncode == 0, listed.stderr
