"""Request bodies are bounded before parsing and while they stream (``app.api.bodies``, issue 15): a 20 MB
JSON body to the login was read and parsed before (422 after parsing); now 413 at once. Uploads to the
monocular benchmark were spooled whole to disk by the form parser before the route's size check."""
from __future__ import annotations

import time

import pytest
from fastapi import FastAPI
from fastapi.testclient import TestClient

from tests.accounts import Account, as_token


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
