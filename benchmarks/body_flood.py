"""Server memory while anonymous clients send large bodies (issue 27, item 1's closing figure).

A fresh SQLite database served by a real ``v3d serve`` (a subprocess, one worker, on a free loopback port; its
process tree's RSS sampled every 10 ms with psutil). Anonymous requests to ``POST /api/auth/login``, each sending
its whole body as an attacker would (over a raw socket, 1 MB at a time, until the body is sent or the server
closes the connection):

* ``multipart``: ``Content-Type: multipart/form-data`` with ``Content-Length`` (issue 27: was read whole, 422
  echoing it, +225 MB for 64 MB);
* ``chunked``: the same without a length (``Transfer-Encoding: chunked``);
* ``json``: ``application/json`` with ``Content-Length`` (413 at once since issue 15).

Prints, per kind, the status, the seconds to the answer, how much of the body the client got to send, and the
server's RSS growth (peak during the request minus the RSS before it). ``--code DIR`` serves the code of another
checkout (e.g. ``/work/main``, for the figure before the change). Run::

    .venv/bin/python benchmarks/body_flood.py --mb 64
"""
from __future__ import annotations

import argparse
import os
import socket
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from benchmarks.scale import free_port

MB = 2**20


def tree_rss(proc: Any) -> int:
    """RSS (bytes) of ``proc`` and its children (uvicorn's workers)."""
    import psutil

    total = 0
    for p in [proc, *proc.children(recursive=True)]:
        try:
            total += p.memory_info().rss
        except psutil.Error:
            pass
    return total


def read_status(sock: socket.socket, t0: float, answer: dict[str, Any]) -> None:
    """Read the status line of the answer on ``sock`` into ``answer["status"]`` ("" when the server closed the
    connection first) and the seconds since ``t0`` (``time.perf_counter``) into ``answer["seconds"]``."""
    data = b""
    try:
        while b"\r\n" not in data:
            more = sock.recv(65536)
            if not more:
                break
            data += more
    except OSError:
        pass
    answer["status"] = data.split(b"\r\n", 1)[0].decode("latin-1")
    answer["seconds"] = time.perf_counter() - t0


def send_body(port: int, kind: str, size: int) -> dict[str, Any]:
    """Send one anonymous login of ``size`` bytes of body (``kind``: multipart, chunked, json) over a socket; the
    status line of the answer, seconds to it, and the bytes of body sent before the server answered or closed."""
    content_type = "application/json" if kind == "json" else "multipart/form-data; boundary=x"
    framing = "Transfer-Encoding: chunked" if kind == "chunked" else f"Content-Length: {size}"
    sock = socket.create_connection(("127.0.0.1", port), timeout=60)
    t0 = time.perf_counter()
    sock.sendall(f"POST /api/auth/login HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\nContent-Type: {content_type}\r\n"
                 f"{framing}\r\n\r\n".encode())
    answer: dict[str, Any] = {}
    reader = threading.Thread(target=read_status, args=(sock, t0, answer))
    reader.start()
    sent = 0
    block = b"a" * MB
    try:
        while sent < size and reader.is_alive():
            sock.sendall(block if kind != "chunked" else f"{MB:x}\r\n".encode() + block + b"\r\n")
            sent += MB
        if kind == "chunked" and reader.is_alive():
            sock.sendall(b"0\r\n\r\n")
    except OSError:
        pass  # the server answered and closed the connection: the rest is never sent
    reader.join(timeout=120)
    sock.close()
    return {"kind": kind, **answer, "sent_mb": sent / MB}


def measure(code: Path, mb: float, kinds: list[str], workdir: Path) -> list[dict[str, Any]]:
    """Serve ``code`` on a fresh database and send each kind of body; the results with RSS growth (MB)."""
    import psutil

    from app.db.session import upgrade_database

    url = f"sqlite:///{workdir / 'flood.sqlite3'}"
    upgrade_database(url)
    port = free_port()
    env = {**os.environ, "V3D_DATABASE_URL": url, "V3D_CALIBRATION_WORKERS": "1", "PYTHONPATH": str(code)}
    cmd = [sys.executable, "-c", "import sys; from app.cli import main; sys.argv[0] = 'v3d'; main()", "serve",
           "--host", "127.0.0.1", "--port", str(port), "--workers", "1"]
    proc = subprocess.Popen(cmd, cwd=code, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.STDOUT,
                            start_new_session=True)
    out = []
    try:
        deadline = time.monotonic() + 120
        while True:
            try:
                with socket.create_connection(("127.0.0.1", port), timeout=1):
                    break
            except OSError:
                if proc.poll() is not None or time.monotonic() > deadline:
                    raise RuntimeError("the server did not start") from None
                time.sleep(0.2)
        time.sleep(2.0)  # let start-up settle
        server = psutil.Process(proc.pid)
        for kind in kinds:
            before = tree_rss(server)
            peak = [before]
            stop = threading.Event()

            def sample(stop: threading.Event, peak: list[float]) -> None:
                while not stop.is_set():
                    peak[0] = max(peak[0], tree_rss(server))
                    time.sleep(0.01)

            sampler = threading.Thread(target=sample, args=(stop, peak))
            sampler.start()
            result = send_body(port, kind, int(mb * MB))
            time.sleep(0.5)
            stop.set()
            sampler.join()
            out.append({**result, "rss_before_mb": before / MB, "rss_growth_mb": (peak[0] - before) / MB})
    finally:
        os.killpg(proc.pid, 15)
        proc.wait(timeout=20)
    return out


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--mb", type=float, default=64.0, help="body size (MB)")
    parser.add_argument("--code", type=Path, default=ROOT, help="the checkout whose code is served")
    parser.add_argument("--kinds", default="multipart,chunked,json")
    args = parser.parse_args(argv)
    with tempfile.TemporaryDirectory(prefix="v3d-body-flood-") as tmp:
        results = measure(args.code.resolve(), args.mb, args.kinds.split(","), Path(tmp))
    for r in results:
        print(f"{r['kind']:9s} {args.mb:g} MB anonymous to /api/auth/login: {r.get('status')!r} after "
              f"{r.get('seconds', float('nan')):.2f} s, {r['sent_mb']:.0f} MB sent; server RSS "
              f"{r['rss_before_mb']:.0f} MB +{r['rss_growth_mb']:.1f} MB")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
