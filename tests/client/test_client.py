"""The client's own promises against a served demo (one for the module, answering a busy database within 0.5 s):
every list read whole across pages; an edit bound to the version read and the typed 412 holding the state now and
the changes since; 503 sent again after its Retry-After, at most ``retries`` times; an upload and a download streamed
with their progress; a job waited for, and its failure typed; the server's words and field in every error; a login by
name and password; a server of another version named at the first call."""
from __future__ import annotations

import sqlite3
import time
import zipfile
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import httpx
import pytest
import sqlalchemy as sa

import app.api.routes.health as health_route
from tests.accounts import PASSWORD
from tests.client.conftest import ServedDemo, page_through, serve_demo, zip_of
from v3d_client import (
    Busy,
    Client,
    Conflict,
    EditConflict,
    Frame,
    Invalid,
    JobFailed,
    Unauthorized,
    VersionMismatch,
)
from v3d_client.models import SystemState


@pytest.fixture(scope="module")
def served_demo(tmp_path_factory: pytest.TempPathFactory, demo_template: Path) -> Iterator[ServedDemo]:
    """This module's served demo: a write waits at most 0.5 s for the database's lock (then 503, Retry-After 2 s)."""
    with serve_demo(tmp_path_factory.mktemp("client"), demo_template, write_lock_timeout_s=0.5) as served:
        yield served


class Recording(httpx.HTTPTransport):
    """The real transport, noting each answer's (monotonic time, method, path, status) and calling ``then`` with
    it."""

    def __init__(self, then: Callable[[int], None] = lambda status: None) -> None:
        super().__init__()
        self.answers: list[tuple[float, str, str, int]] = []
        self.then = then

    def handle_request(self, request: httpx.Request) -> httpx.Response:
        response = super().handle_request(request)
        self.answers.append((time.monotonic(), request.method, request.url.path, response.status_code))
        self.then(response.status_code)
        return response


def client(served: ServedDemo, role: str = "admin", **options: Any) -> Client:
    return Client(served.url, served.token(role), **options)


def test_every_list_is_read_across_its_pages(served_demo: ServedDemo) -> None:
    raw = served_demo.raw()
    with client(served_demo) as v3d:
        assert [s.id for s in v3d.systems(page_size=7)] == [s["id"] for s in page_through(raw, "/api/systems")]
        assert [s.id for s in v3d.systems(status="pending", sort="name", page_size=5)] == \
            [s["id"] for s in page_through(raw, "/api/systems", status="pending", sort="name")]
        assert [f.id for f in v3d.frames(page_size=9)] == [f["id"] for f in page_through(raw, "/api/frames")]
        assert [e.id for e in v3d.audit(page_size=3)] == [e["id"] for e in page_through(raw, "/api/audit")]
        # a span the server filters: from the oldest entry's time (no offset: UTC) to just before the newest's
        entries = list(v3d.audit())
        oldest, newest = entries[-1].at, entries[0].at
        spanned = list(v3d.audit(since=oldest.replace(tzinfo=None), until=newest, page_size=3))
        assert [e.id for e in spanned] == [e.id for e in entries if oldest <= e.at < newest]
        assert [e.id for e in spanned] == [e["id"] for e in page_through(
            raw, "/api/audit", since=oldest.isoformat(), until=newest.isoformat())]


def test_a_stale_edit_raises_the_typed_conflict_with_the_state_now(served_demo: ServedDemo) -> None:
    raw = served_demo.raw("reviewer")
    with client(served_demo, "reviewer") as v3d:
        summary = next(v3d.systems(status="pending"))
        seen = v3d.system(summary.id)
        etag = raw.get(f"/api/systems/{seen.id}").headers["etag"]
        assert raw.post(f"/api/systems/{seen.id}/review", json={"status": "rejected", "comment": "by raw"},
                        headers={"If-Match": etag}).status_code == 200
        with pytest.raises(EditConflict) as caught:
            v3d.decide(seen, "accepted")
        now = raw.get(f"/api/systems/{seen.id}")
        assert isinstance(caught.value.current, SystemState) and caught.value.current.review.status == "rejected"
        assert caught.value.etag == now.headers["etag"] and caught.value.status == 412
        assert [e.actor for e in caught.value.changes_since] == ["test-reviewer"]
        assert raw.get(f"/api/systems/{seen.id}").json()["review"]["status"] == "rejected"  # nothing stored

        view = next(v for v in v3d.system(summary.id).views if v.ball.box is not None)
        frame = v3d.frame(view.frame_id)
        box = list(frame.ball.box or ())
        moved = [box[0] + 1, box[1], box[2] + 1, box[3]]
        assert raw.patch(f"/api/frames/{frame.frame_id}/ball", json={"box": moved},
                         headers={"If-Match": frame.etag}).status_code == 200
        with pytest.raises(EditConflict) as caught:
            v3d.edit_ball(frame, box=[box[0] - 1, box[1], box[2] - 1, box[3]])
        assert isinstance(caught.value.current, Frame) and list(caught.value.current.ball.box or ()) == moved
        after = v3d.edit_ball(caught.value.current, box=box)  # the version now: it lands
        assert list(after.view(frame.frame_id).ball.box or ()) == box


def test_errors_carry_the_servers_words_and_field(served_demo: ServedDemo) -> None:
    with client(served_demo, "annotator") as v3d:
        frame = next(f for f in v3d.frames() if f.ball.box is not None)
        with pytest.raises(Invalid) as caught:
            v3d.edit_ball(v3d.frame(frame.id), box=[-500, -500, -400, -400])
        assert caught.value.field == "box" and caught.value.status == 422 and caught.value.detail
    with Client(served_demo.url, "no-such-token") as v3d, pytest.raises(Unauthorized) as refused:
        v3d.me()
    assert refused.value.detail == served_demo.raw().get("/api/auth/me", headers={
        "Authorization": "Bearer no-such-token"}).json()["detail"]


def _locked(served: ServedDemo) -> sqlite3.Connection:
    """A connection to the served database that takes its write lock by ``BEGIN IMMEDIATE`` (until it commits)."""
    path = sa.make_url(served.settings.database_url).database or ""
    return sqlite3.connect(path, isolation_level=None, check_same_thread=False)


def test_a_busy_server_is_asked_again_after_its_retry_after(served_demo: ServedDemo) -> None:
    holder = _locked(served_demo)
    transport = Recording(then=lambda status: holder.commit() if status == 503 else None)
    with client(served_demo, "reviewer", transport=transport) as v3d:
        system = v3d.system(next(v3d.systems(status="pending")).id)
        holder.execute("BEGIN IMMEDIATE")
        decision = v3d.decide(system, "needs_fix", "busy, then done", assignee="test-annotator")
    holder.close()
    writes = [(t, status) for t, method, _, status in transport.answers if method == "POST"]
    assert [s for _, s in writes] == [503, 200] and decision.status == "needs_fix"
    assert writes[1][0] - writes[0][0] >= 2.0  # the server's Retry-After: 2


def test_the_retries_are_bounded(served_demo: ServedDemo) -> None:
    holder = _locked(served_demo)
    try:
        transport = Recording()
        with client(served_demo, "reviewer", retries=1, transport=transport) as v3d:
            system = v3d.system(next(v3d.systems(status="pending")).id)
            holder.execute("BEGIN IMMEDIATE")
            with pytest.raises(Busy) as caught:
                v3d.decide(system, "rejected")
            assert caught.value.status == 503 and caught.value.retry_after == 2
            posts = [a for a in transport.answers if a[1] == "POST"]
            assert [a[3] for a in posts] == [503, 503]
    finally:
        holder.close()
    assert served_demo.raw().get(f"/api/systems/{system.id}").json()["review"]["status"] == "pending"


def test_an_upload_and_a_download_stream_with_progress(served_demo: ServedDemo, shared_dir: Path,
                                                       tmp_path: Path) -> None:
    archive = zip_of(shared_dir / "data" / "synthetic" / "soccernet-v3-dev", tmp_path / "dev.zip")
    sent: list[tuple[int, int | None]] = []
    stages: list[str] = []
    with client(served_demo) as v3d:
        job = v3d.upload(archive, "soccernet-v3", progress=lambda done, total: sent.append((done, total)))
        done = v3d.wait(job, progress=lambda j: stages.append(j.state), timeout_s=600)
        assert done.result is not None and done.result["systems"] == 40 and stages[-1] == "done"
        size = archive.stat().st_size
        assert sent[-1] == (size, size) and len(sent) > 1
        assert all(a[0] < b[0] for a, b in zip(sent, sent[1:], strict=False))
        with pytest.raises(Conflict) as again:  # the same games again, without a merge
            v3d.upload(archive, "soccernet-v3")
        assert len(again.value.current["games"]) == 2

        received: list[tuple[int, int | None]] = []
        export = v3d.export("soccernet-v3d", tmp_path / "all.zip", include_all=True,
                            progress=lambda got, total: received.append((got, total)))
        on_disk = (tmp_path / "all.zip").read_bytes()
        assert received[-1] == (len(on_disk), len(on_disk))
        assert on_disk == served_demo.raw().get(f"/api/jobs/{export.id}/result").content


def test_a_failed_job_raises_its_message(served_demo: ServedDemo, tmp_path: Path) -> None:
    broken = tmp_path / "broken.zip"
    with zipfile.ZipFile(broken, "w") as zf:
        zf.writestr("lg/2031-2032/a game/Labels-v3.json", "{ not json")
    with client(served_demo) as v3d:
        job = v3d.upload(broken, "soccernet-v3")
        with pytest.raises(JobFailed) as failed:
            v3d.wait(job, timeout_s=600)
    assert "Labels-v3.json" in str(failed.value)
    assert failed.value.job.message == served_demo.raw().get(f"/api/jobs/{job.id}").json()["message"]


def test_a_login_by_name_and_password_writes_with_its_session(served_demo: ServedDemo) -> None:
    with Client(served_demo.url, name="test-annotator", password=PASSWORD) as v3d:
        me = v3d.me()
        frame = v3d.frame(next(f for f in v3d.frames() if f.ball.box is not None).id)
        box = list(frame.ball.box or ())
        v3d.edit_ball(frame, box=[box[0], box[1] + 1, box[2], box[3] + 1])
    assert me.via == "session" and me.name == "test-annotator"
    entry = served_demo.raw().get("/api/audit", params={"frame_id": frame.frame_id}).json()["items"][0]
    assert entry["actor"] == "test-annotator"


def test_a_server_of_another_version_is_named_at_the_first_call(served_demo: ServedDemo,
                                                                monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(health_route, "__version__", "0.2.0")
    transport = Recording()
    with client(served_demo, transport=transport) as v3d:
        with pytest.raises(VersionMismatch) as caught:
            next(v3d.systems())
        assert "server runs v3d 0.2.0, newer than this client" in str(caught.value)
        assert [a[2] for a in transport.answers] == ["/api/health"]
