"""``v3d users add|list|token|tokens|revoke|role|disable|enable``: the token printed alone on the last line
works against the API; the password from standard input or from a hidden prompt asked twice; tokens with
an id, a label and an expiry, revoked one by one; role changes; clear errors."""
from __future__ import annotations

from pathlib import Path

import pytest
from fastapi.testclient import TestClient
from typer.testing import CliRunner

import app.cli.users  # noqa: F401  # registers v3d users
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
    assert rows["cy"][1] == "admin" and rows["cy"][4] == "0" and rows["cy"][5] == "disabled"  # tokens revoked
    assert rows["dee"][1] == "annotator" and rows["dee"][4] == "2" and rows["dee"][5] == "active"


def test_errors_are_clear_and_change_nothing(url: str) -> None:
    assert _add(url, "eve", "annotator").exit_code == 0
    duplicate = _add(url, "eve", "admin")
    assert duplicate.exit_code == 2 and "Error: name: a user named 'eve' already exists" in duplicate.stderr
    role = _add(url, "fay", "boss")
    assert role.exit_code == 2 and "Error: role: unknown role 'boss'; one of annotator, reviewer, admin" in role.stderr
    missing = runner.invoke(cli, ["users", "token", "nobody", "--database-url", url])
    assert missing.exit_code == 2 and "user 'nobody' not found" in missing.stderr
    listed = runner.invoke(cli, ["users", "list", "--database-url", url]).stdout
    assert [line.split()[0] for line in listed.splitlines()[1:]] == ["eve"]


def test_tokens_are_labelled_listed_and_revoked_and_roles_change(url: str) -> None:
    assert _add(url, "gil", "annotator").exit_code == 0
    made = runner.invoke(cli, ["users", "token", "gil", "--label", "nightly CI", "--expires-days", "30",
                               "--database-url", url])
    assert made.exit_code == 0, made.output
    token = made.stdout.strip().splitlines()[-1]
    token_id = int(made.stdout.split("new API token ")[1].split()[0])
    assert "expires" in made.stdout and f"v3d users revoke gil {token_id}" in made.stdout
    listed = runner.invoke(cli, ["users", "tokens", "gil", "--database-url", url])
    assert listed.exit_code == 0 and token not in listed.stdout
    rows = [line.split() for line in listed.stdout.splitlines()[1:]]
    assert [(int(r[0]), r[-1]) for r in rows] == [(token_id - 1, "active"), (token_id, "active")]
    assert "nightly" in listed.stdout and "first" in listed.stdout
    with TestClient(create_app(Settings(database_url=url))) as client:
        assert client.get("/api/games", headers={"Authorization": f"Bearer {token}"}).status_code == 200
        assert runner.invoke(cli, ["users", "revoke", "gil", str(token_id), "--database-url", url]).exit_code == 0
        assert client.get("/api/games", headers={"Authorization": f"Bearer {token}"}).status_code == 401
        assert runner.invoke(cli, ["users", "role", "gil", "admin", "--database-url", url]).exit_code == 0
        first = runner.invoke(cli, ["users", "token", "gil", "--database-url", url]).stdout.strip().splitlines()[-1]
        assert client.get("/api/users", headers={"Authorization": f"Bearer {first}"}).status_code == 200
    assert runner.invoke(cli, ["users", "tokens", "gil", "--database-url", url]).stdout.splitlines()[2].split()[-1] \
        == "revoked"
    bad_role = runner.invoke(cli, ["users", "role", "gil", "boss", "--database-url", url])
    assert bad_role.exit_code == 2 and "Error: role: unknown role 'boss'" in bad_role.stderr
    bad_id = runner.invoke(cli, ["users", "revoke", "gil", "99999", "--database-url", url])
    assert bad_id.exit_code == 2 and "token 99999 not found" in bad_id.stderr
    bad_days = runner.invoke(cli, ["users", "token", "gil", "--expires-days", "0", "--database-url", url])
    assert bad_days.exit_code == 2 and "expires_days" in bad_days.stderr


def test_reserved_names_and_names_differing_only_by_case_or_dots_are_refused(url: str) -> None:
    """Was: ``v3d users add none`` (or ``me``, or ``Eve`` beside ``eve``) made the user: the assignee filter's words
    and look-alike names are no user's name; exit 2 naming why, nothing stored."""
    assert _add(url, "eve", "annotator").exit_code == 0
    for name, why in (("none", "'none' is reserved"), ("Me.", "'Me.' is reserved"),
                      ("Eve", "a user named 'eve' exists: names that differ only by case or trailing dots"),
                      ("eve..", "a user named 'eve' exists")):
        refused = _add(url, name, "annotator")
        assert refused.exit_code == 2 and f"Error: name: {why}" in refused.stderr, (name, refused.stderr)
    listed = runner.invoke(cli, ["users", "list", "--database-url", url]).stdout
    assert [line.split()[0] for line in listed.splitlines()[1:]] == ["eve"]
