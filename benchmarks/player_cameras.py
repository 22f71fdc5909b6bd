"""Cameras the lines cannot place, placed by the players: how many views' stored cameras put the true ball within
20 px (of a 1920-wide image) of its true centre, on each shared synthetic set imported alone.

Each set is imported with ``v3d import soccernet-v3`` (no predictions, no fixes) into a SQLite database under
``--db-dir`` (kept: a second run only scores), and each view's stored camera (what ``GET /api/systems/{id}`` shows as
``views[].calibration.camera``) projects the set's true 3D ball. Counted views: the true ball inside the image (by the
true camera). ``weak``: at most 3 line classes labelled (visible, not dropped) and at least 4 players (class and ID)
shared with the views of its system that have 4 or more classes; ``strong``: 4 or more classes. A view without a
camera counts as a miss. The ball label is never an input of a camera (``app.services.calibration.players``).

Run: ``nice -n 10 .venv/bin/python benchmarks/player_cameras.py [--sets dev-large seed-201 ...] [--db-dir DIR]``.
"""
from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time
from pathlib import Path
from typing import Any, Sequence

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import sqlalchemy as sa  # noqa: E402  # after the path set-up above that makes app importable
from sqlalchemy.orm import Session, selectinload  # noqa: E402  # after the path set-up above that makes app importable

from app.core.paths import SHARED_DIR  # noqa: E402  # after the path set-up above that makes app importable
from app.db.models import CalibrationStatus, Frame, System  # noqa: E402  # after the path set-up above that makes app importable
from app.geometry.calibration.result import PLAYERS_FLAG  # noqa: E402  # after the path set-up above that makes app importable
from app.geometry.camera import Camera  # noqa: E402  # after the path set-up above that makes app importable
from app.geometry.pair_error import REFERENCE_WIDTH_PX  # noqa: E402  # after the path set-up above that makes app importable

SYNTH = SHARED_DIR / "data" / "synthetic"
SETS: dict[str, Path] = {
    "dev-large": SYNTH / "soccernet-v3-dev-large",
    "v3-dev": SYNTH / "soccernet-v3-dev",
    **{f"seed-{n}": SYNTH / "doubts-seeds" / f"seed-{n}" for n in range(201, 206)},
    "detector-dev-large": SYNTH / "detector" / "dev-large-unlabelled",
    "detector-seed-204": SYNTH / "detector" / "seed-204-unlabelled",
}
#: A camera is right when it puts the true ball within this many px of a 1920-wide image of its true centre.
WITHIN_PX = 20.0


def imported(name: str, db_dir: Path) -> Path:
    """The set's database as ``v3d import soccernet-v3`` leaves it (imported when absent)."""
    db_dir.mkdir(parents=True, exist_ok=True)
    path = db_dir / f"{name}.sqlite3"
    if not path.exists():
        part = path.with_suffix(".part")
        part.unlink(missing_ok=True)
        env = {k: v for k, v in os.environ.items() if not k.startswith("V3D_")}
        env.update(V3D_DATABASE_URL=f"sqlite:///{part}", V3D_DATA_ROOT=str(SHARED_DIR / "data"), PYTHONPATH=str(ROOT))
        t0 = time.perf_counter()
        subprocess.run([str(Path(sys.executable).parent / "v3d"), "import", "soccernet-v3", str(SETS[name])],
                       cwd=ROOT, env=env, check=True, capture_output=True)
        print(f"[{name}] imported in {time.perf_counter() - t0:.0f} s", file=sys.stderr)
        part.rename(path)
    return path


def _classes(frame: Frame) -> int:
    lines = frame.field_lines.lines if frame.field_lines is not None else {}
    return sum(1 for polys in lines.values() if polys)


def _players(frame: Frame) -> set[tuple[str, str]]:
    return {(p.cls, p.ident) for p in frame.players if p.ident is not None}


def score(name: str, db: Path) -> dict[str, Any]:
    """The counts of set ``name`` imported in ``db``."""
    truth = json.loads(SETS[name].with_name(SETS[name].name + ".truth.json").read_text())
    with Session(sa.create_engine(f"sqlite:///{db}")) as session:
        return score_session(session, truth)


def score_session(session: Session, truth: dict[str, Any]) -> dict[str, int]:
    """The counts of every stored system against ``truth`` (a synthetic set's truth file, parsed): ``weak`` /
    ``strong`` views (module docstring) and how many of them have a camera within :data:`WITHIN_PX` of the true
    ball (``*_right``), the weak views placed by players (``weak_by_players``, ``weak_by_players_right``), the weak
    views without a camera, and the cameras placed by players anywhere that miss (``by_players_wrong``)."""
    views = {(g["match"], s["action"], v["image"]): (s["ball_3d"], v["camera"])
             for g in truth["games"] for s in g["systems"] for v in s["views"]}
    out = {k: 0 for k in ("weak", "weak_right", "weak_by_players", "weak_by_players_right", "weak_no_camera",
                          "strong", "strong_right", "by_players_wrong")}
    frames = selectinload(System.frames)
    systems = session.scalars(sa.select(System).options(
        selectinload(System.game), frames.selectinload(Frame.calibration), frames.selectinload(Frame.field_lines),
        frames.selectinload(Frame.players))).all()
    for system in systems:
        strong_players: dict[int, set[tuple[str, str]]] = {
            f.id: _players(f) for f in system.frames if _classes(f) >= 4}
        for f in system.frames:
            ball, true_cam = views[(system.game.match, system.name, f.name)]
            true = Camera.from_soccernet(true_cam)
            uv_true, ok = true.project(np.array([ball], float))
            if not ok[0] or not (0 <= uv_true[0, 0] < f.width and 0 <= uv_true[0, 1] < f.height):
                continue
            n = _classes(f)
            shared = set().union(*[p for fid, p in strong_players.items() if fid != f.id]) & _players(f)
            if n >= 4:
                kind = "strong"
            elif len(shared) >= 4:
                kind = "weak"
            else:
                continue
            cal = f.calibration
            right = False
            if cal is not None and cal.status is CalibrationStatus.CALIBRATED and cal.camera is not None:
                uv, good = Camera.from_soccernet(cal.camera).project(np.array([ball], float))
                right = bool(good[0]) and float(np.linalg.norm(uv[0] - uv_true[0])) * (
                    REFERENCE_WIDTH_PX / f.width) <= WITHIN_PX
                by_players = PLAYERS_FLAG in (cal.flags or [])
                if kind == "weak" and by_players:
                    out["weak_by_players"] += 1
                    out["weak_by_players_right"] += right
                if by_players and not right:
                    out["by_players_wrong"] += 1
            elif kind == "weak":
                out["weak_no_camera"] += 1
            out[kind] += 1
            out[f"{kind}_right"] += right
    return out


def main(argv: Sequence[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--sets", nargs="+", default=list(SETS), choices=list(SETS))
    ap.add_argument("--db-dir", type=Path, default=Path("/tmp/v3d-player-cameras"))
    ap.add_argument("--json", type=Path, help="write the counts here too")
    args = ap.parse_args(argv)
    results = {}
    for name in args.sets:
        r = score(name, imported(name, args.db_dir))
        results[name] = r
        pct = lambda a, b: 100.0 * a / b if b else float("nan")  # noqa: E731  # a one-line helper local to the table it formats
        print(f"{name:20s} weak {r['weak_right']}/{r['weak']} ({pct(r['weak_right'], r['weak']):.1f} %) within "
              f"{WITHIN_PX:g} px, {r['weak_by_players']} placed by players ({r['weak_by_players_right']} right), "
              f"{r['weak_no_camera']} without camera; strong {r['strong_right']}/{r['strong']} "
              f"({pct(r['strong_right'], r['strong']):.1f} %); cameras by players off: {r['by_players_wrong']}",
              flush=True)
    if args.json:
        args.json.write_text(json.dumps(results, indent=2))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
