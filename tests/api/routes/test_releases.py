"""Releases over HTTP: the issue's whole scenario through the app (five accepted systems released as ``v1.0``; 403
for an annotator, 409 for a taken name; ``v1.0`` exported as a job names the release and its hash; a ball moved and
accepted again, one rejected, one more accepted, ``v1.1``; the diff names exactly the one added, the one removed
and the moved one with how far its 3D ball moved; ``v1.0`` exported again is byte for byte the first export; both
listed), the CSV diff, and the refusals of an export's ``release`` beside ``all`` or naming no release.
"""
from __future__ import annotations

import csv
import io
import json
import zipfile
from pathlib import Path
from typing import Any

import pytest
import sqlalchemy as sa
from fastapi.testclient import TestClient
from sqlalchemy.orm import Session

from app.core.config import Settings
from app.db.models import Release

from ..conftest import run_queued
from ..factories import Scene, make_game, make_system

#: The edit routes run on a real engine, as served (tests/api/conftest.py).
pytestmark = [pytest.mark.served, pytest.mark.engine]


def _accept(client: TestClient, system_id: int, status: str = "accepted") -> None:
    etag = client.get(f"/api/systems/{system_id}").headers["etag"]
    answer = client.post(f"/api/systems/{system_id}/review", json={"status": status, "comment": ""},
                         headers={"If-Match": etag})
    assert answer.status_code == 200, answer.text


def _export(app: Any, client: TestClient, body: dict[str, Any]) -> bytes:
    job = client.post("/api/exports/soccernet-v3d", json=body)
    assert job.status_code == 202, job.text
    run_queued(app)
    done = client.get(job.json()["url"]).json()
    assert done["state"] == "done", done
    return client.get(done["result_url"]).content


def _labels(data: bytes) -> dict[str, Any]:
    with zipfile.ZipFile(io.BytesIO(data)) as zf:
        return {n: json.loads(zf.read(n)) for n in zf.namelist() if n.endswith("Labels-v3D.json")}


@pytest.fixture
def six(db_session: Session, db_settings: Settings, tmp_path: Path) -> list[Scene]:
    game = make_game(db_session)
    return [make_system(db_session, db_settings, game, f"{i}.png", image_dir=tmp_path) for i in range(1, 7)]


def test_the_release_scenario_end_to_end(app, client: TestClient, six: list[Scene], act_as) -> None:
    act_as("adam", "admin")
    ids = [s.system_id for s in six]
    for sid in ids[:5]:
        _accept(client, sid)
    made = client.post("/api/releases", json={"name": "v1.0", "note": "first"})
    assert made.status_code == 201, made.text
    v10 = made.json()
    assert v10["systems"] == 5 and v10["views"] == 15 and v10["note"] == "first" and v10["created_by"] == "adam"
    assert v10["made_by"] == "adam" and v10["without_ball3d"] == 0
    assert len(v10["hash"]) == 64 and int(v10["hash"], 16) >= 0
    assert client.post("/api/releases", json={"name": "v1.0"}).status_code == 409
    act_as("ana", "annotator")
    assert client.post("/api/releases", json={"name": "v1.0-ana"}).status_code == 403
    act_as("adam", "admin")

    first = _export(app, client, {"release": "v1.0"})
    labels = _labels(first)
    assert [doc["GameMetadata"]["v3d_release"] for doc in labels.values()] == [{"name": "v1.0", "hash": v10["hash"]}]
    with zipfile.ZipFile(io.BytesIO(first)) as zf:
        manifest = json.loads(zf.read("v3d-release.json"))
        assert manifest["hash"] == v10["hash"] and len(manifest["systems"]) == 5
        assert all(info.date_time == (1980, 1, 1, 0, 0, 0) for info in zf.infolist())
        assert sum(1 for n in zf.namelist() if n.endswith("Frames-v3.zip")) == 1  # the images, too

    # one released system's ball moved 6 px and accepted again, one rejected, one more accepted
    frame = six[0].frame_ids[1]
    box = client.get(f"/api/systems/{ids[0]}").json()["views"][1]["ball"]["box"]
    moved = client.patch(f"/api/frames/{frame}/ball", json={"box": [box[0] + 6, box[1], box[2] + 6, box[3]]})
    assert moved.status_code == 200, moved.text
    _accept(client, ids[0])
    _accept(client, ids[1], "rejected")
    _accept(client, ids[5])
    v11 = client.post("/api/releases", json={"name": "v1.1"}).json()
    assert v11["systems"] == 5 and v11["hash"] != v10["hash"]

    diff = client.get("/api/releases/v1.0/diff/v1.1")
    assert diff.status_code == 200, diff.text
    d = diff.json()
    assert [s["system_id"] for s in d["added"]] == [ids[5]]
    assert [(s["system_id"], s["why"]) for s in d["removed"]] == [(ids[1], "rejected")]
    assert [s["system_id"] for s in d["changed"]] == [ids[0]]
    assert d["changed"][0]["ball3d_moved_m"] > 0
    assert {v["frame_id"]: v["changes"] for v in d["changed"][0]["views"]}[frame][0] == "label"
    assert d["unchanged"] == 3 and d["from"] == {"name": "v1.0", "hash": v10["hash"]}
    rows = list(csv.DictReader(io.StringIO(client.get("/api/releases/v1.0/diff/v1.1?format=csv").text)))
    assert [(r["change"], int(r["system_id"])) for r in rows] == [("added", ids[5]), ("removed", ids[1]),
                                                                   ("changed", ids[0])]
    assert float(rows[2]["ball3d_moved_m"]) == d["changed"][0]["ball3d_moved_m"]
    assert [r["why"] for r in rows] == ["", "rejected", ""]

    again = _export(app, client, {"release": "v1.0"})
    assert again == first
    streamed = client.get("/api/exports/soccernet-v3d", params={"release": "v1.0"})
    assert streamed.status_code == 200 and streamed.content == first and streamed.headers["x-v3d-systems"] == "5"
    listed = client.get("/api/releases").json()["items"]
    assert [r["name"] for r in listed] == ["v1.0", "v1.1"]
    assert client.get("/api/releases/v1.1").json() == v11
    assert client.get("/api/releases/v9").status_code == 404
    summaries = [e["summary"] for e in client.get("/api/audit", params={"limit": 500}).json()["items"]]
    assert any(s.startswith("release v1.0 made: 5 systems, 15 views") for s in summaries)


def test_release_exports_refuse_all_and_unknown_releases(client: TestClient, scene: Scene, act_as) -> None:
    act_as("adam", "admin")
    _accept(client, scene.system_id)
    assert client.post("/api/releases", json={"name": "r"}).status_code == 201
    both = client.post("/api/exports/soccernet-v3d", json={"release": "r", "all": True})
    assert both.status_code == 422 and "release" in both.text
    assert client.post("/api/exports/soccernet-v3d", json={"release": "nope"}).status_code == 404
    assert client.get("/api/exports/soccernet-v3d", params={"release": "nope"}).status_code == 404
    assert client.get("/api/exports/soccernet-v3d", params={"release": "r", "all": "true"}).status_code == 422
    for fmt in ("issia-3d", "cameras", "yolo", "coco"):  # every format takes a release
        assert client.post(f"/api/exports/{fmt}", json={"release": "r"}).status_code == 202
        assert client.post(f"/api/exports/{fmt}", json={"release": "r", "all": True}).status_code == 422
    assert client.post("/api/releases", json={"name": " r "}).status_code == 422


def test_a_release_made_over_http_records_the_export_settings_of_the_app(app, client: TestClient, scene: Scene,
                                                                           act_as, db_session: Session) -> None:
    act_as("adam", "admin")
    _accept(client, scene.system_id)
    served = app.state.settings
    app.state.settings = served.model_copy(update={"export_ball_box": "optimised", "ball_diameter_m": 0.3})
    try:
        assert client.post("/api/releases", json={"name": "boxes"}).status_code == 201
    finally:
        app.state.settings = served
    recorded = db_session.scalars(sa.select(Release.export_settings).where(Release.name == "boxes")).one()
    assert recorded == {"ball_diameter_m": 0.3, "export_ball_box": "optimised"}


def test_releases_are_append_only_in_the_database(client: TestClient, scene: Scene, act_as,
                                                  db_session: Session) -> None:
    act_as("adam", "admin")
    _accept(client, scene.system_id)
    assert client.post("/api/releases", json={"name": "fixed"}).status_code == 201
    for statement in ("UPDATE releases SET note = 'x'", "DELETE FROM release_systems",
                      "UPDATE release_documents SET digest = digest", "DELETE FROM release_games"):
        with pytest.raises(sa.exc.DBAPIError, match="append-only"):
            db_session.execute(sa.text(statement))
        db_session.rollback()


@pytest.mark.parametrize(("name", "why"), [
    ("v1\u202egpj", "U+202E"),  # a right-to-left override: the name reads backwards after it
    ("v1\u200b", "U+200B"),  # a zero-width space: two names that look one
    ("\ufeffv1", "U+FEFF"),  # a byte order mark
    ("v1\x1b[2J", "U+001B"),  # a terminal's escape
    ("v1\x85", "U+0085"),  # a C1 control (next line)
    (".", "dots alone"), ("..", "dots alone"), ("...", "dots alone"),
])
def test_a_release_name_people_cannot_read_as_it_is_is_422_naming_it(client: TestClient, scene: Scene, act_as,
                                                                     name: str, why: str) -> None:
    """Was: all accepted (201), and ``.`` / ``..`` made releases whose page cannot be opened."""
    act_as("adam", "admin")
    answer = client.post("/api/releases", json={"name": name})
    assert answer.status_code == 422, answer.text
    assert answer.json()["detail"][0]["loc"] == ["body", "name"] and why in answer.json()["detail"][0]["msg"]
    assert client.get("/api/releases").json()["items"] == []


def test_release_names_are_stored_composed_and_unique_as_people_read_them(client: TestClient, scene: Scene,
                                                                          act_as, db_session: Session) -> None:
    """Was: the decomposed and the composed form of one name (two releases that look identical), and names that
    differ only by case, all accepted. A name is stored in NFC; a second name with the same NFKC case-folded key is
    409, whichever form it came in; the key is the database's unique index, not a read."""
    from app.db.models import Release

    act_as("adam", "admin")
    made = client.post("/api/releases", json={"name": "Cafe\u0301 v1"})  # e + combining acute accent
    assert made.status_code == 201, made.text
    assert made.json()["name"] == "Caf\u00e9 v1"
    assert client.get("/api/releases/Cafe\u0301 v1").json()["name"] == "Caf\u00e9 v1"  # found however typed
    for twin in ("Caf\u00e9 v1", "caf\u00e9 V1", "CAFE\u0301 V1", "\uff23af\u00e9 v1", "Caf\u00e9 v1."):
        again = client.post("/api/releases", json={"name": twin})
        assert again.status_code == 409, (twin, again.text)
        assert "'Café v1' exists" in again.json()["detail"]
    assert [r["name"] for r in client.get("/api/releases").json()["items"]] == ["Caf\u00e9 v1"]
    assert client.post("/api/releases", json={"name": "Caf\u00e9 v2"}).status_code == 201
    # the database holds the rule, whoever writes: a second row with the same key is refused by its unique index
    db_session.add(Release(name="CAF\u00c9 V2", note="", created_by="x", systems=0, views=0, hash=""))
    with pytest.raises(sa.exc.IntegrityError):
        db_session.flush()
    db_session.rollback()


def test_a_release_says_how_many_of_its_systems_were_accepted_without_a_3d_ball(client: TestClient,
                                                                                  six: list[Scene], act_as) -> None:
    act_as("adam", "admin")
    blind = six[2]
    for frame in blind.frame_ids:  # every ball label removed: its views agree on no ball
        assert client.patch(f"/api/frames/{frame}/ball", json={"box": None}).status_code == 200
    assert client.get(f"/api/systems/{blind.system_id}").json()["ball3d"] is None
    for s in six[:3]:
        _accept(client, s.system_id)
    made = client.post("/api/releases", json={"name": "v1"}).json()
    assert made["systems"] == 3 and made["without_ball3d"] == 1
    assert [r["without_ball3d"] for r in client.get("/api/releases").json()["items"]] == [1]
    assert client.get("/api/releases/v1").json()["without_ball3d"] == 1
    summaries = [e["summary"] for e in client.get("/api/audit", params={"limit": 50}).json()["items"]]
    assert any(s.startswith("release v1 made: 3 systems (1 without a 3D ball), ") for s in summaries)
