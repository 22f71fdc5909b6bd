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


def test_a_format_without_a_command_of_its_own_gets_the_registrys(tmp_path) -> None:
    """A format registered with its writer alone is exported by ``v3d export <name>``: the export job's zip unpacked
    into the folder, its counts printed; the formats with a command of their own keep it."""
    import json

    import typer
    from typer.testing import CliRunner

    from app.cli.exports import register_remaining_exports
    from app.services.exports import formats
    from app.services.exports.formats import ExportChoice, ExportFormat, register_export_format

    fmt = ExportFormat("cameras-again", "The cameras, once more.",
                       (ExportChoice("cameras-again", "Again", "the cameras", "again.zip"),),
                       tree=export_format("cameras").tree)
    register_export_format(fmt)
    try:
        app = typer.Typer()
        app.command("cameras")(lambda: None)  # a command of its own
        assert register_remaining_exports(app) == [n for n in export_names() if n != "cameras"]
        helps = {c.name: c.help for c in app.registered_commands}
        assert helps["cameras-again"] == "The cameras, once more."
        url = f"sqlite:///{tmp_path / 'v3d.db'}"
        res = CliRunner().invoke(app, ["cameras-again", str(tmp_path / "out"), "--all", "--database-url", url])
        assert res.exit_code == 0, res.output
        printed = json.loads(res.output.split(": ", 1)[1])
        assert printed["format"] == "cameras-again" and printed["cameras"] == 0
        assert (tmp_path / "out" / "cameras.json").is_file()
        both = CliRunner().invoke(app, ["cameras-again", str(tmp_path / "o2"), "--all", "--release", "r1",
                                        "--database-url", url])
        assert both.exit_code == 2 and "--all and --release exclude each other" in both.output
    finally:
        formats._FORMATS.pop("cameras-again", None)
    assert "cameras-again" not in export_names()
