"""Import a ball detector's predictions (CSV league,season,match,image,x1,y1,x2,y2,score, pixels) as SOURCE, wait
for the import (the doubts see them then), and print every stored source as JSON.

    python examples/client/07_predictions.py detections.csv yolo-ball

An admin's token.
"""
from __future__ import annotations

import json
import sys

from v3d_client import Client


def main(csv_path: str, source: str) -> None:
    with Client.from_env() as v3d:
        v3d.wait(v3d.import_predictions(csv_path, source))
        sources = [s.model_dump(mode="json") for s in v3d.prediction_sources()]
    print(json.dumps(sources, indent=2))


if __name__ == "__main__":
    main(sys.argv[1], sys.argv[2])
