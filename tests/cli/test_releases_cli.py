"""``v3d release create|list|show|diff`` and ``v3d export soccernet-v3d --release`` on a SQLite file: a release made,
listed and shown with its hash; a taken name exits 2; a diff after a system is rejected names it removed (JSON and
CSV); the release exported twice into two folders gives the same files, byte for byte."""
from __future__ import annotations

import json
from pathlib import Path

from sqlalchemy.orm import Session
from typer.testing import CliRunner

import app.cli.datasets  # noqa: F401  # registers its commands
import app.cli.releases  # noqa: F401  # registers its commands
from app.cli._root import cli
from app.core.config import Settings
from app.db.models import ReviewDecision, ReviewStatus, System
from app.db.session import make_engine
from tests.api.factories import make_game, make_system
from tests.conftest import migrate_new_database


def _decide(session: Session, system_id: int, status: ReviewStatus) -> None:
    system = session.get(System, system_id)
    assert system is not None
    system.review = system.review or ReviewDecision()
    system.review.status = system.review_status = status
    session.commit()


def _files(root: Path) -> dict[str, bytes]:
    return {p.relative_to(root).as_posix(): p.read_bytes() for p in sorted(root.rglob("*")) if p.is_file()}


def test_release_commands(tmp_path: Path) -> None:
    url = f"sqlite:///{tmp_path / 'v3d.sqlite3'}"
    migrate_new_database(url)
    settings = Settings(database_url=url, calibration_workers=1)
    with Session(make_engine(url)) as session:
        game = make_game(session)
        ids = [make_system(session, settings, game, f"{i}.png", image_dir=tmp_path).system_id for i in (1, 2)]
        for sid in ids:
            _decide(session, sid, ReviewStatus.ACCEPTED)
    runner = CliRunner()
    db = ["--database-url", url]
    made = runner.invoke(cli, ["release", "create", "v1", "--note", "two", *db])
    assert made.exit_code == 0, made.output
    v1 = json.loads(made.output)
    assert v1["systems"] == 2 and v1["views"] == 6 and len(v1["hash"]) == 64
    taken = runner.invoke(cli, ["release", "create", "v1", *db])
    assert taken.exit_code == 2 and "exists" in taken.output
    with Session(make_engine(url)) as session:
        _decide(session, ids[1], ReviewStatus.REJECTED)
    assert runner.invoke(cli, ["release", "create", "v2", *db]).exit_code == 0
    listed = runner.invoke(cli, ["release", "list", *db]).output.splitlines()
    assert [line.split("\t")[0] for line in listed] == ["v1", "v2"] and v1["hash"] in listed[0]
    assert json.loads(runner.invoke(cli, ["release", "show", "v1", *db]).output) == v1
    assert runner.invoke(cli, ["release", "show", "v9", *db]).exit_code == 2
    diff = json.loads(runner.invoke(cli, ["release", "diff", "v1", "v2", *db]).output)
    assert [s["system_id"] for s in diff["removed"]] == [ids[1]] and diff["added"] == diff["changed"] == []
    rows = runner.invoke(cli, ["release", "diff", "v1", "v2", "--csv", *db]).output.splitlines()
    assert rows[0] == "change,system_id,name,game,ball3d_moved_m,views,why" and rows[1].startswith(f"removed,{ids[1]},")
    assert rows[1].endswith(",rejected")  # why it left the release: rejected since
    for out in ("a", "b"):
        done = runner.invoke(cli, ["export", "soccernet-v3d", str(tmp_path / out), "--release", "v1", *db])
        assert done.exit_code == 0, done.output
    a, b = _files(tmp_path / "a"), _files(tmp_path / "b")
    assert a == b and "v3d-release.json" in a and "SNv3D.csv" in a
    assert runner.invoke(cli, ["export", "soccernet-v3d", str(tmp_path / "c"), "--release", "v1", "--all",
                               *db]).exit_code == 2
    cams = runner.invoke(cli, ["export", "cameras", str(tmp_path / "cams"), "--release", "v1", *db])
    assert cams.exit_code == 0 and "6 camera(s)" in cams.output, cams.output
    index = json.loads((tmp_path / "cams" / "cameras.json").read_text())
    assert sum(len(s["views"]) for s in index["sets"]) == 6
    assert json.loads((tmp_path / "cams" / "v3d-release.json").read_text())["hash"] == v1["hash"]
    import app.cli.detectors  # noqa: F401  # registers v3d export yolo|coco
    yolo = runner.invoke(cli, ["export", "yolo", str(tmp_path / "yolo"), "--release", "v1", *db])
    assert yolo.exit_code == 0 and "train: " in yolo.output, yolo.output
    assert json.loads((tmp_path / "yolo" / "manifest.json").read_text())["release"] == {"name": "v1",
                                                                                         "hash": v1["hash"]}
