"""Small SoccerNet-v3 uploads with images, made from the synthetic demo game (``app.demo``): a few of its systems,
under as many leagues as asked, zipped as ``POST /api/imports`` takes them."""
from __future__ import annotations

import io
import json
import zipfile
from pathlib import Path

from app.demo.generator import generate_demo_dataset


def small_v3_upload(work: Path, systems: int = 2, leagues: int = 1, league: str = "league") -> bytes:
    """A zip of ``leagues`` copies of the demo game cut to its first ``systems`` systems (each action with its
    replays, and their images in ``Frames-v3.zip``), each copy under a league of its own (``<league>-<k>``). The demo
    game is generated in ``work/demo`` unless it is there already."""
    root = work / "demo"
    if not any(root.rglob("Labels-v3.json")):  # made once per folder: the same bytes every time (seed 0)
        root = generate_demo_dataset(root)
    labels_path = next(root.rglob("Labels-v3.json"))
    game = labels_path.parent
    labels = json.loads(labels_path.read_text(encoding="utf-8"))
    actions = dict(list(labels["actions"].items())[:systems])
    replays = {name: item for name, item in labels["replays"].items()
               if any(name in a.get("linked_replays", []) or name.split("_")[0] + ".png" == key
                      for key, a in actions.items())}
    meta = labels["GameMetadata"]
    meta.update(list_actions=list(actions), list_replays=list(replays), num_actions=len(actions),
                num_replays=len(replays))
    labels.update(actions=actions, replays=replays)
    with zipfile.ZipFile(game / "Frames-v3.zip") as zf:
        images = {name: zf.read(name) for name in [*actions, *replays]}
    frames = io.BytesIO()
    with zipfile.ZipFile(frames, "w") as zf:
        for name, data in images.items():
            zf.writestr(name, data)
    relative = game.relative_to(root).as_posix().split("/", 1)[1]  # season/game, under the league
    out = io.BytesIO()
    with zipfile.ZipFile(out, "w") as zf:
        for k in range(leagues):
            folder = f"{league}-{k}/{relative}"
            zf.writestr(f"{folder}/Labels-v3.json", json.dumps(labels))
            zf.writestr(f"{folder}/Frames-v3.zip", frames.getvalue())
    return out.getvalue()
