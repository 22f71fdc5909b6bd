"""Filesystem locations the project agrees on (no settings, no I/O)."""
from __future__ import annotations

from pathlib import Path

#: Root of the checkout (the folder holding ``pyproject.toml``).
PROJECT_ROOT = Path(__file__).resolve().parents[2]
#: ``../shared`` beside the checkout: the paper, method notes and datasets (never copied in).
SHARED_DIR = PROJECT_ROOT.parent / "shared"
#: Static front-end files served by the API.
STATIC_DIR = PROJECT_ROOT / "static"
