"""The S3 store's limits and outages, through the API on a real S3 server (SeaweedFS checking signatures,
``tests.seaweed``): an upload whose object key would pass S3's 1,024 bytes is refused naming its member (400) and
leaves no object; with a wrong secret the start-up says so and every request that needs the store (an image, an
upload) answers 503 in words with ``Retry-After`` at once; with an endpoint that accepts connections and never
answers, each answers 503 within the store's timeout (``V3D_STORE_TIMEOUT_S``, 1 s here: twice that with botocore's
two tries, ``app.services.storage.s3``)."""
from __future__ import annotations

import io
import socket
import threading
import time
import zipfile
from collections.abc import Iterator
from pathlib import Path

import pytest
import sqlalchemy as sa
from fastapi.testclient import TestClient

from app.cli.serve import store_warning
from app.db.models import Frame, Job
from app.services.storage import _s3
from tests.nodes.uploads import small_v3_upload
from tests.seaweed import ACCESS_KEY, REGION, SECRET_KEY, Seaweed, seaweed_for_tests

from ..conftest import run_queued

pytestmark = [pytest.mark.served, pytest.mark.processes]


@pytest.fixture(scope="module")
def seaweed(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Seaweed]:
    with seaweed_for_tests(tmp_path_factory.mktemp("seaweed"), checks_keys=True) as server:
        yield server


@pytest.fixture
def hung_endpoint() -> Iterator[str]:
    """An address that accepts connections and reads what is sent, and never answers."""
    listener = socket.socket()
    listener.bind(("127.0.0.1", 0))
    listener.listen(16)
    held: list[socket.socket] = []
    stop = threading.Event()

    def accept() -> None:
        listener.settimeout(0.2)
        while not stop.is_set():
            try:
                conn, _ = listener.accept()
            except OSError:
                continue
            held.append(conn)  # kept open, never answered

    thread = threading.Thread(target=accept, daemon=True)
    thread.start()
    yield f"http://127.0.0.1:{listener.getsockname()[1]}"
    stop.set()
    thread.join()
    for conn in held:
        conn.close()
    listener.close()


#: The store's timeout in these tests (``V3D_STORE_TIMEOUT_S``): a hung store is met within about twice this.
STORE_TIMEOUT_S = 1.0


def _use_store(app, monkeypatch: pytest.MonkeyPatch, endpoint: str, secret: str, prefix: str) -> None:
    """Point the app's store at ``endpoint`` signing with ``secret`` (the standard AWS variables boto3 reads)."""
    for name, value in {"AWS_ACCESS_KEY_ID": ACCESS_KEY, "AWS_SECRET_ACCESS_KEY": secret, "AWS_DEFAULT_REGION": REGION,
                        "AWS_ENDPOINT_URL": endpoint}.items():
        monkeypatch.setenv(name, value)
    _s3.cache_clear()  # a new client from the variables
    app.state.settings = app.state.settings.model_copy(update={"storage_url": f"s3://v3d/{prefix}",
                                                               "store_timeout_s": STORE_TIMEOUT_S})


@pytest.fixture(autouse=True)
def _fresh_clients() -> Iterator[None]:
    yield
    _s3.cache_clear()


def _objects(seaweed: Seaweed, prefix: str) -> list[str]:
    listed = seaweed.client().list_objects_v2(Bucket=seaweed.bucket, Prefix=f"{prefix}/")
    return [o["Key"] for o in listed.get("Contents", [])]


def _jobs(app) -> int:
    with app.state.session_factory() as session:
        return session.scalar(sa.select(sa.func.count(Job.id))) or 0


def test_an_upload_whose_key_is_too_long_is_refused_and_leaves_no_object(app, client: TestClient, seaweed: Seaweed,
                                                                        tmp_path: Path, monkeypatch) -> None:
    _use_store(app, monkeypatch, seaweed.endpoint, SECRET_KEY, "long")
    upload = io.BytesIO(small_v3_upload(tmp_path / "src", systems=1))
    long_member = "/".join(["z" * 200] * 5) + "/notes.txt"  # each folder a legal name; 1,010 bytes in all
    with zipfile.ZipFile(upload, "a") as zf:
        zf.writestr(long_member, "the last member stored: every other one would be stored before it")
    answer = client.post("/api/imports", data={"kind": "soccernet-v3"},
                         files={"file": ("long.zip", upload.getvalue(), "application/zip")})
    assert answer.status_code == 400, answer.text
    said = answer.json()["detail"]
    assert said.startswith(f"long.zip!{long_member}: its name is too long to be kept in the file store") \
        and "holds at most 1,024" in said, said
    assert _objects(seaweed, "long") == []  # no orphan
    assert _jobs(app) == 0


def test_a_wrong_secret_and_a_hung_store_answer_503_in_words_at_once(app, client: TestClient, seaweed: Seaweed,
                                                                    hung_endpoint: str, tmp_path: Path,
                                                                    monkeypatch) -> None:
    _use_store(app, monkeypatch, seaweed.endpoint, SECRET_KEY, "outage")
    assert store_warning(app.state.settings) is None
    upload = small_v3_upload(tmp_path / "src", systems=1)
    assert client.post("/api/imports", data={"kind": "soccernet-v3"},
                       files={"file": ("one.zip", upload, "application/zip")}).status_code == 202
    run_queued(app)
    with app.state.session_factory() as session:
        frame_id = session.scalars(sa.select(Frame.id).where(Frame.image_root.like("storage:%"))).first()
    assert frame_id is not None and client.get(f"/api/frames/{frame_id}/image").status_code == 200
    stored, jobs = _objects(seaweed, "outage"), _jobs(app)
    another = small_v3_upload(tmp_path / "src", systems=1, league="another")  # games not stored yet

    for endpoint, secret, words in ((seaweed.endpoint, "not-the-secret", "refused v3d's credentials"),
                                    (hung_endpoint, SECRET_KEY, "did not answer within")):
        _use_store(app, monkeypatch, endpoint, secret, "outage")
        warning = store_warning(app.state.settings)
        assert warning is not None and "s3://v3d/outage" in warning and words in warning, warning
        for ask in (lambda: client.get(f"/api/frames/{frame_id}/image"),
                    lambda: client.post("/api/imports", data={"kind": "soccernet-v3"},
                                        files={"file": ("two.zip", another, "application/zip")})):
            t0 = time.monotonic()
            answer = ask()
            took = time.monotonic() - t0
            assert answer.status_code == 503, answer.text
            # botocore's two tries of the timeout, and the work around them: far below the 5 s default's 10 s
            assert answer.headers["retry-after"] == "30" and took < 4 * STORE_TIMEOUT_S + 2, took
            said = answer.json()["detail"]
            assert said.startswith("the file store s3://v3d/outage cannot be used: ") and words in said, said
    assert _jobs(app) == jobs  # no job queued to fail later
    assert _objects(seaweed, "outage") == stored  # nothing more stored, nothing lost
