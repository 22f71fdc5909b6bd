"""Command line entry point ``v3d`` (thin: parses arguments, calls services, prints).

Each command group lives in its own module and registers on the objects of ``app.cli._root`` when imported;
:func:`main` imports them all by name (plain imports: the import graph sees every one, ``tests/test_layers.py``).
"""
from __future__ import annotations

from app.cli._root import cli
from app.cli.errors import fail
from app.core.config import SettingsError


def main() -> None:
    """Run the ``v3d`` command line; a ``V3D_*`` variable it cannot run with ends it with one line naming the variable
    and what it accepts, status 2."""
    from app.cli import (  # noqa: F401  # each module registers its commands
        backup,  # v3d backup, v3d restore
        batches,  # v3d batches create|show|accept|undo
        calibration,  # v3d calibrate
        datasets,  # v3d import ..., v3d export ...
        detectors,  # v3d export yolo|coco, v3d evaluate monocular|sensitivity
        doubts,  # v3d doubts
        evaluation,  # v3d jac
        jobs,  # v3d jobs list|run
        predictions,  # v3d import predictions, v3d predictions list|remove
        releases,  # v3d release create|list|show|diff
        serve,  # v3d serve
        users,  # v3d users add|list|token|disable|enable
    )
    from app.cli.exports import register_remaining_exports

    register_remaining_exports()  # a format no module writes a command for: the registry's generic one
    try:
        cli()
    except SettingsError as exc:  # a bad V3D_* variable: one line naming it, not a traceback
        raise SystemExit(fail(str(exc)).exit_code) from None
