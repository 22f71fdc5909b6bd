"""Fault tests: the real ``v3d import`` and ``v3d serve`` processes killed with SIGKILL (issue 7, item 5).

* An import killed after its job shows whole games stored leaves a sound database (SQLite
  ``PRAGMA integrity_check`` ok and ``foreign_key_check`` empty; on both backends no row whose parent is
  missing and no natural key stored twice); the same command run again resumes the job and ends with
  exactly the rows of a clean import of the same tree.
* A server killed during a stream of ball edits: integrity holds, and every edit it answered 200 is in
  the final state.

Data: three systems of a synthetic dev game (``tests.services.datasets.write_v3_game``) copied under four leagues in
CI's suite and eight in the slow tier (as many games, labels only), stored one game per transaction
(``V3D_IMPORT_BATCH_FRAMES=1``) so that the kill falls between batches of a real multi-game import (it is sent once
the database holds a stored game
and at least two are still to come: the job's stored progress lags the commits by up to a heartbeat, in which a
compiled calibration stores several small games); the edits run on six systems of that game.
"""
from __future__ import annotations

import os
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path
from typing import Any, NamedTuple

import httpx
import pytest
import sqlalchemy as sa

from app.db.models import BallLabel, Base, Calibration, Doubt, Frame, Game, Job, JobState, System, Triangulation
from app.db.session import make_engine
from tests.conftest import migrate_new_database, sizes
from tests.services.datasets import DEV_GAME, write_v3_game

V3D = str(Path(sys.executable).with_name("v3d"))
#: Games of the import killed midway: CI's suite's and the slow tier's.
GAMES = sizes(4, 8)


class Tree(NamedTuple):
    """The folder imported, and how many games it holds."""

    root: Path
    games: int


@pytest.fixture(scope="module", params=GAMES)
def tree(request: pytest.FixtureRequest, shared_dir: Path, tmp_path_factory: pytest.TempPathFactory) -> Tree:
    """:data:`GAMES` games: three systems of the dev game under as many leagues (Labels-v3.json only)."""
    root = tmp_path_factory.mktemp("tree")
    for c in range(request.param):
        write_v3_game(shared_dir, root, game=(f"league_{c}", *DEV_GAME[1:]), with_images=False)
    return Tree(root, request.param)


def _env(url: str, **extra: str) -> dict[str, str]:
    env = {**os.environ, "V3D_DATABASE_URL": url, "V3D_IMPORT_BATCH_FRAMES": "1", "V3D_CALIBRATION_WORKERS": "2",
           "V3D_JOB_HEARTBEAT_SECONDS": "0.2"}
    env.update(extra)
    return env


def _import(url: str, tree: Path) -> subprocess.CompletedProcess:
    return subprocess.run([V3D, "import", "soccernet-v3", str(tree)], env=_env(url), capture_output=True,
                          text=True, timeout=600)


def _snapshot(url: str) -> dict[str, Any]:
    """Counts of every table an import writes, and each frame's calibration and each system's figures
    (rounded: the backends' doubles agree to far better than 1e-9)."""
    engine = make_engine(url)
    try:
        with engine.connect() as conn:
            counts = {m.__tablename__: conn.scalar(sa.select(sa.func.count()).select_from(m))
                      for m in (Game, System, Frame, Calibration, BallLabel, Triangulation, Doubt)}
            cals = sorted((g, s, f, st.value if hasattr(st, "value") else st, round(j or 0, 9))
                          for g, s, f, st, j in conn.execute(
                sa.select(Game.league, System.name, Frame.name, Calibration.status, Calibration.jac_0005)
                .join(System, System.game_id == Game.id).join(Frame, Frame.system_id == System.id)
                .join(Calibration, Calibration.frame_id == Frame.id)))
            systems = sorted((g, s, round(w or 0, 6), d) for g, s, w, d in conn.execute(
                sa.select(Game.league, System.name, System.worst_error_px, System.label_doubts)
                .join(System, System.game_id == Game.id)))
    finally:
        engine.dispose()
    return {"counts": counts, "calibrations": cals, "systems": systems}


def _soundness(url: str) -> None:
    """The database after a kill: SQLite's own checks; on every backend no orphan (every foreign key of
    the models) and no natural key stored twice."""
    engine = make_engine(url)
    try:
        with engine.connect() as conn:
            if engine.dialect.name == "sqlite":
                assert conn.exec_driver_sql("PRAGMA integrity_check").fetchall() == [("ok",)]
                assert conn.exec_driver_sql("PRAGMA foreign_key_check").fetchall() == []
            for table in Base.metadata.sorted_tables:
                for fk in table.foreign_keys:
                    col, parent = fk.parent, fk.column
                    orphans = conn.scalar(sa.select(sa.func.count()).select_from(table).where(
                        col.is_not(None), ~sa.exists().where(parent == col)))
                    assert orphans == 0, f"{table.name}.{col.name}: {orphans} rows whose {parent.table.name} is gone"
            for cols in ((Game.league, Game.season, Game.match), (System.game_id, System.name),
                         (Frame.system_id, Frame.name)):
                dupes = conn.execute(sa.select(*cols).group_by(*cols).having(sa.func.count() > 1)).fetchall()
                assert dupes == [], dupes
    finally:
        engine.dispose()


def _job(url: str) -> list[Job]:
    engine = make_engine(url)
    try:
        with sa.orm.Session(engine) as session:
            return list(session.scalars(sa.select(Job).order_by(Job.id)))
    finally:
        engine.dispose()


@pytest.fixture(scope="module")
def clean(tree: Tree, tmp_path_factory: pytest.TempPathFactory) -> dict[str, Any]:
    """The snapshot of a clean import of :func:`tree`."""
    url = f"sqlite:///{tmp_path_factory.mktemp('clean') / 'clean.sqlite3'}"
    done = _import(url, tree.root)
    assert done.returncode == 0, done.stderr
    snap = _snapshot(url)
    assert snap["counts"]["games"] == tree.games and snap["counts"]["systems"] == 3 * tree.games
    return snap


def _stored_games(engine: sa.Engine) -> int:
    with engine.connect() as conn:
        return conn.scalar(sa.select(sa.func.count()).select_from(Game)) or 0


def _kill_mid_import(url: str, tree: Tree) -> None:
    """Start ``v3d import`` and SIGKILL its process group (its calibration processes included) once the
    database holds a committed game and at least two are still to come."""
    migrate_new_database(url)
    log = open(os.devnull, "w")
    proc = subprocess.Popen([V3D, "import", "soccernet-v3", str(tree.root)], env=_env(url), start_new_session=True,
                            stdout=log, stderr=log)
    deadline = time.monotonic() + 300
    engine = make_engine(url)
    try:
        while True:
            if 1 <= _stored_games(engine) <= tree.games - 2:
                break
            assert proc.poll() is None, f"the import ended (status {proc.returncode}) before it could be killed"
            assert time.monotonic() < deadline, "no game stored within 300 s"
            time.sleep(0.005)
    finally:
        os.killpg(proc.pid, signal.SIGKILL)
        proc.wait(timeout=30)
        log.close()
        engine.dispose()
    assert proc.returncode == -signal.SIGKILL


def _resume_and_compare(url: str, tree: Tree, clean: dict[str, Any]) -> None:
    from app.core.config import Settings
    from app.services.jobs.runner import is_stale

    _soundness(url)
    [job] = _job(url)
    partial = _snapshot(url)["counts"]
    assert 1 <= partial["games"] < tree.games
    # the stored count of games never runs ahead of the committed games (it may lag them by a heartbeat, the job then
    # still showing its first stage, the games read, which counts games of the input, not stored ones)
    assert job.state is JobState.RUNNING and job.total in (0, tree.games)
    assert job.stage != "games" or job.done <= partial["games"], (job.stage, job.done, partial["games"])
    assert is_stale(job, Settings(database_url=url)), "the killed process's job must be claimable at once"

    again = _import(url, tree.root)
    assert again.returncode == 0, again.stderr
    assert f"resuming import job {job.id}" in again.stderr
    _soundness(url)
    [resumed] = _job(url)
    assert (resumed.id, resumed.state, resumed.attempts) == (job.id, JobState.DONE, 2)
    assert resumed.result["games"] == tree.games
    assert resumed.result["systems_new"] == clean["counts"]["systems"] - partial["systems"]
    assert _snapshot(url) == clean


def test_sigkill_mid_import_then_rerun_on_sqlite(tree: Tree, clean: dict[str, Any], tmp_path: Path) -> None:
    url = f"sqlite:///{tmp_path / 'killed.sqlite3'}"
    _kill_mid_import(url, tree)
    _resume_and_compare(url, tree, clean)


@pytest.mark.postgres
def test_sigkill_mid_import_then_rerun_on_postgres(tree: Tree, clean: dict[str, Any], pg_url: str) -> None:
    _kill_mid_import(pg_url, tree)
    _resume_and_compare(pg_url, tree, clean)


# ----- a server killed during edits ----------------------------------------------------------------
def _free_port() -> int:
    import socket

    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _auth_headers(env: dict[str, str]) -> dict[str, str]:
    """An admin token when this version has users (``v3d users add``), else no header."""
    made = subprocess.run([V3D, "users", "add", "fault-tester", "--role", "admin", "--password-stdin"], env=env,
                          input="fault-tester-password\n", capture_output=True, text=True, timeout=120)
    if made.returncode != 0:
        return {}
    return {"Authorization": f"Bearer {made.stdout.strip().splitlines()[-1]}"}


def test_sigkill_during_edits_keeps_every_answered_edit(shared_dir: Path, tmp_path: Path) -> None:
    game = write_v3_game(shared_dir, tmp_path / "tree", actions=tuple(f"{i}.png" for i in range(6)))
    url = f"sqlite:///{tmp_path / 'edits.sqlite3'}"
    env = _env(url, V3D_CALIBRATION_WORKERS="1")
    assert _import(url, game).returncode == 0
    headers = _auth_headers(env)
    port = _free_port()
    server = subprocess.Popen([V3D, "serve", "--port", str(port)], env=env, start_new_session=True,
                              stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    base = f"http://127.0.0.1:{port}"
    answered: dict[int, list[float]] = {}
    errors: list[str] = []
    try:
        deadline = time.monotonic() + 60
        while True:
            try:
                frames = httpx.get(f"{base}/api/frames", params={"limit": 500}, headers=headers, timeout=5)
                if frames.status_code == 200:
                    break
            except httpx.TransportError:
                pass
            assert server.poll() is None and time.monotonic() < deadline, "the server did not start"
            time.sleep(0.2)
        items = frames.json()["items"]
        assert len(items) >= 12

        def edit() -> None:
            """One annotator editing each view once (distinct boxes), until the server is gone."""
            with httpx.Client(base_url=base, headers=headers, timeout=30) as client:
                for i, f in enumerate(items):
                    box = [100.0 + i, 120.0 + i, 118.0 + i, 139.5 + i]  # inside every dev image
                    try:
                        extra = {}
                        current = client.get(f"/api/frames/{f['id']}")
                        if current.status_code == 200 and "etag" in current.headers:
                            extra["If-Match"] = current.headers["etag"]
                        r = client.patch(f"/api/frames/{f['id']}/ball", json={"box": box}, headers=extra)
                    except httpx.TransportError:
                        return  # the server is gone: this edit was never answered
                    if r.status_code != 200:
                        errors.append(f"{f['id']}: {r.status_code} {r.text}")
                        return
                    answered[f["id"]] = box

        workers = [threading.Thread(target=edit)]
        for w in workers:
            w.start()
        while len(answered) < 6 and any(w.is_alive() for w in workers):
            time.sleep(0.005)
    finally:
        os.killpg(server.pid, signal.SIGKILL)
        server.wait(timeout=30)
    for w in workers:
        w.join(timeout=60)
    assert errors == []
    assert 6 <= len(answered) < len(items), "the kill must fall during the edits"
    _soundness(url)
    engine = make_engine(url)
    try:
        with engine.connect() as conn:
            stored = dict(conn.execute(sa.select(BallLabel.frame_id, BallLabel.box)).all())
            assert conn.scalar(sa.select(sa.func.count()).select_from(Frame)) == len(items)
            no_tri = conn.scalar(sa.select(sa.func.count()).select_from(System).where(
                ~sa.exists().where(Triangulation.system_id == System.id)))
    finally:
        engine.dispose()
    assert {fid: stored.get(fid) for fid in answered} == answered
    assert no_tri == 0  # every edited system was recomputed in its edit's transaction
