"""CLI commands for offline calibration and evaluation (``v3d calibrate``, ``v3d jac``).

Registered on :data:`app.cli._root.cli`. Filled in by the calibration and JaC work.
"""
from __future__ import annotations
