"""``v3d release create|list|show|diff``: thin wrappers over ``app.services.releases`` (a release of the accepted
systems as they are now, immutable; the releases; one release; what changed between two). Run by the machine's
owner: the audit names the OS account. A name taken or unknown prints ``error: ...`` and exits 2."""
from __future__ import annotations

import json
from typing import Annotated

import typer

from app.cli._root import cli
from app.cli.datasets import DatabaseOpt, cli_settings, database_session
from app.core.errors import ConflictError, InvalidInputError, NotFoundError

release_cli = typer.Typer(help="Named, immutable releases of the accepted systems, and what changed between two.",
                          no_args_is_help=True)
cli.add_typer(release_cli, name="release")


def _fail(exc: Exception) -> typer.Exit:
    typer.echo(f"error: {exc}", err=True)
    return typer.Exit(code=2)


@release_cli.command("create")
def create_cmd(name: Annotated[str, typer.Argument(help="The release's name (unique).")],
               note: Annotated[str, typer.Option("--note", help="Free text kept with it.")] = "",
               database_url: DatabaseOpt = None) -> None:
    """Make a release of the accepted systems as they are now; prints it as JSON (its hash included)."""
    from app.services.releases.content import create_release, release_summary

    settings = cli_settings(database_url, None)
    with database_session(settings) as session:
        try:
            release = create_release(session, name, note, settings=settings)
        except (ConflictError, InvalidInputError) as exc:
            raise _fail(exc) from None
        typer.echo(json.dumps(release_summary(release), indent=2))


@release_cli.command("list")
def list_cmd(database_url: DatabaseOpt = None) -> None:
    """Every release, oldest first: name, created_at, systems, views, hash."""
    from app.services.releases.content import list_releases

    with database_session(cli_settings(database_url, None)) as session:
        for r in list_releases(session):
            typer.echo(f"{r.name}\t{r.created_at.isoformat()}\t{r.systems} systems\t{r.views} views\t{r.hash}")


@release_cli.command("show")
def show_cmd(name: Annotated[str, typer.Argument(help="The release's name.")],
             database_url: DatabaseOpt = None) -> None:
    """One release as JSON."""
    from app.services.releases.content import get_release, release_summary

    with database_session(cli_settings(database_url, None)) as session:
        try:
            typer.echo(json.dumps(release_summary(get_release(session, name)), indent=2))
        except NotFoundError as exc:
            raise _fail(exc) from None


@release_cli.command("diff")
def diff_cmd(a: Annotated[str, typer.Argument(help="The older release.")],
             b: Annotated[str, typer.Argument(help="The newer release.")],
             as_csv: Annotated[bool, typer.Option("--csv", help="CSV instead of JSON.")] = False,
             database_url: DatabaseOpt = None) -> None:
    """What changed from release A to release B: systems added, removed and changed (how far the 3D ball moved,
    what changed per view)."""
    from app.services.releases.diff import diff_csv, diff_releases

    with database_session(cli_settings(database_url, None)) as session:
        try:
            result = diff_releases(session, a, b)
        except NotFoundError as exc:
            raise _fail(exc) from None
        typer.echo(diff_csv(result) if as_csv else json.dumps(result.as_dict(), indent=2), nl=not as_csv)
