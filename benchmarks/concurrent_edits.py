"""Concurrent edits of the same systems through ``v3d serve --workers 2``, then ``v3d recompute`` in a new process:
the recomputation must change no stored result (an edit and its recomputation commit together, from the labels the
edit's lock saw).

One run makes a fresh demo database (``benchmarks.load.fresh_database``), one annotator and its API token, starts the
real server with two worker processes, and runs ``--clients`` clients on that one token at once, ``--edits`` edits
each, over the views of the demo's first ``--systems`` systems of four views: each edit reads its view (``GET
/api/frames/{id}``, its ETag) and then either moves the view's ball box by 2-8 px or toggles its exclusion, with
``If-Match`` of what it read (412 when another client wrote the view in between). The server is stopped, the derived
tables are read (``triangulations``, ``triangulation_pairs``, ``ball_reprojections``, ``optimised_boxes``,
``doubts``, the queue's figures on ``systems``; time stamps and ids left out), ``v3d recompute`` runs in a new
process, and the tables are read again: they must be equal.

Bounded: ``--clients`` x ``--edits`` requests with a timeout each, loopback only; the server is stopped at the end.

Usage (from the checkout)::

    .venv/bin/python benchmarks/concurrent_edits.py --clients 6 --edits 30
    .venv/bin/python benchmarks/concurrent_edits.py --database-url postgresql+psycopg://postgres@127.0.0.1:5432/test
"""
from __future__ import annotations

import argparse
import collections
import json
import os
import random
import subprocess
import sys
import threading
from pathlib import Path
from typing import Any, Optional

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from benchmarks.load import fresh_database, served, user_tokens
from benchmarks.scale import BenchError, v3d_command

#: The derived tables compared and the columns left out of the comparison (when they were computed, row ids).
DERIVED: dict[str, tuple[str, ...]] = {
    "triangulations": ("computed_at",), "triangulation_pairs": ("id",), "ball_reprojections": (),
    "optimised_boxes": (), "doubts": ("id",),
    "systems": ("version", "created_at", "assigned_at", "assignee_id", "assigned_by"),
}


def derived_rows(database_url: str) -> dict[str, list[str]]:
    """Every row of the :data:`DERIVED` tables as sorted JSON (floats rounded to 1e-6), per table."""
    import sqlalchemy as sa

    from app.db.session import make_engine

    def norm(v: Any) -> Any:
        if isinstance(v, float):
            return round(v, 6)
        if isinstance(v, (list, tuple)):
            return [norm(x) for x in v]
        if isinstance(v, dict):
            return {k: norm(x) for k, x in v.items()}
        return v if v is None or isinstance(v, (int, str, bool)) else str(v)

    engine = make_engine(database_url)
    out: dict[str, list[str]] = {}
    try:
        with engine.connect() as conn:
            meta = sa.MetaData()
            for table, left_out in DERIVED.items():
                t = sa.Table(table, meta, autoload_with=conn)
                cols = [c for c in t.c if c.name not in left_out]
                rows = conn.execute(sa.select(*cols)).mappings().all()
                out[table] = sorted(json.dumps(norm(dict(r)), sort_keys=True, default=str) for r in rows)
    finally:
        engine.dispose()
    return out


def run(database_url: Optional[str] = None, clients: int = 6, edits: int = 30, systems: int = 4,
        seed: int = 1, timeout_s: float = 60.0) -> dict[str, Any]:
    """One bounded run (module docstring); its figures: statuses counted, the recomputation's differences.

    Raises:
        BenchError: the database, the server or ``v3d recompute`` failed.
    """
    import httpx

    statuses: collections.Counter[int] = collections.Counter()
    with fresh_database(database_url) as url:
        token = user_tokens(url, 1)[0]
        headers = {"Authorization": f"Bearer {token}"}
        with served(url, 2) as base:
            with httpx.Client(base_url=base, timeout=timeout_s, headers=headers) as http:
                items = http.get("/api/systems", params={"sort": "name", "limit": 500}).json()["items"]
                views = []
                for item in items:
                    view = http.get(f"/api/systems/{item['id']}").json()
                    if len(view["views"]) == 4 and len({s for s, _ in views}) < systems:
                        views += [(item["id"], v["frame_id"]) for v in view["views"]]

            def client(i: int) -> None:
                rng = random.Random(seed * 1000 + i)
                with httpx.Client(base_url=base, timeout=timeout_s, headers=headers) as c:
                    for _ in range(edits):
                        _, fid = rng.choice(views)
                        got = c.get(f"/api/frames/{fid}")
                        etag, frame = got.headers["etag"], got.json()
                        box = frame["ball"]["box"]
                        if box is not None and rng.random() < 0.7:
                            dx, dy = rng.uniform(2, 8) * rng.choice((-1, 1)), rng.uniform(2, 8) * rng.choice((-1, 1))
                            answer = c.patch(f"/api/frames/{fid}/ball", headers={"If-Match": etag},
                                             json={"box": [box[0] + dx, box[1] + dy, box[2] + dx, box[3] + dy]})
                        else:
                            excluded = bool(frame["review"] and frame["review"].get("excluded"))
                            answer = c.post(f"/api/frames/{fid}/exclusion", headers={"If-Match": etag},
                                            json={"excluded": not excluded})
                        statuses[answer.status_code] += 1

            threads = [threading.Thread(target=client, args=(i,)) for i in range(clients)]
            for t in threads:
                t.start()
            for t in threads:
                t.join()
        before = derived_rows(url)
        done = subprocess.run([*v3d_command(), "recompute"], env={**os.environ, "V3D_DATABASE_URL": url},
                              cwd=ROOT, capture_output=True, text=True, timeout=600)
        if done.returncode != 0:
            raise BenchError(f"v3d recompute failed ({done.returncode}): {done.stderr[-500:]}")
        after = derived_rows(url)
    changed = {t: len(set(before[t]) ^ set(after[t])) for t in DERIVED if before[t] != after[t]}
    return {"clients": clients, "edits": clients * edits, "statuses": dict(sorted(statuses.items())),
            "rows": {t: len(rows) for t, rows in before.items()}, "changed_by_recompute": changed}


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--database-url", default=None, help="PostgreSQL server URL (default: a SQLite file)")
    ap.add_argument("--clients", type=int, default=6)
    ap.add_argument("--edits", type=int, default=30, help="edits per client")
    ap.add_argument("--systems", type=int, default=4)
    ap.add_argument("--seed", type=int, default=1)
    args = ap.parse_args()
    figures = run(args.database_url, args.clients, args.edits, args.systems, args.seed)
    print(json.dumps(figures, indent=1))
    ok = not figures["changed_by_recompute"] and not any(s >= 500 for s in figures["statuses"])
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
