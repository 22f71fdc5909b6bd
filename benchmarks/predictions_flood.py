"""A flood of a detector's predictions against a served demo (the fourth security review's first finding): one zip of
``--rows`` (200,000) CSV predictions all on one image, uploaded to ``POST /api/imports`` (kind ``predictions``) by an
admin, while another annotator edits the ball of another system again and again; then that flooded system's page.

A fresh database holding the demo (SQLite in a temporary folder, or a new database on the PostgreSQL server of
``--database-url``), served by a real ``v3d serve --demo`` (``benchmarks/edge_attacks.py``'s ``demo_server``: a
subprocess on a free loopback port, one worker; ``--code DIR`` serves another checkout, e.g. ``/work/main`` for the
figures before a change). Its memory is sampled and ``GET /api/health`` polled (``edge_attacks.Watch``) throughout.

* **during the import**: ``ana2`` edits the ball of a view of another system (a nudge of 2 px, back and forth, each
  with the view's ``If-Match``) until the import's job has ended; every answer's status and seconds, and the three
  slowest with the job's stage when they began. Targets: never a 503, each within 3 s. Two edits are made before the
  upload (reported as ``warm_up_edits``): a served process's first ball edit loads and compiles what edits run.
* **afterwards**: three parallel ``GET /api/systems/{id}`` of the flooded system (target: each within 3 s), then one
  ball edit of its flooded view (within 5 s).

Everything is bounded in time (``--timeout-s``, 900: the import's job is waited for at most so long) and talks to the
loopback only. Run::

    .venv/bin/python benchmarks/predictions_flood.py [--rows 200000] [--code /work/main]
        [--database-url postgresql+psycopg://postgres@127.0.0.1:5432/test]
"""
from __future__ import annotations

import argparse
import io
import json
import random
import sys
import threading
import time
import zipfile
from collections import Counter
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from benchmarks.edge_attacks import PASSWORD, Watch, demo_server, v3d
from benchmarks.load import fresh_database

HEADER = "league,season,match,image,x1,y1,x2,y2,score\n"


def flood_zip(game: dict[str, Any], image: str, width: int, height: int, rows: int, seed: int = 0) -> bytes:
    """A zip holding one CSV of ``rows`` predictions, all on ``image`` of ``game``: boxes of a ball's size at random
    places of the ``width`` x ``height`` image, random scores (a detector run without non-maximum suppression)."""
    rng = random.Random(seed)
    text = io.StringIO()
    text.write(HEADER)
    prefix = f"{game['league']},{game['season']},{game['match']},{image}"
    for _ in range(rows):
        d = rng.uniform(8, 24)
        x, y = rng.uniform(0, width - d), rng.uniform(0, height - d)
        text.write(f"{prefix},{x:.2f},{y:.2f},{x + d:.2f},{y + d:.2f},{rng.random():.4f}\n")
    out = io.BytesIO()
    with zipfile.ZipFile(out, "w", zipfile.ZIP_DEFLATED) as zf:
        zf.writestr("flood.csv", text.getvalue())
    return out.getvalue()


def _nudge(client: Any, system_id: int, k: int, dx: float) -> tuple[str, float]:
    """One ball edit of view ``k`` of the system (its box moved ``dx`` px, with the view's ``If-Match``): its status
    and the edit's seconds (the read of the view's ETag not counted)."""
    import httpx

    try:
        view = client.get(f"/api/systems/{system_id}").json()["views"][k]
        box = view["ball"]["box"]
        t0 = time.perf_counter()
        answer = client.patch(f"/api/frames/{view['frame_id']}/ball", headers={"If-Match": view["etag"]},
                              json={"box": [box[0] + dx, box[1], box[2] + dx, box[3]]})
        return str(answer.status_code), time.perf_counter() - t0
    except httpx.HTTPError as exc:
        return type(exc).__name__, float("nan")


def _labelled_view(system: dict[str, Any]) -> int:
    """The index of the system's first view with a ball box."""
    return next(k for k, v in enumerate(system["views"]) if (v.get("ball") or {}).get("box"))


def flood(base: str, pid: int, tokens: dict[str, str], rows: int, timeout_s: float) -> dict[str, Any]:
    """The attack and its figures (module docstring)."""
    import httpx

    admin = httpx.Client(base_url=base, timeout=120.0, headers={"Authorization": f"Bearer {tokens['adm']}"})
    editor = httpx.Client(base_url=base, timeout=120.0, headers={"Authorization": f"Bearer {tokens['ana2']}"})
    listed = admin.get("/api/systems", params={"limit": 50}).json()["items"]
    systems = [admin.get(f"/api/systems/{s['id']}").json() for s in listed[:10]]
    labelled = [s for s in systems if any((v.get("ball") or {}).get("box") for v in s["views"])]
    target, other = labelled[0], labelled[1]
    k_target, k_other = _labelled_view(target), _labelled_view(other)
    view = target["views"][k_target]
    data = flood_zip(target["game"], view["name"], view["width"], view["height"], rows)
    edits: list[tuple[str, float]] = []
    started: list[float] = []
    stages: list[tuple[float, str]] = []  # the import job's stage as polled: (seconds since the upload, stage)
    done = threading.Event()

    def edit_meanwhile() -> None:
        dx = 2.0
        while not done.is_set():
            started.append(time.perf_counter() - t0)
            edits.append(_nudge(editor, other["id"], k_other, dx))
            dx = -dx
            time.sleep(0.2)

    def stage_at(t: float) -> str:
        return next((st for at, st in reversed(stages) if at <= t), "upload")

    # a served process's first ball edit loads and compiles what edits run (seconds): made before the flood, as a
    # server that has been editing all day is warm, and reported apart
    cold = [_nudge(editor, other["id"], k_other, d) for d in (2.0, -2.0)]
    with Watch(base, pid) as watch:
        t0 = time.perf_counter()
        answer = admin.post("/api/imports", data={"kind": "predictions", "source": "flood"},
                            files={"file": ("flood.zip", data)})
        upload_s = time.perf_counter() - t0
        if answer.status_code != 202:
            raise RuntimeError(f"the upload was refused: {answer.status_code} {answer.text[:300]}")
        job_url = answer.json()["url"]
        editing = threading.Thread(target=edit_meanwhile)
        editing.start()
        job: dict[str, Any] = {}
        try:
            while time.perf_counter() - t0 < timeout_s:
                job = admin.get(job_url).json()
                stages.append((time.perf_counter() - t0, f"{job['state']} {job.get('stage') or ''}".strip()))
                if job["state"] in ("done", "failed"):
                    break
                time.sleep(0.5)
        finally:
            done.set()
            editing.join()
        import_s = time.perf_counter() - t0
        figures = watch.figures()
    with ThreadPoolExecutor(3) as pool:
        def load_page(_: int) -> tuple[int, float]:
            t = time.perf_counter()
            status = admin.get(f"/api/systems/{target['id']}").status_code
            return status, time.perf_counter() - t
        pages = list(pool.map(load_page, range(3)))
    after_edit = _nudge(editor, target["id"], k_target, 2.0)
    seconds = [s for _, s in edits if s == s]
    slowest = sorted(((d, at) for (_, d), at in zip(edits, started, strict=True) if d == d), reverse=True)[:3]
    result = job.get("result") or {}
    return {
        "warm_up_edits": [(status, round(sec, 3)) for status, sec in cold],
        "rows": rows, "zip_mb": round(len(data) / 2**20, 2), "upload_s": round(upload_s, 2),
        "job": job.get("state"), "job_message": job.get("message"), "import_s": round(import_s, 1),
        "stored": result.get("stored"), "dropped": result.get("dropped"), "batches": result.get("batches"),
        "edits_meanwhile": dict(Counter(status for status, _ in edits)),
        "edit_worst_s": round(max(seconds, default=float("nan")), 3),
        "edit_median_s": round(sorted(seconds)[len(seconds) // 2], 3) if seconds else None,
        "slowest_edits": [{"s": round(d, 2), "at_s": round(at, 1), "job": stage_at(at)} for d, at in slowest],
        "pages_after": [(status, round(s, 3)) for status, s in pages],
        "edit_after": (after_edit[0], round(after_edit[1], 3)),
        **figures,
    }


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--rows", type=int, default=200_000)
    parser.add_argument("--code", type=Path, default=ROOT, help="the checkout whose code is served")
    parser.add_argument("--database-url", default=None, help="a PostgreSQL server (a new database is made there)")
    parser.add_argument("--timeout-s", type=float, default=900.0)
    args = parser.parse_args(argv)
    code = args.code.resolve()
    with fresh_database(args.database_url) as url, demo_server(code, url, 1) as (base, pid, tokens):
        import os

        env = {**os.environ, "V3D_DATABASE_URL": url, "PYTHONPATH": str(code)}
        tokens["adm"] = v3d(code, env, "users", "add", "adm", "--role", "admin", "--password-stdin",
                            stdin=PASSWORD + "\n").strip().splitlines()[-1]
        result = flood(base, pid, tokens, args.rows, args.timeout_s)
        print(json.dumps({"code": str(args.code), "database": url.split(":", 1)[0], **result}), flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
