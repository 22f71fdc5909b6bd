"""``v3d users ...``: the people who may log in and their API tokens (``app.services.accounts.users``).

Run by whoever owns the machine: no token needed, the database is ``V3D_DATABASE_URL`` (or
``--database-url``), migrated first. ``add`` and ``token`` print the new API token alone on the last
line of standard output (``TOKEN=$(v3d users add ana --role annotator --password-stdin <pw | tail -n1)``);
the token is shown only then. Errors print ``error: ...`` and exit with status 2, changing nothing.
"""
from __future__ import annotations

import sys
from typing import Annotated

import typer

from app.cli._root import cli
from app.cli.datasets import DatabaseOpt, cli_settings, database_session
from app.core.errors import InvalidInputError, NotFoundError

users_cli = typer.Typer(help="Users, roles and API tokens.", no_args_is_help=True)
cli.add_typer(users_cli, name="users")


def _fail(exc: Exception) -> typer.Exit:
    typer.echo(f"error: {exc}", err=True)
    return typer.Exit(code=2)


def _read_password(from_stdin: bool) -> str:
    if from_stdin:
        return sys.stdin.readline().rstrip("\r\n")
    return typer.prompt("Password", hide_input=True, confirmation_prompt=True)


@users_cli.command("add")
def add_cmd(
    name: Annotated[str, typer.Argument(help="Login name (letters, digits, . _ @ -).")],
    role: Annotated[str, typer.Option("--role", help="annotator, reviewer or admin.")],
    password_stdin: Annotated[bool, typer.Option("--password-stdin",
                                                 help="Read the browser password from standard input's first line.")] = False,
    database_url: DatabaseOpt = None,
) -> None:
    """Add a user; prints its first API token alone on the last line."""
    from app.services.accounts.users import check_new_user, create_user

    settings = cli_settings(database_url, None)
    with database_session(settings) as session:
        try:
            check_new_user(session, name, role)  # before asking for a password
            user, token = create_user(session, name, role, _read_password(password_stdin))
        except InvalidInputError as exc:
            raise _fail(exc) from None
    typer.echo(f"added {user.name} ({user.role.value}); API token (shown once, send it as Authorization: Bearer):")
    typer.echo(token)


@users_cli.command("token")
def token_cmd(name: Annotated[str, typer.Argument(help="An existing user.")], database_url: DatabaseOpt = None) -> None:
    """Issue another API token to a user; prints it alone on the last line."""
    from app.services.accounts.users import issue_token

    with database_session(cli_settings(database_url, None)) as session:
        try:
            token = issue_token(session, name)
        except NotFoundError as exc:
            raise _fail(exc) from None
    typer.echo(f"new API token of {name} (shown once):")
    typer.echo(token)


@users_cli.command("list")
def list_cmd(database_url: DatabaseOpt = None) -> None:
    """List the users: name, role, created (UTC), number of API tokens, state."""
    from app.services.accounts.users import list_users

    with database_session(cli_settings(database_url, None)) as session:
        rows = list_users(session)
    typer.echo(f"{'name':<24} {'role':<10} {'created (UTC)':<17} {'tokens':>6}  state")
    for u in rows:
        state = ", ".join(s for s, on in (("disabled", u.disabled), ("demo account", u.demo)) if on) or "active"
        typer.echo(f"{u.name:<24} {u.role:<10} {u.created_at:%Y-%m-%d %H:%M} {u.tokens:>6}  {state}")


def _set_disabled(name: str, disabled: bool, database_url: str | None) -> None:
    from app.services.accounts.users import set_disabled

    with database_session(cli_settings(database_url, None)) as session:
        try:
            set_disabled(session, name, disabled)
        except NotFoundError as exc:
            raise _fail(exc) from None
    typer.echo(f"{name}: {'disabled (sessions and tokens stop working)' if disabled else 'enabled'}")


@users_cli.command("disable")
def disable_cmd(name: Annotated[str, typer.Argument(help="An existing user.")], database_url: DatabaseOpt = None) -> None:
    """Disable a user: no login, and its sessions and tokens stop working at once."""
    _set_disabled(name, True, database_url)


@users_cli.command("enable")
def enable_cmd(name: Annotated[str, typer.Argument(help="A disabled user.")], database_url: DatabaseOpt = None) -> None:
    """Enable a disabled user again (its tokens work again; it logs in anew)."""
    _set_disabled(name, False, database_url)
