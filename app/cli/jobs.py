"""``v3d jobs list`` and ``v3d jobs run``: the background jobs of the database (``app.services.jobs.runner``);
``v3d recompute``: the full recompute, a job run in this process with its progress.

``list`` prints the newest jobs with their state and progress; ``run`` runs the queued jobs (and the
ones a killed process left running) in this process until none is left, for a database served with
``V3D_JOB_RUNNER=false`` or by no server at all.
"""
from __future__ import annotations

from typing import Annotated, Optional

import typer

from app.cli._root import cli
from app.cli.datasets import DatabaseOpt, cli_settings, run_job_here, session_factory

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
        typer.echo(f"error: --state: unknown state {state!r} (queued, running, done, failed)", err=True)
        raise typer.Exit(code=2) from None
    settings = cli_settings(database_url, None)
    with session_factory(settings) as factory, factory() as session:
        items, total = jobs.list_jobs(session, wanted, None, limit, 0)
        for job in items:
            stale = " (stale: its process is gone)" if jobs.is_stale(job, settings) else ""
            what = job.params.get("path") or job.params.get("format") or ""
            progress = _progress(job.stage, job.done, job.total)
            line = f"{job.id:>5}  {job.kind:<9} {job.state.value:<8}{stale} {progress:<22} {what}"
            typer.echo(line.rstrip())
            if job.message:
                typer.echo(f"       {job.message}")
    typer.echo(f"{len(items)} of {total} job(s)")


@jobs_cli.command("run")
def run_cmd(database_url: DatabaseOpt = None) -> None:
    """Run queued jobs (and stale ones) in this process until none is left; prints each outcome."""
    from app.services.jobs import runner as jobs

    settings = cli_settings(database_url, None)
    owner = jobs.owner_name(settings)
    with session_factory(settings) as factory:
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
