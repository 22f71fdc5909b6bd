"""Small datasets for tests, written into a temporary folder from ``../shared`` at test time (nothing
is copied into the repository): a few systems of the synthetic SoccerNet-v3 dev set, a few frames of
the real WorldCup 2014 calibration zip."""
from __future__ import annotations

import json
import zipfile
from collections.abc import Callable
from pathlib import Path

#: The synthetic dev game the tests cut systems from, and its path inside ../shared.
DEV_GAME = ("synth_league_a", "2031-2032", "2031-08-01 - 14-00 Dunmore 0 - 3 Glenrock")
#: Systems used by default: 0.png (two views), 2.png (four views, one refused by calibration, the
#: other three triangulated), 3.png (a near-duplicate replay: baseline below 1 m).
DEFAULT_ACTIONS = ("0.png", "2.png", "3.png")


def dev_game_dir(shared_dir: Path) -> Path:
    return shared_dir.joinpath("data", "synthetic", "soccernet-v3-dev", *DEV_GAME)


def write_v3_game(shared_dir: Path, root: Path, actions=DEFAULT_ACTIONS, edit: Callable[[dict], None] | None = None,
                  game: tuple[str, str, str] = DEV_GAME, with_images: bool = True) -> Path:
    """Write ``root/<league>/<season>/<game>/Labels-v3.json`` holding ``actions`` of the dev game and
    their replays (and a ``Frames-v3.zip`` of their images); ``edit`` may damage the labels first.
    Returns the game folder."""
    src = dev_game_dir(shared_dir)
    data = json.loads((src / "Labels-v3.json").read_text())
    keep_replays = [r for a in actions for r in data["actions"][a]["linked_replays"]]
    data["actions"] = {a: data["actions"][a] for a in actions}
    data["replays"] = {r: data["replays"][r] for r in keep_replays}
    if edit is not None:
        edit(data)
    game_dir = root.joinpath(*game)
    game_dir.mkdir(parents=True, exist_ok=True)
    (game_dir / "Labels-v3.json").write_text(json.dumps(data))
    if with_images:
        with zipfile.ZipFile(src / "Frames-v3.zip") as zin, zipfile.ZipFile(game_dir / "Frames-v3.zip", "w") as zout:
            for name in [*actions, *keep_replays]:
                zout.writestr(name, zin.read(name))
    return game_dir


def write_calibration_zip(shared_dir: Path, dest: Path, names=("1.json", "2.json", "3.json"),
                          extra: dict[str, bytes] | None = None) -> Path:
    """A zip of a few frames of the real WorldCup 2014 test annotations (960x540, no images)."""
    src = shared_dir / "data" / "real" / "wc14-test" / "annotations.zip"
    dest.parent.mkdir(parents=True, exist_ok=True)
    with zipfile.ZipFile(src) as zin, zipfile.ZipFile(dest, "w") as zout:
        for name in names:
            zout.writestr(name, zin.read(name))
        for name, raw in (extra or {}).items():
            zout.writestr(name, raw)
    return dest


def true_cameras(shared_dir: Path, game: tuple[str, str, str] = DEV_GAME) -> dict[tuple[str, str], dict]:
    """(system name, frame name) -> the true SoccerNet camera JSON of the dev game's views."""
    truth = json.loads((shared_dir / "data" / "synthetic" / "soccernet-v3-dev.truth.json").read_text())
    (g,) = [g for g in truth["games"] if (g["league"], g["season"], g["match"]) == game]
    return {(s["action"], v["image"]): v["camera"] for s in g["systems"] for v in s["views"]}


def true_balls(shared_dir: Path, game: tuple[str, str, str] = DEV_GAME) -> dict[str, list[float]]:
    """System name -> the true 3D ball (world metres) of the dev game."""
    truth = json.loads((shared_dir / "data" / "synthetic" / "soccernet-v3-dev.truth.json").read_text())
    (g,) = [g for g in truth["games"] if (g["league"], g["season"], g["match"]) == game]
    return {s["action"]: s["ball_3d"] for s in g["systems"]}


def zip_files(data: bytes, where: str = "") -> dict[str, bytes]:
    """Every file of a zip (its bytes) by name, nested zips opened too (``outer.zip!inner``)."""
    import io

    out = {}
    with zipfile.ZipFile(io.BytesIO(data)) as zf:
        for name in zf.namelist():
            raw = zf.read(name)
            out[where + name] = raw
            if name.endswith(".zip"):
                out.update(zip_files(raw, f"{where}{name}!"))
    return out
