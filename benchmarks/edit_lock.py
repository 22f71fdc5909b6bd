"""An unrelated write during a capped-size field-line edit, on a real server (issue 27, item 4).

Before issue 27 an edit computed its recomputation while it held the database's write lock: during a
96,000-point field-line edit (51 s of calibration) an unrelated review waited 60 s and got 500 "database is
locked". Now a line edit gives a view at most ``V3D_MAX_LINE_POINTS_PER_FRAME`` points (2,000) and computes
before it takes the lock. This benchmark, per round:

0. another annotator's write alone (``PATCH /api/frames/{id}/ball`` on a view of another system, its box moved by
   1 px, then back): its status and time (``alone``);
1. one annotator sends ``PUT /api/frames/{id}/field-lines`` with the view's lines resampled to ``--points``
   points (default 2,000: the cap), in a thread;
2. ``--delay`` seconds later (the edit is computing) the same write again (``unrelated_write``), with whether it
   finished before the line edit (``overlapped``);
3. the line edit's status and time.

Then one edit of ``--refused-points`` (96,000, whole pixels so that the body stays within ``V3D_MAX_JSON_KB``) is
sent and its status and time recorded (422 at once when capped).

The server is ``v3d serve --workers N`` on a fresh SQLite (or PostgreSQL) database holding the demo
(``benchmarks.load.fresh_database``, ``served``); ``--root`` runs the server from another checkout (e.g. main's) on
the same database schema, so that both are measured in one run. Prints one JSON object.

Usage::

    .venv/bin/python benchmarks/edit_lock.py --rounds 3
    .venv/bin/python benchmarks/edit_lock.py --rounds 3 --root /work/main --refused-points 0
"""
from __future__ import annotations

import argparse
import copy
import json
import os
import sys
import threading
import time
from contextlib import contextmanager
from pathlib import Path
from typing import Any, Iterator, Optional

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from benchmarks import load


def dense_lines(lines: dict[str, Any], total: int, decimals: int = 3) -> dict[str, Any]:
    """``lines`` (``{class: [[[x, y], ...], ...]}``, px) with each polyline of two points or more resampled along
    its own segments, so that the set holds exactly ``total`` points (rounded to ``decimals``)."""
    polys = [(c, i, np.asarray(p, float)) for c, ps in lines.items() for i, p in enumerate(ps) if len(p) >= 2]
    per = [total // len(polys)] * len(polys)
    per[0] += total - sum(per)
    out = copy.deepcopy(lines)
    for (c, i, p), n in zip(polys, per, strict=False):
        seg = np.r_[0.0, np.cumsum(np.linalg.norm(np.diff(p, axis=0), axis=1))]
        t = np.linspace(0.0, seg[-1], n)
        out[c][i] = np.c_[np.interp(t, seg, p[:, 0]), np.interp(t, seg, p[:, 1])].round(decimals).tolist()
    return out


@contextmanager
def code_of(root: Optional[Path]) -> Iterator[None]:
    """Serve from ``root`` (its ``app`` package first on the path) for the block: the CLI and the servers started in
    it run ``root``'s code (None: this checkout's)."""
    if root is None:
        yield
        return
    old_root, old_path = load.ROOT, os.environ.get("PYTHONPATH")
    load.ROOT = root
    os.environ["PYTHONPATH"] = str(root)
    try:
        yield
    finally:
        load.ROOT = old_root
        if old_path is None:
            os.environ.pop("PYTHONPATH", None)
        else:
            os.environ["PYTHONPATH"] = old_path


def _line_edit(base: str, token: str, frame_id: int, lines: dict[str, Any], out: dict[str, Any]) -> None:
    import httpx

    headers = {"Authorization": f"Bearer {token}"}
    etag = httpx.get(f"{base}/api/frames/{frame_id}", headers=headers, timeout=30).headers["ETag"]
    t0 = time.monotonic()
    r = httpx.put(f"{base}/api/frames/{frame_id}/field-lines", json={"lines": lines},
                  headers={**headers, "If-Match": etag}, timeout=600)
    out.update(status=r.status_code, seconds=round(time.monotonic() - t0, 3), end=time.monotonic())


def _ball_edit(base: str, token: str, frame_id: int, box: list[float], dx: float) -> dict[str, Any]:
    """``PATCH /api/frames/{frame_id}/ball`` with ``box`` moved by ``dx`` px: status, seconds, Retry-After, end."""
    import httpx

    headers = {"Authorization": f"Bearer {token}"}
    etag = httpx.get(f"{base}/api/frames/{frame_id}", headers=headers, timeout=120).headers["ETag"]
    t0 = time.monotonic()
    r = httpx.patch(f"{base}/api/frames/{frame_id}/ball", json={"box": [box[0] + dx, box[1], box[2] + dx, box[3]]},
                    headers={**headers, "If-Match": etag}, timeout=600)
    end = time.monotonic()
    return {"status": r.status_code, "seconds": round(end - t0, 3), "retry_after": r.headers.get("Retry-After"),
            "end": end}


def run(database_url: Optional[str], rounds: int, points: int, refused_points: int, delay_s: float, workers: int,
        root: Optional[Path]) -> dict[str, Any]:
    """The measurement of the module docstring; returns its figures."""
    import httpx

    result: dict[str, Any] = {"points": points, "workers": workers, "root": str(root or load.ROOT), "rounds": []}
    with load.fresh_database(database_url) as url:
        tokens = load.user_tokens(url, 2)
        with code_of(root), load.served(url, workers) as base:
            a = {"Authorization": f"Bearer {tokens[0]}"}
            systems = httpx.get(f"{base}/api/systems", params={"sort": "name", "limit": 50}, headers=a,
                                timeout=30).json()["items"]
            views = load.labelled_views(httpx.Client(base_url=base, headers=a, timeout=60))
            edited = systems[0]["id"]
            view = httpx.get(f"{base}/api/systems/{edited}", headers=a, timeout=30).json()["views"][0]
            frame_id = view["frame_id"]
            _, other_frame, other_box, _, _ = next(v for v in views if v[0] != edited)
            lines = httpx.get(f"{base}/api/frames/{frame_id}", headers=a, timeout=30).json()["field_lines"]
            result["line_classes"] = len(lines)
            for k in range(rounds):
                shifted = dense_lines(lines, points)
                first = next(iter(shifted))
                shifted[first][0][0] = [shifted[first][0][0][0] + 0.5 * (k + 1), shifted[first][0][0][1]]
                alone = _ball_edit(base, tokens[1], other_frame, other_box, 1.0)
                _ball_edit(base, tokens[1], other_frame, other_box, 0.0)
                edit: dict[str, Any] = {}
                thread = threading.Thread(target=_line_edit, args=(base, tokens[0], frame_id, shifted, edit))
                thread.start()
                time.sleep(delay_s)
                during = _ball_edit(base, tokens[1], other_frame, other_box, 1.0)
                thread.join()
                _ball_edit(base, tokens[1], other_frame, other_box, 0.0)
                result["rounds"].append({
                    "alone": {k2: v for k2, v in alone.items() if k2 != "end"},
                    "unrelated_write": {k2: v for k2, v in during.items() if k2 != "end"},
                    "line_edit": {k2: v for k2, v in edit.items() if k2 != "end"},
                    "overlapped": during["end"] < edit.get("end", 0.0),
                })
            if refused_points:
                edit = {}
                _line_edit(base, tokens[0], frame_id, dense_lines(lines, refused_points, decimals=0), edit)
                result["refused"] = {"points": refused_points, "status": edit["status"], "seconds": edit["seconds"]}
    return result


def main(argv: Optional[list[str]] = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--database-url", default=None, help="a PostgreSQL server URL (default: a SQLite file)")
    p.add_argument("--rounds", type=int, default=3)
    p.add_argument("--points", type=int, default=2000, help="points of each line edit (the cap: 2,000)")
    p.add_argument("--refused-points", type=int, default=96_000, help="points of the last edit (0: none)")
    p.add_argument("--delay", type=float, default=0.3, help="seconds between the line edit and the unrelated write")
    p.add_argument("--workers", type=int, default=2)
    p.add_argument("--root", type=Path, default=None, help="serve from this checkout (e.g. main's)")
    a = p.parse_args(argv)
    print(json.dumps(run(a.database_url, a.rounds, a.points, a.refused_points, a.delay, a.workers, a.root), indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
