"""Imports never silently overwrite curation (the third security review's attack on imports), over HTTP.

The attack: an admin uploads a SoccerNet-v3D export whose ``v3d_reviews`` say accepted and whose labels are older
than the database's: every pending system became accepted, a ball edited after the export was put back, a rejected
system kept its rejection over a label it no longer describes, and the only audit entry was "import of upload N",
which cannot be reverted. Now:

* an import whose games are stored already is refused (409 naming them, nothing stored) unless it says how to
  merge them (``merge=keep-newer|overwrite``, a form field);
* ``keep-newer`` keeps what was changed after the newest change the file holds (``GameMetadata.v3d_as_of``);
* a decision comes from the file only for exactly the file's labels, and says so; a decision whose labels the merge
  changed goes back to pending;
* one audit entry per system the merge changed, revertible through the audit log's revert.
"""
from __future__ import annotations

import csv
import io
import json
import zipfile
from pathlib import Path
from typing import Any

import pytest
from fastapi.testclient import TestClient
from sqlalchemy.orm import Session

from app.core.config import Settings
from app.db.models import Game

from ..conftest import run_queued
from ..factories import Scene, make_system

pytestmark = pytest.mark.engine

GAME = "england_epl/2014-2015/2015-02-21 - 18-00 Chelsea 1 - 1 Burnley"


@pytest.fixture
def three(scene: Scene, db_session: Session, db_settings: Settings) -> dict[str, Scene]:
    """Systems A (the scene's), B and C of one game."""
    game = db_session.get(Game, scene.game_id)
    return {"A": scene, "B": make_system(db_session, db_settings, game, "2.png"),
            "C": make_system(db_session, db_settings, game, "3.png")}


def _export(client: TestClient, where: Path) -> Path:
    """The whole database as a SoccerNet-v3D export (``GET /api/exports/soccernet-v3d?all=true&images=false``),
    unpacked under ``where``."""
    answer = client.get("/api/exports/soccernet-v3d", params={"all": "true", "images": "false"})
    assert answer.status_code == 200, answer.text
    with zipfile.ZipFile(io.BytesIO(answer.content)) as zf:
        zf.extractall(where)
    return where


def _crafted(tree: Path, moved_frame: str, dx: float) -> None:
    """Make the export say every system is accepted, and move the ball of frame ``moved_frame`` by ``dx`` px in
    ``SNv3D.csv`` (an older label than the database's)."""
    (labels,) = tree.rglob("Labels-v3D.json")
    doc = json.loads(labels.read_text())
    doc["GameMetadata"]["v3d_reviews"] = {name: "accepted" for name in doc["GameMetadata"]["v3d_reviews"]}
    labels.write_text(json.dumps(doc))
    path = tree / "SNv3D.csv"
    with path.open(newline="") as fh:
        rows = list(csv.DictReader(fh))
    for row in rows:
        if row["action"] == moved_frame or (row["replay"] == "" and row["main_action"] == moved_frame):
            box = json.loads(row["ball_bbox"])
            row["ball_bbox"] = json.dumps([box[0] + dx, box[1], box[2] + dx, box[3]])
    with path.open("w", newline="") as fh:
        writer = csv.DictWriter(fh, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)


def _zipped(tree: Path) -> bytes:
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w") as zf:
        for p in sorted(tree.rglob("*")):
            if p.is_file():
                zf.write(p, p.relative_to(tree).as_posix())
    return buf.getvalue()


def _upload(client: TestClient, data: bytes, **fields: str):
    return client.post("/api/imports", data={"kind": "soccernet-v3d", **fields},
                       files={"file": ("export.zip", data, "application/zip")})


def _system(client: TestClient, scene: Scene) -> dict[str, Any]:
    answer = client.get(f"/api/systems/{scene.system_id}")
    assert answer.status_code == 200, answer.text
    return answer.json()


def _moved(box: list[float], dx: float) -> list[float]:
    return [box[0] + dx, box[1], box[2] + dx, box[3]]


def _after_export(client: TestClient, systems: dict[str, Scene], act_as) -> tuple[list[float], list[float]]:
    """After the export: an annotator moves B's second ball 25 px, a reviewer rejects C. Answers B's ball before and
    after the move."""
    act_as("ana")
    before = _system(client, systems["B"])["views"][1]["ball"]["box"]
    moved = client.patch(f"/api/frames/{systems['B'].frame_ids[1]}/ball", json={"box": _moved(before, 25.0)})
    assert moved.status_code == 200, moved.text
    act_as("rita", "reviewer")
    rejected = client.post(f"/api/systems/{systems['C'].system_id}/review",
                           json={"status": "rejected", "comment": "no"})
    assert rejected.status_code == 200, rejected.text
    act_as("adam", "admin")
    return before, _moved(before, 25.0)


def _imported(app, client: TestClient, data: bytes, merge: str) -> dict[str, Any]:
    answer = _upload(client, data, merge=merge)
    assert answer.status_code == 202, answer.text
    assert answer.json()["params"]["merge"] == merge
    assert run_queued(app) == [answer.json()["id"]]
    job = client.get(answer.json()["url"]).json()
    assert job["state"] == "done", job
    return job["result"]


def _merge_entries(client: TestClient) -> dict[int, dict[str, Any]]:
    items = client.get("/api/audit", params={"limit": 500}).json()["items"]
    return {e["system_id"]: e for e in items if e["action"] == "system.import"}


def test_a_crafted_export_of_stored_games_is_refused_unless_it_says_how_to_merge(
        app, client: TestClient, three: dict[str, Scene], tmp_path: Path, act_as) -> None:
    tree = _export(client, tmp_path / "export")
    _crafted(tree, "3.png", 30.0)
    _after_export(client, three, act_as)
    states = {k: _system(client, s) for k, s in three.items()}
    jobs = client.get("/api/jobs").json()["total"]
    refused = _upload(client, _zipped(tree))
    assert refused.status_code == 409, refused.text
    assert GAME in refused.json()["detail"] and "merge=keep-newer" in refused.json()["detail"]
    assert refused.json()["current"]["games"] == [GAME]
    assert set(refused.json()["current"]["merge_modes"]) == {"keep-newer", "overwrite"}  # what a page offers
    assert client.get("/api/jobs").json()["total"] == jobs  # nothing queued, nothing stored
    assert {k: _system(client, s) for k, s in three.items()} == states
    bad = _upload(client, _zipped(tree), merge="newest")
    assert bad.status_code == 422 and "merge" in bad.text


def test_keep_newer_keeps_later_edits_and_decisions_and_says_what_it_took_from_the_file(
        app, client: TestClient, three: dict[str, Scene], tmp_path: Path, act_as) -> None:
    tree = _export(client, tmp_path / "export")
    _crafted(tree, "3.png", 30.0)
    c_ball = _system(client, three["C"])["views"][0]["ball"]["box"]
    _, b_moved = _after_export(client, three, act_as)
    result = _imported(app, client, _zipped(tree), "keep-newer")
    assert (result["systems_merged"], result["decisions_from_file"], result["decisions_reset"]) == (2, 1, 1)
    a, b, c = (_system(client, three[k]) for k in "ABC")
    # A: untouched since the export, exactly the file's labels: the file's decision, said
    assert a["review"]["status"] == "accepted"
    assert a["review"]["comment"].startswith("as the import of export.zip (upload ")
    # B: the ball moved after the export stays, and the file's accept (of the older ball) is not taken
    assert b["views"][1]["ball"]["box"] == b_moved and b["review"]["status"] == "pending"
    # C: its label took the file's (nobody changed it since the export); the rejection of the label it had no
    # longer describes it: pending, with the reason
    assert c["views"][0]["ball"]["box"] == _moved(c_ball, 30.0)
    assert c["review"]["status"] == "pending" and "changed its labels" in c["review"]["reset_reason"]
    entries = _merge_entries(client)
    assert set(entries) == {three["A"].system_id, three["C"].system_id}
    assert entries[three["A"].system_id]["summary"].endswith("system accepted (as the import of "
                                                             f"{a['review']['comment'][len('as the import of '):]})")
    assert "ball of V1 moved 30.0 px" in entries[three["C"].system_id]["summary"]
    assert all(e["revertible"] for e in entries.values())
    # revertible through the audit log: C gets its label and its rejection back
    act_as("rita", "reviewer")
    reverted = client.post(f"/api/audit/{entries[three['C'].system_id]['id']}/revert")
    assert reverted.status_code == 200, reverted.text
    assert reverted.json()["views"][0]["ball"]["box"] == c_ball
    assert reverted.json()["review"]["status"] == "rejected" and reverted.json()["review"]["comment"] == "no"


def test_overwrite_replaces_later_edits_and_each_system_reverts_on_its_own(
        app, client: TestClient, three: dict[str, Scene], tmp_path: Path, act_as) -> None:
    tree = _export(client, tmp_path / "export")
    b_before, b_moved = _after_export(client, three, act_as)
    result = _imported(app, client, _zipped(tree), "overwrite")
    b = _system(client, three["B"])
    assert b["views"][1]["ball"]["box"] == b_before  # the file's ball, the edit since replaced
    assert b["review"]["status"] == "pending"  # the file says pending for B: taken, said in the entry
    c = _system(client, three["C"])
    assert c["review"]["status"] == "pending"  # the file's decision replaces the later rejection
    assert result["systems_merged"] == 2
    entries = _merge_entries(client)
    act_as("rita", "reviewer")
    reverted = client.post(f"/api/audit/{entries[three['B'].system_id]['id']}/revert")
    assert reverted.status_code == 200, reverted.text
    assert reverted.json()["views"][1]["ball"]["box"] == b_moved
    assert _system(client, three["C"])["review"]["status"] == "pending"  # C's own entry is another revert


def test_a_malformed_as_of_fails_the_import_naming_the_field(app, client: TestClient, scene: Scene,
                                                             tmp_path: Path) -> None:
    tree = _export(client, tmp_path / "export")
    (labels,) = tree.rglob("Labels-v3D.json")
    doc = json.loads(labels.read_text())
    assert doc["GameMetadata"]["v3d_as_of"].endswith("+00:00")
    doc["GameMetadata"]["v3d_as_of"] = "2026-11-27 09:00"  # no offset: which time is it?
    labels.write_text(json.dumps(doc))
    answer = _upload(client, _zipped(tree), merge="keep-newer")
    assert answer.status_code == 202, answer.text
    run_queued(app)
    job = client.get(answer.json()["url"]).json()
    assert job["state"] == "failed" and "GameMetadata.v3d_as_of: expected an ISO 8601 time" in job["message"]


def test_an_import_of_the_same_export_again_changes_nothing_and_writes_no_entry(
        app, client: TestClient, three: dict[str, Scene], tmp_path: Path) -> None:
    tree = _export(client, tmp_path / "export")
    before = {k: _system(client, s) for k, s in three.items()}
    result = _imported(app, client, _zipped(tree), "keep-newer")
    assert (result["systems_merged"], result["decisions_from_file"], result["decisions_reset"]) == (0, 0, 0)
    assert _merge_entries(client) == {}
    after = {k: _system(client, s) for k, s in three.items()}
    for k in three:
        assert [v["ball"] for v in after[k]["views"]] == [v["ball"] for v in before[k]["views"]]
        assert after[k]["review"]["status"] == before[k]["review"]["status"]
