"""Server CPU per request, as a ratio to ``GET /api/health`` (issue 29's table), in one run.

One run makes a fresh demo database (``benchmarks.load.fresh_database``), starts the real server with one
worker (``v3d serve --workers 1``, a subprocess) and an annotator, then measures, in interleaved rounds, the
server process's CPU time (user + system, ``psutil`` over the server and its children: the same counters as
``/proc/<pid>/stat``) spent on a batch of each request, one client, one request at a time:

* ``health``: ``GET /api/health``;
* ``page``: ``GET /api/systems/{id}`` of a 4-view system (its wire and JSON sizes are printed, asked with
  ``Accept-Encoding: gzip``);
* ``ball``: ``PATCH /api/frames/{id}/ball`` moving the view's box by 2-3 px back and forth (every edit changes
  the label, so none skips its recomputation);
* ``line``: ``PUT /api/frames/{id}/field-lines`` moving one point of the view's lines by 0.05 px back and forth.

Each round runs every kind's batch in a shuffled order; the per-request CPU of a kind is its batch's CPU over its
size; the figures printed are the medians over rounds (ms) and their ratios to health's median. Interleaving the
kinds in every round keeps a slow phase of the machine from falling on one kind only.

Bounded: ``--rounds`` x ``--batch`` requests per kind, a timeout per request, loopback only; the server is stopped
at the end.

Usage (from the checkout)::

    .venv/bin/python benchmarks/request_cpu.py --rounds 7 --batch 10
    .venv/bin/python benchmarks/request_cpu.py --database-url postgresql+psycopg://postgres@127.0.0.1:5432/test
    git archive 158795d | tar -x -C /tmp/old && .venv/bin/python benchmarks/request_cpu.py --against /tmp/old
"""
from __future__ import annotations

import argparse
import json
import os
import random
import statistics
import sys
from pathlib import Path
from typing import Any, Callable, Optional

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from benchmarks.load import fresh_database, served, user_tokens
from benchmarks.scale import BenchError

KINDS = ("health", "page", "ball", "line")


def server_process(port: int) -> Any:
    """The ``psutil.Process`` of the server listening on ``port`` (the one whose command line names it).

    Raises:
        BenchError: no such process.
    """
    import psutil

    for proc in psutil.process_iter(["cmdline"]):
        cmd = proc.info.get("cmdline") or []
        if "serve" in cmd and "--port" in cmd and str(port) in cmd:
            return proc
    raise BenchError(f"no server process found for port {port}")


def cpu_seconds(proc: Any) -> float:
    """CPU seconds of ``proc`` and of its living children (uvicorn's workers): the sum over their threads of the
    time on a CPU that ``/proc/<pid>/task/<tid>/schedstat`` counts in nanoseconds; where the kernel has no
    schedstat, user + system time from psutil (``/proc/<pid>/stat``, 10 ms clock ticks: a batch of 40 requests
    then resolves 0.25 ms per request)."""
    total = 0.0
    for p in [proc, *proc.children(recursive=True)]:
        try:
            total += _schedstat_seconds(p.pid)
        except OSError:  # no schedstat here, or a child that ended between the listing and the read
            try:
                t = p.cpu_times()
                total += t.user + t.system
            except Exception:
                pass
    return total


def _schedstat_seconds(pid: int) -> float:
    """CPU seconds of every living thread of process ``pid``, from their schedstat (ns). Raises OSError."""
    ns = 0
    for tid in os.listdir(f"/proc/{pid}/task"):
        try:
            with open(f"/proc/{pid}/task/{tid}/schedstat") as fh:
                ns += int(fh.read().split()[0])
        except FileNotFoundError:  # a thread that ended meanwhile
            pass
    return ns / 1e9


def postgres_cpu_seconds(database: str) -> float:
    """User + system CPU seconds of the PostgreSQL backends serving ``database`` (their process titles name it:
    ``postgres: USER DATABASE HOST(PORT) STATE``); 0 when there are none."""
    import psutil

    total = 0.0
    for p in psutil.process_iter(["cmdline"]):
        title = " ".join(p.info.get("cmdline") or [])
        if title.startswith("postgres: ") and f" {database} " in title:
            try:
                t = p.cpu_times()
                total += t.user + t.system
            except Exception:
                pass
    return total


def four_view_system(client: Any) -> dict[str, Any]:
    """The system view of the first system with four views, each with a ball box and field lines.

    Raises:
        BenchError: the database holds none.
    """
    for s in client.get("/api/systems", params={"sort": "name", "limit": 500}).json()["items"]:
        view = client.get(f"/api/systems/{s['id']}").json()
        views = view["views"]
        if len(views) == 4 and all(v["ball"]["kind"] == "box" and v["field_lines"] for v in views):
            return view
    raise BenchError("no 4-view system with ball boxes in the database")


def requests_of(client: Any, system: dict[str, Any]) -> dict[str, Callable[[int], Any]]:
    """One callable per kind, taking the request's sequence number and sending it (asserting a 2xx)."""
    view = system["views"][0]
    fid, box = view["frame_id"], view["ball"]["box"]
    lines = client.get(f"/api/frames/{fid}").json()["field_lines"]
    cls = next(c for c, polys in lines.items() if polys and polys[0])

    etag = [client.get(f"/api/frames/{fid}").headers["ETag"]]  # writes send If-Match: the frame's newest ETag

    def ok(r: Any) -> Any:
        if r.status_code >= 300:
            raise BenchError(f"{r.request.method} {r.request.url.path}: {r.status_code} {r.text[:200]}")
        if r.request.method != "GET":
            etag[0] = r.headers["ETag"]
        return r

    def ball(i: int) -> Any:
        d = 2.0 + (i % 2)  # 2 px or 3 px: every edit changes the stored box
        return ok(client.patch(f"/api/frames/{fid}/ball", headers={"If-Match": etag[0]},
                               json={"box": [box[0] + d, box[1], box[2] + d, box[3]]}))

    def line(i: int) -> Any:
        moved = json.loads(json.dumps(lines))
        moved[cls][0][0][0] += 0.05 * (1 + i % 2)
        return ok(client.put(f"/api/frames/{fid}/field-lines", headers={"If-Match": etag[0]}, json={"lines": moved}))

    return {
        "health": lambda i: ok(client.get("/api/health")),
        "page": lambda i: ok(client.get(f"/api/systems/{system['id']}", headers={"Accept-Encoding": "gzip"})),
        "ball": ball,
        "line": line,
    }


def measure(base: str, token: str, rounds: int, batch: int, seed: int,
            postgres_database: Optional[str] = None) -> dict[str, Any]:
    """Per-request server CPU (ms, medians over ``rounds``) of each kind, their ratios to health, and the
    system page's sizes (bytes on the wire and of its JSON); with ``postgres_database`` also the CPU of the
    PostgreSQL backends serving it (ms per request, medians)."""
    import httpx

    port = int(base.rsplit(":", 1)[1])
    proc = server_process(port)
    rng = random.Random(seed)
    with httpx.Client(base_url=base, headers={"Authorization": f"Bearer {token}"}, timeout=60.0) as client:
        system = four_view_system(client)
        send = requests_of(client, system)
        for kind in KINDS:  # warm every path once
            send[kind](0)
        per_kind: dict[str, list[float]] = {k: [] for k in KINDS}
        per_kind_pg: dict[str, list[float]] = {k: [] for k in KINDS}
        seq = 1
        for _ in range(rounds):
            order = list(KINDS)
            rng.shuffle(order)
            for kind in order:
                before = cpu_seconds(proc)
                pg_before = postgres_cpu_seconds(postgres_database) if postgres_database else 0.0
                for _ in range(batch):
                    send[kind](seq)
                    seq += 1
                per_kind[kind].append((cpu_seconds(proc) - before) / batch * 1000.0)
                if postgres_database:
                    per_kind_pg[kind].append((postgres_cpu_seconds(postgres_database) - pg_before) / batch * 1000.0)
        page = client.get(f"/api/systems/{system['id']}", headers={"Accept-Encoding": "gzip"})
        wire = page.num_bytes_downloaded
        size = len(page.content)
    med = {k: statistics.median(v) for k, v in per_kind.items()}
    pg = {k: statistics.median(v) for k, v in per_kind_pg.items()} if postgres_database else None
    return {"cpu_ms": med, "ratio": {k: med[k] / med["health"] for k in KINDS}, "postgres_cpu_ms": pg,
            "page_wire_bytes": wire, "page_json_bytes": size, "rounds": rounds, "batch": batch}


def measure_against(bases: dict[str, str], tokens: dict[str, str], rounds: int, batch: int,
                    seed: int) -> dict[str, Any]:
    """:func:`measure` of two servers in one run (``bases``: label -> base URL, each over its own database holding the
    demo; ``tokens``: label -> an annotator's API token there): every round runs each (server, kind) batch once, in a
    shuffled order, so a slow phase of the machine falls on both alike. Returns per server its medians (ms) and ratios
    to its health, and the ratio of each kind's median to the first server's (``ratio_to``: the second label's over the
    first's)."""
    import httpx

    rng = random.Random(seed)
    procs = {label: server_process(int(base.rsplit(":", 1)[1])) for label, base in bases.items()}
    clients = {label: httpx.Client(base_url=base, headers={"Authorization": f"Bearer {tokens[label]}"},
                                   timeout=60.0) for label, base in bases.items()}
    try:
        send = {}
        for label, client in clients.items():
            send[label] = requests_of(client, four_view_system(client))
            for kind in KINDS:  # warm every path once
                send[label][kind](0)
        per: dict[str, dict[str, list[float]]] = {label: {k: [] for k in KINDS} for label in bases}
        seq = 1
        for _ in range(rounds):
            order = [(label, kind) for label in bases for kind in KINDS]
            rng.shuffle(order)
            for label, kind in order:
                before = cpu_seconds(procs[label])
                for _ in range(batch):
                    send[label][kind](seq)
                    seq += 1
                per[label][kind].append((cpu_seconds(procs[label]) - before) / batch * 1000.0)
    finally:
        for client in clients.values():
            client.close()
    med = {label: {k: statistics.median(v) for k, v in kinds.items()} for label, kinds in per.items()}
    first, second = list(bases)
    return {"cpu_ms": med, "ratio": {label: {k: m[k] / m["health"] for k in KINDS} for label, m in med.items()},
            "ratio_to": {k: med[second][k] / med[first][k] for k in KINDS}, "rounds": rounds, "batch": batch}


def main(argv: Optional[list[str]] = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--database-url", default=None, help="PostgreSQL server URL (default: a SQLite file)")
    ap.add_argument("--rounds", type=int, default=7)
    ap.add_argument("--batch", type=int, default=10)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--json", action="store_true", help="print the result as JSON")
    ap.add_argument("--against", type=Path, default=None,
                    help="a checkout of other code (``git archive REV | tar -x -C DIR``): both servers measured in "
                         "the same interleaved rounds, each over a demo database of its own (SQLite), and this "
                         "code's medians given as ratios to its")
    args = ap.parse_args(argv)
    if args.against is not None:
        return _main_against(args)
    with fresh_database(args.database_url) as url:
        token = user_tokens(url, 1)[0]
        with served(url, workers=1) as base:
            from sqlalchemy.engine import make_url

            u = make_url(url)
            pg = u.database if u.get_backend_name() == "postgresql" else None
            out = measure(base, token, args.rounds, args.batch, args.seed, postgres_database=pg)
    if args.json:
        print(json.dumps(out, indent=2))
        return 0
    print(f"server CPU per request, medians of {out['rounds']} interleaved rounds of {out['batch']}:")
    pg = out["postgres_cpu_ms"]
    print("| request | CPU ms | x health |" + (" PostgreSQL CPU ms |" if pg else ""))
    print("|---|---|---|" + ("---|" if pg else ""))
    for k in KINDS:
        print(f"| {k} | {out['cpu_ms'][k]:.1f} | {out['ratio'][k]:.1f} |" + (f" {pg[k]:.1f} |" if pg else ""))
    print(f"system page: {out['page_wire_bytes'] / 1024:.1f} KB on the wire, {out['page_json_bytes'] / 1024:.1f} KB "
          "JSON")
    return 0



def _main_against(args: argparse.Namespace) -> int:
    """``--against DIR``: this checkout's server and DIR's, each on a fresh demo database (SQLite) that its own code
    migrated and filled (their migrations may differ), one annotator's token each."""
    import subprocess
    import tempfile
    from contextlib import ExitStack

    from benchmarks.edit_lock import code_of

    if args.database_url is not None:
        raise BenchError("--against measures two servers on SQLite files of their own: leave --database-url out")
    root = args.against.resolve()
    prepare = ("import sys; from app.cli.serve import load_demo_if_empty; from app.core.config import Settings; "
               "from app.db.session import upgrade_database; upgrade_database(sys.argv[1]); "
               "print(load_demo_if_empty(Settings(database_url=sys.argv[1], calibration_workers=1)))")
    with fresh_database(None) as url, tempfile.TemporaryDirectory(prefix="v3d-against-") as tmp, ExitStack() as stack:
        tokens = {"this": user_tokens(url, 1)[0]}
        theirs_url = f"sqlite:///{Path(tmp) / 'against.sqlite3'}"
        with code_of(root):
            subprocess.run([sys.executable, "-c", prepare, theirs_url], cwd=root, env=dict(os.environ), check=True)
            tokens["against"] = user_tokens(theirs_url, 1)[0]
            theirs = stack.enter_context(served(theirs_url, workers=1))
        ours = stack.enter_context(served(url, workers=1))
        out = measure_against({"against": theirs, "this": ours}, tokens, args.rounds, args.batch, args.seed)
    if args.json:
        print(json.dumps(out, indent=2))
        return 0
    print(f"server CPU per request, medians of {out['rounds']} interleaved rounds of {out['batch']}, this checkout "
          f"against {args.against}:")
    print("| request | against: CPU ms | x health | this: CPU ms | x health | this / against |")
    print("|---|---|---|---|---|---|")
    for k in KINDS:
        a, t = out["cpu_ms"]["against"][k], out["cpu_ms"]["this"][k]
        print(f"| {k} | {a:.2f} | {out['ratio']['against'][k]:.1f} | {t:.2f} | {out['ratio']['this'][k]:.1f} | "
              f"{out['ratio_to'][k]:.2f} |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
