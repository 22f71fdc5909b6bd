"""Releases as stored: content-addressed documents (an unchanged system costs no new document), the hash recomputed
from a release's export by the recipe of docs/exports.md, immutability against later edits, and a release exported
by two separate processes (nothing shared, nothing cached) to the same bytes."""
from __future__ import annotations

import gzip
import hashlib
import io
import json
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest
import sqlalchemy as sa
from sqlalchemy.orm import Session

from app.core.config import Settings
from app.db.models import BallLabel, ReleaseDocument, ReviewDecision, ReviewStatus, System, Triangulation
from app.db.session import make_engine
from app.services.derivation.recompute import recompute_system
from app.services.exports.files import write_export_zip
from app.services.releases.content import create_release, get_release, release_content
from app.services.releases.diff import diff_releases
from tests.api.factories import make_game, make_system
from tests.conftest import migrate_new_database

_EXPORT = """
import sys
from pathlib import Path
from app.core.config import Settings
from app.db.session import make_engine
from sqlalchemy.orm import Session
from app.services.exports.files import write_export_zip
settings = Settings(database_url=sys.argv[1], calibration_workers=1)
with Session(make_engine(sys.argv[1])) as session:
    write_export_zip(session, "soccernet-v3d", Path(sys.argv[2]), False, settings, release=sys.argv[3])
"""


def _accept(session: Session, system_id: int) -> None:
    system = session.get(System, system_id)
    assert system is not None
    if system.review is None:
        system.review = ReviewDecision(status=ReviewStatus.ACCEPTED)
    system.review.status = ReviewStatus.ACCEPTED
    system.review_status = ReviewStatus.ACCEPTED
    session.commit()


def _database(tmp_path: Path) -> tuple[str, Settings, Session, list[int]]:
    url = f"sqlite:///{tmp_path / 'v3d.sqlite3'}"
    migrate_new_database(url)
    settings = Settings(database_url=url, calibration_workers=1)
    session = Session(make_engine(url))
    game = make_game(session)
    ids = [make_system(session, settings, game, f"{i}.png", image_dir=tmp_path).system_id for i in range(1, 4)]
    for sid in ids:
        _accept(session, sid)
    return url, settings, session, ids


@pytest.mark.processes
def test_a_release_exports_to_the_same_bytes_from_two_processes_and_its_hash_is_recomputed(tmp_path: Path) -> None:
    url, settings, session, ids = _database(tmp_path)
    release_hash = create_release(session, "v1", "note", actor="adam").hash
    session.close()
    outs = [tmp_path / f"export-{k}.zip" for k in range(2)]
    for out in outs:
        done = subprocess.run([sys.executable, "-c", _EXPORT, url, str(out), "v1"], capture_output=True, text=True,
                              timeout=300)
        assert done.returncode == 0, done.stderr
    first, second = (o.read_bytes() for o in outs)
    assert first == second and len(first) > 1000
    # the recipe of docs/exports.md, from the download alone
    with zipfile.ZipFile(io.BytesIO(first)) as zf:
        manifest = json.loads(zf.read("v3d-release.json"))
        stored = zf.getinfo("v3d-release/documents.jsonl.gz")
        assert stored.compress_type == zipfile.ZIP_STORED  # gzip already: the zip holds it as it is
        lines = gzip.decompress(zf.read(stored)).splitlines()
    digests = {hashlib.sha256(line).hexdigest() for line in lines}
    assert digests == set(manifest["games"].values()) | set(manifest["systems"].values())
    text = "".join(f"game {g} {d}\n" for g, d in sorted(manifest["games"].items(), key=lambda kv: int(kv[0])))
    text += "".join(f"system {s} {d}\n" for s, d in sorted(manifest["systems"].items(), key=lambda kv: int(kv[0])))
    assert hashlib.sha256(text.encode()).hexdigest() == manifest["hash"] == release_hash
    assert sorted(int(s) for s in manifest["systems"]) == ids


def test_later_edits_never_change_a_release_and_unchanged_systems_cost_no_document(tmp_path: Path) -> None:
    url, settings, session, ids = _database(tmp_path)
    v1 = create_release(session, "v1")
    before = write_export_zip(session, "soccernet-v3d", tmp_path / "a.zip", False, settings, release="v1")
    documents = session.scalar(sa.select(sa.func.count()).select_from(ReleaseDocument))
    same = create_release(session, "v1-again")
    assert same.hash == v1.hash  # content only: not the name, time or author
    assert session.scalar(sa.select(sa.func.count()).select_from(ReleaseDocument)) == documents
    # move one ball 4 px and recompute: the live data changes, v1 does not
    label = session.scalars(sa.select(BallLabel).join(BallLabel.frame)
                            .where(sa.text("frames.system_id = :s")).params(s=ids[0])).first()
    assert label is not None and label.box is not None
    label.box = [label.box[0] + 4, label.box[1], label.box[2] + 4, label.box[3]]
    system = session.get(System, ids[0])
    assert system is not None
    recompute_system(session, system, settings)
    session.commit()
    v2 = create_release(session, "v2")
    assert v2.hash != v1.hash
    # one new system document (and the game's, whose as-of time is its newest change), the others named again
    added = session.scalar(sa.select(sa.func.count()).select_from(ReleaseDocument)) - documents
    assert added <= 2
    assert release_content(session, get_release(session, "v1")).systems == release_content(session, v1).systems
    after = write_export_zip(session, "soccernet-v3d", tmp_path / "b.zip", False, settings, release="v1")
    assert (tmp_path / "a.zip").read_bytes() == (tmp_path / "b.zip").read_bytes()
    assert before["hash"] == after["hash"] == v1.hash
    diff = diff_releases(session, "v1", "v2")
    assert [c["system_id"] for c in diff.changed] == [ids[0]] and not diff.added and not diff.removed
    assert diff.changed[0]["ball3d_moved_m"] > 0
    session.close()


def _members(data: bytes) -> dict[str, bytes]:
    with zipfile.ZipFile(io.BytesIO(data)) as zf:
        return {n: zf.read(n) for n in zf.namelist()}


def test_the_cameras_export_of_a_release_is_the_live_one_then_and_stays_the_same(tmp_path: Path) -> None:
    url, settings, session, ids = _database(tmp_path)
    release = create_release(session, "v1")
    write_export_zip(session, "cameras", tmp_path / "live.zip", False, settings)
    made = write_export_zip(session, "cameras", tmp_path / "r1.zip", False, settings, release="v1")
    assert made["hash"] == release.hash and made["cameras"] == 9
    live, ours = _members((tmp_path / "live.zip").read_bytes()), _members((tmp_path / "r1.zip").read_bytes())
    named = {n: ours.pop(n) for n in ("v3d-release.json", "v3d-release/", "v3d-release/documents.jsonl.gz")}
    assert ours == live  # the same index, ground truth and predictions as the database had then
    assert json.loads(named["v3d-release.json"])["hash"] == release.hash
    # a later edit changes the live export, not the release's
    label = session.scalars(sa.select(BallLabel).join(BallLabel.frame)
                            .where(sa.text("frames.system_id = :s")).params(s=ids[1])).first()
    assert label is not None and label.box is not None
    label.box = [label.box[0] + 4, label.box[1], label.box[2] + 4, label.box[3]]
    session.commit()
    _decline(session, ids[2])
    write_export_zip(session, "cameras", tmp_path / "r2.zip", False, settings, release="v1")
    assert (tmp_path / "r2.zip").read_bytes() == (tmp_path / "r1.zip").read_bytes()
    session.close()


def _decline(session: Session, system_id: int) -> None:
    system = session.get(System, system_id)
    assert system is not None and system.review is not None
    system.review.status = system.review_status = ReviewStatus.REJECTED
    session.commit()


def test_yolo_and_coco_of_a_release_are_the_live_ones_then_naming_it_and_stay_the_same(tmp_path: Path) -> None:
    url, settings, session, ids = _database(tmp_path)
    release = create_release(session, "v1")
    marker = {"name": "v1", "hash": release.hash}
    for fmt in ("yolo", "coco"):
        write_export_zip(session, fmt, tmp_path / f"{fmt}-live.zip", False, settings)
        made = write_export_zip(session, fmt, tmp_path / f"{fmt}-r1.zip", False, settings, release="v1")
        assert made["hash"] == release.hash and sum(made["images"].values()) == 6  # two views with an image each
        live = _members((tmp_path / f"{fmt}-live.zip").read_bytes())
        ours = _members((tmp_path / f"{fmt}-r1.zip").read_bytes())
        for name in ("v3d-release.json", "v3d-release/", "v3d-release/documents.jsonl.gz"):
            ours.pop(name)
        manifest = json.loads(ours.pop("manifest.json"))
        assert manifest.pop("release") == marker and manifest == json.loads(live.pop("manifest.json"))
        if fmt == "yolo":
            named, rest = ours.pop("data.yaml").decode().split("\n", 1)
            assert named == f"# release v1 (hash {release.hash})" and rest == live.pop("data.yaml").decode()
        else:
            for split in ("train", "test"):
                a, b = json.loads(ours.pop(f"{split}/instances.json")), json.loads(live.pop(f"{split}/instances.json"))
                assert a.pop("info")["v3d_release"] == marker
                b.pop("info")
                assert a == b
        assert ours == live  # the same images and labels as the database had then
    # a later move and a rejection change the database, not the release's exports
    label = session.scalars(sa.select(BallLabel).join(BallLabel.frame)
                            .where(sa.text("frames.system_id = :s")).params(s=ids[0])).first()
    assert label is not None and label.box is not None
    label.box = [label.box[0] + 4, label.box[1], label.box[2] + 4, label.box[3]]
    system = session.get(System, ids[0])
    assert system is not None
    recompute_system(session, system, settings)
    session.commit()
    _decline(session, ids[1])
    for fmt in ("yolo", "coco"):
        write_export_zip(session, fmt, tmp_path / f"{fmt}-r2.zip", False, settings, release="v1")
        assert (tmp_path / f"{fmt}-r2.zip").read_bytes() == (tmp_path / f"{fmt}-r1.zip").read_bytes()
    session.close()


def test_an_unconfirmed_placement_is_in_no_release_export_as_in_no_live_one(tmp_path: Path) -> None:
    """A ball placed from a doubt's fix (a detector's box) that no person confirmed is released as no label: the
    release's YOLO export draws no ball box there, exactly as the live export made at the same moment."""
    url, settings, session, ids = _database(tmp_path)
    label = session.scalars(sa.select(BallLabel).join(BallLabel.frame)
                            .where(sa.text("frames.system_id = :s")).params(s=ids[0])
                            .order_by(BallLabel.frame_id)).first()
    assert label is not None and label.box is not None and not label.suggested
    label.provenance = {"detector": "det", "score": 0.9}
    session.commit()
    assert label.suggested
    write_export_zip(session, "yolo", tmp_path / "live.zip", False, settings)
    create_release(session, "v1")
    write_export_zip(session, "yolo", tmp_path / "r1.zip", False, settings, release="v1")
    live, ours = _members((tmp_path / "live.zip").read_bytes()), _members((tmp_path / "r1.zip").read_bytes())
    labels = {n: v for n, v in ours.items() if n.startswith("labels/") and n.endswith(".txt")}
    assert labels == {n: v for n, v in live.items() if n.startswith("labels/") and n.endswith(".txt")}
    balls = sum(line.startswith(b"0 ") for v in labels.values() for line in v.splitlines())
    assert balls == 5  # six views with an image, one holding only the unconfirmed placement
    session.close()


def test_a_release_counts_its_systems_accepted_without_a_3d_ball_from_its_documents(tmp_path: Path,
                                                                                    monkeypatch) -> None:
    from app.services.releases import content

    url, settings, session, ids = _database(tmp_path)
    # one accepted system's ball labels removed: its views agree on no ball, and it stays accepted
    for label in session.scalars(sa.select(BallLabel).join(BallLabel.frame)
                                 .where(sa.text("frames.system_id = :s")).params(s=ids[1])):
        session.delete(label)
    system = session.get(System, ids[1])
    assert system is not None
    recompute_system(session, system, settings)
    session.commit()
    _accept(session, ids[1])
    assert session.scalars(sa.select(Triangulation.ball3d).where(Triangulation.system_id == ids[1])).one() is None
    v1 = create_release(session, "v1")
    assert content.systems_without_ball(session, v1) == 1
    # counted again from the stored documents, as a new process would, whatever the live data became since
    _accept(session, ids[0])
    monkeypatch.setattr(content, "_WITHOUT_BALL", {})
    assert content.systems_without_ball(session, get_release(session, "v1")) == 1
    assert v1.systems == 3
    session.close()
