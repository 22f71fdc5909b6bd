"""``v3d serve``: migrates the database, loads the demo only into an empty one, prints the URL and
hands ``create_app(settings)`` to uvicorn (recorded here instead of listening on a port)."""
from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
import sqlalchemy as sa
import uvicorn
from fastapi import FastAPI
from typer.testing import CliRunner

import app.cli.serve  # noqa: F401  (registers the command)
from app.cli._root import cli
from app.core.config import get_settings
from app.db.models import Game
from app.db.session import make_engine, make_session_factory, upgrade_database


@pytest.fixture
def database(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Iterator[str]:
    """``V3D_DATABASE_URL`` of a SQLite file in a folder that does not exist yet."""
    url = f"sqlite:///{tmp_path / 'var' / 'v3d.sqlite3'}"
    monkeypatch.setenv("V3D_DATABASE_URL", url)
    monkeypatch.setenv("V3D_CALIBRATION_WORKERS", "1")
    get_settings.cache_clear()
    yield url
    get_settings.cache_clear()


@pytest.fixture
def served(monkeypatch: pytest.MonkeyPatch) -> list[dict[str, Any]]:
    """The calls ``serve`` makes to ``uvicorn.run``."""
    calls: list[dict[str, Any]] = []
    monkeypatch.setattr(uvicorn, "run", lambda app, **kw: calls.append({"app": app, **kw}))
    return calls


def _games(url: str) -> int:
    engine = make_engine(url)
    try:
        with make_session_factory(engine)() as session:
            return session.scalar(sa.select(sa.func.count(Game.id))) or 0
    finally:
        engine.dispose()


def test_serve_migrates_prints_the_url_and_runs_the_app(database: str, served: list, tmp_path: Path) -> None:
    result = CliRunner().invoke(cli, ["serve", "--host", "127.0.0.2", "--port", "8123"])
    assert result.exit_code == 0, result.output
    assert "http://127.0.0.2:8123/" in result.output
    assert (tmp_path / "var" / "v3d.sqlite3").is_file() and _games(database) == 0
    assert len(served) == 1 and isinstance(served[0]["app"], FastAPI)
    assert (served[0]["host"], served[0]["port"]) == ("127.0.0.2", 8123)


def test_demo_is_not_loaded_into_a_database_with_games(database: str, served: list, tmp_path: Path) -> None:
    upgrade_database(database)
    engine = make_engine(database)
    with make_session_factory(engine)() as session:
        session.add(Game(league="l", season="s", match="m", source_path="/x"))
        session.commit()
    engine.dispose()
    result = CliRunner().invoke(cli, ["serve", "--demo"])
    assert result.exit_code == 0, result.output
    assert "already holds games" in result.output
    assert not (tmp_path / "var" / "demo").exists() and _games(database) == 1


def test_demo_is_generated_and_imported_into_an_empty_database(database: str, served: list,
                                                               tmp_path: Path) -> None:
    result = CliRunner().invoke(cli, ["serve", "--demo"])
    assert result.exit_code == 0, result.output
    assert "demo: imported" in result.output
    assert (tmp_path / "var" / "demo").is_dir() and _games(database) == 1
    assert len(served) == 1
