"""``v3d import predictions FILE [--source NAME]`` and ``v3d predictions list|remove``: a ball detector's predictions
(thin wrappers over ``app.services.transfer.predictions``). The import is a job run here to completion (its
progress drawn), the systems it touches recomputed (their doubts stored) before the command exits; a malformed
file prints ``Error: <file>: line <n> ...: <problem>`` and exits 2 with nothing stored.
"""
from __future__ import annotations

from pathlib import Path
from typing import Annotated, Any, Optional

import typer

from app.cli._root import cli, import_cli
from app.cli.datasets import DatabaseOpt, cli_settings, database_session, run_job_here
from app.cli.errors import fail
from app.cli.remote import remote_client, upload_and_wait
from app.services.jobs.work import import_params

predictions_cli = typer.Typer(help="A ball detector's stored predictions, by source.", no_args_is_help=True)
cli.add_typer(predictions_cli, name="predictions")


@import_cli.command("predictions")
def import_predictions_cmd(
    path: Annotated[Path, typer.Argument(help="A CSV league,season,match,image,x1,y1,x2,y2,score (pixels of the "
                                              "image, top-left origin), one row per detection.")],
    source: Annotated[Optional[str], typer.Option(help="The detector's name (default: the file's stem); importing "
                                                       "it again replaces its predictions.")] = None,
    database_url: DatabaseOpt = None,
) -> None:
    """Import a ball detector's predictions; the systems they touch get their doubts recomputed. With --server: the
    file is uploaded and imported there."""
    with remote_client() as client:
        if client is not None:
            job = upload_and_wait(client, path, "predictions", source=source)
            _print_report(job.id, job.result or {})
            return
    settings = cli_settings(database_url, None)
    _print_report(*run_job_here(settings, "import", import_params("predictions", path, source=source)))


def _print_report(job_id: int, r: dict[str, Any]) -> None:
    """The counts of the predictions' import job ``job_id`` (its result ``r``), run here or on a server."""
    typer.echo(f"imported {r['stored']} prediction(s) of source {r['source']!r} from {r['rows']} row(s) on "
               f"{r['frames']} frame(s) of {r['systems']} system(s) ({r['replaced']} earlier one(s) replaced, "
               f"{r['clipped']} box(es) clipped to their image) in {r['seconds']:.1f} s (job {job_id})")
    if r.get("dropped"):
        typer.echo(f"{r['dropped']} prediction(s) left out: beyond {r['cap']} a frame (V3D_MAX_PREDICTIONS_PER_FRAME, "
                   "all sources together; the best by score are kept)")
    if r["unknown"]:
        typer.echo(f"{r['unknown']} row(s) name an image v3d does not hold, e.g.:")
        for name in r["unknown_images"]:
            typer.echo(f"  unknown: {name}")


@predictions_cli.command("list")
def list_cmd(database_url: DatabaseOpt = None) -> None:
    """Every stored source: its predictions, the frames they lie on, when imported."""
    from app.services.transfer.predictions import prediction_sources

    settings = cli_settings(database_url, None)
    with database_session(settings) as session:
        sources = prediction_sources(session)
    if not sources:
        typer.echo("no predictions stored")
    for s in sources:
        typer.echo(f"{s['source']}: {s['predictions']} prediction(s) on {s['frames']} frame(s), imported "
                   f"{s['imported_at']}")


@predictions_cli.command("remove")
def remove_cmd(
    source: Annotated[str, typer.Argument(help="The source to remove.")],
    database_url: DatabaseOpt = None,
) -> None:
    """Delete a source's predictions (labels placed from them stay) and recompute the systems they touched."""
    from app.services.transfer.predictions import remove_predictions

    settings = cli_settings(database_url, None)
    with database_session(settings) as session:
        n = remove_predictions(session, settings, source)
    if not n:
        raise fail(f"no predictions of source {source!r}")
    typer.echo(f"removed {n} prediction(s) of source {source!r}")
