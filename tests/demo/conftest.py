"""Fixtures of the demo-dataset tests: one generated dataset shared by the session's tests."""
from __future__ import annotations

import time

import pytest

from app.demo import generate_demo_dataset
from tests.demo.support import Demo, load_demo


@pytest.fixture(scope="session")
def demo(tmp_path_factory: pytest.TempPathFactory) -> Demo:
    """The demo dataset for seed 0, generated once per test session."""
    out = tmp_path_factory.mktemp("demo")
    t0 = time.process_time()
    root = generate_demo_dataset(out, seed=0)
    return load_demo(root, time.process_time() - t0)
