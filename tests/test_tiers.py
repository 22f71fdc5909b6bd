"""The structure of the test run (docs/testing.md): on pytest-xdist's workers, every test of a module runs on one
worker, as ``tests/conftest.py`` groups them (``--dist loadgroup``); a version of pytest or
pytest-xdist that silently stopped honouring the groups would split the browser modules' walks over two databases."""
from __future__ import annotations

import os
import re
import subprocess
import sys
from collections import defaultdict

import pytest

from app.core.paths import PROJECT_ROOT

pytestmark = pytest.mark.processes

#: Three small modules of several tests each (pure geometry: no database, no data).
MODULES = ("tests/geometry/test_camera.py", "tests/geometry/test_projection.py", "tests/geometry/test_metrics.py")


def test_each_module_runs_whole_on_one_worker() -> None:
    # CI's options (PYTEST_ADDOPTS: -q) would quieten the -v lines this reads
    env = {k: v for k, v in os.environ.items() if k != "PYTEST_ADDOPTS"}
    done = subprocess.run([sys.executable, "-m", "pytest", "-n", "2", "--dist", "loadgroup", "-v", "-p",
                           "no:cacheprovider", *MODULES], cwd=PROJECT_ROOT, capture_output=True, text=True,
                          timeout=300, env=env)
    assert done.returncode == 0, done.stdout[-3000:] + done.stderr[-3000:]
    ran = re.findall(r"^\[(gw\d)\] \[\s*\d+%\] PASSED (\S+?)::\S+\s*$", done.stdout, re.MULTILINE)
    workers = defaultdict(set)
    for worker, module in ran:
        workers[module].add(worker)
    assert set(workers) == set(MODULES), done.stdout[-3000:]
    assert all(len(w) == 1 for w in workers.values()), dict(workers)
    assert len({w for ws in workers.values() for w in ws}) == 2, "both workers ran tests"
