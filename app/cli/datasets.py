"""CLI module datasets (registered on app.cli._root)."""
from __future__ import annotations
