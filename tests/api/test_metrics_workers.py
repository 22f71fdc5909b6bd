"""``v3d serve --workers 2``: each worker counts in files of one folder (prometheus-client's multiprocess mode), and a
scrape answered by either worker adds up both; the folder ``serve`` made goes when it stops."""
from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import httpx
import pytest
from prometheus_client.parser import text_string_to_metric_families

from app.core.paths import PROJECT_ROOT
from tests.accounts import make_accounts
from tests.conftest import migrate_new_database
from tests.live_server import free_port

pytestmark = pytest.mark.processes

_SERVE = "import sys; from app.cli import main; sys.argv = ['v3d', *sys.argv[1:]]; main()"


def _health_count(text: str) -> float:
    labels = {"route": "/api/health", "method": "GET", "status": "200"}
    return sum(s.value for family in text_string_to_metric_families(text) for s in family.samples
               if s.name == "v3d_http_request_duration_seconds_count" and s.labels == labels)


def test_two_workers_count_into_one_scrape(tmp_path: Path) -> None:
    url = f"sqlite:///{tmp_path / 'metrics.sqlite3'}"
    migrate_new_database(url)
    admin = make_accounts(url, login=False, roles=("admin",))["admin"]
    port = free_port()
    env = {k: v for k, v in os.environ.items() if k != "PROMETHEUS_MULTIPROC_DIR"}
    env.update(PYTHONPATH=str(PROJECT_ROOT), V3D_DATABASE_URL=url, V3D_JOB_RUNNER="false", TMPDIR=str(tmp_path))
    server = subprocess.Popen([sys.executable, "-c", _SERVE, "serve", "--port", str(port), "--workers", "2"],
                              env=env, cwd=tmp_path, start_new_session=True, stdout=subprocess.DEVNULL,
                              stderr=subprocess.PIPE, text=True)
    base = f"http://127.0.0.1:{port}"
    try:
        deadline = time.monotonic() + 120
        healthy = 0  # the start-up polls answered 200: each is counted too
        while True:
            try:
                if httpx.get(f"{base}/api/health", timeout=5).status_code == 200:
                    healthy += 1
                    break
            except httpx.TransportError:
                pass
            assert server.poll() is None and time.monotonic() < deadline, "the server did not start"
            time.sleep(0.2)
        folders = list(tmp_path.glob("v3d-metrics-*"))
        assert len(folders) == 1  # made by serve, before the workers started
        first = httpx.get(f"{base}/metrics", headers=admin.bearer, timeout=30)
        assert first.status_code == 200, first.text
        for _ in range(40):  # new connections: the kernel spreads them over both workers
            assert httpx.get(f"{base}/api/health", timeout=10).status_code == 200
        # each worker counts in files of its own (its counters made at import, its histograms at its first request)
        assert len(list(folders[0].glob("counter_*.db"))) == 2 and list(folders[0].glob("histogram_*.db"))
        # whichever worker answers, the scrape adds up every worker's files. A request is observed once its last byte
        # has left, which may be just after its client read the answer: wait for the last one to be counted first.
        expected = healthy + 40
        settle = time.monotonic() + 10
        while (_health_count(httpx.get(f"{base}/metrics", headers=admin.bearer, timeout=30).text) < expected
               and time.monotonic() < settle):
            time.sleep(0.1)
        counts = [_health_count(httpx.get(f"{base}/metrics", headers=admin.bearer, timeout=30).text)
                  for _ in range(4)]
        assert counts == [expected] * 4, counts
    finally:
        os.killpg(server.pid, signal.SIGINT)
        server.wait(timeout=60)
    assert not folders[0].exists()  # removed when serve stopped
