"""A detector's predictions checked against one labelled ray whose camera the players placed, on a game of the
shared detector set imported as a user would (its labels a third removed, its true ball and centres in the truth
file): where no view with enough lines is labelled, such a view's label is the lone ray, and every detection it
places is right."""
from __future__ import annotations

import json
import math
import shutil
from pathlib import Path
from typing import Any

import sqlalchemy as sa

from app.core.config import Settings
from app.db.models import Doubt, Frame, Game, System
from app.geometry.calibration.result import PLAYERS_FLAG
from app.services.derivation.doubts import doubt_view
from app.services.transfer.importing import import_soccernet_v3
from app.services.transfer.predictions import import_predictions

#: The game of the shared ``dev-large`` detector set where a camera the players placed is the only labelled ray of
#: two systems (benchmarks/DETECTOR.md, 2026-11-27).
GAME = Path("synth_league_b/2031-2032/2031-12-01 - 14-00 Glenrock 2 - 3 Oakhurst")


def test_a_camera_the_players_placed_is_the_lone_ray_and_its_detections_are_right(shared_dir, tmp_path,
                                                                                   fresh_session_factory):
    with fresh_session_factory("game") as session:
        frames, centres = import_detector_game(session, shared_dir, tmp_path, "dev-large", GAME)
        placed = {fid for fid, f in frames.items() if f.calibration is not None
                  and PLAYERS_FLAG in (f.calibration.flags or [])}
        assert placed and all(doubt_view(frames[fid]).player_assisted for fid in placed)
        assert not any(doubt_view(f).player_assisted for fid, f in frames.items() if fid not in placed)
        detected = list(session.scalars(sa.select(Doubt).where(Doubt.kind == "ball_detected",
                                                              Doubt.frame_id.in_(frames))))
        by_players = [d for d in detected if d.evidence["code"] == "one_ray"
                      and set(d.evidence["agreeing_views"]) <= placed]
        # two views filled from a lone ray the players placed when written; their labels' rays only
        assert len(by_players) >= 1
        assert all(frames[a].ball_label is not None for d in by_players for a in d.evidence["agreeing_views"])
        for d in detected:  # every detection the checks place here is the ball (within max(3 px, d/2))
            (cx, cy), tol = centres[frames[d.frame_id].name]
            b = d.suggestion["box"] if d.suggestion else d.evidence["box"]  # with its key or without (no_key)
            assert math.hypot((b[0] + b[2]) / 2 - cx, (b[1] + b[3]) / 2 - cy) <= tol, frames[d.frame_id].name


def import_detector_game(session: Any, shared_dir: Path, tmp_path: Path, set_name: str, game: Path
                         ) -> tuple[dict[int, Frame], dict[str, tuple]]:
    """One game of the shared detector set ``set_name`` imported into ``session`` as a user would (``v3d import
    soccernet-v3`` of its labels, ``v3d import predictions`` of its rows of the CSV): its views by frame id, and image
    -> (true centre, the scorer's tolerance max(3 px, d/2)) of its unlabelled views."""
    detector = shared_dir / "data/synthetic/detector"
    (tmp_path / "set" / game).mkdir(parents=True)
    shutil.copy(detector / f"{set_name}-unlabelled" / game / "Labels-v3.json", tmp_path / "set" / game)
    truth = json.loads((detector / f"{set_name}-unlabelled.truth.json").read_text())
    match = game.name
    centres = {u["image"]: (u["center"], max(3.0, u["d"] / 2)) for u in truth["unlabelled"] if u["match"] == match}
    lines = (detector / f"{set_name}-predictions.csv").read_text().splitlines()
    (tmp_path / "game.csv").write_text("\n".join([lines[0], *(r for r in lines[1:] if f",{match}," in r)]) + "\n")
    settings = Settings(calibration_workers=1)
    import_soccernet_v3(session, tmp_path / "set", settings)
    session.commit()
    import_predictions(session, tmp_path / "game.csv", settings, source="detector")
    session.commit()
    frames = {f.id: f for f in session.scalars(sa.select(Frame).join(System).join(Game).where(Game.match == match))}
    return frames, centres
