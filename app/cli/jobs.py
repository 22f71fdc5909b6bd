"""``v3d jobs list``, ``v3d jobs wait ID`` and ``v3d jobs run``: the background jobs of the database
(``app.services.jobs.runner``; ``list`` and ``wait`` also of a server, with ``--server``);
``v3d recompute``: the full recompute, a job run in this process with its progress.

``list`` prints the newest jobs with their state and progress; ``run`` runs the queued jobs (and the
ones a killed process left running) in this process until none is left, for a database served with
``V3D_JOB_RUNNER=false`` or by no server at all.
"""
from __future__ import annotations

import contextlib
from typing import Annotated, Any, Optional

import typer

from app.cli._root import cli
from app.cli.bars import StageBars
from app.cli.datasets import DatabaseOpt, cli_settings, run_job_here, session_factory
from app.cli.errors import fail
from app.cli.remote import remote_client

jobs_cli = typer.Typer(help="Background jobs: imports, full recomputes, exports.", no_args_is_help=True)
cli.add_typer(jobs_cli, name="jobs")


def _progress(stage: Optional[str], done: int, total: int) -> str:
    if not stage:
        return ""
    return f"{stage} {done}/{total}" if total else f"{stage} {done}"


@jobs_cli.command("list")
def list_cmd(
    state: Annotated[Optional[str],
                     typer.Option(help="Only jobs in this state: queued, running, done, failed.")] = None,
    limit: Annotated[int, typer.Option(min=1, max=500, help="How many (newest first).")] = 20,
    database_url: DatabaseOpt = None,
) -> None:
    """Print the newest jobs: id, kind, state, progress, what they run and, failed, why."""
    from app.db.models import JobState
    from app.services.jobs import runner as jobs

    try:
        wanted = JobState(state) if state else None
    except ValueError:
        raise fail(f"--state: unknown state {state!r} (queued, running, done, failed)") from None
    with remote_client() as client:
        if client is not None:
            page = client.job_page(state=state, limit=limit)
            for j in page.items:
                _echo_job(j.id, j.kind, j.state, "", j.stage, j.done, j.total, j.params, j.message)
            typer.echo(f"{len(page.items)} of {page.total} job(s)")
            return
    settings = cli_settings(database_url, None)
    with session_factory(settings) as factory, factory() as session:
        items, total = jobs.list_jobs(session, wanted, None, limit, 0)
        for job in items:
            stale = " (stale: its process is gone)" if jobs.is_stale(job, settings) else ""
            _echo_job(job.id, job.kind, job.state.value, stale, job.stage, job.done, job.total, job.params,
                      job.message)
    typer.echo(f"{len(items)} of {total} job(s)")


def _echo_job(job_id: int, kind: str, state: str, stale: str, stage: Optional[str], done: int, total: int,
              params: dict[str, Any], message: Optional[str]) -> None:
    """One line of ``jobs list`` (and the job's message under it)."""
    what = params.get("path") or params.get("name") or params.get("format") or ""
    line = f"{job_id:>5}  {kind:<9} {state:<8}{stale} {_progress(stage, done, total):<22} {what}"
    typer.echo(line.rstrip())
    if message:
        typer.echo(f"       {message}")


@jobs_cli.command("wait")
def wait_cmd(
    job_id: Annotated[int, typer.Argument(metavar="ID", help="The job's id (v3d jobs list).")],
    timeout: Annotated[Optional[float], typer.Option(min=0, help="Give up after this many seconds (exit 1).")] = None,
    database_url: DatabaseOpt = None,
) -> None:
    """Wait until a job is done, drawing its progress; prints its result as JSON. A failed job prints its message and
    exits 1 (2 when its input was invalid); a job not done within --timeout exits 1."""
    import json
    import time

    with remote_client() as client:
        if client is not None:
            stages = StageBars()
            try:
                done = client.wait(job_id, progress=stages.job, timeout_s=timeout)
            finally:
                stages.close()
            typer.echo(json.dumps(done.result, indent=2, sort_keys=True))
            return
    from app.core.errors import NotFoundError
    from app.db.models import JobState
    from app.services.jobs import runner as jobs

    settings = cli_settings(database_url, None)
    deadline = None if timeout is None else time.monotonic() + timeout
    bars = StageBars()
    try:
        with session_factory(settings) as factory:
            while True:
                with factory() as session:
                    try:
                        job = jobs.get_job(session, job_id)
                    except NotFoundError as exc:
                        raise fail(str(exc)) from None
                bars.job(job)
                if job.state in (JobState.DONE, JobState.FAILED):
                    break
                if deadline is not None and time.monotonic() >= deadline:
                    raise fail(f"job {job_id} is still {job.state.value} after {timeout:g} s", 1)
                time.sleep(0.5)  # a job's progress is written to its row about this often
    finally:
        bars.close()
    if job.state is JobState.FAILED:
        raise fail(str(job.message), 2 if (job.result or {}).get("invalid_input") else 1)
    typer.echo(json.dumps(job.result, indent=2, sort_keys=True))


@jobs_cli.command("run")
def run_cmd(database_url: DatabaseOpt = None) -> None:
    """Run queued jobs (and stale ones) in this process until none is left; prints each outcome."""
    from app.db.in_use import DatabaseInUse, using
    from app.services.jobs import runner as jobs

    settings = cli_settings(database_url, None)
    owner = jobs.owner_name(settings)
    with contextlib.ExitStack() as stack:
        try:  # the database's in-use lock while it runs jobs: `v3d restore` refuses meanwhile (app.db.in_use)
            stack.enter_context(using(settings.database_url, "jobs run"))
        except DatabaseInUse as exc:
            raise fail(str(exc)) from None
        factory = stack.enter_context(session_factory(settings))
        while (job_id := jobs.claim_next(factory, owner, settings)) is not None:
            job = jobs.run_job(factory, job_id, settings, owner)
            typer.echo(f"job {job.id} ({job.kind}): {job.state.value}" + (f": {job.message}" if job.message else ""))


@cli.command("recompute")
def recompute_cmd(database_url: DatabaseOpt = None) -> None:
    """Recompute every system with the current settings (calibrations untouched: admission, triangulation,
    reprojections, optimised boxes, mirror flags, doubts, queue figures), 500 systems a transaction, with
    progress; killed, the same command run again resumes the job. One audit entry."""
    settings = cli_settings(database_url, None)
    job_id, result = run_job_here(settings, "recompute", {})
    typer.echo(f"recomputed {result['systems']} system(s), {result['triangulated']} triangulated (job {job_id})")
