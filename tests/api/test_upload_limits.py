"""Each upload route is bounded by its own limit while its body streams (``app.api.bodies``, the route's declared
``x-v3d-upload-limit``; ``app.services.transfer.archives.upload_limit``). The monocular benchmark's predictions were
bounded only by the 2 GB upload limit: a 1,000 MB upload was spooled to disk by the form parser, copied, and only
then refused by the 64 MB predictions limit (+2,000 MB of disk at the peak). Now the body is cut once
``V3D_MAX_PREDICTIONS_MB`` has arrived; ``benchmarks/body_flood.py --predictions-mb 300`` measures the disk."""
from __future__ import annotations

import pytest
from fastapi import FastAPI
from fastapi.testclient import TestClient

from tests.accounts import Account, as_token
from tests.api.test_bodies import _asgi_post

MB = 2**20
BOUNDARY = "v3d-boundary"


def _stream_upload(app: FastAPI, path: str, token: str, field: str, size: int, *,
                   chunked: bool = True) -> tuple[int, str, int]:
    """A multipart upload of one file of ``size`` bytes (field ``field``) sent to ``app`` over ASGI in 256 KB chunks
    as a socket delivers it (``tests/api/test_bodies._asgi_post``); the status, the answer and how many bytes of the
    body the app read before it answered."""
    head = (f'--{BOUNDARY}\r\nContent-Disposition: form-data; name="{field}"; filename="p.json"\r\n'
            "Content-Type: application/json\r\n\r\n").encode()
    tail = f"\r\n--{BOUNDARY}--\r\n".encode()
    framing = {"transfer-encoding": "chunked"} if chunked else {"content-length": str(len(head) + size + len(tail))}
    headers = {"authorization": f"Bearer {token}", "content-type": f"multipart/form-data; boundary={BOUNDARY}",
               **framing}
    status, body, read = _asgi_post(app, path, headers, size, chunk=256 * 1024, head=head, tail=tail)
    return status, body.decode(), read


@pytest.fixture
def predictions_app(app: FastAPI, db_settings) -> FastAPI:
    """The app with ``V3D_MAX_PREDICTIONS_MB`` = 1 (and the default 2 GB ``V3D_MAX_UPLOAD_MB``), on the test's
    database."""
    from app.main import create_app

    small = create_app(db_settings.model_copy(update={"max_predictions_mb": 1.0}))
    small.state.session_factory = app.state.session_factory
    return small


@pytest.mark.parametrize("chunked", [True, False], ids=["chunked", "declared"])
def test_a_predictions_upload_is_cut_once_its_own_limit_has_arrived(predictions_app: FastAPI,
                                                                    accounts: dict[str, Account],
                                                                    chunked: bool) -> None:
    """Was: an annotator's 1,000 MB upload to ``POST /api/evaluations/monocular`` was read whole (spooled, then
    copied) before the 64 MB predictions limit refused it. Here the predictions limit is 1 MB and 8 MB are sent: 413
    naming V3D_MAX_PREDICTIONS_MB, with at most the limit and one chunk read (nothing more reached the disk)."""
    status, body, read = _stream_upload(predictions_app, "/api/evaluations/monocular",
                                        accounts["annotator"].token, "predictions", 8 * MB, chunked=chunked)
    assert status == 413, body[:300]
    assert "V3D_MAX_PREDICTIONS_MB" in body
    assert read <= 1 * MB + 256 * 1024, read


def test_a_predictions_upload_under_its_limit_is_read(predictions_app: FastAPI,
                                                      accounts: dict[str, Account]) -> None:
    """Below its limit the upload goes through to the benchmark (here no predictions file at all: 422, not 413)."""
    status, body, read = _stream_upload(predictions_app, "/api/evaluations/monocular",
                                        accounts["annotator"].token, "predictions", MB // 2)
    assert status == 422 and "413" not in body, body[:300]


def test_every_declared_upload_limit_names_a_setting_and_bounds_its_route(app: FastAPI) -> None:
    """Each upload route's own limit is a setting of ``Settings`` (its environment name), shown in the OpenAPI
    document; the monocular benchmark's is ``V3D_MAX_PREDICTIONS_MB``, the import's the general one (each import
    format declares its own, ``ImportFormat.upload_limit``)."""
    from fastapi.routing import iter_route_contexts

    from app.api.bodies import UPLOAD_LIMIT, declared_upload_limit, upload_routes
    from app.core.config import Settings
    from app.services.transfer.import_formats import registered_formats

    declared = {(m, str(c.path)): declared_upload_limit(c) for c in iter_route_contexts(app.routes)
                for m in c.methods or () if (m, str(c.path)) in upload_routes(app.routes)}
    assert declared == {("POST", "/api/evaluations/monocular"): "V3D_MAX_PREDICTIONS_MB",
                        ("POST", "/api/imports"): "V3D_MAX_UPLOAD_MB"}
    fields = {f"V3D_{name.upper()}" for name in Settings.model_fields}
    assert set(declared.values()) <= fields
    assert {f.upload_limit for f in registered_formats().values()} <= fields
    assert app.openapi()["paths"]["/api/evaluations/monocular"]["post"][UPLOAD_LIMIT] == "V3D_MAX_PREDICTIONS_MB"


def test_an_import_format_with_a_smaller_limit_is_held_to_it(app: FastAPI, db_settings,
                                                            accounts: dict[str, Account],
                                                            monkeypatch: pytest.MonkeyPatch) -> None:
    """An import format may declare a limit of its own below the route's (a predictions import of 100 MB beside
    datasets of gigabytes): an upload of that kind above it is 413 naming its setting, before it is unpacked."""
    import dataclasses

    from app.services.transfer import import_formats

    fmt = import_formats.import_format("soccernet-v3")
    monkeypatch.setitem(import_formats._FORMATS, "soccernet-v3",
                        dataclasses.replace(fmt, upload_limit="V3D_MAX_PREDICTIONS_MB"))
    from app.main import create_app

    small = create_app(db_settings.model_copy(update={"max_predictions_mb": 0.125}))
    small.state.session_factory = app.state.session_factory
    with TestClient(small) as c:
        client = as_token(c, accounts["admin"])
        big = client.post("/api/imports", data={"kind": "soccernet-v3"}, files={"file": ("x.zip", b"0" * 200_000)})
        assert big.status_code == 413 and "V3D_MAX_PREDICTIONS_MB" in big.json()["detail"], big.text
        small_zip = client.post("/api/imports", data={"kind": "soccernet-v3"}, files={"file": ("x.zip", b"0" * 1000)})
        assert small_zip.status_code == 400, small_zip.text  # within it: read, and refused as no zip
