"""``v3d backup DEST`` and ``v3d restore ARCHIVE``: thin wrappers over ``app.services.backup`` (one consistent
snapshot of the database and the store's objects it names, online; its restore into the database and store that
``V3D_DATABASE_URL`` and ``V3D_STORAGE_URL`` name, any engine to any engine). Progress is drawn on a terminal. A
failure prints ``Error: ...`` and exits 1 (the backup leaves no archive), a refused restore (a broken archive, a
target holding data, a key the store cannot hold) exits 2 and writes nothing."""
from __future__ import annotations

import sys
from pathlib import Path
from typing import Annotated, Optional

import typer
from sqlalchemy.exc import SQLAlchemyError

from app.cli._root import cli
from app.cli.bars import StageBars
from app.cli.datasets import DatabaseOpt, cli_settings
from app.cli.errors import fail
from app.core.errors import ConflictError, InvalidInputError


def _bars() -> Optional[StageBars]:
    return StageBars() if sys.stderr.isatty() else None


@cli.command("backup")
def backup_cmd(
    destination: Annotated[str, typer.Argument(help="The archive to write: a file path, or s3://BUCKET/KEY (through "
                                                    "the store's AWS_* credentials).")],
    without_local_files: Annotated[bool, typer.Option(
        "--without-local-files", help="Leave out the images of datasets read from this machine's folders (a "
                                      "command-line import's, the demo's); the manifest lists their folders and a "
                                      "restore names those its machine lacks.")] = False,
    database_url: DatabaseOpt = None,
) -> None:
    """Back up the whole deployment while it serves: every table in one read transaction and every stored object the
    snapshot names, in one zip with manifest.json (the v3d version, schema revision, each table's rows and every
    member's SHA-256). It holds password and token hashes: keep it as a secret."""
    from app.db.session import RestoreUnfinished, make_engine, refuse_unfinished_restore
    from app.services.backup.snapshot import write_backup

    settings = cli_settings(database_url, None)
    engine = make_engine(settings.database_url)
    bars = _bars()
    try:
        refuse_unfinished_restore(engine)
        report = write_backup(engine, settings, destination, bars, local_files=not without_local_files)
    except RestoreUnfinished as exc:
        raise fail(str(exc)) from None
    except (OSError, ValueError) as exc:
        raise fail(f"the backup failed, no archive was written: {exc}", 1) from None
    finally:
        if bars is not None:
            bars.close()
        engine.dispose()
    typer.echo(f"{report.destination}: {report.size:,} bytes, {report.tables} tables, {report.rows:,} rows, "
               f"{report.objects:,} files, schema {report.schema_revision}, {report.seconds:.1f} s")
    for name in report.missing:
        typer.echo(f"warning: named by the database but not found, not in the archive: {name}", err=True)
    for part in report.stale_parts:
        what = "remove it once no backup is running" if Path(part).exists() else "this backup wrote over it"
        typer.echo(f"warning: {part} was left by a backup that did not finish (killed, or running now) and holds "
                   f"secrets: {what}", err=True)


@cli.command("restore")
def restore_cmd(
    archive: Annotated[str, typer.Argument(help="The archive: a file path, or s3://BUCKET/KEY.")],
    replace: Annotated[bool, typer.Option("--replace", help="Drop what the target database holds first (without "
                                                            "it, a target holding data is refused).")] = False,
    verify_only: Annotated[bool, typer.Option("--verify-only", help="Check every member's SHA-256 against the "
                                                                    "manifest and write nothing.")] = False,
    new_secrets: Annotated[Optional[str], typer.Option(
        "--new-secrets", metavar="ADMIN", help="An archive you did not make: restore its data with a new session "
                                               "key, every API token revoked and every account disabled but ADMIN "
                                               "(made if the archive has none), an admin with the password asked "
                                               "for and one new token (printed).")] = None,
    password_stdin: Annotated[bool, typer.Option(
        "--password-stdin", help="With --new-secrets: read ADMIN's password from standard input's first line.")
    ] = False,
    database_url: DatabaseOpt = None,
) -> None:
    """Restore a backup into the database and store of V3D_DATABASE_URL and V3D_STORAGE_URL (any engine to any
    engine), after verifying every member. Run again after an interruption, it finishes the restore. A plain restore
    keeps the archive's accounts, tokens and session key working (its author is an admin here): restore an archive
    you did not make with --new-secrets."""
    from app.services.backup.archive import BrokenArchive
    from app.services.backup.restore import restore_backup, verify

    settings = cli_settings(database_url, None)
    taking = None
    if new_secrets is not None and not verify_only:  # asked before anything is read: the restore may take long
        password = (sys.stdin.readline().rstrip("\r\n") if password_stdin
                    else typer.prompt(f"Password of {new_secrets}", hide_input=True, confirmation_prompt=True))
        taking = (new_secrets, password)
    bars = _bars()
    try:
        if verify_only:
            manifest = verify(archive, settings, bars)
        else:
            report = restore_backup(archive, settings, replace=replace, progress=bars, new_secrets=taking)
            manifest = report.manifest
    except BrokenArchive as exc:
        raise fail(f"the archive is broken, nothing was restored: {exc}") from None
    except (ConflictError, InvalidInputError, FileNotFoundError, ValueError) as exc:
        raise fail(str(exc)) from None
    except (OSError, SQLAlchemyError) as exc:  # the target failed midway: marked, it refuses to serve
        raise fail(f"the restore stopped ({type(exc).__name__}: {exc}); the target refuses to serve until "
                   f"`v3d restore {archive}` is run again and finishes", 1) from None
    finally:
        if bars is not None:
            bars.close()
    rows = sum(t.rows for t in manifest.tables)
    if verify_only:
        typer.echo(f"{archive}: whole ({len(manifest.members)} members verified; v3d {manifest.v3d_version}, schema "
                   f"{manifest.schema_revision}, {len(manifest.tables)} tables, {rows:,} rows, made "
                   f"{manifest.created_at})")
        return
    typer.echo(f"restored {archive}: {report.rows:,} rows, {report.objects:,} files, {report.seconds:.1f} s")
    if report.jobs_not_run:
        typer.echo(f"{report.jobs_not_run} job(s) the archive held queued or running are kept failed, not run here: "
                   f"queue them again on this deployment if they are still wanted", err=True)
    if report.taken_over is not None:
        done = report.taken_over
        typer.echo(f"new secrets: the session key is new, {done.tokens_revoked} API token(s) revoked, "
                   f"{done.users_disabled} account(s) disabled (v3d users enable NAME); {done.admin} is "
                   f"{'a new' if done.made else 'the'} admin, its API token:", err=True)
        typer.echo(done.token)
    for root in report.missing_roots:
        typer.echo(f"warning: the images of {root} were not in the archive and are not on this machine", err=True)
