"""API test fixtures: ``create_app`` on the migrated test database, every request's session joined to
the per-test transaction (``db_connection`` of ``tests/conftest.py``) so nothing outlives a test."""
from __future__ import annotations

from collections.abc import Iterator

import pytest
import sqlalchemy as sa
from fastapi import FastAPI
from fastapi.testclient import TestClient
from sqlalchemy.orm import Session, sessionmaker

from app.core.config import Settings
from app.main import create_app

from .factories import Scene, make_game, make_system


@pytest.fixture
def app(db_settings: Settings, db_connection: sa.Connection) -> FastAPI:
    """The real application; its sessions commit into savepoints of the test's transaction."""
    application = create_app(db_settings)
    application.state.session_factory = sessionmaker(
        bind=db_connection, join_transaction_mode="create_savepoint", expire_on_commit=False
    )
    return application


@pytest.fixture
def client(app: FastAPI) -> Iterator[TestClient]:
    """HTTP client of :func:`app` (server errors raise in the test)."""
    with TestClient(app) as c:
        yield c


@pytest.fixture
def scene(db_session: Session, db_settings: Settings, tmp_path) -> Scene:
    """One game with one three-view system (exact cameras, ball boxes, images for two views)."""
    game = make_game(db_session)
    return make_system(db_session, db_settings, game, "1.png", image_dir=tmp_path)
