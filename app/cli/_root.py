"""The Typer application objects every CLI module registers its commands on.

Kept apart from ``app/cli/__init__.py`` so that command modules can import them without a cycle.
"""
from __future__ import annotations

from typing import Annotated, Optional

import typer

cli = typer.Typer(
    name="v3d",
    help="v3d: multi-view soccer annotations to reviewed 3D ball labels (SoccerNet-v3D).",
    no_args_is_help=True,
    add_completion=False,
)
import_cli = typer.Typer(help="Import datasets into the database.", no_args_is_help=True)
export_cli = typer.Typer(help="Export reviewed labels from the database.", no_args_is_help=True)
cli.add_typer(import_cli, name="import")
cli.add_typer(export_cli, name="export")


def fail(message: str, code: int = 2) -> typer.Exit:
    """Print ``Error: <message>`` on standard error and return the exit to raise with status ``code`` (2: the input
    or the request is refused, 1: the work failed). Click prints its own refusals of options and arguments with that
    prefix, so that every refusal of ``v3d`` reads alike and a script can grep one word for it."""
    typer.echo(f"Error: {message}", err=True)
    return typer.Exit(code=code)


@cli.callback()
def root(server: Annotated[Optional[str], typer.Option(
        "--server", envvar="V3D_URL", metavar="URL",
        help="Run the command on this v3d server through its REST API (with the API token V3D_TOKEN) instead of on "
             "the local database: import soccernet-v3 / predictions, export, release, users list / add / disable, "
             "jobs list / wait, stats.")] = None) -> None:
    """v3d: multi-view soccer annotations to reviewed 3D ball labels (SoccerNet-v3D)."""
    from app.cli.remote import use_server

    use_server(server)
