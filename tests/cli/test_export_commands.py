"""``v3d export`` has one command per registered export format (app.services.exports.formats), each
with the registry's description as its help."""
from __future__ import annotations

from app.cli import datasets, detectors  # noqa: F401  (each registers its export commands)
from app.cli._root import export_cli
from app.services.exports.formats import export_format, export_names


def test_every_export_format_has_its_command_and_nothing_else() -> None:
    commands = {c.name: c for c in export_cli.registered_commands}
    assert sorted(commands) == sorted(export_names())
    for name, command in commands.items():
        assert command.help == export_format(name).describes
