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
from fastapi.testclient import TestClient
from typer.testing import CliRunner

import app.cli.serve  # noqa: F401  # registers the command
from app.cli._root import cli
from app.core.config import get_settings
from app.core.metrics import MULTIPROC_ENV
from app.db.models import Game, User
from app.db.session import make_engine, make_session_factory
from tests.conftest import copy_sqlite, migrate_new_database


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
def demo_database(database: str, demo_template: Path) -> str:
    """:func:`database`, holding a copy of the demo already imported (``tests.conftest.demo_template``: its dataset
    stays in the template's folder)."""
    copy_sqlite(demo_template, Path(sa.make_url(database).database or ""))
    return database


@pytest.fixture
def served(monkeypatch: pytest.MonkeyPatch) -> list[dict[str, Any]]:
    """The calls ``serve`` makes to ``uvicorn.run`` (the metrics' folder it sets for workers is unset afterwards)."""
    calls: list[dict[str, Any]] = []
    monkeypatch.setenv(MULTIPROC_ENV, "")
    monkeypatch.delenv(MULTIPROC_ENV)
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


@pytest.mark.parametrize("host", ["0.0.0.0", "::", "192.168.1.20", "v3d.example.org"])
def test_demo_is_refused_on_a_host_that_faces_a_network(database: str, served: list, tmp_path: Path,
                                                         host: str) -> None:
    """``--demo`` makes an admin whose password is public: on a non-loopback interface the command stops
    before touching the database, saying why (exit 2), and serves nothing."""
    result = CliRunner().invoke(cli, ["serve", "--host", host, "--demo"])
    assert result.exit_code == 2, result.output
    assert "must never face a network" in result.output and host in result.output
    assert served == [] and not (tmp_path / "var" / "v3d.sqlite3").exists()


def test_demo_is_refused_behind_a_declared_reverse_proxy(database: str, served: list, tmp_path: Path,
                                                        monkeypatch: pytest.MonkeyPatch) -> None:
    """On 127.0.0.1 behind a proxy (``V3D_TRUSTED_PROXIES`` set) the network reaches the demo admin: refused, saying
    why. (A proxy left undeclared is met by the login itself: ``tests/api/test_auth.py``.)"""
    monkeypatch.setenv("V3D_TRUSTED_PROXIES", '["127.0.0.1"]')
    get_settings.cache_clear()
    result = CliRunner().invoke(cli, ["serve", "--host", "127.0.0.1", "--demo"])
    assert result.exit_code == 2, result.output
    assert "V3D_TRUSTED_PROXIES" in result.output and "must never face a network" in result.output
    assert served == [] and not (tmp_path / "var" / "v3d.sqlite3").exists()
    assert CliRunner().invoke(cli, ["serve", "--host", "127.0.0.1"]).exit_code == 0  # without the demo it serves


@pytest.mark.parametrize("host", ["127.0.0.1", "127.0.0.2", "localhost", "::1"])
def test_demo_is_served_on_loopback_hosts(demo_database: str, served: list, host: str) -> None:
    result = CliRunner().invoke(cli, ["serve", "--host", host, "--demo"])
    assert result.exit_code == 0, result.output
    assert len(served) == 1 and served[0]["host"] == host


def test_an_enabled_demo_account_keeps_the_server_off_the_network(demo_database: str, served: list) -> None:
    """A database that still holds the enabled demo account (made by an earlier ``--demo``) is not served
    on 0.0.0.0 even without ``--demo``; once the account is disabled it is."""
    assert CliRunner().invoke(cli, ["serve", "--demo"]).exit_code == 0
    result = CliRunner().invoke(cli, ["serve", "--host", "0.0.0.0"])
    assert result.exit_code == 2, result.output
    assert "v3d users disable demo" in result.output
    engine = make_engine(demo_database)
    with make_session_factory(engine)() as session:
        session.scalar(sa.select(User).where(User.name == "demo")).disabled = True
        session.commit()
    engine.dispose()
    result = CliRunner().invoke(cli, ["serve", "--host", "0.0.0.0"])
    assert result.exit_code == 0, result.output
    assert served[-1]["host"] == "0.0.0.0"


def test_demo_is_not_loaded_into_a_database_with_games(database: str, served: list, tmp_path: Path) -> None:
    migrate_new_database(database)
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


def test_demo_makes_a_labelled_demo_account_and_says_how_to_log_in(demo_database: str, served: list) -> None:
    """``--demo`` makes the demo account once (``demo`` / ``demo``, admin, flagged); the served app logs
    it in and its login page's hint names it. Without ``--demo`` there is no such account."""
    plain = CliRunner().invoke(cli, ["serve"])
    assert plain.exit_code == 0 and "/login" in plain.output and "demo account" not in plain.output
    with TestClient(served[0]["app"]) as client:
        assert client.get("/api/auth/demo").json() == {"account": None}
    for _ in range(2):  # a second start keeps the one account
        result = CliRunner().invoke(cli, ["serve", "--demo"])
        assert result.exit_code == 0, result.output
        assert "demo account (role admin, for trying v3d only): log in as 'demo' with password 'demo'" in result.output
        assert "http://127.0.0.1:8000/login" in result.output
    with TestClient(served[-1]["app"], client=("127.0.0.1", 50000),
                    base_url="http://127.0.0.1:8000") as client:  # a browser on this machine (loopback peer and Host)
        assert client.get("/api/auth/demo").json() == {"account": {"name": "demo", "password": "demo"}}
        login = client.post("/api/auth/login", json={"name": "demo", "password": "demo"})
        assert login.status_code == 200 and login.json()["role"] == "admin"
        assert client.get("/api/systems").json()["total"] > 0
    engine = make_engine(demo_database)
    with make_session_factory(engine)() as session:
        assert [(u.name, u.demo) for u in session.scalars(sa.select(User))] == [("demo", True)]
    engine.dispose()


def test_workers_start_up_once_then_uvicorn_builds_the_app_per_process(database: str, served: list,
                                                                        tmp_path: Path) -> None:
    result = CliRunner().invoke(cli, ["serve", "--demo", "--workers", "2", "--port", "8124"])
    assert result.exit_code == 0, result.output
    assert "demo: imported" in result.output and "2 worker processes" in result.output
    assert _games(database) == 1  # migrated and loaded here, once, before any worker starts
    assert len(served) == 1
    call = served[0]
    assert (call["app"], call["factory"], call["workers"], call["port"]) == ("app.main:create_app", True, 2, 8124)
    from app.main import create_app

    built = create_app()  # what each worker does: the settings of the environment
    assert isinstance(built, FastAPI) and built.state.settings.database_url == database


def test_serving_to_a_network_says_which_host_names_are_answered(database: str, served: list,
                                                                  monkeypatch: pytest.MonkeyPatch) -> None:
    """Issue 27, item 3: requests naming a Host other than a loopback name or one of V3D_ALLOWED_HOSTS get 400, so
    serving on a network interface says which names are answered (and how to add one)."""
    monkeypatch.setenv("V3D_ALLOWED_HOSTS", "")
    get_settings.cache_clear()
    result = CliRunner().invoke(cli, ["serve", "--host", "0.0.0.0"])
    assert result.exit_code == 0 and "set V3D_ALLOWED_HOSTS to the name other machines use" in result.output
    monkeypatch.setenv("V3D_ALLOWED_HOSTS", "v3d.example.org")
    get_settings.cache_clear()
    result = CliRunner().invoke(cli, ["serve", "--host", "0.0.0.0"])
    assert "as V3D_ALLOWED_HOSTS (v3d.example.org)" in result.output
    with TestClient(served[-1]["app"], base_url="http://v3d.example.org") as named:
        assert named.get("/api/health").status_code == 200
    with TestClient(served[-1]["app"], base_url="http://192.0.2.7:8000") as by_address:
        assert by_address.get("/api/health").status_code == 400
    assert "reachable" not in CliRunner().invoke(cli, ["serve"]).output  # loopback: nothing to say


def test_every_way_of_serving_bounds_a_requests_head_and_idle_connections(database: str, served: list) -> None:
    """The third security review: an 80 MB header froze the server, whose httptools parser bounds nothing. One process
    and N workers (and so ``scripts/serve.sh`` and the Docker image, which run ``v3d serve``) serve with uvicorn's h11
    parser, bounded by ``V3D_MAX_HEADER_KB``, and close idle connections after ``V3D_KEEP_ALIVE_S``
    (``tests/api/test_edge.py`` sends the attack to such a server)."""
    for args in ([], ["--workers", "2"]):
        result = CliRunner().invoke(cli, ["serve", *args])
        assert result.exit_code == 0, result.output
    assert len(served) == 2
    for call in served:
        assert (call["http"], call["h11_max_incomplete_event_size"], call["timeout_keep_alive"]) == ("h11", 32768, 5)
