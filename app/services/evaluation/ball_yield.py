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

from typing import Any, Iterator, Mapping

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


def truth_balls(truth: Mapping[str, Any]) -> dict[tuple[str, str], np.ndarray]:
    """(match, system name) -> the true 3D ball (3,) world metres, from a synthetic set's truth JSON.

    Raises:
        ValueError: the truth has no ``games`` list (not a synthetic set's truth file)."""
    games = truth.get("games")
    if not isinstance(games, list):
        raise ValueError("truth: expected a synthetic set's truth JSON with a 'games' list")
    out = {}
    for g in games:
        for s in g.get("systems") or []:
            if s.get("ball_3d") is not None:
                out[(str(g["match"]), str(s["action"]))] = np.asarray(s["ball_3d"], float)
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


def ball_yield(session: Session, settings: Settings, truth: Mapping[str, Any] | None = None,
               batch: int = 500) -> dict[str, Any]:
    """The systems with a 3D ball under the paper's rules and under v3d's, and with a right one given ``truth``
    (module docstring). Reads only."""
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
