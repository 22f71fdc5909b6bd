"""A login flood and an oversized body against the real server (issue 15's closing figures).

A fresh SQLite database with one admin, served by ``v3d serve`` as a subprocess (``benchmarks.load.served``).
Then:

* **flood**: ``--attempts`` wrong passwords for the admin's name (default 60), ``--concurrency`` at once
  (default 16), while another client asks ``GET /api/health`` every 25 ms. Prints the statuses (401 until the
  per-name limit, 429 after), the health probe's median and worst time during the flood and before it
  (idle), and whether the right password is refused (429) at the end, as it must be within the window.
* **body**: a JSON body of ``--body-mb`` MB (default 20) to ``POST /api/auth/login``: status and time.

Run::

    .venv/bin/python benchmarks/login_flood.py [--attempts 60 --concurrency 16 --body-mb 20]

``tests/benchmarks/test_login_flood.py`` runs a small version.
"""
from __future__ import annotations

import argparse
import statistics
import sys
import tempfile
import threading
import time
from collections import Counter
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parent.parent
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from benchmarks.load import served

NAME, PASSWORD = "flood-admin", "the right password"


def _probe(base: str, stop: threading.Event, times: list[float], statuses: Counter) -> None:
    import httpx

    with httpx.Client(base_url=base, timeout=30.0) as client:
        while not stop.is_set():
            t0 = time.perf_counter()
            statuses[client.get("/api/health").status_code] += 1
            times.append((time.perf_counter() - t0) * 1000.0)
            time.sleep(0.025)


def _health(base: str, seconds: float) -> list[float]:
    stop, times, statuses = threading.Event(), [], Counter()
    thread = threading.Thread(target=_probe, args=(base, stop, times, statuses))
    thread.start()
    time.sleep(seconds)
    stop.set()
    thread.join()
    return times


def flood(base: str, attempts: int, concurrency: int) -> dict[str, Any]:
    """The flood against ``base``: statuses, health times (ms) idle and during, and the right password after."""
    import httpx

    idle = _health(base, 1.0)
    stop, during, health_status = threading.Event(), [], Counter()
    probe = threading.Thread(target=_probe, args=(base, stop, during, health_status))
    probe.start()

    def attempt(i: int) -> int:
        with httpx.Client(base_url=base, timeout=120.0) as client:
            return client.post("/api/auth/login", json={"name": NAME, "password": f"guess {i}"}).status_code

    t0 = time.perf_counter()
    with ThreadPoolExecutor(max_workers=concurrency) as pool:
        statuses = Counter(pool.map(attempt, range(attempts)))
    seconds = time.perf_counter() - t0
    stop.set()
    probe.join()
    import httpx as _httpx

    after = _httpx.post(f"{base}/api/auth/login", json={"name": NAME, "password": PASSWORD}, timeout=60.0)
    return {"attempts": attempts, "concurrency": concurrency, "statuses": dict(sorted(statuses.items())),
            "seconds": seconds, "right_password_after": after.status_code,
            "retry_after_s": after.headers.get("retry-after"),
            "health_statuses": dict(health_status), "health_idle_ms": _stats(idle), "health_during_ms": _stats(during)}


def oversized_body(base: str, megabytes: float) -> dict[str, Any]:
    """A JSON login body of ``megabytes`` MB: the answer's status and the time to it (s)."""
    import httpx

    body = b'{"name": "x", "password": "' + b"a" * int(megabytes * 2**20) + b'"}'
    t0 = time.perf_counter()
    answer = httpx.post(f"{base}/api/auth/login", content=body, headers={"Content-Type": "application/json"},
                        timeout=120.0)
    return {"megabytes": megabytes, "status": answer.status_code, "seconds": time.perf_counter() - t0}


def _stats(times: list[float]) -> dict[str, float]:
    return {"n": len(times), "median": statistics.median(times) if times else float("nan"),
            "worst": max(times) if times else float("nan")}


def run(attempts: int, concurrency: int, body_mb: float, workdir: Path) -> dict[str, Any]:
    """Set up the database and the admin, serve, and measure both."""
    from app.db.session import make_engine, make_session_factory, upgrade_database
    from app.services.accounts.users import create_user

    url = f"sqlite:///{workdir / 'flood.sqlite3'}"
    upgrade_database(url)
    engine = make_engine(url)
    with make_session_factory(engine)() as session:
        create_user(session, NAME, "admin", PASSWORD)
    engine.dispose()
    with served(url, workers=1, launcher="uvicorn") as base:
        return {"flood": flood(base, attempts, concurrency), "body": oversized_body(base, body_mb)}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--attempts", type=int, default=60)
    parser.add_argument("--concurrency", type=int, default=16)
    parser.add_argument("--body-mb", type=float, default=20.0)
    args = parser.parse_args(argv)
    with tempfile.TemporaryDirectory(prefix="v3d-flood-") as tmp:
        out = run(args.attempts, args.concurrency, args.body_mb, Path(tmp))
    f, b = out["flood"], out["body"]
    print(f"flood: {f['attempts']} wrong passwords, {f['concurrency']} at once, {f['seconds']:.1f} s: "
          f"statuses {f['statuses']}; the right password after: {f['right_password_after']} "
          f"(Retry-After {f['retry_after_s']} s)")
    print(f"/api/health idle: median {f['health_idle_ms']['median']:.1f} ms, worst {f['health_idle_ms']['worst']:.1f} "
          f"ms ({f['health_idle_ms']['n']}); during the flood: median {f['health_during_ms']['median']:.1f} ms, "
          f"worst {f['health_during_ms']['worst']:.1f} ms ({f['health_during_ms']['n']}, statuses "
          f"{f['health_statuses']})")
    print(f"body: {b['megabytes']:g} MB JSON to /api/auth/login: {b['status']} in {b['seconds']:.2f} s")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
