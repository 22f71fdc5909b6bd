"""The Typer application objects every CLI module registers its commands on.

Kept apart from ``app/cli/__init__.py`` so that command modules can import them without a cycle.
"""
from __future__ import annotations

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
