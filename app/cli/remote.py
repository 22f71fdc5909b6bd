"""``v3d --server URL`` (or ``V3D_URL``, with ``V3D_TOKEN``): the commands a team runs against a shared server,
spoken through the Python client (``v3d_client``) instead of run on the local database.

The root command's ``--server`` names the server (:func:`use_server`); each command that runs remotely asks
:func:`remote_client` for a client (None: run locally, as before) and does its work through it: ``import soccernet-v3``
and ``import predictions`` (the folder, zip or file uploaded), ``export FORMAT OUT`` and ``release export NAME FORMAT
OUT`` (the export job's zip downloaded to the system's temporary folder and unpacked under OUT, as the local command
writes it), ``release create|list|show|diff``, ``batches create|show|accept|undo``, ``users list|add|disable``,
``jobs list|wait``, ``stats`` and ``stats annotators``, each with progress bars on standard error. A remote command
writes nothing in its working folder but the OUT it was given. Any other command named with ``--server`` is refused
(:func:`refuse_remote`, exit 2): it runs on the server's machine only. A refusal of the server (401, 403, 404, 409,
413, 422) prints ``Error: <the server's words>`` and exits 2; a failed job exits as the local command does (2 for
invalid input, else 1), as do a server that does not answer and a wait past its ``--timeout`` (1). A server that
answers what its route does not promise (not JSON, another shape, a redirect, more than ``V3D_REMOTE_MAX_ANSWER_MB``,
not complete within ``V3D_REMOTE_TIMEOUT_S``) ends the command with one ``Error:`` line naming it and what it answered
(exit 1).
"""
from __future__ import annotations

import os
import tempfile
import zipfile
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import TYPE_CHECKING, Any, Optional

import typer

from app.cli.errors import fail

if TYPE_CHECKING:
    from v3d_client import Client, Job

#: The commands ``--server`` runs, as the refusal of any other names them.
REMOTE_COMMANDS = ("import soccernet-v3", "import predictions", "export FORMAT OUT", "release create|list|show|diff|"
                   "export", "batches create|show|accept|undo", "users list|add|disable", "jobs list|wait", "stats",
                   "stats annotators")
#: The environment variable of the API token a remote command sends (the examples' name too).
TOKEN_ENV = "V3D_TOKEN"

_server: dict[str, Optional[str]] = {"url": None}


def use_server(url: Optional[str]) -> None:
    """Make the commands of this run speak to the server at ``url`` (None: the local database)."""
    _server["url"] = url.rstrip("/") if url else None


def server_url() -> Optional[str]:
    """The server this run speaks to, or None."""
    return _server["url"]


def refuse_remote() -> None:
    """End a command that runs on the local database only when a server was named (exit 2, saying which run
    remotely)."""
    if _server["url"] is not None:
        raise fail(f"this command runs on the server's machine only; with --server (or V3D_URL) v3d runs: "
                   f"{', '.join(REMOTE_COMMANDS)}")


@contextmanager
def remote_client() -> Iterator[Optional["Client"]]:
    """A client of the named server with ``V3D_TOKEN`` (None when no server was named); an error of the client or
    the server inside the block ends the command with the server's words (exit 2; a failed job: 2 for invalid input,
    else 1).

    Raises:
        typer.Exit: no token, or a refusal.
    """
    if _server["url"] is None:
        yield None
        return
    from app.core.config import get_settings
    from v3d_client import BadAnswer, Client, JobFailed, JobTimeout, Unreachable, V3DError

    token = os.environ.get(TOKEN_ENV)
    if not token:
        raise fail(f"{TOKEN_ENV} is not set: a remote command sends an API token (v3d users add prints one)")
    settings = get_settings()
    url = _server["url"]
    try:
        # each wait at most half the request's time: a read begun just before its end ends within 1.5 times it
        with Client(url, token, timeout=settings.remote_timeout_s / 2, total_timeout_s=settings.remote_timeout_s,
                    max_answer_bytes=int(settings.remote_max_answer_mb * 2**20)) as client:
            yield client
    except JobFailed as exc:
        raise fail(str(exc.job.message), 2 if (exc.job.result or {}).get("invalid_input") else 1) from None
    except (Unreachable, JobTimeout, BadAnswer) as exc:
        raise fail(str(exc), 1) from None
    except V3DError as exc:
        raise fail(str(exc)) from None
    except (KeyError, TypeError, ValueError, AttributeError, IndexError) as exc:
        # an answer of the right shape as the client's models see it, yet not what the command reads in it (a job's
        # free-form result): the server's fault, said in one line, never a traceback
        raise fail(f"{url} answered what this command cannot read ({type(exc).__name__}: {str(exc)[:200]})",
                   1) from None


def wait_with_bars(client: "Client", job: "Job") -> "Job":
    """Wait for ``job`` drawing a bar per stage (standard error); the finished job."""
    from app.cli.bars import StageBars

    typer.echo(f"job {job.id} queued on {client.url}", err=True)
    bars = StageBars()
    try:
        return client.wait(job, progress=bars.job)
    finally:
        bars.close()


def upload_and_wait(client: "Client", path: Path, kind: str, **options: Any) -> "Job":
    """Upload ``path`` (a folder, zip or file) as a dataset of ``kind`` with an upload bar, then wait for its import
    job with a bar per stage; the finished job."""
    from v3d_client.progress import tqdm_bytes

    bar = tqdm_bytes(f"uploading {path.name}", leave=True)
    try:
        job = client.upload(path, kind, progress=bar, **options)
    finally:
        bar.close()
    return wait_with_bars(client, job)


def export_tree(client: "Client", fmt: str, out_dir: Path, include_all: bool, images: bool,
                release: Optional[str]) -> dict[str, Any]:
    """The export ``fmt`` (of the accepted systems now, every system, or ``release``) run as a job on the server,
    its zip downloaded into the system's temporary folder and unpacked under ``out_dir`` (as ``v3d export`` writes
    it locally); the job's result (its counts)."""
    from v3d_client.progress import tqdm_bytes

    job = wait_with_bars(client, client.start_export(fmt, include_all=include_all, release=release, images=images))
    with tempfile.TemporaryDirectory(prefix="v3d-download-") as tmp:
        bar = tqdm_bytes(f"downloading {fmt}", leave=True)
        try:
            archive = client.download(job, Path(tmp) / "export.zip", progress=bar)
        finally:
            bar.close()
        out_dir.mkdir(parents=True, exist_ok=True)
        with zipfile.ZipFile(archive) as zf:
            zf.extractall(out_dir)  # the server's member names are checked folder names (exporting.safe_component)
    return job.result or {}
