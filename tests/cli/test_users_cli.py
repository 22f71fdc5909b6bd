"""``v3d users add|list|token|disable|enable``: the token printed alone on the last line works against
the API; the password from standard input or from a hidden prompt asked twice; clear errors."""
from __future__ import annotations

from pathlib import Path

import pytest
from fastapi.testclient import TestClient
from typer.testing import CliRunner

import app.cli.users  # noqa: F401  (registers v3d users)
from app.cli._root import cli
from app.core.config import Settings
from app.main import create_app

runner = CliRunner()


@pytest.fixture
def url(tmp_path: Path) -> str:
    return f"sqlite:///{tmp_path / 'users.sqlite3'}"


def _add(url: str, name: str, role: str, password: str = "pw one") -> object:
    return runner.invoke(cli, ["users", "add", name, "--role", role, "--password-stdin", "--database-url", url],
                         input=f"{password}\n")


def test_add_prints_a_token_on_the_last_line_that_works_against_the_api(url: str) -> None:
    result = _add(url, "ana", "reviewer", "my browser password")
    assert result.exit_code == 0, result.output
    token = result.stdout.strip().splitlines()[-1]
    assert token.startswith("v3d_") and " " not in token
    with TestClient(create_app(Settings(database_url=url))) as client:
        me = client.get("/api/auth/me", headers={"Authorization": f"Bearer {token}"})
        assert me.json() == {"name": "ana", "role": "reviewer", "roles": ["annotator", "reviewer"], "via": "token",
                             "csrf_token": None}
        assert client.get("/api/games", headers={"Authorization": f"Bearer {token}x"}).status_code == 401
        login = client.post("/api/auth/login", json={"name": "ana", "password": "my browser password"})
        assert login.status_code == 200  # the password read from standard input is the browser's


def test_without_password_stdin_the_password_is_prompted_twice(url: str) -> None:
    args = ["users", "add", "bo", "--role", "annotator", "--database-url", url]
    mismatch = runner.invoke(cli, args, input="one\ntwo\n")
    assert mismatch.exit_code != 0 and "do not match" in mismatch.output.lower()
    result = runner.invoke(cli, args, input="same\nsame\n")
    assert result.exit_code == 0, result.output
    assert "same" not in result.output  # hidden input is not echoed
    assert result.stdout.strip().splitlines()[-1].startswith("v3d_")


def test_list_token_and_disable(url: str) -> None:
    assert _add(url, "cy", "admin").exit_code == 0
    assert _add(url, "dee", "annotator").exit_code == 0
    again = runner.invoke(cli, ["users", "token", "dee", "--database-url", url])
    assert again.exit_code == 0 and again.stdout.strip().splitlines()[-1].startswith("v3d_")
    assert runner.invoke(cli, ["users", "disable", "cy", "--database-url", url]).exit_code == 0
    listed = runner.invoke(cli, ["users", "list", "--database-url", url])
    assert listed.exit_code == 0
    rows = {line.split()[0]: line.split() for line in listed.stdout.splitlines()[1:]}
    assert rows["cy"][1] == "admin" and rows["cy"][4] == "1" and rows["cy"][5] == "disabled"
    assert rows["dee"][1] == "annotator" and rows["dee"][4] == "2" and rows["dee"][5] == "active"


def test_errors_are_clear_and_change_nothing(url: str) -> None:
    assert _add(url, "eve", "annotator").exit_code == 0
    duplicate = _add(url, "eve", "admin")
    assert duplicate.exit_code == 2 and "error: name: a user named 'eve' already exists" in duplicate.stderr
    role = _add(url, "fay", "boss")
    assert role.exit_code == 2 and "error: role: unknown role 'boss'; one of annotator, reviewer, admin" in role.stderr
    missing = runner.invoke(cli, ["users", "token", "nobody", "--database-url", url])
    assert missing.exit_code == 2 and "user 'nobody' not found" in missing.stderr
    listed = runner.invoke(cli, ["users", "list", "--database-url", url]).stdout
    assert [line.split()[0] for line in listed.splitlines()[1:]] == ["eve"]
