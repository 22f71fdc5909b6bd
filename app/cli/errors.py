"""How every ``v3d`` command refuses: one line ``Error: ...`` on standard error and an exit status, in a module of
its own that both the commands and the root's ``--server`` switch (:mod:`app.cli.remote`) import."""
from __future__ import annotations

import typer


def fail(message: str, code: int = 2) -> typer.Exit:
    """Print ``Error: <message>`` on standard error and return the exit to raise with status ``code`` (2: the input
    or the request is refused, 1: the work failed). Click prints its own refusals of options and arguments with that
    prefix, so that every refusal of ``v3d`` reads alike and a script can grep one word for it."""
    typer.echo(f"Error: {message}", err=True)
    return typer.Exit(code=code)
