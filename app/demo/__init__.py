"""Built-in demo dataset: a small synthetic SoccerNet-v3 game made in code (no files shipped).

``generate_demo_dataset(out_dir, seed=0)`` writes the game tree and ``demo-truth.json`` and returns
the root to import (see :mod:`app.demo.generator`).
"""
from __future__ import annotations

from app.demo.generator import generate_demo_dataset

__all__ = ["generate_demo_dataset"]
