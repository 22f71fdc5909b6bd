"""The server's edge and each user's share under attack: the three attacks of the third security review that stalled,
filled or starved a running ``v3d serve --demo``, full size, with the figures they are judged by.

A fresh database holding the demo (SQLite in a temporary folder, or a new database on the PostgreSQL server of
``--database-url``), served by a real ``v3d serve --demo`` (a subprocess on a free loopback port, one worker unless
``--workers``; ``--code DIR`` serves another checkout's code, e.g. ``/work/main`` for the figures before a change).
Its process tree's resident memory is sampled every 20 ms (psutil) and ``GET /api/health`` is polled every 50 ms
throughout each attack:

* ``header``: one anonymous connection sends a request whose one header value is ``--header-mb`` MB (80), 1 MB at a
  time, until it is sent or the server closes the connection. Figures: the answer, health's worst latency (target
  < 2 s) and the server's memory growth (< 150 MB).
* ``previews``: two annotators each send ``--rounds`` (5) rounds of ``--parallel`` (30) parallel ``POST
  /api/frames/{id}/calibration-preview`` of their frames' own field lines cut finer (each polyline's segments split
  until the view has about ``--points`` (1,900) points), while a reviewer reads ``GET /api/systems/{id}`` in a loop.
  Figures: every status counted (no 5xx anywhere, the previews' included; 429 is a refusal of the share), the
  reviewer's worst latency (target: 200 within 5 s).
* ``unread``: the audit is first filled with line edits of such lines (``--edits``), then ``--sockets`` (40)
  connections each ask ``GET /api/audit?limit=500`` and never read the answer, for ``--hold-s`` seconds. Figures: the
  size of one such answer read whole (and of the 500 entries' pages when the answer is capped), the server's memory
  growth while they hold (< 150 MB) and after they close.

Run::

    .venv/bin/python benchmarks/edge_attacks.py [--attacks header,previews,unread] [--code /work/main]
        [--database-url postgresql+psycopg://postgres@127.0.0.1:5432/test]
"""
from __future__ import annotations

import argparse
import json
import os
import socket
import subprocess
import sys
import threading
import time
from collections import Counter
from concurrent.futures import ThreadPoolExecutor
from contextlib import contextmanager
from pathlib import Path
from typing import Any, Iterator, Optional

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from benchmarks.body_flood import read_status, tree_rss
from benchmarks.load import fresh_database
from benchmarks.scale import free_port

MB = 2**20
ATTACKS = ("header", "previews", "unread")
PASSWORD = "edge-attacks-password"


class Watch:
    """While the block runs: the server's peak resident memory (sampled every 20 ms) and ``GET /api/health`` every
    50 ms (each latency and status; a probe that fails counts as its exception's name)."""

    def __init__(self, base: str, pid: int) -> None:
        import psutil

        self.base, self.server = base, psutil.Process(pid)
        self.before = self.peak = tree_rss(self.server)
        self.health_s: list[float] = []
        self.health: Counter[str] = Counter()
        self._stop = threading.Event()

    def _sample(self) -> None:
        while not self._stop.is_set():
            self.peak = max(self.peak, tree_rss(self.server))
            time.sleep(0.02)

    def _probe(self) -> None:
        import httpx

        with httpx.Client(base_url=self.base, timeout=60.0) as client:
            while not self._stop.is_set():
                t0 = time.perf_counter()
                try:
                    self.health[str(client.get("/api/health").status_code)] += 1
                except httpx.HTTPError as exc:
                    self.health[type(exc).__name__] += 1
                self.health_s.append(time.perf_counter() - t0)
                time.sleep(0.05)

    def __enter__(self) -> "Watch":
        self._threads = [threading.Thread(target=self._sample), threading.Thread(target=self._probe)]
        for t in self._threads:
            t.start()
        return self

    def __exit__(self, *exc: Any) -> None:
        self._stop.set()
        for t in self._threads:
            t.join()

    def figures(self) -> dict[str, Any]:
        """Health's worst latency (s) and statuses, the memory before (MB) and its growth at the peak (MB)."""
        return {"health_worst_s": round(max(self.health_s, default=float("nan")), 3),
                "health": dict(self.health), "rss_before_mb": round(self.before / MB, 1),
                "rss_growth_mb": round((self.peak - self.before) / MB, 1)}


def v3d(code: Path, env: dict[str, str], *args: str, stdin: Optional[str] = None) -> str:
    """Run ``v3d ARGS`` with the code of ``code``; its standard output."""
    cmd = [sys.executable, "-c", "import sys; from app.cli import main; sys.argv[0] = 'v3d'; main()", *args]
    done = subprocess.run(cmd, cwd=code, env=env, input=stdin, capture_output=True, text=True, check=True)
    return done.stdout


@contextmanager
def demo_server(code: Path, database_url: str, workers: int) -> Iterator[tuple[str, int, dict[str, str]]]:
    """``v3d serve --demo`` of ``code`` over ``database_url`` on a free loopback port; yields its base URL, its pid and
    API tokens of two annotators (``ana1``, ``ana2``) and a reviewer (``rev``); stops it at the end."""
    import httpx

    env = {**os.environ, "V3D_DATABASE_URL": database_url, "V3D_CALIBRATION_WORKERS": "1", "PYTHONPATH": str(code)}
    tokens = {name: v3d(code, env, "users", "add", name, "--role", role, "--password-stdin",
                        stdin=PASSWORD + "\n").strip().splitlines()[-1]
              for name, role in (("ana1", "annotator"), ("ana2", "annotator"), ("rev", "reviewer"))}
    port = free_port()
    cmd = [sys.executable, "-c", "import sys; from app.cli import main; sys.argv[0] = 'v3d'; main()", "serve",
           "--demo", "--host", "127.0.0.1", "--port", str(port), "--workers", str(workers)]
    proc = subprocess.Popen(cmd, cwd=code, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.STDOUT,
                            start_new_session=True)
    base = f"http://127.0.0.1:{port}"
    try:
        deadline = time.monotonic() + 300
        while True:
            try:
                if httpx.get(f"{base}/api/health", timeout=2.0).status_code == 200:
                    break
            except httpx.HTTPError:
                pass
            if proc.poll() is not None or time.monotonic() > deadline:
                raise RuntimeError(f"the server did not start: {' '.join(cmd)}")
            time.sleep(0.3)
        time.sleep(2.0)  # let start-up settle before memory is measured
        yield base, proc.pid, tokens
    finally:
        os.killpg(proc.pid, 15)
        try:
            proc.wait(timeout=20)
        except subprocess.TimeoutExpired:
            os.killpg(proc.pid, 9)
            proc.wait()


# ----- attack 1: one huge header -----------------------------------------------------------------

def huge_header(base: str, pid: int, megabytes: int) -> dict[str, Any]:
    """One anonymous request whose one header value is ``megabytes`` MB, sent 1 MB at a time (module docstring)."""
    port = int(base.rsplit(":", 1)[1])
    answer: dict[str, Any] = {}
    with Watch(base, pid) as watch:
        sock = socket.create_connection(("127.0.0.1", port), timeout=120)
        t0 = time.perf_counter()

        reader = threading.Thread(target=read_status, args=(sock, t0, answer))
        reader.start()
        sent = 0
        try:
            sock.sendall(f"GET /api/health HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\nX-Flood: ".encode())
            block = b"a" * MB
            while sent < megabytes * MB and reader.is_alive():
                sock.sendall(block)
                sent += MB
            sock.sendall(b"\r\n\r\n")
        except OSError:
            pass  # the server refused the request and closed the connection
        reader.join(timeout=120)
        sock.close()
        time.sleep(1.0)
    answer["status"] = answer.get("status") or "closed"
    answer["seconds"] = round(answer.get("seconds", float("nan")), 2)
    return {"attack": "header", "header_mb": megabytes, **answer, "sent_mb": sent // MB, **watch.figures()}


# ----- attack 2: previews of fine lines ------------------------------------------------------------

def finer(lines: dict[str, Any], points: int) -> dict[str, Any]:
    """``lines`` (``{class: [[[x, y], ...], ...]}`` px) with every polyline's segments split evenly so that the
    view holds about ``points`` points (the same lines, cut finer: the same calibration problem, more points)."""
    segments = sum(max(len(p) - 1, 0) for polys in lines.values() for p in polys)
    total = sum(len(p) for polys in lines.values() for p in polys)
    cuts = max(1, (points - total) // max(segments, 1) + 1)
    out: dict[str, Any] = {}
    for name, polys in lines.items():
        out[name] = []
        for poly in polys:
            fine = [poly[0]] if poly else []
            for (x0, y0), (x1, y1) in zip(poly, poly[1:], strict=False):
                fine += [[round(x0 + (x1 - x0) * k / cuts, 2), round(y0 + (y1 - y0) * k / cuts, 2)]
                         for k in range(1, cuts + 1)]
            out[name].append(fine[:1000])
    return out


def framed_lines(base: str, token: str, points: int) -> list[tuple[int, dict[str, Any], str]]:
    """(frame id, its field lines cut finer, its ETag) of every demo view with field lines."""
    import httpx

    out = []
    with httpx.Client(base_url=base, headers={"Authorization": f"Bearer {token}"}, timeout=60) as client:
        systems = client.get("/api/systems", params={"limit": 200}).json()["items"]
        for s in systems:
            for view in client.get(f"/api/systems/{s['id']}").json()["views"]:
                if view["field_lines"]:
                    frame = client.get(f"/api/frames/{view['frame_id']}")
                    out.append((view["frame_id"], finer(view["field_lines"], points), frame.headers["etag"]))
    return out


def previews(base: str, pid: int, tokens: dict[str, str], rounds: int, parallel: int,
             points: int) -> dict[str, Any]:
    """Two annotators' rounds of parallel previews while a reviewer reads a system (module docstring)."""
    import httpx

    frames = framed_lines(base, tokens["ana1"], points)
    sizes = [sum(len(p) for polys in lines.values() for p in polys) for _, lines, _ in frames]
    statuses: Counter[str] = Counter()
    reviewer: Counter[str] = Counter()
    reviewer_s: list[float] = []
    stop = threading.Event()
    with httpx.Client(base_url=base, headers={"Authorization": f"Bearer {tokens['rev']}"}, timeout=120) as c:
        system_id = c.get("/api/systems", params={"limit": 1}).json()["items"][0]["id"]

    def review() -> None:
        with httpx.Client(base_url=base, headers={"Authorization": f"Bearer {tokens['rev']}"}, timeout=120) as client:
            while not stop.is_set():
                t0 = time.perf_counter()
                try:
                    reviewer[str(client.get(f"/api/systems/{system_id}").status_code)] += 1
                except httpx.HTTPError as exc:
                    reviewer[type(exc).__name__] += 1
                reviewer_s.append(time.perf_counter() - t0)
                time.sleep(0.2)

    def preview(client: Any, frame_id: int, lines: dict[str, Any]) -> None:
        try:
            statuses[str(client.post(f"/api/frames/{frame_id}/calibration-preview",
                                     json={"lines": lines}).status_code)] += 1
        except httpx.HTTPError as exc:
            statuses[type(exc).__name__] += 1

    limits = httpx.Limits(max_connections=parallel, max_keepalive_connections=parallel)
    clients = [httpx.Client(base_url=base, headers={"Authorization": f"Bearer {tokens[n]}"}, timeout=120,
                            limits=limits) for n in ("ana1", "ana2")]
    t_start = time.perf_counter()
    with Watch(base, pid) as watch, ThreadPoolExecutor(2 * parallel) as pool:
        reader = threading.Thread(target=review)
        reader.start()
        for _ in range(rounds):
            jobs = [pool.submit(preview, client, *frames[i % len(frames)][:2])
                    for client in clients for i in range(parallel)]
            for job in jobs:
                job.result()
        stop.set()
        reader.join()
    for client in clients:
        client.close()
    return {"attack": "previews", "views": len(frames), "points_per_view": [min(sizes), max(sizes)],
            "seconds": round(time.perf_counter() - t_start, 1), "previews": dict(statuses),
            "reviewer": dict(reviewer), "reviewer_worst_s": round(max(reviewer_s, default=float("nan")), 3),
            **watch.figures()}


# ----- attack 3: answers nobody reads -------------------------------------------------------------

def fill_audit(base: str, token: str, edits: int, points: int) -> int:
    """``edits`` field-line edits alternating each view's lines and the same lines cut finer: audit entries of large
    before / after states. Answers how many were stored."""
    import httpx

    frames = framed_lines(base, token, points)
    done = 0
    with httpx.Client(base_url=base, headers={"Authorization": f"Bearer {token}"}, timeout=120) as client:
        state = {fid: (client.get(f"/api/frames/{fid}").json()["field_lines"], fine, etag)
                 for fid, fine, etag in frames}
        for i in range(edits):
            fid = frames[i % len(frames)][0]
            coarse, fine, etag = state[fid]
            lines = fine if (i // len(frames)) % 2 == 0 else coarse
            answer = client.put(f"/api/frames/{fid}/field-lines", headers={"If-Match": etag}, json={"lines": lines})
            if answer.status_code == 200:
                done += 1
                state[fid] = (coarse, fine, answer.headers["etag"])
    return done


def unread_answers(base: str, pid: int, tokens: dict[str, str], sockets: int, hold_s: float, edits: int,
                   points: int) -> dict[str, Any]:
    """``sockets`` connections ask for ``GET /api/audit?limit=500`` and never read it (module docstring)."""
    import httpx

    stored = fill_audit(base, tokens["ana1"], edits, points)
    with httpx.Client(base_url=base, headers={"Authorization": f"Bearer {tokens['ana1']}",
                                              "Accept-Encoding": "identity"}, timeout=120) as client:
        whole = client.get("/api/audit", params={"limit": 500})
        page = whole.json()
        pages, all_bytes, offset = 1, len(whole.content), page.get("next_offset")
        while offset is not None and offset < 500:  # the same 500 entries, page by page (a capped answer)
            more = client.get("/api/audit", params={"limit": 500 - offset, "offset": offset})
            pages, all_bytes, offset = pages + 1, all_bytes + len(more.content), more.json().get("next_offset")
    port = int(base.rsplit(":", 1)[1])
    request = (f"GET /api/audit?limit=500 HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\nAuthorization: Bearer "
               f"{tokens['ana1']}\r\nAccept-Encoding: identity\r\n\r\n").encode()
    time.sleep(1.0)
    with Watch(base, pid) as watch:
        held = []
        for _ in range(sockets):
            s = socket.socket()
            s.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)  # the client's kernel takes little of it
            s.connect(("127.0.0.1", port))
            s.sendall(request)
            held.append(s)
        time.sleep(hold_s)
        holding_peak = watch.peak
        for s in held:
            s.close()
        time.sleep(3.0)
        import psutil

        after = tree_rss(psutil.Process(pid))
    return {"attack": "unread", "audit_entries": stored, "answer_mb": round(len(whole.content) / MB, 2),
            "answer_items": len(page.get("items", [])), "answer_total": page.get("total"),
            "next_offset": page.get("next_offset"), "pages_of_500": pages, "all_500_mb": round(all_bytes / MB, 2),
            "sockets": sockets, "hold_s": hold_s,
            "rss_growth_holding_mb": round((holding_peak - watch.before) / MB, 1),
            "rss_after_close_mb": round((after - watch.before) / MB, 1), **watch.figures()}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--attacks", default=",".join(ATTACKS))
    parser.add_argument("--code", type=Path, default=ROOT, help="the checkout whose code is served")
    parser.add_argument("--database-url", default=None, help="a PostgreSQL server (a new database is made there)")
    parser.add_argument("--workers", type=int, default=1)
    parser.add_argument("--header-mb", type=int, default=80)
    parser.add_argument("--rounds", type=int, default=5)
    parser.add_argument("--parallel", type=int, default=30)
    parser.add_argument("--points", type=int, default=1900)
    parser.add_argument("--sockets", type=int, default=40)
    parser.add_argument("--hold-s", type=float, default=20.0)
    parser.add_argument("--edits", type=int, default=500)
    args = parser.parse_args(argv)
    attacks = [a for a in args.attacks.split(",") if a]
    if unknown := set(attacks) - set(ATTACKS):
        parser.error(f"unknown attacks {sorted(unknown)}; choose among {ATTACKS}")
    with fresh_database(args.database_url) as url, demo_server(args.code.resolve(), url, args.workers) as (
            base, pid, tokens):
        for attack in attacks:
            if attack == "header":
                result = huge_header(base, pid, args.header_mb)
            elif attack == "previews":
                result = previews(base, pid, tokens, args.rounds, args.parallel, args.points)
            else:
                result = unread_answers(base, pid, tokens, args.sockets, args.hold_s, args.edits, args.points)
            print(json.dumps({"code": str(args.code), "database": url.split(":", 1)[0], **result}), flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
