"""Server memory while anonymous clients send large bodies (issue 27, item 1's closing figure), the server's disk
during a large predictions upload, and the review passes one annotator can store.

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

``--predictions-mb N`` instead uploads N MB of predictions to ``POST /api/evaluations/monocular`` as an annotator
(one multipart file, its length declared and then chunked, over a socket) and prints the growth of the disk the
server's files take while it runs (the peak, sampled every 10 ms, and what is left afterwards): its temporary and jobs
folders and every regular file its processes hold open, each file once (the form parser's spool is an unnamed
temporary file, seen only through its open descriptor). The predictions route was bounded by the 2 GB upload limit
alone (its 1,000 MB was spooled, copied, then refused: +2,000 MB); it is now cut once ``V3D_MAX_PREDICTIONS_MB`` has
arrived::

    .venv/bin/python benchmarks/body_flood.py --predictions-mb 300

``--passes N`` instead serves the demo (``v3d serve --demo``) and begins N fresh review passes (``POST /api/passes
{"fresh": true}``) as one annotator, then counts the passes stored for that annotator (each holds every system id of
its queue; they were kept without bound, now at most ``V3D_MAX_PASSES_PER_USER``)::

    .venv/bin/python benchmarks/body_flood.py --passes 300

``--line-edits N`` makes N field-line edits of one demo view as one annotator, each of 2,000 points at full
precision, and prints what the audit log stored per edit (the states were stored whole, before and after, in every
entry; a large one is now stored once, compressed)::

    .venv/bin/python benchmarks/body_flood.py --line-edits 10
"""
from __future__ import annotations

import argparse
import contextlib
import os
import socket
import stat
import subprocess
import sys
import tempfile
import threading
import time
from functools import partial
from pathlib import Path
from typing import Any, Callable, Iterator

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


def send_over_socket(port: int, path: str, content_type: str, size: int, *, chunked: bool, extra_headers: str = "",
                     head: bytes = b"", tail: bytes = b"", fill: bytes = b"a", timeout: float = 60) -> dict[str, Any]:
    """POST ``head``, ``size`` bytes of ``fill`` and ``tail`` to ``path`` over a socket as an attacker would send them:
    1 MB at a time (``Content-Length`` declared, or ``chunked``) until all is sent or the server answers; the status
    line of the answer, seconds to it, and the MB of the ``size`` bytes sent before the server answered or closed."""
    def framed(data: bytes) -> bytes:
        return f"{len(data):x}\r\n".encode() + data + b"\r\n" if chunked and data else data

    framing = "Transfer-Encoding: chunked" if chunked else f"Content-Length: {len(head) + size + len(tail)}"
    sock = socket.create_connection(("127.0.0.1", port), timeout=timeout)
    t0 = time.perf_counter()
    sock.sendall(f"POST {path} HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\n{extra_headers}Content-Type: {content_type}\r\n"
                 f"{framing}\r\n\r\n".encode() + framed(head))
    answer: dict[str, Any] = {}
    reader = threading.Thread(target=read_status, args=(sock, t0, answer))
    reader.start()
    sent = 0
    block = fill * MB
    try:
        while sent < size and reader.is_alive():
            sock.sendall(framed(block[:size - sent]))
            sent += min(MB, size - sent)
        if reader.is_alive():
            sock.sendall(framed(tail) + (b"0\r\n\r\n" if chunked else b""))
    except OSError:
        pass  # the server answered and closed the connection: the rest is never sent
    reader.join(timeout=timeout * 10)
    sock.close()
    return {**answer, "sent_mb": sent / MB}


def send_body(port: int, kind: str, size: int) -> dict[str, Any]:
    """Send one anonymous login of ``size`` bytes of body (``kind``: multipart, chunked, json) over a socket
    (:func:`send_over_socket`)."""
    content_type = "application/json" if kind == "json" else "multipart/form-data; boundary=x"
    return {"kind": kind, **send_over_socket(port, "/api/auth/login", content_type, size, chunked=kind == "chunked")}


@contextlib.contextmanager
def served(code: Path, workdir: Path, demo: bool = False) -> Iterator[tuple[int, Any]]:
    """``v3d serve`` of ``code`` (one worker; ``--demo`` with ``demo``) on a fresh SQLite database in ``workdir``, its
    temporary files in ``workdir/tmp``; yields its port and its process (psutil), and stops it afterwards."""
    import psutil

    url = f"sqlite:///{workdir / 'flood.sqlite3'}"  # migrated by the served code's own v3d serve
    (workdir / "tmp").mkdir(exist_ok=True)
    port = free_port()
    env = {**os.environ, "V3D_DATABASE_URL": url, "V3D_CALIBRATION_WORKERS": "1", "PYTHONPATH": str(code),
           "TMPDIR": str(workdir / "tmp"), "V3D_JOBS_DIR": str(workdir / "jobs")}
    cmd = [sys.executable, "-c", "import sys; from app.cli import main; sys.argv[0] = 'v3d'; main()", "serve",
           "--host", "127.0.0.1", "--port", str(port), "--workers", "1", *(["--demo"] if demo else [])]
    proc = subprocess.Popen(cmd, cwd=code, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.STDOUT,
                            start_new_session=True)
    try:
        deadline = time.monotonic() + (600 if demo else 120)
        while True:
            try:
                with socket.create_connection(("127.0.0.1", port), timeout=1):
                    break
            except OSError:
                if proc.poll() is not None or time.monotonic() > deadline:
                    raise RuntimeError("the server did not start") from None
                time.sleep(0.2)
        time.sleep(2.0)  # let start-up settle
        yield port, psutil.Process(proc.pid)
    finally:
        os.killpg(proc.pid, 15)
        proc.wait(timeout=20)


def _peak_during(sample: Callable[[], float],
                 work: Callable[[], dict[str, Any]]) -> tuple[dict[str, Any], float, float]:
    """Run ``work`` while ``sample()`` is taken every 10 ms; its result, the sample before it and the peak."""
    before = sample()
    peak = [before]
    stop = threading.Event()

    def watch() -> None:
        while not stop.is_set():
            peak[0] = max(peak[0], sample())
            time.sleep(0.01)

    watcher = threading.Thread(target=watch)
    watcher.start()
    try:
        result = work()
        time.sleep(0.5)
    finally:
        stop.set()
        watcher.join()
    return result, before, peak[0]


def measure(code: Path, mb: float, kinds: list[str], workdir: Path) -> list[dict[str, Any]]:
    """Serve ``code`` on a fresh database and send each kind of body; the results with RSS growth (MB)."""
    out = []
    with served(code, workdir) as (port, server):
        for kind in kinds:
            result, before, peak = _peak_during(lambda: tree_rss(server), partial(send_body, port, kind, int(mb * MB)))
            out.append({**result, "rss_before_mb": before / MB, "rss_growth_mb": (peak - before) / MB})
    return out


def disk_bytes(server: Any, folders: list[Path]) -> int:
    """Disk blocks (bytes) of the files under ``folders`` and of every regular file the process tree of ``server``
    holds open (an upload's spool is an unnamed file, unlinked at once: seen only through its open descriptor), each
    file once."""
    import psutil

    files: dict[tuple[int, int], int] = {}
    for folder in folders:
        for path in folder.rglob("*"):
            try:
                st = path.lstat()
            except OSError:
                continue
            if stat.S_ISREG(st.st_mode):
                files[(st.st_dev, st.st_ino)] = st.st_blocks * 512
    for proc in [server, *server.children(recursive=True)]:
        try:
            fds = os.listdir(f"/proc/{proc.pid}/fd")
        except (OSError, psutil.Error):
            continue
        for fd in fds:
            try:
                st = os.stat(f"/proc/{proc.pid}/fd/{fd}")
            except OSError:
                continue
            if stat.S_ISREG(st.st_mode):
                files[(st.st_dev, st.st_ino)] = st.st_blocks * 512
    return sum(files.values())


def annotator_token(code: Path, workdir: Path) -> str:
    """An annotator's API token in the benchmark's database (``v3d users add`` of ``code``)."""
    env = {**os.environ, "V3D_DATABASE_URL": f"sqlite:///{workdir / 'flood.sqlite3'}", "PYTHONPATH": str(code)}
    done = subprocess.run([sys.executable, "-c", "import sys; from app.cli import main; sys.argv[0] = 'v3d'; main()",
                           "users", "add", "flood-annotator", "--role", "annotator", "--password-stdin"],
                          input="flood-annotator-password\n", capture_output=True, text=True, cwd=code, env=env,
                          check=True)
    return done.stdout.strip().splitlines()[-1]


def send_predictions(port: int, token: str, size: int, chunked: bool = False) -> dict[str, Any]:
    """Upload ``size`` bytes of predictions (one multipart file of spaces; ``Content-Length`` declared, or
    ``chunked``) to ``POST /api/evaluations/monocular`` as ``token``'s user over a socket (:func:`send_over_socket`)."""
    head = (b"--x\r\nContent-Disposition: form-data; name=\"predictions\"; filename=\"p.json\"\r\n"
            b"Content-Type: application/json\r\n\r\n")
    return send_over_socket(port, "/api/evaluations/monocular", "multipart/form-data; boundary=x", size,
                            chunked=chunked, extra_headers=f"Authorization: Bearer {token}\r\n", head=head,
                            tail=b"\r\n--x--\r\n", fill=b" ", timeout=300)


def measure_passes(code: Path, n: int, workdir: Path) -> dict[str, Any]:
    """Serve ``code`` with the demo and send ``n`` ``POST /api/passes {"fresh": true}`` as one annotator; the
    answers, the seconds taken, and the passes stored for that annotator afterwards (rows, and the bytes of their
    frozen system ids)."""
    import sqlite3
    import urllib.request

    token = annotator_token(code, workdir)
    with served(code, workdir, demo=True) as (port, _):
        statuses: dict[int, int] = {}
        t0 = time.perf_counter()
        for _ in range(n):
            request = urllib.request.Request(f"http://127.0.0.1:{port}/api/passes", data=b'{"fresh": true}',
                                             method="POST", headers={"Authorization": f"Bearer {token}",
                                                                     "Content-Type": "application/json"})
            with urllib.request.urlopen(request, timeout=60) as answer:
                statuses[answer.status] = statuses.get(answer.status, 0) + 1
        seconds = time.perf_counter() - t0
        with sqlite3.connect(workdir / "flood.sqlite3") as db:
            rows, size = db.execute("SELECT count(*), coalesce(sum(length(system_ids)), 0) FROM review_passes "
                                    "WHERE user_name = 'flood-annotator'").fetchone()
    return {"statuses": statuses, "seconds": seconds, "stored": rows, "stored_kb": size / 1024}


def _api(port: int, token: str, method: str, path: str, body: Any = None,
         headers: dict[str, str] | None = None) -> tuple[int, dict[str, str], Any]:
    """One JSON request to the served API with an API token: the status, the headers and the decoded answer."""
    import json
    import urllib.request

    request = urllib.request.Request(
        f"http://127.0.0.1:{port}{path}", method=method, data=None if body is None else json.dumps(body).encode(),
        headers={"Authorization": f"Bearer {token}", "Content-Type": "application/json", **(headers or {})})
    with urllib.request.urlopen(request, timeout=120) as answer:
        return answer.status, dict(answer.headers), json.loads(answer.read() or b"null")


def measure_line_edits(code: Path, n: int, workdir: Path) -> dict[str, Any]:
    """Serve ``code`` with the demo and make ``n`` field-line edits of one view as one annotator, each of 2,000
    points at full precision (the view's own polylines cut finer, moved 0.25 px further by each edit, so that every
    edit's lines are new and its lines before are the previous edit's after); the bytes the audit log stored for them
    (its entries' states as text, and the distinct stored states they name where the schema has ``audit_states``) per
    edit."""
    import sqlite3

    from benchmarks.edit_lock import dense_lines

    token = annotator_token(code, workdir)
    with served(code, workdir, demo=True) as (port, _):
        system_id = _api(port, token, "GET", "/api/systems?limit=1")[2]["items"][0]["id"]
        frame_id = _api(port, token, "GET", f"/api/systems/{system_id}")[2]["views"][0]["frame_id"]
        lines = _api(port, token, "GET", f"/api/frames/{frame_id}")[2]["field_lines"]
        dense = dense_lines(lines, 2000, decimals=17)
        entries = []
        for i in range(n):
            moved = {c: [[[x + 0.25 * (i + 1), y] for x, y in poly] for poly in polys] for c, polys in dense.items()}
            etag = _api(port, token, "GET", f"/api/frames/{frame_id}")[1]["etag"]
            _, headers, _ = _api(port, token, "PUT", f"/api/frames/{frame_id}/field-lines", {"lines": moved},
                                 {"If-Match": etag})
            entries.append(int(headers["x-v3d-audit-entry"]))
    with sqlite3.connect(workdir / "flood.sqlite3") as db:
        ids = ",".join(map(str, entries))
        inline = db.execute(f"SELECT coalesce(sum(length(before)), 0) + coalesce(sum(length(after)), 0) "
                            f"FROM audit_entries WHERE id IN ({ids})").fetchone()[0]
        shared = 0
        if db.execute("SELECT count(*) FROM sqlite_master WHERE name = 'audit_states'").fetchone()[0]:
            shared = db.execute(f"SELECT coalesce(sum(length(body)), 0) FROM audit_states WHERE digest IN "
                                f"(SELECT before_digest FROM audit_entries WHERE id IN ({ids}) UNION "
                                f"SELECT after_digest FROM audit_entries WHERE id IN ({ids}))").fetchone()[0]
    return {"edits": n, "inline_kb": inline / 1024, "shared_kb": shared / 1024,
            "per_edit_kb": (inline + shared) / 1024 / n}


def measure_predictions(code: Path, mb: float, workdir: Path) -> list[dict[str, Any]]:
    """Serve ``code`` on a fresh database and upload ``mb`` MB of predictions as an annotator, with its length
    declared and chunked; for each the answer and the growth (MB) of the disk the server's files take (its temporary
    and jobs folders, its open files)."""
    token = annotator_token(code, workdir)
    out = []
    with served(code, workdir) as (port, server):
        folders = [workdir / "tmp", workdir / "jobs"]
        for chunked in (False, True):
            result, before, peak = _peak_during(partial(disk_bytes, server, folders),
                                                partial(send_predictions, port, token, int(mb * MB), chunked))
            after = disk_bytes(server, folders)
            out.append({**result, "kind": "chunked" if chunked else "declared", "disk_growth_mb": (peak - before) / MB,
                        "disk_left_mb": (after - before) / MB})
    return out


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--mb", type=float, default=64.0, help="body size (MB)")
    parser.add_argument("--code", type=Path, default=ROOT, help="the checkout whose code is served")
    parser.add_argument("--kinds", default="multipart,chunked,json")
    parser.add_argument("--predictions-mb", type=float, default=None,
                        help="instead: upload this many MB of predictions to the monocular benchmark as an annotator "
                             "and measure the server's disk")
    parser.add_argument("--line-edits", type=int, default=None,
                        help="instead: make this many 2,000-point field-line edits of one view on a demo server and "
                             "measure what the audit log stores per edit")
    parser.add_argument("--passes", type=int, default=None,
                        help="instead: begin this many fresh review passes as one annotator on a demo server and "
                             "count those stored")
    args = parser.parse_args(argv)
    with tempfile.TemporaryDirectory(prefix="v3d-body-flood-") as tmp:
        if args.line_edits is not None:
            r = measure_line_edits(args.code.resolve(), args.line_edits, Path(tmp))
            print(f"{r['edits']} line edits of 2,000 points (v3d serve --demo): the audit log stored "
                  f"{r['per_edit_kb']:.1f} KB per edit ({r['inline_kb']:.0f} KB in its entries, "
                  f"{r['shared_kb']:.0f} KB of states stored once)")
            return 0
        if args.passes is not None:
            r = measure_passes(args.code.resolve(), args.passes, Path(tmp))
            print(f"{args.passes} POST /api/passes {{\"fresh\": true}} by one annotator (v3d serve --demo): "
                  f"{r['statuses']} in {r['seconds']:.1f} s; stored {r['stored']} passes ({r['stored_kb']:.0f} KB of "
                  "system ids)")
            return 0
        if args.predictions_mb is not None:
            for r in measure_predictions(args.code.resolve(), args.predictions_mb, Path(tmp)):
                print(f"{r['kind']:8s} {args.predictions_mb:g} MB of predictions to /api/evaluations/monocular: "
                      f"{r.get('status')!r} after {r.get('seconds', float('nan')):.2f} s, {r['sent_mb']:.0f} MB sent; "
                      f"server disk +{r['disk_growth_mb']:.1f} MB at the peak, +{r['disk_left_mb']:.1f} MB after")
            return 0
        results = measure(args.code.resolve(), args.mb, args.kinds.split(","), Path(tmp))
    for r in results:
        print(f"{r['kind']:9s} {args.mb:g} MB anonymous to /api/auth/login: {r.get('status')!r} after "
              f"{r.get('seconds', float('nan')):.2f} s, {r['sent_mb']:.0f} MB sent; server RSS "
              f"{r['rss_before_mb']:.0f} MB +{r['rss_growth_mb']:.1f} MB")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
