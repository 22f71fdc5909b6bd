"""Request bodies are bounded before parsing and while they stream (``app.api.bodies``, issue 15): a 20 MB
JSON body to the login was read and parsed before (422 after parsing); now 413 at once. Uploads to the
monocular benchmark were spooled whole to disk by the form parser before the route's size check. Issue 27: the
limit and the types a body may have are the route's, whatever its ``Content-Type`` says (415 before it is read),
and no error answer quotes a long input or a password."""
from __future__ import annotations

import asyncio
import concurrent.futures
import time

import pytest
from fastapi import FastAPI
from fastapi.testclient import TestClient

from tests.accounts import Account, as_token

from .factories import Scene


@pytest.fixture
def small_app(app: FastAPI, db_settings) -> FastAPI:
    """The app with V3D_MAX_JSON_KB = 4 and V3D_MAX_UPLOAD_MB = 0.25 (the middleware reads them when the app
    is made), on the test's database."""
    from app.main import create_app

    small = create_app(db_settings.model_copy(update={"max_json_kb": 4, "max_upload_mb": 0.25}))
    small.state.session_factory = app.state.session_factory
    return small


def test_a_20_mb_json_body_is_refused_before_it_is_read(anonymous: TestClient) -> None:
    body = b'{"name": "x", "password": "' + b"a" * (20 * 2**20) + b'"}'
    t0 = time.perf_counter()
    answer = anonymous.post("/api/auth/login", content=body, headers={"Content-Type": "application/json"})
    elapsed = time.perf_counter() - t0
    assert answer.status_code == 413, answer.text
    assert "larger than 1024 KB (V3D_MAX_JSON_KB)" in answer.json()["detail"]
    assert elapsed < 5.0  # generous: the point is that no parsing happens (the test client still sends it)


def test_a_streamed_json_body_is_cut_off_at_the_limit(small_app: FastAPI, accounts: dict[str, Account]) -> None:
    def chunks():
        yield b'{"name": "x", "password": "'
        for _ in range(64):  # 64 kB, no Content-Length: counted as it arrives
            yield b"a" * 1024
        yield b'"}'

    with TestClient(small_app) as c:
        answer = c.post("/api/auth/login", content=chunks(), headers={"Content-Type": "application/json"})
        assert answer.status_code == 413 and "(V3D_MAX_JSON_KB)" in answer.json()["detail"]
        ok = c.post("/api/auth/login", json={"name": "test-admin", "password": accounts["admin"].password})
        assert ok.status_code == 200  # a body under the limit goes through


def test_an_upload_to_the_monocular_benchmark_is_bounded_while_it_streams(small_app: FastAPI,
                                                                           accounts: dict[str, Account]) -> None:
    with TestClient(small_app) as c:
        client = as_token(c, accounts["annotator"])
        big = b"[" + b" " * 400_000 + b"]"
        declared = client.post("/api/evaluations/monocular", files={"predictions": ("p.json", big)})
        assert declared.status_code == 413 and "(V3D_MAX_UPLOAD_MB)" in declared.json()["detail"]
        boundary = "v3d"

        def chunks():
            yield (f'--{boundary}\r\nContent-Disposition: form-data; name="predictions"; filename="p.json"\r\n'
                   "Content-Type: application/json\r\n\r\n").encode()
            for _ in range(40):
                yield b" " * 10_000
            yield f"\r\n--{boundary}--\r\n".encode()

        streamed = client.post("/api/evaluations/monocular", content=chunks(),
                               headers={"Content-Type": f"multipart/form-data; boundary={boundary}"})
        assert streamed.status_code == 413, streamed.text
        small = client.post("/api/evaluations/monocular", files={"predictions": ("p.json", b"[]")})
        assert small.status_code != 413


def test_every_operation_declares_413(app: FastAPI) -> None:
    paths = app.openapi()["paths"]
    missing = [(m, p) for p, ops in paths.items() for m, op in ops.items() if "413" not in op["responses"]]
    assert missing == []


# ----- issue 27, item 1: bodies bounded by the route, never by the client's Content-Type --------------------
MB = 2**20


def _asgi_post(app: FastAPI, path: str, headers: dict[str, str], size: int, chunk: int = 64 * 1024,
               method: str = "POST", head: bytes = b"", tail: bytes = b"") -> tuple[int, bytes, int]:
    """Send ``head``, ``size`` bytes and ``tail`` to ``app`` straight over ASGI, chunk by chunk as a socket would
    deliver them (the test client reads a whole body first); returns the status, the answer's body and how many bytes
    the app read."""

    body = head + b"a" * size + tail
    read = 0
    answer: dict[str, object] = {"body": b""}

    async def receive() -> dict:
        nonlocal read
        if read >= len(body):
            return {"type": "http.disconnect"}
        n = min(chunk, len(body) - read)
        read += n
        return {"type": "http.request", "body": body[read - n:read], "more_body": read < len(body)}

    async def send(message: dict) -> None:
        if message["type"] == "http.response.start":
            answer["status"] = message["status"]
        elif message["type"] == "http.response.body":
            answer["body"] = answer["body"] + message.get("body", b"")  # type: ignore[operator]  # answer["body"] holds bytes

    raw = [(k.lower().encode(), v.encode()) for k, v in {"host": "testserver", **headers}.items()]
    scope = {"type": "http", "asgi": {"version": "3.0"}, "http_version": "1.1", "method": method, "scheme": "http",
             "path": path, "raw_path": path.encode(), "root_path": "", "query_string": b"", "headers": raw,
             "client": ("127.0.0.1", 50000), "server": ("testserver", 80), "state": {}}
    # In a thread of its own: ``asyncio.run`` refuses a thread whose loop is running, as Playwright's is in a worker
    # that has run a browser test (the session's Chromium holds it).
    with concurrent.futures.ThreadPoolExecutor(max_workers=1) as pool:
        pool.submit(asyncio.run, app(scope, receive, send)).result()
    return int(answer["status"]), bytes(answer["body"]), read  # type: ignore[arg-type]  # set by the answer


def test_a_body_goes_over_asgi_from_a_thread_whose_event_loop_is_running(app: FastAPI) -> None:
    """A worker that has run a browser test holds Playwright's running loop in its thread for the session (pytest-xdist
    may hand it the browser modules first): the ASGI helper still sends its body, here from inside a running loop."""

    async def beside_a_running_loop() -> tuple[int, bytes, int]:
        return _asgi_post(app, "/api/auth/login", {"content-type": "text/plain", "content-length": str(MB)}, MB)

    with concurrent.futures.ThreadPoolExecutor(max_workers=1) as pool:  # this thread may hold a running loop itself
        status, _, read = pool.submit(asyncio.run, beside_a_running_loop()).result()
    assert status == 415 and read == 0, (status, read)


@pytest.mark.parametrize("length", ["declared", "chunked"])
def test_an_anonymous_64_mb_multipart_body_to_the_login_is_refused_unread(app: FastAPI, length: str) -> None:
    """Was (issue 27): ``POST /api/auth/login`` with ``multipart/form-data`` took the 2 GB upload limit, read all
    64 MB, answered 422 echoing them (server memory +225 MB). The login takes JSON only: 415 before a byte is read,
    whether the length is declared or the body is chunked."""
    size = 64 * MB
    headers = {"content-type": "multipart/form-data; boundary=x"}
    headers.update({"content-length": str(size)} if length == "declared" else {"transfer-encoding": "chunked"})
    status, body, read = _asgi_post(app, "/api/auth/login", headers, size)
    assert status == 415 and read == 0, (status, read)
    assert "application/json" in body.decode() and len(body) < 300


def test_twenty_mb_as_multipart_to_an_annotator_json_write_is_refused_unread(app: FastAPI, scene: Scene,
                                                                              accounts: dict[str, Account]) -> None:
    """Was: 20 MB of JSON sent as multipart to an annotator's write were read whole (the upload limit)."""
    token = {"authorization": accounts["annotator"].bearer["Authorization"]}
    for content_type in ("multipart/form-data; boundary=x", "text/plain", ""):
        headers = {**token, "content-length": str(20 * MB), **({"content-type": content_type} if content_type else {})}
        status, body, read = _asgi_post(app, f"/api/frames/{scene.frame_ids[0]}/ball", headers, 20 * MB,
                                        method="PATCH")
        assert status == 415 and read == 0, (content_type, status, body[:200])
    # as JSON, the route's own type, the JSON limit holds (413 before it is read) ...
    status, _, read = _asgi_post(app, f"/api/frames/{scene.frame_ids[0]}/ball",
                                 {**token, "content-type": "application/json", "content-length": str(20 * MB)},
                                 20 * MB, method="PATCH")
    assert status == 413 and read == 0


def test_a_real_server_answers_415_before_the_body_is_sent(app: FastAPI, db_settings) -> None:
    """Over a socket, as an attacker would send it: the headers of a 64 MB multipart login and 64 KB of its body;
    the 415 arrives while 99.9 % of the body was never sent (the server did not wait for it)."""
    import socket
    from urllib.parse import urlsplit

    from app.main import create_app
    from tests.live_server import serve_app

    served = create_app(db_settings)
    served.state.session_factory = app.state.session_factory
    with serve_app(served) as base:
        port = urlsplit(base).port
        for framing in (f"Content-Length: {64 * MB}", "Transfer-Encoding: chunked"):
            with socket.create_connection(("127.0.0.1", port), timeout=10) as sock:
                sock.sendall((f"POST /api/auth/login HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\n"
                              f"Content-Type: multipart/form-data; boundary=x\r\n{framing}\r\n\r\n").encode())
                first = b"a" * 65536
                sock.sendall(first if "Length" in framing else b"10000\r\n" + first + b"\r\n")
                answer = sock.recv(65536).decode("latin-1")
            assert answer.startswith("HTTP/1.1 415"), answer[:200]


def test_upload_routes_are_derived_from_the_routes_and_agree_with_openapi(app: FastAPI) -> None:
    """The routes that may take ``V3D_MAX_UPLOAD_MB`` are read off the routes themselves (their body parameters,
    or the request body their OpenAPI operation declares), never from a list kept by hand: they are every route
    with a ``File`` / ``UploadFile`` / ``Form`` parameter and every operation whose OpenAPI body is multipart."""
    from fastapi.params import File, Form
    from fastapi.routing import iter_route_contexts

    from app.api.bodies import route_media_types, upload_routes

    found = upload_routes(app.routes)
    assert found == [("POST", "/api/evaluations/monocular"), ("POST", "/api/imports")]
    openapi = app.openapi()["paths"]
    declared = sorted((m.upper(), p) for p, ops in openapi.items() for m, op in ops.items()
                      if "multipart/form-data" in op.get("requestBody", {}).get("content", {}))
    assert found == declared
    with_form_params = sorted((m, str(c.path)) for c in iter_route_contexts(app.routes)
                              if any(isinstance(f.field_info, (File, Form))
                                     for f in getattr(getattr(c.original_route, "dependant", None), "body_params", []))
                              for m in c.methods or ())
    assert set(with_form_params) <= set(found) and with_form_params
    # every operation's declared body types are the types the middleware lets through
    for c in iter_route_contexts(app.routes):
        for method in c.methods or ():
            op = openapi.get(str(c.path), {}).get(method.lower())
            if op is not None:
                assert route_media_types(c) == set(op.get("requestBody", {}).get("content", {})), (method, c.path)


def test_each_route_takes_only_its_own_body_types(client: TestClient, scene: Scene) -> None:
    """415 for a body of a type the route does not take, before it is read; its own types go through."""
    login = client.post("/api/auth/login", content=b"name=a&password=b",
                        headers={"Content-Type": "application/x-www-form-urlencoded"})
    assert login.status_code == 415 and "takes application/json" in login.json()["detail"]
    assert client.post("/api/auth/login", content=b'{"name": "x", "password": "y"}',
                       headers={"Content-Type": "text/plain"}).status_code == 415
    as_json = client.post("/api/imports", json={"kind": "soccernet-v3", "path": "nowhere-at-all"})
    assert as_json.status_code in (400, 403), as_json.text  # the JSON form of the import route is read
    upload = client.post("/api/imports", data={"kind": "soccernet-v3"}, files={"file": ("x.zip", b"not a zip")})
    assert upload.status_code == 400, upload.text  # the multipart form of it too (a broken zip, named)
    assert client.post("/api/evaluations/monocular", json={"predictions": []}).status_code == 415
    # a route without a body ignores a JSON one, and refuses any other
    assert client.post("/api/auth/logout", json={}).status_code == 204
    assert client.request("GET", "/api/health", content=b"x",
                          headers={"Content-Type": "text/plain"}).status_code == 415


def test_a_422_does_not_echo_a_long_input(anonymous: TestClient, client: TestClient) -> None:
    """Was: a 422 quoted its whole ``input`` back (the login answered a 64 MB body with 64 MB)."""
    long_name = "n" * 5000
    answer = anonymous.post("/api/auth/login", json={"name": long_name, "password": "pw"})
    assert answer.status_code == 422 and answer.json()["detail"][0]["loc"] == ["body", "name"]
    assert long_name[:300] not in answer.text and len(answer.text) < 1000
    query = client.get("/api/systems", params={"limit": "9" * 400})
    assert query.status_code == 422 and "9" * 250 not in query.text
    short = client.get("/api/systems", params={"limit": "many"})
    assert short.json()["detail"][0]["input"] == "many"  # a short input is still quoted: it helps


def test_a_login_without_a_name_does_not_echo_the_password(anonymous: TestClient) -> None:
    """Was: 422 echoing the whole body, password included."""
    secret = "correct-horse-battery-staple-7"
    answer = anonymous.post("/api/auth/login", json={"password": secret})
    assert answer.status_code == 422
    assert [e["loc"] for e in answer.json()["detail"]] == [["body", "name"]]
    assert secret not in answer.text
    wrong_type = anonymous.post("/api/auth/login", json={"name": "x", "password": 12345678901})
    assert wrong_type.status_code == 422 and "12345678901" not in wrong_type.text
