"""Fixtures of the service tests (datasets from :mod:`tests.services.datasets`, extra databases)."""
from __future__ import annotations

from collections.abc import Callable, Iterator
from pathlib import Path

import pytest
from sqlalchemy.orm import Session

from app.core.config import Settings
from app.db.session import make_engine, make_session_factory, upgrade_database

from .datasets import write_v3_game


@pytest.fixture
def v3_tree(shared_dir: Path, tmp_path: Path) -> Path:
    """Root of a SoccerNet-v3 tree with the :data:`DEFAULT_ACTIONS` systems of the dev game."""
    root = tmp_path / "v3"
    write_v3_game(shared_dir, root)
    return root


@pytest.fixture
def fresh_session_factory(tmp_path: Path) -> Iterator[Callable[[str], Session]]:
    """``make(name)``: a session on a new migrated SQLite file (for tests that need two databases)."""
    engines = []

    def make(name: str) -> Session:
        url = f"sqlite:///{tmp_path / (name + '.sqlite3')}"
        upgrade_database(url)
        engine = make_engine(url)
        engines.append(engine)
        return make_session_factory(engine)()

    yield make
    for e in engines:
        e.dispose()


@pytest.fixture
def settings(db_settings: Settings) -> Settings:
    return db_settings
