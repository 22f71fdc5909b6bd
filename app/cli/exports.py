"""``v3d export <format>`` of every registered export format that no module gives a command of its own: a new format
needs only its registry entry and its writer (``app.services.exports.formats``). The command writes the export as an
export job writes it (a zip, unpacked under ``OUT_DIR``: the same files as a download) and prints its counts."""
from __future__ import annotations

import json
from pathlib import Path
from typing import Annotated, Optional

import typer

from app.cli._root import export_cli
from app.cli.datasets import DatabaseOpt, cli_settings, exported_remotely, release_tree, zip_tree
from app.services.exports.formats import export_format, export_names


def generic_export_command(name: str, app: typer.Typer = export_cli) -> None:
    """Register ``v3d export <name>`` on ``app``, its help the registry's description of the format: ``OUT_DIR``,
    ``--all``, ``--release NAME`` (exclusive with ``--all``) and ``--database-url``."""
    images = bool(export_format(name).choices[0].options.get("images", True))  # the format's default choice

    def command(
        out_dir: Annotated[Path, typer.Argument(help="Destination folder (created if missing).")],
        include_all: Annotated[bool, typer.Option("--all", help="Every system, not only the accepted ones.")] = False,
        release: Annotated[Optional[str], typer.Option("--release", help="Export this release instead of the "
                                                       "database now (the same files every time).")] = None,
        database_url: DatabaseOpt = None,
    ) -> None:
        if exported_remotely(name, out_dir, include_all, images, release):
            return
        settings = cli_settings(database_url, None)
        if release is not None:
            written = release_tree(settings, out_dir, release, include_all, images, name)
        else:
            written = zip_tree(settings, out_dir, name, include_all, images, None)
        typer.echo(f"exported {name} to {out_dir}: {json.dumps(written, sort_keys=True)}")

    app.command(name, help=export_format(name).describes)(command)


def register_remaining_exports(app: typer.Typer = export_cli) -> list[str]:
    """Give each registered format without a command on ``app`` the generic one (after every module registered its
    own); the names given, in the registry's order."""
    taken = {c.name for c in app.registered_commands}
    missing = [name for name in export_names() if name not in taken]
    for name in missing:
        generic_export_command(name, app)
    return missing
