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


@cli.callback()
def root(server: Annotated[Optional[str], typer.Option(
        "--server", envvar="V3D_URL", metavar="URL",
        help="Run the command on this v3d server through its REST API (with the API token V3D_TOKEN) instead of on "
             "the local database: import soccernet-v3 / predictions, export, release, users list / add / disable, "
             "jobs list / wait, stats.")] = None) -> None:
    """v3d: multi-view soccer annotations to reviewed 3D ball labels (SoccerNet-v3D)."""
    from app.cli.remote import use_server

    use_server(server)
