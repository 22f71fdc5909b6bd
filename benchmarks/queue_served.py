"""The default queue page served by the demo's server and the scale database's at the same time, their requests
interleaved: ``scale.py``'s ``queue_p95_ms`` (``GET /api/systems``, the default page of 50 rows) measured so that both
servers share whatever else the machine runs.

``scale.py`` measures the demo's server, then the scale one's, each in its own minutes: on a machine shared with other
jobs the two p95 figures then meet different loads, and their ratio says more about the load than about the code. Here
both servers run at once (``scale.Server``: ``v3d serve`` on loopback, an admin's token), and the requests alternate
in blocks of ``--block`` (demo, scale, demo, ...; the first block of each round alternates too). Reported per
database: wall p50 / p95 ms of a request, and the **server's CPU** per request (its process's user + system time over
each block, ``psutil``), the work done whatever the load; and the ratios scale / demo.

Usage::

    .venv/bin/python benchmarks/queue_served.py --db scale.sqlite3 [--demo-db demo.sqlite3] [--requests 300]
"""
from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from benchmarks.scale import Server, build_demo_db, percentile  # noqa: E402  # after the checkout is on the path


def _cpu_s(pid: int) -> float:
    """User + system CPU seconds of process ``pid`` and its children so far."""
    import psutil

    proc = psutil.Process(pid)
    total = 0.0
    for p in [proc, *proc.children(recursive=True)]:
        try:
            t = p.cpu_times()
            total += t.user + t.system
        except psutil.NoSuchProcess:
            pass
    return total


def measure(servers: dict[str, Server], requests: int, block: int, path: str) -> dict[str, dict[str, float]]:
    """Per server name: wall p50 / p95 ms and mean server CPU ms per request of ``requests`` requests of ``path``,
    sent in alternating blocks of ``block``."""
    import httpx

    clients = {name: httpx.Client(base_url=s.base_url, headers=s.headers, timeout=60.0) for name, s in servers.items()}
    walls: dict[str, list[float]] = {name: [] for name in servers}
    cpus: dict[str, list[float]] = {name: [] for name in servers}
    try:
        for client in clients.values():  # warm-up: imports, caches, the connection pool
            for _ in range(10):
                client.get(path).raise_for_status()
        names = list(servers)
        for r in range(max(1, requests // block)):
            for name in names if r % 2 == 0 else names[::-1]:
                client, pid = clients[name], servers[name].proc.pid  # type: ignore[union-attr]  # a started server
                c0 = _cpu_s(pid)
                for _ in range(block):
                    t0 = time.perf_counter()
                    client.get(path).raise_for_status()
                    walls[name].append((time.perf_counter() - t0) * 1000.0)
                cpus[name].append((_cpu_s(pid) - c0) * 1000.0 / block)
    finally:
        for client in clients.values():
            client.close()
    return {name: {"p50_ms": percentile(walls[name], 50), "p95_ms": percentile(walls[name], 95),
                   "cpu_ms": sum(cpus[name]) / len(cpus[name])} for name in servers}


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--db", type=Path, required=True, help="The scale database (SQLite).")
    p.add_argument("--demo-db", type=Path, help="The demo's database (default: built as scale.py builds it).")
    p.add_argument("--requests", type=int, default=300, help="Requests per server (default 300).")
    p.add_argument("--block", type=int, default=10, help="Requests per block before switching server (default 10).")
    p.add_argument("--path", default="/api/systems", help="The request (default: the default queue page).")
    args = p.parse_args(argv)
    with tempfile.TemporaryDirectory(prefix="v3d-queue-served-") as tmp:
        demo = args.demo_db or build_demo_db(Path(tmp))
        with Server(demo) as d, Server(args.db) as s:
            out = measure({"demo": d, "scale": s}, args.requests, args.block, args.path)
    for name, f in out.items():
        print(f"{name:<6} wall p50 {f['p50_ms']:6.1f} ms  p95 {f['p95_ms']:6.1f} ms  server CPU {f['cpu_ms']:5.2f} ms "
              "a request")
    d, s = out["demo"], out["scale"]
    print(f"ratio  wall p50 {s['p50_ms'] / d['p50_ms']:.2f}  p95 {s['p95_ms'] / d['p95_ms']:.2f}  "
          f"server CPU {s['cpu_ms'] / d['cpu_ms']:.2f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
