"""``v3d batches create|show|accept|undo``: thin wrappers over ``app.services.curation.batches`` (the pending vouched
systems of a queue accepted after a random sample). With ``--server``, through that server's API (``app.cli.remote``,
the caller's token: reviewers); without, on the local database as the machine's account. Each prints the batch (or
the accept's or undo's answer) as JSON; a refusal (a system that stops the batch, named by id) prints ``Error: ...``
and exits 2."""
from __future__ import annotations

import dataclasses
import json
from datetime import datetime
from typing import Annotated, Any, Optional

import typer

from app.cli._root import cli
from app.cli.datasets import DatabaseOpt, cli_settings, database_session
from app.cli.errors import fail
from app.cli.remote import remote_client
from app.core.errors import ConflictError, InvalidInputError, NotFoundError

batches_cli = typer.Typer(help="Accept the pending vouched systems of a queue after a random sample a person reviews.",
                          no_args_is_help=True)
cli.add_typer(batches_cli, name="batches")

BatchId = Annotated[int, typer.Argument(help="The batch's id.", min=1)]


def _print(answer: dict[str, Any]) -> None:
    typer.echo(json.dumps(answer, indent=2, default=str))


def _local_batch(session: Any, batch: Any) -> dict[str, Any]:
    """A batch of this database as the API answers it (``batches.batch_facts``, times in ISO 8601)."""
    from app.services.curation import batches

    return {k: v.isoformat() if isinstance(v, datetime) else v for k, v in batches.batch_facts(session, batch).items()}


@batches_cli.command("create")
def create_cmd(
    confidence: Annotated[float, typer.Option("--confidence", help="How sure, when no sampled system is wrong, that "
                                                                  "at most --max-wrong-share of the batch is (0.95).")
                          ] = 0.95,
    max_wrong_share: Annotated[float, typer.Option("--max-wrong-share", help="The largest share of wrong systems "
                                                                             "tolerated (0.05).")] = 0.05,
    game_id: Annotated[Optional[int], typer.Option("--game-id", help="Only this game's systems.")] = None,
    doubt: Annotated[Optional[str], typer.Option("--doubt", help="The queue's doubt filter (a kind, any, none).")
                     ] = None,
    assignee: Annotated[Optional[str], typer.Option("--assignee", help="Only systems assigned to this user (none: "
                                                                       "unassigned).")] = None,
    sigma_max: Annotated[Optional[float], typer.Option("--sigma-max", help="The 3D ball's sigma at most this (m).")
                         ] = None,
    error_max: Annotated[Optional[float], typer.Option("--error-max", help="Worst reprojection error at most this "
                                                                           "(px).")] = None,
    jac_min: Annotated[Optional[float], typer.Option("--jac-min", help="Lowest JaC@0.5% at least this.")] = None,
    database_url: DatabaseOpt = None,
) -> None:
    """Make a batch of the pending systems whose ball is vouched for that the filters select, with the server's
    random sample of the zero-acceptance plan's size and the plan in words; prints it."""
    filters = {"game_id": game_id, "doubt": doubt, "assignee": assignee, "sigma_max": sigma_max,
               "error_max": error_max, "jac_min": jac_min}
    with remote_client() as client:
        if client is not None:
            _print(client.create_batch(confidence=confidence, max_wrong_share=max_wrong_share, **filters)
                   .model_dump(mode="json"))
            return
    from app.services.audit.log import local_actor
    from app.services.curation import batches
    from app.services.curation.queue import SystemFilters

    query = SystemFilters(game_id=game_id, doubt=doubt, assignee=assignee, sigma_max=sigma_max, error_max=error_max,
                          jac_min=jac_min)
    with database_session(cli_settings(database_url, None)) as session:
        try:
            batch = batches.create_batch(session, local_actor(), query, confidence, max_wrong_share)
        except InvalidInputError as exc:
            raise fail(str(exc)) from None
        _print(_local_batch(session, batch))


@batches_cli.command("show")
def show_cmd(batch_id: BatchId, database_url: DatabaseOpt = None) -> None:
    """One batch: its systems, sample, plan, state and, while open, what stops its accept now."""
    with remote_client() as client:
        if client is not None:
            _print(client.batch(batch_id).model_dump(mode="json"))
            return
    from app.services.curation import batches

    with database_session(cli_settings(database_url, None)) as session:
        try:
            _print(_local_batch(session, batches.get_batch(session, batch_id)))
        except NotFoundError as exc:
            raise fail(str(exc)) from None


@batches_cli.command("accept")
def accept_cmd(batch_id: BatchId, database_url: DatabaseOpt = None) -> None:
    """Accept the batch's unsampled systems once a person accepted every sampled one and nothing else changed;
    otherwise exits 2 naming each system that stops it."""
    with remote_client() as client:
        if client is not None:
            _print(client.accept_batch(batch_id).model_dump(mode="json"))
            return
    from app.services.curation import batches

    with database_session(cli_settings(database_url, None)) as session:
        try:
            _print({"accepted": batches.accept_batch(session, batch_id, None)})
        except (ConflictError, NotFoundError) as exc:
            raise fail(str(exc)) from None


@batches_cli.command("undo")
def undo_cmd(batch_id: BatchId, database_url: DatabaseOpt = None) -> None:
    """Put the systems the batch accepted back to pending (those a person decided since are kept)."""
    with remote_client() as client:
        if client is not None:
            _print(client.undo_batch(batch_id).model_dump(mode="json"))
            return
    from app.services.curation import batches

    with database_session(cli_settings(database_url, None)) as session:
        try:
            undone = batches.undo_batch(session, batch_id, None)
            _print({"undone": undone.undone, "kept": [dataclasses.asdict(s) for s in undone.kept]})
        except (ConflictError, NotFoundError) as exc:
            raise fail(str(exc)) from None
