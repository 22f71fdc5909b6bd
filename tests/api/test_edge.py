"""The server's edge and each user's share (the third security review's attacks 1 to 3): a request's head is bounded
by the parser ``v3d serve`` runs, an answer leaves in pieces that a client must take within the send timeout, the
audit's pages are capped in bytes, previews and evaluations past a user's share answer 429 at once and compute
without a pooled connection, and the health probe never waits for the request pool.

A ``served`` module: the app runs on a real engine of a database of the test's own (SQLite file or PostgreSQL). The
full-size attacks and their figures: ``benchmarks/edge_attacks.py`` (``benchmarks/SECURITY_FIGURES.md``)."""
from __future__ import annotations

import logging
import socket
import threading
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from typing import Any
from urllib.parse import urlsplit

import httpx
import pytest
from fastapi import FastAPI
from fastapi.testclient import TestClient
from sqlalchemy.orm import Session

from app.cli.serve import server_options
from app.core.config import Settings
from app.db.models import Frame
from app.db.session import held_connection
from app.main import create_app
from app.services.audit import log as audit
from app.services.curation import calibration_preview
from tests.accounts import Account
from tests.live_server import serve_app

from .factories import Scene

pytestmark = [pytest.mark.served, pytest.mark.engine]

KB, MB = 1024, 2**20


@contextmanager
def _served(app: FastAPI, settings: Settings, **update: Any) -> Iterator[tuple[str, int]]:
    """The app's database served as ``v3d serve`` serves it (its uvicorn options), with ``update`` to its settings;
    yields its base URL and port."""
    settings = app.state.settings.model_copy(update=update)
    with serve_app(create_app(settings), **server_options(settings)) as base:
        yield base, int(urlsplit(base).port or 0)


def _big_entries(db_session: Session, scene: Scene, count: int, kb: int) -> None:
    """``count`` audit entries of field-line edits whose before and after states are each about ``kb`` KB of JSON."""
    frame = db_session.get(Frame, scene.frame_ids[0])
    points = [[round(i * 0.37, 2), round(i * 0.11, 2)] for i in range(kb * KB // 16)]
    for i in range(count):
        audit.record(db_session, actor="ana", action="field_lines.replace", frame=frame,
                     before={"lines": {"Side line top": [points]}}, after={"lines": {"Side line top": [points[i:]]}})
    db_session.commit()


#: How many times its own time just before the flood health may take while the flood arrives. The event loop the old
#: parser held for seconds would make it hundreds of times slower; a busy machine's scheduling makes one answer now
#: and then a few times slower than the others, which the fastest of :data:`HEALTH_TRIES` answers leaves out.
HEALTH_SLOWDOWN = 10
HEALTH_TRIES = 3


def _health_s(client: httpx.Client, base: str) -> float:
    """The fastest of :data:`HEALTH_TRIES` answers of ``/api/health`` (each 200), in seconds."""
    times = []
    for _ in range(HEALTH_TRIES):
        t0 = time.perf_counter()
        assert client.get(f"{base}/api/health").status_code == 200
        times.append(time.perf_counter() - t0)
    return min(times)


def test_a_header_of_megabytes_is_refused_as_it_arrives_and_health_answers_meanwhile(app: FastAPI) -> None:
    """Was: one anonymous header value of 80 MB sent in 1 MB pieces was read whole by the httptools parser, whose cost
    grows with the square of the header's size on the event loop: ``/api/health`` waited 8-15 s, then the request
    answered 200. Now the parser refuses the head once ``V3D_MAX_HEADER_KB`` has arrived (400, the connection
    closed), long before 4 MB of it are sent, and health answers meanwhile as fast as it did just before the flood
    (within :data:`HEALTH_SLOWDOWN` times: a bound relative to this machine's load now, never a time of its own)."""
    with _served(app, app.state.settings, max_header_kb=32) as (base, port), httpx.Client(timeout=60) as client:
        before = max(_health_s(client, base) for _ in range(3))
        during: list[float] = []
        with socket.create_connection(("127.0.0.1", port), timeout=60) as sock:
            sock.sendall(f"GET /api/health HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\nX-Flood: ".encode())
            sent, answer = 0, b""
            try:
                while sent < 4 * MB and not answer:
                    sock.sendall(b"a" * (64 * KB))
                    sent += 64 * KB
                    sock.settimeout(0.0)
                    try:
                        answer = sock.recv(65536)
                    except BlockingIOError:
                        pass
                    sock.settimeout(60)
                    during.append(_health_s(client, base))
                answer = answer or sock.recv(65536)
            except OSError:
                pass  # the server closed the connection (the rest is never sent), or never answered
        assert sent < 4 * MB and (answer.startswith(b"HTTP/1.1 400") or answer == b""), (sent, answer[:100])
        during.append(_health_s(client, base))  # and once the flood is refused (its first piece may already be)
        assert max(during) < HEALTH_SLOWDOWN * before, (during, before)


def test_a_request_of_too_many_header_lines_is_431(app: FastAPI) -> None:
    """300 small header lines fit in the head's bytes: they are counted (``V3D_MAX_HEADER_COUNT``, 100) before any
    route sees them."""
    with TestClient(app) as client:
        many = {f"x-h{i}": "1" for i in range(300)}
        refused = client.get("/api/health", headers=many)
        assert refused.status_code == 431 and "V3D_MAX_HEADER_COUNT" in refused.json()["detail"]
        assert client.get("/api/health", headers={f"x-h{i}": "1" for i in range(50)}).status_code == 200


def test_the_audit_page_stops_at_its_byte_cap_and_names_the_next_offset(app: FastAPI, db_session: Session,
                                                                         scene: Scene,
                                                                         accounts: dict[str, Account]) -> None:
    """Was: ``GET /api/audit?limit=500`` answered every entry whole (10-17 MB when line edits of 2,000 points filled
    the log). A page now stops before the entry that would pass ``V3D_MAX_ANSWER_KB`` and says where the next one
    starts; paging through gives every entry once."""
    _big_entries(db_session, scene, 7, kb=20)  # each entry about 40 KB of JSON
    capped = create_app(app.state.settings.model_copy(update={"max_answer_kb": 100}))
    with TestClient(capped) as client:
        client.headers.update(accounts["annotator"].bearer)
        first = client.get("/api/audit", params={"limit": 500})
        page = first.json()
        assert first.status_code == 200 and len(first.content) <= 100 * KB
        assert page["total"] == 7 and len(page["items"]) == 2 and page["next_offset"] == 2
        ids, offset = [], 0
        while offset is not None:
            page = client.get("/api/audit", params={"limit": 500, "offset": offset}).json()
            ids += [e["id"] for e in page["items"]]
            offset = page["next_offset"]
        assert len(ids) == 7 == len(set(ids)) and ids == sorted(ids, reverse=True)
        tiny = create_app(app.state.settings.model_copy(update={"max_answer_kb": 1}))
        with TestClient(tiny) as small:  # an entry larger than the cap still leaves, alone
            small.headers.update(accounts["annotator"].bearer)
            assert len(small.get("/api/audit", params={"limit": 500}).json()["items"]) == 1


#: How long the server may take to give up on a client that reads nothing (its send timeout is 1 s; the rest is a
#: bound for a loaded machine, not a measure).
ABANDON_TIMEOUT_S = 120


@contextmanager
def _abandoned_answers() -> Iterator[threading.Event]:
    """An event set when the served app (in this process) abandons an answer its client does not read: the edge's
    warning (``app.api.edge``), logged as it gives up, before it closes the connection."""
    from app.api import edge

    seen = threading.Event()

    class _Seen(logging.Handler):
        def emit(self, record: logging.LogRecord) -> None:
            if record.levelno >= logging.WARNING and "abandoned" in record.getMessage():
                seen.set()

    handler = _Seen()
    edge.log.addHandler(handler)
    try:
        yield seen
    finally:
        edge.log.removeHandler(handler)


def test_a_client_that_never_reads_its_answer_is_dropped_after_the_send_timeout(app: FastAPI, db_session: Session,
                                                                                scene: Scene,
                                                                                accounts: dict[str, Account]) -> None:
    """Was: an answer was written into the connection whole and kept there for as long as the client stayed without
    reading (40 such clients of a 17 MB audit page: +1,265 MB). Now it leaves in pieces, each waiting for the client to
    take the one before within ``V3D_SEND_TIMEOUT_S``: a client that reads nothing for that long gets no more of it
    (what the kernel had buffered, then the end of the connection), and the server holds none of it."""
    _big_entries(db_session, scene, 40, kb=100)  # an 8 MB page: more than the kernel's socket buffers hold
    with _served(app, app.state.settings, max_answer_kb=16 * KB, send_timeout_s=1.0) as (base, port), \
            _abandoned_answers() as abandoned:
        token = accounts["annotator"].bearer["Authorization"]
        with socket.socket() as sock:
            sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)
            sock.connect(("127.0.0.1", port))
            sock.sendall(f"GET /api/audit?limit=500 HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\nAuthorization: {token}\r\n"
                         "Accept-Encoding: identity\r\n\r\n".encode())
            # reads nothing until the server has given up on it (the send timeout passed without a piece taken):
            # however long a loaded machine takes to get there, the client reads only after it
            assert abandoned.wait(ABANDON_TIMEOUT_S), f"the answer was not abandoned within {ABANDON_TIMEOUT_S} s"
            sock.settimeout(60)
            data = b""
            while more := sock.recv(1 << 20):
                data += more
        head, _, body = data.partition(b"\r\n\r\n")
        length = int(next(line.split(b":")[1] for line in head.split(b"\r\n")
                          if line.lower().startswith(b"content-length")))
        assert head.startswith(b"HTTP/1.1 200") and length > 6 * MB
        assert len(body) < length  # the server gave up on this client, then closed the connection
        assert httpx.get(f"{base}/api/health", timeout=10).status_code == 200


@pytest.fixture
def held_previews(app: FastAPI, monkeypatch: pytest.MonkeyPatch) -> Iterator[tuple[threading.Event, list[int]]]:
    """Previews that stop inside their computation until the event is set; the list gets, for each, how many pooled
    connections its session holds while it computes (``app.db.session.held_connection``)."""
    release, checked_out = threading.Event(), []
    real = calibration_preview.calibrate_frame_lines

    def held(session: Session, *args: Any, **kwargs: Any) -> Any:
        checked_out.append(int(held_connection(session) is not None or session.in_transaction()))
        assert release.wait(30)
        return real(session, *args, **kwargs)

    monkeypatch.setattr(calibration_preview, "calibrate_frame_lines", held)
    yield release, checked_out
    release.set()


def _in_thread(call: Callable[[], httpx.Response]) -> tuple[threading.Thread, list[httpx.Response]]:
    out: list[httpx.Response] = []
    thread = threading.Thread(target=lambda: out.append(call()), daemon=True)
    thread.start()
    return thread, out


def test_previews_past_the_users_share_are_429_and_hold_no_pooled_connection_while_they_compute(
        app: FastAPI, scene: Scene, accounts: dict[str, Account],
        held_previews: tuple[threading.Event, list[int]]) -> None:
    """Was: one annotator's 30 parallel previews each held a pooled connection while computing: a reviewer's page
    answered 500 after 30 s (the pool's limit), and so did previews and health. Now a user's third preview at once
    (``V3D_COMPUTE_SHARE``, 2) is 429 with ``Retry-After`` before it reads anything; the two computing hold no
    connection of the pool; the same user's edit is not refused; health answers."""
    release, checked_out = held_previews
    with TestClient(app) as client:
        client.headers.update(accounts["annotator"].bearer)
        system = client.get(f"/api/systems/{scene.system_id}").json()

        def preview(i: int) -> Callable[[], httpx.Response]:
            view = system["views"][i]
            return lambda: client.post(f"/api/frames/{view['frame_id']}/calibration-preview",
                                       json={"lines": view["field_lines"]})

        running = [_in_thread(preview(i)) for i in (0, 1)]
        deadline = time.monotonic() + 20
        while len(checked_out) < 2 and time.monotonic() < deadline:
            time.sleep(0.02)
        assert checked_out == [0, 0]  # both compute, and neither holds a connection of the pool
        third, answered = _in_thread(preview(2))
        third.join(timeout=10)
        assert answered and answered[0].status_code == 429, answered
        assert int(answered[0].headers["retry-after"]) >= 1 and "V3D_COMPUTE_SHARE" in answered[0].json()["detail"]
        view = system["views"][2]
        edit = client.put(f"/api/frames/{view['frame_id']}/field-lines", json={"lines": view["field_lines"]},
                          headers={"If-Match": client.get(f"/api/frames/{view['frame_id']}").headers["etag"]})
        assert edit.status_code == 200  # edits take no share
        assert client.get("/api/health").status_code == 200
        release.set()
        for thread, out in running:
            thread.join(timeout=30)
            assert out and out[0].status_code == 200
        assert preview(2)().status_code == 200  # the share is free again


def test_health_never_waits_for_the_request_pool(app: FastAPI) -> None:
    """Was: ``/api/health`` took a connection of the request pool: with the pool held by slow requests it waited the
    pool's 30 s and answered 500. It asks the database on a connection of its own: the request pool sees no checkout
    of it."""
    import sqlalchemy as sa

    app = create_app(app.state.settings.model_copy(update={"job_runner": False}))  # no runner polling the pool
    engine = app.state.session_factory.kw["bind"]
    checkouts: list[object] = []

    def count(*args: object) -> None:
        checkouts.append(args)

    with TestClient(app) as client:
        assert client.get("/api/health").status_code == 200  # the app's start reads its session key
        sa.event.listen(engine, "checkout", count)
        try:
            assert [client.get("/api/health").status_code for _ in range(3)] == [200, 200, 200]
        finally:
            sa.event.remove(engine, "checkout", count)
    assert not checkouts
