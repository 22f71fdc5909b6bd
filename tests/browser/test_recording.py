"""A failing browser test explains itself (``tests/recording.py``): a test that fails on purpose, run in a pytest of
its own, leaves its trace and a screenshot of its open page, and its report names them and what the page logged."""
from __future__ import annotations

import os
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

from tests.recording import TRACES

pytestmark = pytest.mark.browser

ROOT = Path(__file__).resolve().parents[2]

FAILING = '''
def test_a_page_that_logs_an_error_then_fails(browser):
    page = browser.new_context().new_page()
    page.set_content("<h1>the page's last state</h1><script>console.error('something broke')</script>")
    assert page.inner_text("h1") == "another state"


def test_a_page_that_passes(browser):
    page = browser.new_context().new_page()
    page.set_content("<h1>fine</h1>")
    assert page.inner_text("h1") == "fine"
'''


def test_a_failed_test_keeps_its_trace_and_a_screenshot_and_a_passed_one_keeps_nothing(tmp_path: Path) -> None:
    module = tmp_path / "test_recorded.py"
    module.write_text(FAILING)
    name = f"{tmp_path.name}_test_recorded.py_test_a_page_that"
    done = subprocess.run(
        [sys.executable, "-m", "pytest", "-p", "tests.conftest", "-p", "no:cacheprovider", "-n", "0", "-q",
         "-c", str(ROOT / "pyproject.toml"), "--rootdir", str(tmp_path.parent), str(module)],
        cwd=ROOT, capture_output=True, text=True, timeout=300,
        # the run's own options only: CI's PYTEST_ADDOPTS (its -q on top of this -q) would drop the summary's counts
        env={k: v for k, v in os.environ.items() if k != "PYTEST_ADDOPTS"})
    kept = sorted(TRACES.glob(f"{name}*"))
    try:
        assert "1 failed, 1 passed" in done.stdout, done.stdout + done.stderr
        failed = f"{name}_logs_an_error_then_fails"
        assert [p.name for p in kept] == [f"{failed}-page1.png", f"{failed}.zip"], done.stdout
        assert kept[0].read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
        assert any(n.endswith(".trace") for n in zipfile.ZipFile(kept[1]).namelist())
        assert f"test-artifacts/traces/{failed}.zip" in done.stdout
        assert "console error: something broke" in done.stdout
    finally:
        for path in kept:
            path.unlink()
