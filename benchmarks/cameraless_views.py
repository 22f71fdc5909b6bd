"""Views the players left without any camera: why, and where the camera they refused would have put the ball.

For each view of an imported synthetic set that has no camera (its lines refused, and the players placed none), has
4 or more players with an ID and shares at least ``--min-shared`` players (class and ID) with a view of its system
that has a camera, the players' placement (``app.services.calibration.players``) is run again in process on the
stored views, the game's rig made as the import makes it (``rig_of_views``), and printed: the first round's refusal
(``no_anchor`` for a system without an anchor view, ``no_camera_in_system`` when no view of it has a camera), the
second round's (``_chained``: the anchors' feet and heads and the helper views' feet), and the candidate camera: the
best rig-position fit (``players._rig_fits``) to the players the second round places, with its pixel uncertainty
where the play is (``sigma_px``, px@1920, what the ``camera_unsure`` gate reads) and its error at the true ball
(px@1920: the set's true 3D ball projected by the candidate against its projection by the true camera). The
candidate is scored against the truth only; nothing here feeds a camera, and the ball is never a fit's input.

Run: ``PYTHONPATH=$PWD .venv/bin/python benchmarks/cameraless_views.py DB.sqlite3 TRUTH.json [--json OUT]``
(``DB``: the set as ``v3d import soccernet-v3`` left it; read only).
"""
from __future__ import annotations

import argparse
import collections
import json
import math
import sys
from pathlib import Path
from typing import Any, Mapping, Sequence

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import sqlalchemy as sa
from sqlalchemy.orm import Session, selectinload

from app.core.config import Settings
from app.db.models import CalibrationStatus, Frame, System
from app.geometry.annotations import lines_from_json_lists
from app.geometry.calibration import players as gp
from app.geometry.calibration.grass import (
    GrassPlayer,
    PlayerKey,
    head_pixel,
    players_on_grass,
    players_on_grass_by_heads,
)
from app.geometry.calibration.player_problem import PlayerProblem
from app.geometry.calibration.result import principal_point
from app.geometry.calibration.rig import CameraRig
from app.geometry.camera import Camera
from app.geometry.pair_error import REFERENCE_WIDTH_PX
from app.services.calibration import players as sp

#: A candidate camera is right when it puts the true ball within this many px@1920 of its true centre.
WITHIN_PX = 20.0


def ball_error_px(camera: Camera, ball: Sequence[float], true_uv: np.ndarray, width: int) -> float:
    """Distance (px@1920) of ``camera``'s projection of the 3D ``ball`` from ``true_uv`` (px of a ``width``-px view);
    inf behind the camera."""
    uv, ok = camera.project(np.array([ball], float))
    return float(np.linalg.norm(uv[0] - true_uv)) * REFERENCE_WIDTH_PX / width if ok[0] else math.inf


def refusal_words(got: Any) -> str:
    """A placement's answer in a few words: ``placed``, or its refusal code and numbers."""
    if isinstance(got, gp.PlayerRefusal):
        return got.code + "".join(f" {k}={float(v):.3g}" for k, v in got.numbers.items())
    return "placed" if got is not None else "-"


def second_round_grass(views: Sequence[sp.PlacementView], first: Mapping[int, Any], cameras: Mapping[int, Camera],
                       feet: Mapping[int, Mapping[PlayerKey, np.ndarray]]) -> dict[PlayerKey, GrassPlayer]:
    """Where the second round (``players._chained``) puts the players: the anchors' feet, then their heads, then the
    helper views' feet, each only where the earlier sources did not place the player."""
    helpers = sp._helpers(views, first, cameras)
    grass = dict(players_on_grass([(cameras[a], feet[a]) for a in cameras]))
    heads = [(cameras[a], {k: uv for k, uv in sp.feet_of(views[a].players, views[a].width, views[a].height,
                                                        head_pixel).items() if k not in feet[a]}) for a in cameras]
    for source in (players_on_grass_by_heads(heads), players_on_grass([(helpers[h], feet[h]) for h in helpers])):
        for k, g in source.items():
            grass.setdefault(k, g)
    return grass


def candidate(view: sp.PlacementView, feet: Mapping[PlayerKey, np.ndarray], grass: Mapping[PlayerKey, GrassPlayer],
              rig: CameraRig) -> tuple[Camera, float, str] | None:
    """The best rig-position fit of ``view`` to its players on ``grass`` (at least 3, as the first round asks), its
    ``sigma_px`` (px@1920; inf when undetermined) and what the fit's tests say of it (``ok`` or a refusal code);
    None without 3 players or a fit."""
    s = gp.PlayerFitSettings()
    heads = sp.feet_of(view.players, view.width, view.height, head_pixel)
    footed = [k for k in feet if k in grass]
    keys = footed + [k for k in heads if k in grass and k not in feet]
    if len(keys) < 3:
        return None
    w, h = view.width, view.height
    head_of = np.array([i for i, k in enumerate(keys) if k in heads], dtype=int)
    lines = {c: x for c, x in lines_from_json_lists(dict(view.lines)).items() if x}
    problem = PlayerProblem(
        uv=np.array([np.asarray(feet[k], float) for k in footed]).reshape(-1, 2),
        world=np.array([[grass[k].point_m[0], grass[k].point_m[1], 0.0] for k in keys]), lines=dict(lines),
        pp=principal_point(w, h), width=w, height=h, scale=w / REFERENCE_WIDTH_PX,
        cov_g=np.array([grass[k].cov_m2 for k in keys], float),
        uv_head=np.array([np.asarray(heads[keys[i]], float) for i in head_of]).reshape(-1, 2), head_of=head_of,
        foot_of=np.arange(len(footed)))
    fits = gp._rig_fits(problem, [p.centre_m for p in rig.positions], s)
    if not fits:
        return None
    best = fits[0]
    verdict = gp._judge(problem, best, s)
    sigma = math.inf
    if verdict is None:
        got = gp._accepted(problem, best, keys, s)
        if isinstance(got, gp.PlayerFit):
            sigma, words = got.sigma_px, "ok"
        else:
            sigma, words = float(got.numbers.get("sigma_px", math.inf)), got.code
    else:
        words = verdict.code
    return best.param.camera(best.x), sigma, words


def diagnose(session: Session, truth: Mapping[str, Any], min_shared: int = 4) -> list[dict[str, Any]]:
    """One row per view without a camera sharing at least ``min_shared`` players with a view of its system that has
    one (module docstring)."""
    settings = Settings()
    true_views = {(g["match"], s["action"], v["image"]): (s["ball_3d"], v)
                  for g in truth["games"] for s in g["systems"] for v in s["views"]}
    frames_of = selectinload(System.frames)
    systems = session.scalars(sa.select(System).options(
        selectinload(System.game), frames_of.selectinload(Frame.calibration),
        frames_of.selectinload(Frame.field_lines), frames_of.selectinload(Frame.players))).all()
    games: dict[int | None, list[System]] = collections.defaultdict(list)
    for system in systems:
        games[system.game_id].append(system)
    rows = []
    for group in games.values():
        game_views = [[sp.view_of_frame(f, settings) for f in s.frames] for s in group]
        rig = sp.rig_of_views([v for views in game_views for v in views])
        for system, views in zip(group, game_views, strict=True):
            frames = list(system.frames)
            with_camera = [i for i, v in enumerate(views)
                           if v.status is CalibrationStatus.CALIBRATED and v.camera is not None]
            ids = [{(c, i) for c, i, _ in v.players if i is not None} for v in views]
            todo = [i for i in range(len(views)) if i not in with_camera and len(ids[i]) >= 4
                    and max([len(ids[i] & ids[j]) for j in with_camera] or [0]) >= min_shared]
            if not todo:
                continue
            anchors = [i for i, v in enumerate(views) if sp.is_anchor(v)]
            feet = {i: sp.feet_of(v.players, v.width, v.height) for i, v in enumerate(views)}
            cameras = {a: Camera.from_soccernet(dict(views[a].camera or {})) for a in anchors}
            grass = players_on_grass([(cameras[a], feet[a]) for a in anchors])
            weak = [i for i, v in enumerate(views) if sp.is_weak(v)]
            first = {i: sp._placed_one(views[i], rig, feet[i], grass) for i in weak} if anchors else {}
            chained_grass = second_round_grass(views, first, cameras, feet)
            chained_settings = gp.PlayerFitSettings(min_players_rig=sp.CHAINED_MIN_PLAYERS)
            for i in todo:
                v = views[i]
                ball, tv = true_views[(system.game.match, system.name, frames[i].name)]
                true = Camera.from_soccernet(tv["camera"])
                true_uv, ok = true.project(np.array([ball], float))
                second = sp._placed_one(v, rig, feet[i], chained_grass, chained_settings, at_rig_only=True)
                cand = candidate(v, feet[i], chained_grass, rig)
                stored = sp.place_in_system(views, rig, only=i).get(i)
                rows.append({
                    "match": system.game.match, "system": system.name, "view": frames[i].name,
                    "role": frames[i].role.value, "line_classes": sp.line_classes(v.lines),
                    "players": len(ids[i]), "shared": max((len(ids[i] & ids[j]) for j in with_camera), default=0),
                    "anchors": len(anchors),
                    "on_grass_first": sum(1 for k in feet[i] if k in grass),
                    "on_grass_second": sum(1 for k in feet[i] if k in chained_grass),
                    "first": (refusal_words(first.get(i)) if anchors
                              else "no_anchor" if with_camera else "no_camera_in_system"),
                    "second": refusal_words(second),
                    "placed_now": isinstance(stored, sp.CalibrationFields),
                    "true_rig_m": round(min((float(np.linalg.norm(np.asarray(true.C) - np.asarray(p.centre_m)))
                                             for p in rig.positions), default=math.inf), 2),
                    "ball_in_image": bool(ok[0] and 0 <= true_uv[0, 0] < v.width and 0 <= true_uv[0, 1] < v.height),
                    "candidate_px": None if cand is None else round(
                        ball_error_px(cand[0], ball, true_uv[0], v.width), 1),
                    "candidate_sigma_px": None if cand is None else round(cand[1], 1),
                    "candidate_tests": None if cand is None else cand[2],
                })
    return rows


def reason(row: Mapping[str, Any]) -> str:
    """The step that refused the view: the first round's code, or ``no_anchor``."""
    return str(row["first"]).split(" ")[0]


def main(argv: Sequence[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("db", type=Path)
    ap.add_argument("truth", type=Path)
    ap.add_argument("--min-shared", type=int, default=4,
                    help="fewest players shared with a view that has a camera (0: every view without a camera that "
                         "has 4 or more players with an ID)")
    ap.add_argument("--json", type=Path, help="write the rows here too")
    args = ap.parse_args(argv)
    truth = json.loads(args.truth.read_text())
    with Session(sa.create_engine(f"sqlite:///file:{args.db}?mode=ro&uri=true")) as session:
        rows = diagnose(session, truth, args.min_shared)
    for r in rows:
        print(f"{r['match'][-24:]:24s} {r['view']:9s} {r['role'][:6]:6s} cl {r['line_classes']} players "
              f"{r['players']:2d} shared {r['shared']:2d} anchors {r['anchors']} feet on grass {r['on_grass_first']}/"
              f"{r['on_grass_second']} | first: {r['first'][:40]} | second: {r['second'][:40]} | candidate "
              f"{r['candidate_px']} px, sigma {r['candidate_sigma_px']} ({r['candidate_tests']})")
    by = collections.defaultdict(list)
    for r in rows:
        by[reason(r)].append(r)
    print("reason: views, with a candidate, candidate within 20 px")
    for k, rs in sorted(by.items(), key=lambda t: -len(t[1])):
        cands = [r for r in rs if r["candidate_px"] is not None]
        print(f"{k:20s} {len(rs):3d} {len(cands):3d} {sum(r['candidate_px'] <= WITHIN_PX for r in cands):3d}")
    if args.json:
        args.json.write_text(json.dumps(rows, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
