"""The command line (``v3d --server``) and ``v3d_client`` against a broken or hostile server: a small threaded HTTP
server of this test answers what no v3d route promises (an HTML page, JSON of another shape, a redirect, a body past
the bound, a body that never ends, fast or a byte at a time). Each ends in one ``Error:`` line naming the server and
what it answered, within the time bound and without reading past the size bound; the client raises its own typed
error for each. CI runs them at small bounds (settings); the slow tier at the defaults, with the review's sizes."""
from __future__ import annotations

import gzip
import json
import os
import subprocess
import sys
import threading
import time
from collections.abc import Iterator
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from typing import Any

import pytest

from app.core.paths import PROJECT_ROOT as PROJECT

#: What the server answers to every route but its health (``mode`` -> the behaviour in :class:`_Hostile`).
MODES = ("html", "shape", "redirect", "huge", "endless", "drip")


class _Hostile(BaseHTTPRequestHandler):
    """Answers ``GET /api/health`` as a v3d of the client's version (so the command reaches its route), unless the
    mode is ``html-health``; every other request as the server's ``mode`` says. Counts the bytes it sent."""

    server: "_Server"

    def log_message(self, *args: Any) -> None:  # quiet
        pass

    def _send(self, status: int, body: bytes, kind: str = "application/json", **headers: str) -> None:
        self.send_response(status)
        self.send_header("Content-Type", kind)
        self.send_header("Content-Length", str(len(body)))
        for name, value in headers.items():
            self.send_header(name, value)
        self.end_headers()
        self.wfile.write(body)

    def do_GET(self) -> None:  # noqa: N802  # http.server's name
        from v3d_client import __version__

        mode = self.server.mode
        if self.path.startswith("/api/health") and mode != "html-health":
            self._send(200, json.dumps({"status": "ok", "version": __version__}).encode())
            return
        if mode in ("html", "html-health"):
            self._send(200, b"<html><body>Sign in to the proxy</body></html>", "text/html")
        elif mode == "shape":
            self._send(200, json.dumps({"items": "not a list", "total": "many"}).encode())
        elif mode == "gzip-bomb":  # 8 MiB of JSON-looking zeros in a few KiB
            self._send(200, gzip.compress(b"[" + b"0," * (4 << 20)), **{"Content-Encoding": "gzip"})
        elif mode == "redirect":
            self._send(302, b"", **{"Location": "http://elsewhere.example/api/users"})
        else:  # a body without a length: "huge" fast and ending, "endless" fast forever, "drip" a byte at a time
            self.send_response(200)
            self.send_header("Content-Type", "application/json")
            self.end_headers()
            chunk = b"[" + b"0," * (1 << 16)
            sent, limit = 0, self.server.huge_bytes if mode == "huge" else None
            try:
                while limit is None or sent < limit:
                    piece = b" " if mode == "drip" else chunk
                    self.wfile.write(piece)
                    self.wfile.flush()
                    sent += len(piece)
                    self.server.sent += len(piece)
                    if mode == "drip":
                        time.sleep(0.05)
            except OSError:  # the client hung up: what it must do
                return

    do_POST = do_GET  # noqa: N815  # http.server's name


class _Server(ThreadingHTTPServer):
    daemon_threads = True
    mode = "html"
    sent = 0
    huge_bytes = 4 << 20


@pytest.fixture
def hostile() -> Iterator[_Server]:
    server = _Server(("127.0.0.1", 0), _Hostile)
    thread = threading.Thread(target=server.serve_forever, daemon=True)
    thread.start()
    try:
        yield server
    finally:
        server.shutdown()
        server.server_close()


def _url(server: _Server) -> str:
    return f"http://127.0.0.1:{server.server_address[1]}"


def _run(server: _Server, *args: str, within_s: float | None = None, **env: str) -> tuple[int, str, float]:
    """``v3d --server URL ARGS``: in this process, or (``within_s`` given) in a process of its own as a user runs it,
    given that long to end; (exit status, standard output and error, seconds)."""
    started = time.monotonic()
    if within_s is None:
        from typer.testing import CliRunner

        from app.cli import _root, users  # noqa: F401  # users registers its commands
        from app.core.config import get_settings

        get_settings.cache_clear()  # the settings of ``env``, not those an earlier test read
        try:
            result = CliRunner().invoke(_root.cli, ["--server", _url(server), *args],
                                        env={"V3D_TOKEN": "a-token", "V3D_URL": "", **env})
        finally:
            get_settings.cache_clear()
        return result.exit_code, result.output, time.monotonic() - started
    command = [sys.executable, "-c", "from app.cli import main; main()", "--server", _url(server), *args]
    try:
        done = subprocess.run(command, capture_output=True, text=True, timeout=within_s, cwd=PROJECT,
                              env={**os.environ, "V3D_TOKEN": "a-token", "V3D_URL": "", **env})
    except subprocess.TimeoutExpired:
        raise AssertionError(f"v3d --server {' '.join(args)} still ran after {within_s:g} s") from None
    return done.returncode, done.stdout + done.stderr, time.monotonic() - started


@pytest.mark.parametrize("mode, words", [
    ("html", "not JSON"), ("html-health", "not JSON"), ("shape", "not the shape of its route"),
    ("redirect", "302"), ("huge", "more than 1,048,576 bytes"),
    pytest.param("endless", "more than 1,048,576 bytes", marks=pytest.mark.processes),
    pytest.param("drip", "did not answer GET /api/users completely within 1 s", marks=pytest.mark.processes)])
def test_the_command_line_ends_in_one_error_line_naming_the_server(hostile, mode: str, words: str) -> None:
    hostile.mode = mode
    # a body that never ends would hold this process forever without the bounds: those run in a process of their own
    code, output, seconds = _run(hostile, "users", "list", within_s=30 if mode in ("endless", "drip") else None,
                                 V3D_REMOTE_TIMEOUT_S="1", V3D_REMOTE_MAX_ANSWER_MB="1")
    lines = output.strip().splitlines()
    assert code != 0 and len(lines) == 1 and lines[0].startswith(f"Error: {_url(hostile)}") and words in lines[0], \
        output
    assert "Traceback" not in output and seconds < 20
    assert hostile.sent < 16 << 20  # the client hung up near its bound, whatever the server would have sent


def test_the_client_raises_its_own_typed_error_for_each(hostile) -> None:
    from v3d_client import AnswerTooLarge, AnswerTooSlow, Client, NotJSON, Redirected, WrongShape

    expected = {"html": NotJSON, "shape": WrongShape, "redirect": Redirected, "huge": AnswerTooLarge,
                "endless": AnswerTooLarge, "drip": AnswerTooSlow, "gzip-bomb": AnswerTooLarge}
    for mode, error in expected.items():
        hostile.mode = mode
        with Client(_url(hostile), "a-token", timeout=1, total_timeout_s=1, max_answer_bytes=1 << 20) as client:
            with pytest.raises(error, match=f"^{_url(hostile)}"):
                list(client.users())
    hostile.mode = "html"
    with Client(_url(hostile), "a-token", total_timeout_s=1, max_answer_bytes=1 << 20) as client:
        with pytest.raises(NotJSON):  # a generator's answer too (the queue's pages)
            next(iter(client.systems()))


@pytest.mark.slow
@pytest.mark.processes
@pytest.mark.parametrize("mode", ["endless", "drip", "huge"])
def test_at_the_default_bounds_a_hostile_server_is_left_within_a_minute_and_500_mb(hostile, mode: str) -> None:
    """The review's sizes at the default settings: a 10 MB body that is no JSON (read whole: below the 64 MB bound),
    a body that never ends, fast or a byte at a time: one Error: line within 60 s, the command's process under
    500 MB."""
    import resource

    hostile.mode, hostile.huge_bytes = mode, 10 << 20
    code, output, seconds = _run(hostile, "users", "list", within_s=60)
    assert code == 1 and len(output.strip().splitlines()) == 1 and output.startswith("Error: "), output
    assert seconds < 60 and hostile.sent < 500 << 20, (seconds, hostile.sent)
    assert resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss < 500 << 10  # KiB: the largest child's peak
