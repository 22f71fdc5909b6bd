"""A release made by an older v3d (158795d, unpacked from this repository's history) on its SQLite database keeps its
hash, its API token and each export's bytes once this tree migrates the database: the small version of
``benchmarks/release_upgrade.py`` (which does the same through two running servers and the demo)."""
from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest
import sqlalchemy as sa
from fastapi.testclient import TestClient
from sqlalchemy.orm import Session

from app.core.config import Settings
from app.db.session import make_engine, upgrade_database
from app.main import create_app
from app.services.exports.files import write_export_zip
from tests.services.releases.make_golden import write_issia

pytestmark = pytest.mark.processes

ROOT = Path(__file__).resolve().parents[3]
OLD = "158795d"
FORMATS = ("soccernet-v3d", "yolo", "coco", "cameras", "issia-3d")

#: Run by the older tree: its own factories' scenes and the ISSIA folder given, accepted, a release made, an API
#: token issued, every format exported; prints the release's hash and the token.
_OLD = """
import json, sys
from pathlib import Path
from sqlalchemy import select
from sqlalchemy.orm import Session
from app.core.config import Settings
from app.db.models import System
from app.db.session import make_engine, upgrade_database
from app.services.accounts.users import create_user, issue_token
from app.services.curation.decisions import decide_review
from app.services.issia.sequences import import_issia
from app.services.releases.content import create_release
from app.services.transfer.export_files import write_export_zip
from tests.api.factories import make_game, make_system

url, issia, out = sys.argv[1], Path(sys.argv[2]), Path(sys.argv[3])
upgrade_database(url)
settings = Settings(database_url=url, calibration_workers=1)
with Session(make_engine(url)) as session:
    game = make_game(session)
    ids = [make_system(session, settings, game, f"{i}.png", image_dir=out, shift_px=(0.0, float(i), 0.0)).system_id
           for i in range(1, 3)]
    import_issia(session, issia, settings)
    ids += list(session.scalars(select(System.id).where(System.frame_index.is_not(None))))
    for sid in ids:
        decide_review(session, system_id=sid, status="accepted")
    session.commit()
    release = create_release(session, "before", "made by the older tree", actor="old")
    create_user(session, "ada", "admin", "a long enough password")
    token = issue_token(session, "ada", label="kept").token
    session.commit()
    for fmt in sys.argv[4:]:
        write_export_zip(session, fmt, out / f"{fmt}.zip", False, settings, release="before")
    print(json.dumps({"hash": release.hash, "systems": release.systems, "token": token}))
"""


def _old_tree(dest: Path) -> Path:
    archive = subprocess.run(["git", "-C", str(ROOT), "archive", OLD], capture_output=True)
    if archive.returncode != 0:
        pytest.skip(f"no {OLD} in this checkout's history (a shallow clone?): {archive.stderr.decode()[:200]}")
    dest.mkdir()
    subprocess.run(["tar", "-x", "-C", str(dest)], input=archive.stdout, check=True)
    return dest


def _revision(url: str) -> str:
    with make_engine(url).connect() as con:
        return str(con.execute(sa.text("SELECT version_num FROM alembic_version")).scalar_one())


def test_a_release_made_by_the_older_tree_keeps_its_hash_token_and_export_bytes(tmp_path: Path) -> None:
    old = _old_tree(tmp_path / "old")
    url = f"sqlite:///{tmp_path / 'v3d.sqlite3'}"
    made = tmp_path / "made"
    made.mkdir()
    done = subprocess.run([sys.executable, "-c", _OLD, url, str(write_issia(tmp_path / "issia")), str(made), *FORMATS],
                          cwd=old, env={**os.environ, "PYTHONPATH": str(old)}, capture_output=True, text=True,
                          timeout=600)
    assert done.returncode == 0, done.stderr[-3000:]
    before = json.loads(done.stdout.strip().splitlines()[-1])
    exported = {fmt: (made / f"{fmt}.zip").read_bytes() for fmt in FORMATS}
    for fmt in FORMATS:
        (made / f"{fmt}.zip").unlink()  # the export files made before the upgrade are gone

    old_revision = _revision(url)
    upgrade_database(url)  # as ``v3d serve`` does at start-up
    assert _revision(url) != old_revision  # the schema did move on since
    settings = Settings(database_url=url, calibration_workers=1)
    shown = TestClient(create_app(settings)).get("/api/releases/before",
                                                 headers={"Authorization": f"Bearer {before['token']}"})
    assert shown.status_code == 200, shown.text
    assert (shown.json()["hash"], shown.json()["systems"]) == (before["hash"], 7)
    with Session(make_engine(url)) as session:
        for fmt in FORMATS:
            report = write_export_zip(session, fmt, tmp_path / f"{fmt}.zip", False, settings, release="before")
            assert report["hash"] == before["hash"]
            assert (tmp_path / f"{fmt}.zip").read_bytes() == exported[fmt], fmt


@pytest.mark.slow
def test_the_demo_release_made_by_the_older_servers_keeps_its_hash_and_every_export_byte(tmp_path: Path) -> None:
    """The full-size upgrade (``benchmarks/release_upgrade.py``): the older tree serves the demo (and a stretch of
    the ISSIA dev sequence with ``../shared``), a release is made and exported in every format through its API, then
    this tree's server migrates the database at start-up and gives the same hash and the same bytes."""
    from benchmarks import release_upgrade
    from tests.seaweed import free_ports

    if subprocess.run(["git", "-C", str(ROOT), "cat-file", "-e", OLD], capture_output=True).returncode != 0:
        pytest.skip(f"no {OLD} in this checkout's history (a shallow clone?)")
    out = release_upgrade.run(OLD, tmp_path / "work", free_ports(1)[0])
    assert out["token_after_upgrade"] == 200 and out["hash_kept"], out
    assert out["schema"][0] != out["schema"][1], out["schema"]
    assert set(out["formats"]) == set(release_upgrade.FORMATS), out["formats"]
    assert all(f["equal"] for f in out["formats"].values()), out["formats"]
    assert out["ok"] and out["release"]["systems"] > 0, out
