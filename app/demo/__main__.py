"""``python -m app.demo OUT_DIR [SEED]``: write the demo dataset and print its root."""
from __future__ import annotations

import sys
from pathlib import Path

from app.demo import generate_demo_dataset

if __name__ == "__main__":
    if len(sys.argv) not in (2, 3):
        sys.exit("usage: python -m app.demo OUT_DIR [SEED]")
    print(generate_demo_dataset(Path(sys.argv[1]), seed=int(sys.argv[2]) if len(sys.argv) == 3 else 0))
