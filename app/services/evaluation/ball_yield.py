"""Yield, side by side (``v3d stats yield``): how many of an imported set's multi-view systems end with a 3D ball
under the paper's rules and under v3d's, and, given the set's truth, how many with a right one.

* **paper**: the SoccerNet-v3D paper's triangulation (Sec. 3, Eq. triangulation; method.md section 5) of each system
  from scratch: only views whose calibration is admitted by JaC@0.5 % > 0.75 (``Settings.admit_jac_min`` at
  ``admit_jac_gamma``, :func:`app.services.calibration.admission.is_admitted`), only views a person labelled (a
  label a doubt's fix placed and nobody confirmed is left out), every pair whose error is below tau
  (``Settings.triangulation_tau_px`` with ``pair_error_rule``) and whose cameras are at least 1 m apart
  (``min_baseline_m``), no parallax filter and no play volume (``app.core.config.PAPER_PROFILE``), the mean of the
  kept pair points (:func:`app.geometry.triangulation.triangulate_ball` without weights);
* **v3d**: the system's stored 3D ball (``Triangulation.ball3d``) as the recomputation made it from the labels as
  they are now (v3d's own calibrations, weights and rules; suggested labels make no 3D ball until confirmed). Run
  before and after a pass of the doubts' fixes, it gives both of v3d's columns.

:func:`ball_yield` returns::

    {"systems": n, "truth_systems": n | None,
     "paper": {"with_ball": n, "right": n | None, "wrong": n | None},
     "v3d": {"with_ball": n, "right": n | None, "wrong": n | None},
     "right_m": 0.5, "wrong_m": 1.0}

A 3D ball is right within ``right_m`` (0.5 m) of the truth's, wrong beyond ``wrong_m`` (1 m) (as
``../shared/tools/detector_fill_eval.py`` scores systems). The truth is a synthetic set's truth JSON
(``{"games": [{"match", "systems": [{"action", "ball_3d"}]}]}``): a system is matched by its game's match and its
name (the action image), SoccerNet world metres.
"""
from __future__ import annotations

import math
from typing import Any, Iterator

import numpy as np
import sqlalchemy as sa
from sqlalchemy.orm import Session

from app.core.config import PAPER_PROFILE, Settings
from app.db.models import Game, System
from app.geometry.triangulation import BallObservation, triangulate_ball
from app.services.calibration.admission import is_admitted
from app.services.derivation.cameras import stored_camera
from app.services.derivation.recompute import load_for_recompute

RIGHT_M = 0.5
WRONG_M = 1.0


def paper_ball(system: System, settings: Settings) -> np.ndarray | None:
    """The system's 3D ball under the paper's rules (module docstring), world metres (3,), or None (fewer than two
    admitted labelled views, or every pair dropped)."""
    obs = []
    for f in system.frames:
        label, cal = f.ball_label, f.calibration
        if label is None or label.suggested or not is_admitted(cal, settings):
            continue
        if label.box is not None:
            b = label.box
            centre = np.array([(b[0] + b[2]) / 2, (b[1] + b[3]) / 2], float)
        elif label.point is not None:
            centre = np.asarray(label.point, float).reshape(2)
        else:
            continue
        assert cal is not None and cal.camera is not None  # admitted
        obs.append(BallObservation(f.id, stored_camera(cal.camera), centre, float(f.width)))
    if len(obs) < 2:
        return None
    result = triangulate_ball(obs, tau_px=settings.triangulation_tau_px, rule=settings.pair_error_rule,
                              min_baseline_m=settings.min_baseline_m,
                              min_parallax_deg=float(PAPER_PROFILE["min_parallax_deg"]))
    return result.point


def _finite_number(value: Any) -> bool:
    """True for a JSON number that is a finite float (not a boolean, NaN, an infinity or an integer past floats)."""
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        return False
    try:
        return math.isfinite(float(value))
    except OverflowError:
        return False


def truth_balls(truth: Any) -> dict[tuple[str, str], np.ndarray]:
    """(match, system name) -> the true 3D ball (3,) world metres, from a synthetic set's truth JSON
    (``{"games": [{"match", "systems": [{"action", "ball_3d": [x, y, z] | null}]}]}``).

    Raises:
        ValueError: the truth is not of that shape, naming the place (``games[2].systems[0].ball_3d``) and what it
            should be: no ``games`` list, a game or system that is not an object, a game without its ``match``
            (text) or ``systems`` list, a system without its ``action``, a ``ball_3d`` that is not three finite
            numbers."""
    games = truth.get("games") if isinstance(truth, dict) else None
    if not isinstance(games, list):
        raise ValueError("expected a synthetic set's truth JSON: an object with a 'games' list")
    out = {}
    for i, g in enumerate(games):
        if not isinstance(g, dict):
            raise ValueError(f"games[{i}]: expected a game (an object with 'match' and 'systems')")
        match, systems = g.get("match"), g.get("systems", [])
        if not isinstance(match, str) or not match:
            raise ValueError(f"games[{i}].match: expected the game's match (text)")
        if not isinstance(systems, list):
            raise ValueError(f"games[{i}].systems: expected a list of systems")
        for j, sy in enumerate(systems):
            where = f"games[{i}].systems[{j}]"
            if not isinstance(sy, dict):
                raise ValueError(f"{where}: expected a system (an object with 'action' and 'ball_3d')")
            action, ball = sy.get("action"), sy.get("ball_3d")
            if not isinstance(action, (str, int)) or isinstance(action, bool) or action == "":
                raise ValueError(f"{where}.action: expected the system's name (its action image)")
            if ball is None:
                continue
            if not (isinstance(ball, list) and len(ball) == 3 and all(_finite_number(v) for v in ball)):
                raise ValueError(f"{where}.ball_3d: expected three finite numbers (x, y, z in metres) or null")
            out[(match, str(action))] = np.asarray(ball, float)
    return out


def _systems(session: Session, batch: int, predictions: int) -> Iterator[tuple[str, System]]:
    """Every multi-view system with its game's match, ``batch`` at a time (what the recomputation loads, at most
    ``predictions`` a view)."""
    rows = session.execute(sa.select(System.id, Game.match).join(Game, Game.id == System.game_id)
                           .order_by(System.id)).all()
    for start in range(0, len(rows), batch):
        chunk = rows[start:start + batch]
        loaded = load_for_recompute(session, [r.id for r in chunk], predictions=predictions)
        for r in chunk:
            yield r.match, loaded[r.id]
        session.expunge_all()


def ball_yield(session: Session, settings: Settings, truth: Any = None,
               batch: int = 500) -> dict[str, Any]:
    """The systems with a 3D ball under the paper's rules and under v3d's, and with a right one given ``truth``
    (module docstring). Reads only.

    Raises:
        ValueError: ``truth`` is not a truth file's content (:func:`truth_balls`), before anything is read."""
    true = truth_balls(truth) if truth is not None else None
    counts = {rule: {"with_ball": 0, "right": 0, "wrong": 0} for rule in ("paper", "v3d")}
    n = matched = 0
    for match, system in _systems(session, batch, settings.max_predictions_per_frame):
        n += 1
        t = None if true is None else true.get((match, system.name))
        matched += t is not None
        tri = system.triangulation
        balls = {"paper": paper_ball(system, settings),
                 "v3d": None if tri is None or tri.ball3d is None else np.asarray(tri.ball3d, float)}
        for rule, ball in balls.items():
            if ball is None:
                continue
            counts[rule]["with_ball"] += 1
            if t is not None:
                e = float(np.linalg.norm(ball - t))
                counts[rule]["right"] += e <= RIGHT_M
                counts[rule]["wrong"] += e > WRONG_M
    out: dict[str, Any] = {"systems": n, "truth_systems": None if true is None else matched,
                           "right_m": RIGHT_M, "wrong_m": WRONG_M}
    for rule, c in counts.items():
        out[rule] = {"with_ball": c["with_ball"], "right": c["right"] if true is not None else None,
                     "wrong": c["wrong"] if true is not None else None}
    return out
