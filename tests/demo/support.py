"""Helpers of the demo-dataset tests: a generated dataset, parsed."""
from __future__ import annotations

import json
import zipfile
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from app.demo.generator import FRAMES_FILE, LABELS_FILE, TRUTH_FILE


@dataclass(frozen=True)
class Demo:
    """A generated demo dataset, parsed."""

    root: Path
    game_dir: Path
    labels: dict[str, Any]
    truth: dict[str, Any]
    cpu_seconds: float

    def frames(self) -> dict[str, dict[str, Any]]:
        """Every frame's labels by image name (actions then replays)."""
        return {**self.labels["actions"], **self.labels["replays"]}

    def views(self) -> dict[str, dict[str, Any]]:
        """Every view's truth by image name."""
        return {v["image"]: v for s in self.truth["systems"] for v in s["views"]}

    def zip_names(self) -> list[str]:
        with zipfile.ZipFile(self.game_dir / FRAMES_FILE) as zf:
            return zf.namelist()


def load_demo(root: Path, cpu_seconds: float = 0.0) -> Demo:
    """Parse a generated dataset (exactly one game under ``root``)."""
    games = sorted(root.glob(f"*/*/*/{LABELS_FILE}"))
    assert len(games) == 1, games
    game_dir = games[0].parent
    return Demo(root, game_dir, json.loads(games[0].read_text(encoding="utf-8")),
                json.loads((root / TRUTH_FILE).read_text(encoding="utf-8")), cpu_seconds)
