"""Fixtures shared by the whole suite."""
from __future__ import annotations

from pathlib import Path

import pytest

from app.core.paths import SHARED_DIR


@pytest.fixture(scope="session")
def shared_dir() -> Path:
    """``../shared`` beside the checkout; tests that need it skip with the reason when it is absent."""
    if not (SHARED_DIR / "data").is_dir():
        pytest.skip(f"../shared not found at {SHARED_DIR}: real and synthetic data unavailable")
    return SHARED_DIR
