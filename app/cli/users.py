"""``v3d users ...``: the people who may log in and their API tokens (``app.services.accounts.users``).

Run by whoever owns the machine: no token needed (``list``, ``add`` and ``disable`` also run on a server through its
API with ``--server`` and an admin's ``V3D_TOKEN``), the database is ``V3D_DATABASE_URL`` (or
``--database-url``), migrated first. ``add`` and ``token`` print the new API token alone on the last
line of standard output (``token`` prints its id on the line before)
(``TOKEN=$(v3d users add ana --role annotator --password-stdin <pw | tail -n1)``); the token is shown only then. Errors
print ``Error: ...`` and exit with status 2, changing nothing.
"""
from __future__ import annotations

import sys
from typing import Annotated, Any, Optional

import typer

from app.cli._root import cli
from app.cli.datasets import DatabaseOpt, cli_settings, database_session
from app.cli.errors import fail
from app.cli.remote import remote_client
from app.core.errors import InvalidInputError, NotFoundError

users_cli = typer.Typer(help="Users, roles and API tokens.", no_args_is_help=True)
cli.add_typer(users_cli, name="users")



def _read_password(from_stdin: bool) -> str:
    if from_stdin:
        return sys.stdin.readline().rstrip("\r\n")
    return typer.prompt("Password", hide_input=True, confirmation_prompt=True)


@users_cli.command("add")
def add_cmd(
    name: Annotated[str, typer.Argument(help="Login name (letters, digits, . _ @ -).")],
    role: Annotated[str, typer.Option("--role", help="annotator, reviewer or admin.")],
    password_stdin: Annotated[bool, typer.Option(
        "--password-stdin", help="Read the browser password from standard input's first line.")] = False,
    database_url: DatabaseOpt = None,
) -> None:
    """Add a user; prints its first API token alone on the last line."""
    with remote_client() as client:
        if client is not None:
            made = client.add_user(name, role, _read_password(password_stdin))
            typer.echo(f"added {made.name} ({role}); API token (shown once, send it as Authorization: Bearer):")
            typer.echo(made.token)
            return
    from app.services.accounts.users import check_new_user, create_user

    settings = cli_settings(database_url, None)
    with database_session(settings) as session:
        try:
            check_new_user(session, name, role)  # before asking for a password
            user, token = create_user(session, name, role, _read_password(password_stdin))
        except InvalidInputError as exc:
            raise fail(str(exc)) from None
    typer.echo(f"added {user.name} ({user.role.value}); API token (shown once, send it as Authorization: Bearer):")
    typer.echo(token)


@users_cli.command("token")
def token_cmd(
    name: Annotated[str, typer.Argument(help="An existing user.")],
    label: Annotated[Optional[str], typer.Option("--label", help="What the token is for (listed with it).")] = None,
    expires_days: Annotated[Optional[float], typer.Option("--expires-days", help="The token stops working this "
                                                          "many days from now (default: until revoked).")] = None,
    database_url: DatabaseOpt = None,
) -> None:
    """Issue another API token to a user; prints its id, then the token alone on the last line."""
    from app.services.accounts.users import issue_token

    with database_session(cli_settings(database_url, None)) as session:
        try:
            issued = issue_token(session, name, label=label, expires_days=expires_days)
        except (NotFoundError, InvalidInputError) as exc:
            raise fail(str(exc)) from None
    expiry = f", expires {issued.expires_at:%Y-%m-%d %H:%M} UTC" if issued.expires_at else ""
    typer.echo(f"new API token {issued.id} of {name}{expiry} (shown once; revoke it with "
               f"`v3d users revoke {name} {issued.id}`):")
    typer.echo(issued.token)


@users_cli.command("tokens")
def tokens_cmd(name: Annotated[str, typer.Argument(help="An existing user.")],
               database_url: DatabaseOpt = None) -> None:
    """List a user's API tokens: id, label, created, last used, expiry (UTC), state. Never the tokens."""
    from app.services.accounts.users import list_tokens

    with database_session(cli_settings(database_url, None)) as session:
        try:
            rows = list_tokens(session, name)
        except NotFoundError as exc:
            raise fail(str(exc)) from None

    def when(t):
        return f"{t:%Y-%m-%d %H:%M}" if t else "-"

    typer.echo(f"{'id':>6}  {'label':<24} {'created':<16} {'last used':<16} {'expires':<16} state")
    for t in rows:
        typer.echo(f"{t.id:>6}  {(t.label or '-'):<24} {when(t.created_at):<16} {when(t.last_used_at):<16} "
                   f"{when(t.expires_at):<16} {t.state}")


@users_cli.command("revoke")
def revoke_cmd(name: Annotated[str, typer.Argument(help="The token's user.")],
               token_id: Annotated[int, typer.Argument(help="The token's id (v3d users tokens NAME).")],
               database_url: DatabaseOpt = None) -> None:
    """Revoke one API token: it stops working at once, for good."""
    from app.services.accounts.users import revoke_token

    with database_session(cli_settings(database_url, None)) as session:
        try:
            revoke_token(session, name, token_id)
        except NotFoundError as exc:
            raise fail(str(exc)) from None
    typer.echo(f"token {token_id} of {name}: revoked")


@users_cli.command("role")
def role_cmd(name: Annotated[str, typer.Argument(help="An existing user.")],
             role: Annotated[str, typer.Argument(help="annotator, reviewer or admin.")],
             database_url: DatabaseOpt = None) -> None:
    """Give a user another role (its sessions and tokens carry it from their next request)."""
    from app.services.accounts.users import set_role

    with database_session(cli_settings(database_url, None)) as session:
        try:
            set_role(session, name, role)
        except (NotFoundError, InvalidInputError) as exc:
            raise fail(str(exc)) from None
    typer.echo(f"{name}: role {role}")


@users_cli.command("list")
def list_cmd(database_url: DatabaseOpt = None) -> None:
    """List the users: name, role, created (UTC), number of API tokens, state."""
    from app.services.accounts.users import list_users

    with remote_client() as client:
        rows: list[Any] = client.users() if client is not None else []
    if client is None:
        with database_session(cli_settings(database_url, None)) as session:
            rows = list_users(session)
    typer.echo(f"{'name':<24} {'role':<10} {'created (UTC)':<17} {'tokens':>6}  state")
    for u in rows:
        state = ", ".join(s for s, on in (("disabled", u.disabled), ("demo account", u.demo)) if on) or "active"
        typer.echo(f"{u.name:<24} {u.role:<10} {u.created_at:%Y-%m-%d %H:%M} {u.tokens:>6}  {state}")


def _set_disabled(name: str, disabled: bool, database_url: str | None) -> None:
    from app.services.accounts.users import set_disabled

    with remote_client() as client:
        if client is not None:
            client.update_user(name, disabled=disabled)
    if client is None:
        with database_session(cli_settings(database_url, None)) as session:
            try:
                set_disabled(session, name, disabled)
            except NotFoundError as exc:
                raise fail(str(exc)) from None
    done = ("disabled (sessions end; every API token revoked for good)" if disabled
            else "enabled (log in again; issue a new token with v3d users token)")
    typer.echo(f"{name}: {done}")


@users_cli.command("disable")
def disable_cmd(name: Annotated[str, typer.Argument(help="An existing user.")],
                database_url: DatabaseOpt = None) -> None:
    """Disable a user: no login, its sessions end and every API token it holds is revoked for good."""
    _set_disabled(name, True, database_url)


@users_cli.command("enable")
def enable_cmd(name: Annotated[str, typer.Argument(help="A disabled user.")], database_url: DatabaseOpt = None) -> None:
    """Enable a disabled user again: it logs in anew; its revoked tokens stay revoked."""
    _set_disabled(name, False, database_url)
