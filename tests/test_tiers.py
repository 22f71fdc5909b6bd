"""The structure of the test run (docs/testing.md): on pytest-xdist's workers, every test of a module runs on one
worker, in the module's order, as ``tests/conftest.py`` groups them (``--dist loadgroup``); a version of pytest or
pytest-xdist that silently stopped honouring the groups would split the browser modules' walks over two databases."""
from __future__ import annotations

import re
import subprocess
import sys
from collections import defaultdict

import pytest

from app.core.paths import PROJECT_ROOT

pytestmark = pytest.mark.processes

#: Three small modules of several tests each (pure geometry: no database, no data).
MODULES = ("tests/geometry/test_camera.py", "tests/geometry/test_projection.py", "tests/geometry/test_metrics.py")


def test_each_module_runs_whole_on_one_worker_in_its_order() -> None:
    done = subprocess.run([sys.executable, "-m", "pytest", "-n", "2", "--dist", "loadgroup", "-v", "-p",
                           "no:cacheprovider", *MODULES], cwd=PROJECT_ROOT, capture_output=True, text=True,
                          timeout=300)
    assert done.returncode == 0, done.stdout[-3000:] + done.stderr[-3000:]
    ran = re.findall(r"^\[(gw\d)\] \[\s*\d+%\] PASSED (\S+?)::(\S+)\s*$", done.stdout, re.MULTILINE)
    workers, order = defaultdict(set), defaultdict(list)
    for worker, module, test in ran:
        workers[module].add(worker)
        order[module].append(test.split("@", 1)[0])
    assert set(workers) == set(MODULES), done.stdout[-3000:]
    assert all(len(w) == 1 for w in workers.values()), dict(workers)
    assert len({w for ws in workers.values() for w in ws}) == 2, "both workers ran tests"
    collected = subprocess.run([sys.executable, "-m", "pytest", "--collect-only", "-q", "-p", "no:cacheprovider",
                                *MODULES], cwd=PROJECT_ROOT, capture_output=True, text=True, timeout=300)
    listed = defaultdict(list)
    for line in collected.stdout.splitlines():
        if "::" in line:
            module, test = line.split("::", 1)
            listed[module].append(test)
    assert dict(order) == dict(listed)
