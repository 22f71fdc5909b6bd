"""Command line entry point ``v3d`` (thin: parses arguments, calls services, prints).

Each command group lives in its own module and registers on the objects of ``app.cli._root``.
"""
from __future__ import annotations

import importlib

from app.cli._root import cli

# Modules that register commands; a missing module is a programming error, not a user one.
_COMMAND_MODULES = (
    "app.cli.evaluation",  # v3d jac
    "app.cli.calibration",  # v3d calibrate
    "app.cli.datasets",  # v3d import ..., v3d export ...
    "app.cli.jobs",  # v3d jobs list|run
    "app.cli.detectors",  # v3d export yolo|coco, v3d evaluate monocular|sensitivity
    "app.cli.serve",  # v3d serve
    "app.cli.doubts",  # v3d doubts
    "app.cli.users",  # v3d users add|list|token|disable|enable
)


def _load_commands() -> None:
    for name in _COMMAND_MODULES:
        importlib.import_module(name)


def main() -> None:
    """Run the ``v3d`` command line."""
    _load_commands()
    cli()
