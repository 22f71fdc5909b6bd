"""What one edit may ask for is bounded, and a write never waits long (issue 27, item 4): a field-line edit of
more than ``V3D_MAX_LINE_POINTS_PER_FRAME`` points is 422 naming ``lines`` before any geometry; a view stored
with more points before the cap still opens and edits; a write that waits for the database's lock past
``V3D_WRITE_LOCK_TIMEOUT_S`` is answered 503 with ``Retry-After``, never 500, and changes nothing (a real
SQLite file whose write lock another process holds; a PostgreSQL row lock held by another edit)."""
from __future__ import annotations

import contextlib
import time
from collections.abc import Iterator
from pathlib import Path

import pytest
from fastapi.testclient import TestClient
from sqlalchemy.orm import Session

from app.core.config import Settings
from app.db.models import Frame
from app.db.session import begin_write, make_engine, make_session_factory
from app.main import create_app
from app.services.accounts.users import create_user
from app.services.curation import writing
from app.services.curation.writing import lock_system
from benchmarks.edit_lock import dense_lines
from tests.api.factories import Scene, make_game, make_system
from tests.conftest import PG_ADMIN_URL, fresh_postgresql_database, migrate_new_database

#: The edit routes run on a real engine, as served (tests/api/conftest.py).
pytestmark = [pytest.mark.served, pytest.mark.engine]


def _moved(box: list[float], dx: float) -> list[float]:
    return [box[0] + dx, box[1], box[2] + dx, box[3]]


def test_a_line_edit_above_the_cap_is_422_naming_lines_and_changes_nothing(client: TestClient, scene: Scene) -> None:
    fid = scene.frame_ids[0]
    frame = client.get(f"/api/frames/{fid}")
    etag, lines = frame.headers["ETag"], frame.json()["field_lines"]
    too_many = dense_lines(lines, 2001)
    answer = client.put(f"/api/frames/{fid}/field-lines", json={"lines": too_many}, headers={"If-Match": etag})
    assert answer.status_code == 422, answer.text
    assert answer.json()["field"] == "lines"
    assert "2001 points" in answer.json()["detail"] and "V3D_MAX_LINE_POINTS_PER_FRAME" in answer.json()["detail"]
    after = client.get(f"/api/frames/{fid}")
    assert after.headers["ETag"] == etag and after.json()["field_lines"] == lines
    at_cap = dense_lines(lines, 2000)
    assert client.put(f"/api/frames/{fid}/field-lines", json={"lines": at_cap},
                      headers={"If-Match": etag}).status_code == 200


def test_a_view_stored_with_more_points_before_the_cap_still_opens_and_edits(
        client: TestClient, scene: Scene, db_session: Session) -> None:
    fid = scene.frame_ids[1]
    frame = db_session.get(Frame, fid)
    frame.field_lines.lines = dense_lines(frame.field_lines.lines, 3000)  # stored before the cap
    db_session.commit()
    assert client.get(f"/api/systems/{scene.system_id}").status_code == 200
    got = client.get(f"/api/frames/{fid}")
    box = _moved(got.json()["ball"]["box"], 3.0)
    edited = client.patch(f"/api/frames/{fid}/ball", json={"box": box}, headers={"If-Match": got.headers["ETag"]})
    assert edited.status_code == 200, edited.text
    excluded = client.post(f"/api/frames/{fid}/exclusion", json={"excluded": True},
                           headers={"If-Match": edited.headers["ETag"] if "ETag" in edited.headers
                                    else client.get(f"/api/frames/{fid}").headers["ETag"]})
    assert excluded.status_code == 200, excluded.text


@pytest.fixture(params=["sqlite", pytest.param("postgresql", marks=pytest.mark.postgres)])
def served(request: pytest.FixtureRequest, tmp_path: Path) -> Iterator[tuple[TestClient, Scene, str, Session]]:
    """The app on a real database (a SQLite file, or a fresh PostgreSQL database) with a 0.5 s lock timeout, one
    three-view system and an annotator's API token; yields its client (sending the token), the scene, the
    backend and a session of another engine (another process) to hold locks with."""
    with contextlib.ExitStack() as stack:
        url = (f"sqlite:///{tmp_path / 'served.sqlite3'}" if request.param == "sqlite"
               else stack.enter_context(fresh_postgresql_database(PG_ADMIN_URL, migrated=True)))
        migrate_new_database(url)
        settings = Settings(_env_file=None, database_url=url, calibration_workers=1, job_runner=False,
                            write_lock_timeout_s=0.5, data_root=tmp_path)
        other = make_engine(url)
        stack.callback(other.dispose)
        with make_session_factory(other)() as s:
            scene = make_system(s, settings, make_game(s), "1.png")
            _, token = create_user(s, "ann", "annotator", "correct horse battery staple")
            s.commit()
        client = stack.enter_context(TestClient(create_app(settings)))
        client.headers["Authorization"] = f"Bearer {token}"
        holder = stack.enter_context(make_session_factory(other)())
        yield client, scene, request.param, holder


def test_a_write_waiting_past_the_lock_timeout_is_503_with_retry_after(served, monkeypatch) -> None:
    client, scene, backend, holder = served
    stored: list[tuple[int, str | None]] = []
    write = writing.guarded_write

    def counted(session, system_id, *args, **kwargs):  # the real write, counted with how it was stored
        done = write(session, system_id, *args, **kwargs)
        stored.append((system_id, kwargs["edit"].outcome))
        return done

    monkeypatch.setattr(writing, "guarded_write", counted)
    fid = scene.frame_ids[0]
    got = client.get(f"/api/frames/{fid}")
    etag, box = got.headers["ETag"], got.json()["ball"]["box"]
    begin_write(holder)  # another process's write: SQLite's write lock
    lock_system(holder, scene.system_id)  # PostgreSQL: the system's row lock of an edit under way
    t0 = time.monotonic()
    busy = client.patch(f"/api/frames/{fid}/ball", json={"box": _moved(box, 6.0)}, headers={"If-Match": etag})
    waited = time.monotonic() - t0
    holder.rollback()
    assert busy.status_code == 503, busy.text
    assert busy.headers["Retry-After"] == "2"
    assert "busy" in busy.json()["detail"]
    assert 0.4 <= waited < 5.0, waited  # the lock timeout, not today's minute
    after = client.get(f"/api/frames/{fid}")
    assert after.headers["ETag"] == etag and after.json()["ball"]["box"] == box  # nothing changed
    again = client.patch(f"/api/frames/{fid}/ball", json={"box": _moved(box, 6.0)}, headers={"If-Match": etag})
    assert again.status_code == 200, again.text  # the same request, sent again once the lock is free
    assert stored == [(scene.system_id, "computed")]  # computed after its reads, stored under the lock
