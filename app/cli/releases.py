"""``v3d release create|list|show|diff|export``: thin wrappers over ``app.services.releases`` (a release of the
accepted systems as they are now, immutable; the releases; one release; what changed between two; a release's
export). Run by the machine's owner: the audit names the OS account; with ``--server``, through that server's API
(``app.cli.remote``). A name taken or unknown prints ``Error: ...`` and exits 2."""
from __future__ import annotations

import json
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Any, Literal

import typer

from app.cli._root import cli
from app.cli.datasets import DatabaseOpt, cli_settings, database_session, exported_remotely, release_tree
from app.cli.errors import fail
from app.cli.remote import remote_client
from app.core.errors import ConflictError, InvalidInputError, NotFoundError
from app.services.exports.formats import export_format, export_names

if TYPE_CHECKING:  # mypy cannot build a Literal from values computed at import
    ExportName = str
    from v3d_client import Release
else:
    ExportName = Literal[tuple(export_names())]

release_cli = typer.Typer(help="Named, immutable releases of the accepted systems, and what changed between two.",
                          no_args_is_help=True)
cli.add_typer(release_cli, name="release")


def _summary(release: "Release") -> dict[str, Any]:
    """A release read from a server as the local commands print it (:func:`_local_summary`'s keys)."""
    return release.model_dump(mode="json", include={"name", "note", "created_at", "created_by", "systems", "views",
                                                    "hash", "without_ball3d"})


def _local_summary(session: Any, release: Any) -> dict[str, Any]:
    """A release of this database as the commands print it: ``content.release_summary`` and how many of its systems
    were accepted with no 3D ball (``without_ball3d``), as the API answers it."""
    from app.services.releases.content import release_summary, systems_without_ball

    return {**release_summary(release), "without_ball3d": systems_without_ball(session, release)}



@release_cli.command("create")
def create_cmd(name: Annotated[str, typer.Argument(help="The release's name (unique).")],
               note: Annotated[str, typer.Option("--note", help="Free text kept with it.")] = "",
               database_url: DatabaseOpt = None) -> None:
    """Make a release of the accepted systems as they are now; prints it as JSON (its hash included)."""
    with remote_client() as client:
        if client is not None:
            typer.echo(json.dumps(_summary(client.create_release(name, note)), indent=2))
            return
    from app.services.releases.content import create_release

    settings = cli_settings(database_url, None)
    with database_session(settings) as session:
        try:
            release = create_release(session, name, note, settings=settings)
        except (ConflictError, InvalidInputError) as exc:
            raise fail(str(exc)) from None
        typer.echo(json.dumps(_local_summary(session, release), indent=2))


@release_cli.command("list")
def list_cmd(database_url: DatabaseOpt = None) -> None:
    """Every release, oldest first: name, created_at, systems, views, hash."""
    from app.services.releases.content import list_releases

    with remote_client() as client:
        if client is not None:
            for made in client.releases():
                typer.echo(f"{made.name}\t{made.created_at.isoformat()}\t{made.systems} systems\t{made.views} views\t"
                           f"{made.hash}")
            return
    with database_session(cli_settings(database_url, None)) as session:
        for r in list_releases(session):
            typer.echo(f"{r.name}\t{r.created_at.isoformat()}\t{r.systems} systems\t{r.views} views\t{r.hash}")


@release_cli.command("show")
def show_cmd(name: Annotated[str, typer.Argument(help="The release's name.")],
             database_url: DatabaseOpt = None) -> None:
    """One release as JSON."""
    with remote_client() as client:
        if client is not None:
            typer.echo(json.dumps(_summary(client.release(name)), indent=2))
            return
    from app.services.releases.content import get_release

    with database_session(cli_settings(database_url, None)) as session:
        try:
            typer.echo(json.dumps(_local_summary(session, get_release(session, name)), indent=2))
        except NotFoundError as exc:
            raise fail(str(exc)) from None


@release_cli.command("diff")
def diff_cmd(a: Annotated[str, typer.Argument(help="The older release.")],
             b: Annotated[str, typer.Argument(help="The newer release.")],
             as_csv: Annotated[bool, typer.Option("--csv", help="CSV instead of JSON.")] = False,
             database_url: DatabaseOpt = None) -> None:
    """What changed from release A to release B: systems added, removed and changed (how far the 3D ball moved,
    what changed per view)."""
    from app.services.releases.diff import diff_csv, diff_releases

    with remote_client() as client:
        if client is not None:
            if as_csv:
                typer.echo(client.release_diff_csv(a, b), nl=False)
            else:
                typer.echo(json.dumps(client.release_diff(a, b).model_dump(mode="json", by_alias=True), indent=2))
            return
    with database_session(cli_settings(database_url, None)) as session:
        try:
            result = diff_releases(session, a, b)
        except NotFoundError as exc:
            raise fail(str(exc)) from None
        typer.echo(diff_csv(result) if as_csv else json.dumps(result.as_dict(), indent=2), nl=not as_csv)


@release_cli.command("export")
def export_cmd(name: Annotated[str, typer.Argument(help="The release's name.")],
               fmt: Annotated[ExportName, typer.Argument(metavar="FORMAT", help="soccernet-v3d, cameras, yolo, coco or "
                                                                               "issia-3d.")],
               out_dir: Annotated[Path, typer.Argument(metavar="OUT", help="Destination folder (created if missing).")],
               no_images: Annotated[bool, typer.Option("--no-images", help="soccernet-v3d: leave out each game's "
                                                                          "Frames-v3.zip.")] = False,
               database_url: DatabaseOpt = None) -> None:
    """Export a release in FORMAT under OUT: the files its export job writes, the same every time (as ``v3d export
    FORMAT OUT --release NAME``)."""
    images = not no_images and bool(export_format(fmt).choices[0].options.get("images", True))
    if exported_remotely(fmt, out_dir, False, images, name):
        return
    written = release_tree(cli_settings(database_url, None), out_dir, name, False, images, fmt)
    typer.echo(f"exported {fmt} of release {name} to {out_dir}: {json.dumps(written, sort_keys=True)}")
